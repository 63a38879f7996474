"""Each drone's geofence: an inclusion polygon around its whole flight, and a ceiling.

The polygon is the convex hull of everything the drone flies over in every sortie - its zone's
cells, its launch point (take-off, return, landing) and every waypoint - grown by a margin
(SafetySettings.fence_margin_m), with mitred corners so it keeps the hull's few vertices (an
autopilot stores fence points in scarce memory). A hull of more than MAX_VERTICES points is
replaced by its minimum rotated rectangle (4 points), which contains it. The ceiling is the
drone's altitude plus the same margin, kept at or under --max-altitude when that leaves room. Over a
DEM the altitude is a height above the ground while the ceiling, as autopilots take it (FENCE_ALT_MAX),
is relative to home: the ceiling then rises by the ground's rise in the fenced area above the launch
point (the highest ground inside the polygon minus the ground at home, never below 0), so that a drone
at its planned height above the highest ground it may fly over is not cut.

The fence goes into the drone's .plan files as QGroundControl's geoFence (one inclusion polygon)
with the ceiling as `maxAltitude` (QGroundControl ignores the key; ArduPilot takes its ceiling
from the FENCE_ALT_MAX parameter, PX4 from GF_MAX_VER_DIST): bridge/ uploads the polygon with
the mission. Grid metres (row axis, column axis) in, latitude/longitude out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from missionplan.bridge.formats.mission_items import (CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, Mission,
                                                      MissionItem, MissionType)
from missionplan.geo.frame import GridFrame

MAX_VERTICES = 24
# The ground inside a fence is sampled on a grid this fine (metres), coarser for a large fence so that it
# stays under GROUND_SAMPLES points; with the polygon's own vertices.
GROUND_STEP_M = 5.0
GROUND_SAMPLES = 250_000

# The ground under a plan over a DEM: heights above sea level at arrays of latitudes and longitudes.
GroundHeights = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass
class Fence:
    polygon_m: np.ndarray  # (n, 2) vertices in grid metres (row_m, col_m), not closed
    latlon: np.ndarray  # (n, 2) the same vertices as latitude, longitude
    max_altitude_m: float
    ground_rise_m: float | None = None  # over a DEM: how far the ceiling was raised for the ground (None: flat)

    def mission(self) -> Mission:
        """The fence as MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION items (what bridge/ uploads)."""
        # autocontinue 0, as the .plan reader makes fence points and ArduPilot stores them
        items = [MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=float(len(self.latlon)),
                             x=float(lat), y=float(lon), z=0.0, autocontinue=False) for lat, lon in self.latlon]
        return Mission(items=items, mission_type=MissionType.FENCE)


def drone_fence(frame: GridFrame, zone_cells: np.ndarray, points_m: np.ndarray, altitude_m: float,
                margin_m: float, max_altitude_m: float, ground: GroundHeights | None = None) -> Fence:
    """The fence around `zone_cells` (n, 2 grid cells) and `points_m` (m, 2 grid metres: the launch point
    first, then the waypoints). `ground`: the plan is over a DEM, its altitudes above the ground; the ceiling
    rises by the ground's rise above the launch point inside the fence (ground_rise_m)."""
    import shapely

    cell = frame.cell_m
    corners = [np.asarray(points_m, dtype=float).reshape(-1, 2)]
    if len(zone_cells):
        centres = np.asarray(zone_cells, dtype=float) * cell
        for dr in (-0.5, 0.5):
            for dc in (-0.5, 0.5):
                corners.append(centres + np.array([dr, dc]) * cell)
    hull = shapely.MultiPoint(np.vstack(corners)).convex_hull
    if len(shapely.get_coordinates(hull)) - 1 > MAX_VERTICES:
        hull = shapely.minimum_rotated_rectangle(hull)
    grown = hull.buffer(margin_m, quad_segs=2, join_style="mitre", mitre_limit=2.0)
    ring = shapely.get_coordinates(grown.exterior)[:-1]
    lat, lon = frame.grid_to_latlon(ring[:, 0] / cell, ring[:, 1] / cell)
    ceiling = altitude_m + margin_m
    if ceiling > max_altitude_m and max_altitude_m > altitude_m + 1.0:
        ceiling = max_altitude_m
    if ground is None:
        return Fence(ring, np.column_stack([lat, lon]), round(float(ceiling), 2))
    rise = ground_rise_m(frame, grown, np.asarray(points_m, dtype=float).reshape(-1, 2)[0], ground)
    return Fence(ring, np.column_stack([lat, lon]), round(float(ceiling + rise), 2), round(rise, 2))


def ground_rise_m(frame: GridFrame, area: Any, home_m: np.ndarray, ground: GroundHeights) -> float:
    """How far the ground inside `area` (a shapely polygon in grid metres) rises above the ground at `home_m`
    (grid metres), never below 0: its highest point sampled every GROUND_STEP_M (or coarser, GROUND_SAMPLES at
    most) and at the polygon's vertices."""
    import shapely

    cell = frame.cell_m
    min_r, min_c, max_r, max_c = shapely.bounds(area)
    step = max(GROUND_STEP_M, float(np.sqrt((max_r - min_r) * (max_c - min_c) / GROUND_SAMPLES)))
    rows, cols = np.meshgrid(np.arange(min_r, max_r + step, step), np.arange(min_c, max_c + step, step), indexing="ij")
    inside = shapely.contains_xy(area, rows.ravel(), cols.ravel())
    ring = shapely.get_coordinates(shapely.get_exterior_ring(area))
    at_r = np.concatenate([rows.ravel()[inside], ring[:, 0], home_m[:1]])
    at_c = np.concatenate([cols.ravel()[inside], ring[:, 1], home_m[1:2]])
    lat, lon = frame.grid_to_latlon(at_r / cell, at_c / cell)
    heights = np.asarray(ground(lat, lon), dtype=float)
    home, highest = float(heights[-1]), float(np.nanmax(heights))
    return max(0.0, highest - home)
