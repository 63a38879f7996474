"""Grid plan -> smoothed tracks -> missions -> mission files (`uavK.plan`, `uavK.waypoints`).

The last stage of `missionplan plan` when the grid is georeferenced: each drone's cell path
goes through the trajectory corrector, its waypoints are turned into latitude/longitude by
the grid frame, and missions.build_mission makes its MAVLink mission. Drone k's files are
`uavK.*` (K from 1): it is meant for the autopilot with system id K. All files are written
to a temporary name and renamed.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.base.naming import Named
from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.formats.missionfile import PlanFile, write_mission_file
from missionplan.geo.frame import GridFrame

from ..grid.planresult import PlanResult
from ..grid.world import FOOTPRINT_RADIUS
from ..maps.gridmap import GridMap, MapError
from .corrector import MARGIN_CELLS, CorrectedPath, correct_path
from .geofence import Fence, drone_fence
from .plan_blocks import ClearancePromise, Closest, DronePlan, FencePlan, PathShape, SeparationPromise, SortiePlan
from .drone_missions import DroneMission, GroundHeights, MissionSettings
from .layers import planned_photos
from .photo_overlap import OverlapMeasure, measure_overlap
from .safety import SafetySettings
from .separation import Layering, SeparationError, choose_layers, closest_over_sorties, position_at
from .sorties import Sortie, sortie_file, split_sorties
from .track_missions import LaunchWays, track_mission
from .timeline import ASSUMES, PX4_ASSUMES, FlightModel, closest_approach, leg_speeds, planned_track

SORTIE_FIT_TRIES = 6  # re-cuts of a drone's sorties when one came out over the budget on the timeline


@dataclass
class FlightPlans:
    corrected: list[CorrectedPath]
    waypoints_latlon: list[np.ndarray]  # per drone (n, 2): the corrected waypoints as (lat, lon)
    drones: list[DroneMission]  # per drone, its first sortie's mission (its only one without an endurance)
    settings: MissionSettings  # with the altitude step the separation chose
    timed: dict[int, np.ndarray]  # sysid -> (n, 4) t, row_m, col_m, up_m of the first sortie (timeline)
    sorties: list[list[DroneMission]] = field(default_factory=list)  # per drone, every sortie's mission
    sortie_tracks: list[dict[int, np.ndarray]] = field(default_factory=list)  # per sortie, sysid -> timed track
    sortie_routes: list[list[np.ndarray]] = field(default_factory=list)  # per drone, per sortie: launch + waypoints, grid m
    sortie_starts: list[np.ndarray] = field(default_factory=list)  # per drone (J, 2) grid row, col: each sortie's survey start
    fences: list[Fence] = field(default_factory=list)  # per drone; empty when no safety settings were given
    layering: Layering | None = None
    safety: SafetySettings | None = None
    ground: GroundHeights | None = None  # the ground under a plan over a DEM (its heights are above it)
    terrain_spacing: int | None = None  # ArduPilot's TERRAIN_SPACING the plan was checked at (terrain_missions)
    above_ground: list[tuple[float, float]] = field(default_factory=list)  # per drone: lowest, highest as flown

    def __post_init__(self) -> None:
        if not self.sorties:
            self.sorties = [[drone] for drone in self.drones]
        if not self.sortie_tracks:
            self.sortie_tracks = [self.timed]

    def relabel(self, ids: list[int]) -> None:
        """Give drone k the system id ids[k] (planned as k + 1): a re-plan's drones are the vehicles chosen
        to fly it, named by their own ids in the files, the report and the separation figures."""
        if len(ids) != len(self.sorties) or len(set(ids)) != len(ids):
            raise ValueError(f"{len(self.sorties)} drones need as many distinct ids, got {ids}")
        for k, missions in enumerate(self.sorties):
            for mission in missions:
                mission.sysid = ids[k]
        for k, drone in enumerate(self.drones):
            drone.sysid = ids[k]
        rename = {k + 1: ids[k] for k in range(len(ids))}
        self.timed = {rename[key]: track for key, track in self.timed.items()}
        self.sortie_tracks = [{rename[key]: track for key, track in tracks.items()} for tracks in self.sortie_tracks]

    def drone_flight_s(self) -> np.ndarray:
        """(drones,) each drone's flight time, all its sorties together."""
        return np.array([sum(m.flight_s for m in missions) for missions in self.sorties], dtype=float)

    def separation(self) -> SeparationPromise:
        """report.json's `separation`: the closest approach of two drones if all fly as planned; with
        safety settings, the minimum it guarantees and how."""
        approach = closest_over_sorties(self.sortie_tracks)
        promise = SeparationPromise(Closest.from_json(approach), approach["sortie"],
                                    PX4_ASSUMES if self.settings.autopilot == "px4" else ASSUMES,
                                    tuple(Closest.from_json(closest_approach(tracks)) for tracks in self.sortie_tracks))
        if self.safety is not None and self.layering is not None:
            promise = replace(promise, required_m=self.safety.min_separation_m, method=self.layering.method,
                              altitude_step_m=self.layering.step_m,
                              guaranteed_m=None if approach["3d"] is None else approach["3d"])
        return promise

    def clearance(self, gmap: GridMap, frame: GridFrame) -> ClearancePromise:
        """report.json's `clearance`: each drone's smallest horizontal distance from an obstacle cell over
        all its sorties (missionplan.mission.clearance) on `gmap` (the map as given, without the clearance band),
        the asked margin, and where the closest track is."""
        from .clearance import obstacle_shape, track_clearance

        shape = obstacle_shape(gmap.obstacle, frame.cell_m)
        per_drone, worst = [], (float("inf"), 0, np.zeros(2))
        for k, missions in enumerate(self.sortie_routes):
            distance, where = float("inf"), np.zeros(2)
            for route in missions:
                d, w = track_clearance(shape, route)
                if d < distance:
                    distance, where = d, w
            per_drone.append(round(distance, 2) if np.isfinite(distance) else None)
            if distance < worst[0]:
                worst = (distance, self.sorties[k][0].sysid, where)
        required = self.safety.clearance_m if self.safety is not None else None
        kept = None if not np.isfinite(worst[0]) else round(worst[0], 2)
        promise = ClearancePromise(required, kept, tuple(per_drone),
                                   required is None or kept is None or kept >= required - 1e-6)
        if kept is not None:
            lat, lon = frame.grid_to_latlon(np.array([worst[2][0] / frame.cell_m]), np.array([worst[2][1] / frame.cell_m]))
            promise = replace(promise, closest_uav=worst[1],
                              closest_at=(round(float(lat[0]), 7), round(float(lon[0]), 7)))
        return promise

    def photo_centres(self, frame: GridFrame) -> tuple[np.ndarray, np.ndarray]:
        """((n, 2) grid metres where every sortie's mission takes its photos (layers.planned_photos), in
        the order taken; (n,) each photo's sortie, numbered 0.. over the drones' sorties)."""
        def to_m(lat: float, lon: float) -> np.ndarray:
            row, col = frame.latlon_to_grid(np.array([lat]), np.array([lon]))
            return np.array([float(np.atleast_1d(row)[0]), float(np.atleast_1d(col)[0])]) * frame.cell_m

        trigger = self.settings.trigger_distance_m
        photos = [planned_photos(mission.mission.items, trigger, to_m) for missions in self.sorties for mission in missions]
        runs = np.concatenate([np.full(len(points), k) for k, points in enumerate(photos)]) if photos else np.zeros(0)
        return (np.vstack(photos) if photos else np.zeros((0, 2))), runs

    def overlap(self, frame: GridFrame, targets: np.ndarray, side_overlap: float | None = None,
                flyable: np.ndarray | None = None) -> OverlapMeasure:
        """The overlaps the planned photos give (photo_overlap.measure_overlap): every sortie's photos where
        its mission takes them (layers.planned_photos), each sortie a run, against the front overlap the
        settings ask and `side_overlap` (a fraction, None: not asked); `targets` (n, 2) the grid cells to
        photograph; `flyable` the grid's cells a photo may be centred on (splits reachable and bounded
        points). The footprint is the lowest drone's (settings.footprint_m): a higher layer sees more."""
        centres, runs = self.photo_centres(frame)
        return measure_overlap(centres, runs, self.settings.footprint_m, targets, frame.cell_m,
                               asked_front=self.settings.overlap, asked_side=side_overlap, flyable=flyable)

    def drone_plans(self) -> tuple[DronePlan, ...]:
        """report.json's `drones`: one per drone (totals over its sorties, then each sortie)."""
        rows = []
        for k, (track, missions) in enumerate(zip(self.corrected, self.sorties)):
            sysid = missions[0].sysid
            fence = None
            if self.fences:
                fence = FencePlan(len(self.fences[k].latlon), self.fences[k].max_altitude_m,
                                  self.safety.fence_margin_m if self.safety else None, self.fences[k].ground_rise_m)
            rows.append(DronePlan(
                id=sysid, cells=int(track.before["waypoints"]), waypoints=int(sum(m.waypoints for m in missions)),
                length_m=round(sum(m.length_m for m in missions), 2),
                flight_s=round(sum(m.flight_s for m in missions), 1),
                photos=int(sum(m.photos for m in missions)), altitude_m=round(self.settings.altitude_of(k), 2),
                before=PathShape.from_json(track.before), after=PathShape.from_json(track.after),
                sorties=tuple(SortiePlan(sortie_file(sysid, j + 1), round(m.flight_s, 1), m.photos, m.waypoints)
                              for j, m in enumerate(missions)),
                geofence=fence, above_ground_m=self.above_ground[k] if self.above_ground else None))
        return tuple(rows)


def _place(frame: GridFrame, point_m: np.ndarray) -> str:
    lat, lon = frame.grid_to_latlon(np.array([point_m[0] / frame.cell_m]), np.array([point_m[1] / frame.cell_m]))
    return f"{float(lat[0]):.6f},{float(lon[0]):.6f}, {point_m[2]:.1f} m up"


def make_flight_plans(result: PlanResult, frame: GridFrame, settings: MissionSettings,
                      safety: SafetySettings | None = None, base: GridMap | None = None,
                      ground: GroundHeights | None = None, keep: np.ndarray | None = None) -> FlightPlans:
    """Correct every drone's path and build its missions.

    With `safety`: routes longer than the endurance become sorties, the altitude layers are chosen so
    the separation holds (SeparationError names the pair and the place otherwise), each drone gets a
    geofence. Without it: one mission per drone at the altitudes of `settings`, nothing enforced.
    `base`: the map as given when the planner flew it with a clearance band (missionplan.mission.clearance): the
    corrector keeps the clearance from its obstacles and every target the grid path photographed.
    `ground`: the plan is over a DEM; its altitudes are heights above the ground (drone_missions). `keep`: cells
    where the corrector keeps a turn as a waypoint (lanes closer than a footprint, an overlap fill's detours:
    correct_path)."""
    paths = result.run.paths
    base = result.gmap if base is None else base
    targets = result.world.reachable if base is result.gmap else base.target
    cell = frame.cell_m
    corrected, latlons, launches, routes = [], [], [], []
    model = FlightModel.for_autopilot(settings.autopilot, settings.speed_m_s, settings.acceptance_m,
                                      settings.transit_speed_m_s)
    # Not touching an obstacle square within a box buffer of `margin` cells keeps the segment at least
    # that far from it (Chebyshev distance <= Euclidean).
    margin_cells = MARGIN_CELLS if safety is None else max(MARGIN_CELLS, safety.clearance_m / cell)
    for k in range(paths.shape[0]):
        # A diagonal is credited only with the cells every photo spacing still sees.
        track = correct_path(paths[k], base.obstacle, targets, footprint_radius=FOOTPRINT_RADIUS,
                             sample_step=max(settings.trigger_distance_m / cell, 0.25), margin_cells=margin_cells,
                             keep=keep)
        waypoints = np.asarray(track.waypoints, dtype=float)
        latlons.append(np.column_stack(frame.grid_to_latlon(waypoints[:, 0], waypoints[:, 1])))
        launches.append(np.asarray(result.starts[k], dtype=float) * cell)
        routes.append(waypoints * cell)
        corrected.append(track)
    uavs = len(routes)
    budget = safety.budget_s if safety is not None else None
    # With safety settings, the way out to a sortie's start and the way home go round the obstacles
    # (along free cells of the planner's map, then through the corrector), never straight through them.
    homing = [LaunchWays(result.gmap.free, result.starts[k], base.obstacle, margin_cells, cell) if safety is not None
              else None for k in range(uavs)]

    def split_one(k: int, altitude: float) -> list[Sortie]:
        """Drone k's sorties, each proven within the budget on the timeline itself: the splitter times
        the way out and home as straight legs, but they go round obstacles, so a sortie that came out
        over the budget is cut again with a budget shrunk by the excess (a bounded number of times)."""
        target = budget
        for _ in range(SORTIE_FIT_TRIES):
            sorties = split_sorties(launches[k], routes[k], altitude, settings.end, model, target, f"uav{k + 1}",
                                    home_m=homing[k].home_m if homing[k] else None,
                                    step_m=cell if homing[k] else None)
            if budget is None:
                return sorties
            worst = max(float(planned_track(launches[k], flown(k, s), altitude, s.end, model, speeds(k, s))[-1, 0])
                        for s in sorties)
            if worst <= budget:
                return sorties
            target *= 0.98 * budget / worst
        raise MapError(Named("uav{0}: could not cut its route into sorties of at most {1:.0f} s (one still takes "
                             "{2:.0f} s): raise {endurance} or lower {reserve}", k + 1, budget, worst))

    def split(step: float) -> list[list[Sortie]]:
        layered = replace(settings, altitude_step_m=step)
        return [split_one(k, layered.altitude_of(k)) for k in range(uavs)]

    def legs(k: int, sortie: Sortie) -> tuple[np.ndarray, np.ndarray]:
        """(the way out, the way home) of a sortie, metres; empty where the flight needs none."""
        if homing[k] is None or not len(sortie.waypoints_m):
            return np.zeros((0, 2)), np.zeros((0, 2))
        out = homing[k].way(sortie.waypoints_m[0], outbound=True) if sortie.resumes else np.zeros((0, 2))
        back = homing[k].way(sortie.waypoints_m[-1], outbound=False) if sortie.end == "rtl" else np.zeros((0, 2))
        return out, back

    def flown(k: int, sortie: Sortie) -> np.ndarray:
        out, back = legs(k, sortie)
        return np.vstack([out, sortie.waypoints_m, back])

    def speeds(k: int, sortie: Sortie) -> np.ndarray:
        """The speed of each leg of flown(k, sortie): the ways out and home at the transit speed."""
        out, back = legs(k, sortie)
        return leg_speeds(model, len(out), len(sortie.waypoints_m), len(back), sortie.resumes)

    def tracks_for(step: float) -> list[dict[int, np.ndarray]]:
        sorties = split(step)
        count = max(len(s) for s in sorties)
        return [{k + 1: planned_track(launches[k], flown(k, sorties[k][j]), settings.altitude_m + k * step,
                                      sorties[k][j].end, model, speeds(k, sorties[k][j]))
                 for k in range(uavs) if j < len(sorties[k])} for j in range(count)]

    layering = None
    step = settings.altitude_step_m
    if safety is not None:
        try:
            layering = choose_layers(tracks_for, uavs, settings.altitude_m, settings.altitude_step_m,
                                     safety.min_separation_m, safety.max_altitude_m)
        except SeparationError as failure:
            if failure.layering is None:  # every candidate's top layer is above the ceiling
                failure.args = (Named("{min_separation} {0:g} m cannot be guaranteed{1}", safety.min_separation_m,
                                      failure.ceiling),)
                raise failure from None
            raise _separation_failure(failure, frame, tracks_for, safety) from None
        step = layering.step_m
    settings = replace(settings, altitude_step_m=step)
    all_sorties = split(step)
    sortie_tracks = tracks_for(step)
    missions: list[list[DroneMission]] = []
    starts, fences = [], []
    for k in range(uavs):
        launch_lat, launch_lon = frame.grid_to_latlon(launches[k][:1] / cell, launches[k][1:] / cell)
        home = (float(launch_lat[0]), float(launch_lon[0]))
        drone_missions = []
        for j, sortie in enumerate(all_sorties[k]):
            out, back = legs(k, sortie)
            drone_missions.append(track_mission(frame, k, home, sortie.waypoints_m, launches[k], settings,
                                                flight_s=float(sortie_tracks[j][k + 1][-1, 0]), end=sortie.end,
                                                resumes=sortie.resumes, out_m=out, back_m=back, ground=ground))
        missions.append(drone_missions)
        starts.append(np.array([s.waypoints_m[0] / cell for s in all_sorties[k] if len(s.waypoints_m)]).reshape(-1, 2))
        if safety is not None:
            points = np.vstack([launches[k][None, :]] + [flown(k, s) for s in all_sorties[k]])
            fences.append(drone_fence(frame, np.argwhere(result.zones.zone == k), points, settings.altitude_of(k),
                                      safety.fence_margin_m, safety.max_altitude_m, ground=ground))
    sortie_routes = [[np.vstack([launches[k][None, :], flown(k, s), launches[k][None, :]])
                      if s.end == "rtl" else np.vstack([launches[k][None, :], flown(k, s)])
                      for s in all_sorties[k]] for k in range(uavs)]
    plans = FlightPlans(corrected, latlons, [m[0] for m in missions], settings, sortie_tracks[0], missions,
                        sortie_tracks, sortie_routes, starts, fences, layering, safety, ground)
    if ground is not None:
        _heights_over_ground(plans, ground)
    return plans


def _heights_over_ground(plans: FlightPlans, ground: GroundHeights) -> None:
    """A plan over a DEM: the TERRAIN_SPACING ArduPilot needs to follow it, and each drone's lowest and highest
    height above the ground as its autopilot will fly its waypoint legs (terrain_missions)."""
    from .terrain_missions import flown_above_ground, terrain_spacing

    every = [m.mission for missions in plans.sorties for m in missions]
    if plans.settings.autopilot != "px4":  # the spacing is chosen from the heights as flown: those are reported
        plans.terrain_spacing, flown_each = terrain_spacing(every, ground)
    else:
        flown_each = [flown_above_ground(mission, ground, None) for mission in every]
    start = 0
    for missions in plans.sorties:
        flown = np.concatenate(flown_each[start:start + len(missions)])
        start += len(missions)
        flown = flown[np.isfinite(flown)]
        plans.above_ground.append((round(float(flown.min()), 2), round(float(flown.max()), 2)) if len(flown)
                                  else (float("nan"), float("nan")))


def _separation_failure(failure: SeparationError, frame: GridFrame,
                        tracks_for: Any, safety: SafetySettings) -> SeparationError:
    """The error naming the pair, the sortie, the time and the place of the closest approach."""
    layering = failure.layering
    assert layering is not None
    approach = layering.approach
    a, b = approach["pair_3d"]
    sortie = approach["sortie"]
    tracks = tracks_for(layering.step_m)[sortie - 1]
    origin = min(float(t[0, 0]) for t in tracks.values())
    where = position_at(tracks[a], origin + approach["at_s"])
    error = SeparationError(layering, failure.ceiling)
    error.args = (Named("{min_separation} {0:g} m cannot be guaranteed: uav{1} and uav{2} come within {3} m of each "
                        "other near {4}, {5} s into sortie {6} ({7}){8}. Lower {min_separation}, raise {max_altitude} "
                        "or move the launch points apart", safety.min_separation_m, a, b, approach["3d"],
                        _place(frame, where), approach["at_s"], sortie, layering.method, failure.ceiling),)
    return error


def write_flight_files(out: Path, plans: FlightPlans, autopilot: Flavour = Flavour.ARDUPILOT) -> list[Path]:
    """Write every sortie's uavK[-sJ].plan and .waypoints into `out`; returns the paths.

    `autopilot` is the target (`plan --autopilot`): each .plan carries its QGroundControl firmwareType
    (ArduPilot 3, PX4 12), which `upload` and `fly` check against the vehicle. The items are the same
    for both (PX4 SIH accepts and starts them; docs/px4-missions.md). PX4 gets no .waypoints: QGC WPL
    110's line 0 is home only by ArduPilot's convention (QGroundControl on PX4 reads it as a first
    waypoint at 0 m AMSL), and the format cannot say which autopilot it was written for."""
    written = []
    suffixes = (".plan", ".waypoints") if autopilot is Flavour.ARDUPILOT else (".plan",)
    for k, missions in enumerate(plans.sorties):
        fence = plans.fences[k] if plans.fences else None
        for j, drone in enumerate(missions):
            plan_file = PlanFile(mission=drone.mission, cruise_speed=plans.settings.speed_m_s,
                                 hover_speed=plans.settings.speed_m_s, firmware=autopilot)
            if fence is not None:
                plan_file.fence = fence.mission()
                plan_file.fence_max_altitude = fence.max_altitude_m
            for suffix in suffixes:
                path = out / sortie_file(drone.sysid, j + 1, suffix)
                write_mission_file(path, plan_file)
                written.append(path)
    return written
