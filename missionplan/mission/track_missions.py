"""Tracks -> missions: a drone's ways out and home round the obstacles, and its mission from its tracks.

The stage both `plan` and the live re-task end with: `plan` (flightplan.make_flight_plans) for each
battery sortie of each drone from its launch point, the re-task (missionplan.planning.retask) for a survivor's
new survey from where it hovers. Tracks are in grid metres (row, column times the cell size) of the
plan's GridFrame.
  LaunchWays        one drone's ways between its launch point and any cell, along free cells (breadth
                    first, once), straightened by the corrector with the clearance margin
  grid_m_to_latlon  (n, 2) grid metres -> (n, 2) latitude, longitude
  track_mission     one drone's mission from its survey track and its ways out and home
                    (drone_missions.build_mission, every leg also in latitude, longitude)
"""

from __future__ import annotations

import numpy as np

from missionplan.geo.frame import GridFrame

from .corrector import correct_path
from .drone_missions import DroneMission, GroundHeights, MissionSettings, build_mission


def grid_m_to_latlon(frame: GridFrame, points_m: np.ndarray) -> np.ndarray:
    """(n, 2) grid metres -> (n, 2) latitude, longitude."""
    if not len(points_m):
        return np.zeros((0, 2))
    grid = np.asarray(points_m, dtype=float) / frame.cell_m
    return np.column_stack(frame.grid_to_latlon(grid[:, 0], grid[:, 1]))


class LaunchWays:
    """One drone's ways between its launch point and any cell, along free cells (breadth first, once),
    straightened by the corrector with the clearance margin and no coverage duty."""

    def __init__(self, free: np.ndarray, launch: tuple[int, int], obstacle: np.ndarray, margin_cells: float,
                 cell_m: float) -> None:
        from .clearance import steps_toward

        source = np.zeros(free.shape, dtype=bool)
        source[tuple(launch)] = True
        self.steps, self.toward = steps_toward(free, source)
        self.obstacle, self.margin, self.cell = obstacle, margin_cells, cell_m
        self._ways: dict[tuple[int, int], np.ndarray] = {}

    def _cell(self, point_m: np.ndarray) -> tuple[int, int]:
        return int(round(point_m[0] / self.cell)), int(round(point_m[1] / self.cell))

    def home_m(self, point_m: np.ndarray) -> float:
        """Length of the free-cell way from the launch point to `point_m` (an upper bound of the flown one)."""
        steps = self.steps[self._cell(point_m)]
        return float(steps) * self.cell if steps >= 0 else float(np.hypot(*point_m)) + 1e9

    def way(self, point_m: np.ndarray, outbound: bool) -> np.ndarray:
        """Waypoints (metres) strictly between the launch point and `point_m`, out from launch or home to it;
        the way home ends over the launch point itself."""
        start = self._cell(point_m)
        if start not in self._ways:
            from .clearance import way_to_source

            track = correct_path(np.array(way_to_source(self.toward, start)), self.obstacle,
                                 np.zeros(self.obstacle.shape, dtype=bool),
                                 margin_cells=self.margin)
            self._ways[start] = np.asarray(track.waypoints, dtype=float) * self.cell  # point ... launch
        home = self._ways[start]
        if outbound:
            return home[::-1][1:-1]
        return home[1:]


def track_mission(frame: GridFrame, drone: int, home_latlon: tuple[float, float], survey_m: np.ndarray,
                  start_m: np.ndarray, settings: MissionSettings, flight_s: float, end: str | None = None,
                  resumes: bool = False, out_m: np.ndarray | None = None,
                  back_m: np.ndarray | None = None, ground: GroundHeights | None = None) -> DroneMission:
    """Drone `drone`'s mission (0-based) from its survey track `survey_m` (grid metres), flown from
    `start_m` (its launch point, or where it hovers), with its RTL home at home_latlon. out_m / back_m:
    the ways out to the survey and home from it (LaunchWays.way), flown with the camera off; None: none.
    flight_s, end, resumes, ground: as drone_missions.build_mission takes them."""
    transit = None if out_m is None else (grid_m_to_latlon(frame, out_m), out_m)
    back = None if back_m is None else (grid_m_to_latlon(frame, back_m), back_m)
    return build_mission(drone, home_latlon, grid_m_to_latlon(frame, survey_m), survey_m, start_m, settings,
                         flight_s=flight_s, end=end, resumes=resumes, transit=transit, back=back, ground=ground)
