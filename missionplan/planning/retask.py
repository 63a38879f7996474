"""Live re-tasking (`fly --replan`): when a drone is lost or ends early, plan what the flight has
not photographed yet for the drones still flying, from where they are, and prove it safe first.

Called by fly (missionplan/flight/fly.py, through the planner missionplan/cli/fly.py hands it: retask_planner,
fly's flight.retask_planner.RetaskPlanner) with what the flight knows at that moment: the photos the vehicles confirmed, each survivor's position, home and
flight time so far. It plans *everything* left, not only the lost drone's share: the survivors'
own unflown parts are re-split with it, so the result is a fresh plan for the survivors from that
moment (Lloyd/Voronoi zones, the same policy, clearance band and altitude layers as `plan`). Each
survivor's new mission: its camera on where it is, its survey, the way home round the obstacles
(mission.track_missions: LaunchWays, track_mission) to its real home, RTL. Before anything is uploaded:
- endurance: each survivor's new flight, on the timeline, fits in what its battery budget (the
  plan's endurance less the reserve) has left after the time it has flown;
- separation: the new tracks, all starting now from the survivors' positions in the air, never come
  closer than the plan's minimum separation plus two acceptance radii (a corner cut by each), even
  with any survivor ahead of or behind another by a few seconds and a share of the time since the
  release (OUT_OF_STEP, by autopilot; timeline.closest_approach_out_of_step): on one altitude their
  distance rests on timing, which a timeline started from a hover knows least well. The altitude
  layers are chosen on those tracks as `plan` chooses them (separation.choose_layers), and that
  distance is the promise the flight is judged against from then on;
- geofence: a new fence per survivor around its new zone, its track, its position and its home.
Any of these failing ends the re-task with the reason (RetaskPlanningError); the survivors fly on with the
missions they have, and `missionplan replan` plans the rest after landing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from missionplan.bridge.formats.mission_items import Mission

from .errors import RetaskPlanningError
from .field_plan import plan_field
from .terrain import folder_terrain
from ..flight.retask_planner import RetaskPlan, Survivor
from ..flight.plan_report import frame_of, missing_map, planned_grid, target_cells, to_grid_m
from ..flight.ledger import Ledger, covered_cells
from ..mission.clearance import clearance_band
from ..mission.geofence import drone_fence
from ..mission.plan_record import PlanRecord
from ..mission.separation import SeparationError, choose_layers
from ..mission.timeline import FlightModel, closest_approach_out_of_step, leg_speeds, planned_track
from ..mission.track_missions import LaunchWays, track_mission

# How far out of step two survivors may fly, t seconds after their release: floor_s + rate * t, by the
# autopilot the plan was made for. ArduCopter: its timeline is within 2-6 % of ArduCopter SITL
# (docs/flight-timeline.md), the mock flies the timeline itself; the floor is the spread of the releases.
# PX4: measured on PX4 SIH (sitl_tests/test_survey_px4.py), two survivors 1-3 s apart from their
# timelines within 20 s of the release (a corner costs 0-3.7 s against the model's one figure per
# angle), and one re-task promised at 31 m was flown at 15 m, over 3 s out of step; PX4 flights run
# within 13-20 % of their timeline (docs/px4-flight.md), two drones' errors partly cancelling.
OUT_OF_STEP = {"ardupilot": (0.5, 0.05), "px4": (3.0, 0.10)}  # autopilot -> (floor_s, rate)




def _free_cell(free: np.ndarray, cell: tuple[int, int], taken: set[tuple[int, int]]) -> tuple[int, int]:
    """cell if it is free and not taken, else the nearest such cell (the grid planner starts on free cells)."""
    rows, cols = free.shape
    r, c = min(max(cell[0], 0), rows - 1), min(max(cell[1], 0), cols - 1)
    if free[r, c] and (r, c) not in taken:
        return r, c
    candidates = np.argwhere(free)
    order = np.argsort(np.hypot(candidates[:, 0] - r, candidates[:, 1] - c))
    for index in order:
        found = (int(candidates[index, 0]), int(candidates[index, 1]))
        if found not in taken:
            return found
    raise RetaskPlanningError("no free cell to start a survivor from")


def retask_planner(plan_dir: Path, record: PlanRecord, survivors: Sequence[Survivor],
                   photos_latlon: np.ndarray) -> RetaskPlan | None:
    """plan_retask as fly's RetaskPlanner (flight.retask_planner): a plan that cannot be made, for any reason
    the planning side names (a map, a setting, a check), is a RetaskPlanningError with that reason."""
    try:
        return plan_retask(plan_dir, record, survivors, photos_latlon)
    except RetaskPlanningError:
        raise
    except ValueError as err:  # MapError, GeoError, SeparationError...: their one-line reason
        raise RetaskPlanningError(str(err)) from err


def plan_retask(plan_dir: Path, record: PlanRecord, survivors: Sequence[Survivor],
                photos_latlon: np.ndarray, policy: str | None = None) -> RetaskPlan | None:
    """The re-task of `survivors` (see the module docstring); None when nothing is left to photograph.
    photos_latlon: (n, 2) lat, lon of every photo the vehicles confirmed so far in this flight."""
    import time

    started = time.monotonic()
    stored = record.settings
    if stored is None:
        raise RetaskPlanningError(f"{plan_dir / 'report.json'}: no `settings` (planned by an older missionplan): plan again")
    settings, safety = stored.mission, stored.safety
    frame = frame_of(record)
    cell = frame.cell_m
    targets = target_cells(record)
    with Ledger.of(plan_dir) as ledger:  # earlier flights of the survey count too
        done = ledger.covered_mask()
        _, cells = covered_cells(ledger.survey, photos_latlon[:, 0], photos_latlon[:, 1])
    done[cells[:, 0], cells[:, 1]] = True
    left = targets[~done[targets[:, 0], targets[:, 1]]]
    if not len(left) or not survivors:
        return None
    base = planned_grid(record)
    band = clearance_band(base.obstacle, safety.clearance_m / cell)
    flyable = ~base.obstacle & ~band
    starts: list[tuple[int, int]] = []
    for s in survivors:
        r, c = frame.latlon_to_grid(np.array([s.lat]), np.array([s.lon]))
        starts.append(_free_cell(flyable, (int(np.rint(np.atleast_1d(r)[0])), int(np.rint(np.atleast_1d(c)[0]))),
                                 set(starts)))
    gmap = missing_map(record, left, starts, suffix="retask")
    # Endurance and separation are checked below, on the tracks the survivors will fly: plan_field's own
    # checks model drones taking off from the ground where they start, and these are in the air.
    terrain = folder_terrain(plan_dir, record)  # a plan over a DEM is re-tasked over the same ground
    ground = terrain.height_amsl if terrain is not None else None
    field = plan_field(gmap, len(survivors), frame, settings,
                       replace(safety, endurance_s=None, min_separation_m=0.0), ground=ground,
                       policy=policy or stored.policy, zone_method=stored.zones,
                       seed=0, progress=False, balance_zones=bool(stored.balance_zones),
                       lanes=stored.open_ground == "lanes", lane_spacing=stored.lane_spacing_cells)
    if field.plans is None:
        raise RetaskPlanningError(f"the re-task could not be planned: {field.result.run.failure}")
    plans = field.plans
    model = FlightModel.for_autopilot(settings.autopilot, settings.speed_m_s, settings.acceptance_m,
                                      settings.transit_speed_m_s)
    margin = max(0.5, safety.clearance_m / cell)
    here, homes, surveys, backs, routes, speeds = [], [], [], [], [], []
    for k, s in enumerate(survivors):
        here.append(to_grid_m(frame, [s.lat], [s.lon])[0])
        homes.append(to_grid_m(frame, [s.home[0]], [s.home[1]])[0])
        home_cell = _free_cell(flyable, (int(np.rint(homes[k][0] / cell)), int(np.rint(homes[k][1] / cell))), set())
        surveys.append(np.asarray(plans.corrected[k].waypoints, dtype=float) * cell)
        homing = LaunchWays(flyable, home_cell, base.obstacle, margin, cell)
        backs.append(homing.way(surveys[k][-1], outbound=False) if len(surveys[k]) else np.zeros((0, 2)))
        routes.append(np.vstack([surveys[k], backs[k], homes[k][None, :]]))
        # The way home at the transit speed where the mission has one (track_mission sets it before `backs`).
        speeds.append(np.append(leg_speeds(model, 0, len(surveys[k]), len(backs[k])),
                                model.transit_m_s if len(backs[k]) else model.speed_m_s))

    timed: dict[float, list[dict[int, np.ndarray]]] = {}  # per layer step: the chosen one is needed again

    def tracks_for(step: float) -> list[dict[int, np.ndarray]]:
        """The survivors' new flights with drone k at altitude + k * step, started together now. From where
        each is, already in the air: the timeline's climb from the ground is cut off (its length differs
        between layers and would shift the tracks against each other); each lands at home (RTL)."""
        if step not in timed:
            altitude = replace(settings, altitude_step_m=step).altitude_of
            timed[step] = [{s.sysid: airborne(planned_track(here[k], routes[k], altitude(k), "land", model, speeds[k]),
                                              altitude(k)) for k, s in enumerate(survivors)}]
        return timed[step]

    # Each may cut a corner by its acceptance radius, which the timeline cannot know: a margin for both.
    corners = 2.0 * settings.acceptance_m
    floor_s, rate = OUT_OF_STEP["px4" if settings.autopilot == "px4" else "ardupilot"]
    try:
        layering = choose_layers(tracks_for, len(survivors), settings.altitude_m, settings.altitude_step_m,
                                 safety.min_separation_m + corners, safety.max_altitude_m,
                                 measure=lambda tracks: closest_approach_out_of_step(tracks, floor_s, rate))
    except SeparationError as failure:
        if failure.layering is None:
            raise RetaskPlanningError(f"the re-task's altitude layers would not fit under the ceiling{failure.ceiling}") from None
        approach = failure.layering.approach
        a, b = approach["pair_3d"]
        raise RetaskPlanningError(f"the re-task would bring uav{a} and uav{b} within {approach['3d']:.2f} m of each other "
                          f"(at {approach['at_s']} s), under the minimum separation {safety.min_separation_m:g} m "
                          f"plus {corners:.2f} m for the corners each may cut, with either up to "
                          f"{floor_s:g} s + {rate:.0%} of the time out of step") from None
    layered = replace(settings, altitude_step_m=layering.step_m)
    tracks = tracks_for(layering.step_m)[0]
    missions, fences, resume, flight_s, photos = {}, {}, {}, {}, {}
    for k, s in enumerate(survivors):
        flight_s[s.sysid] = float(tracks[s.sysid][-1, 0])
        if safety.budget_s is not None and s.flown_s + flight_s[s.sysid] > safety.budget_s:
            raise RetaskPlanningError(f"uav{s.sysid} would need {flight_s[s.sysid]:.0f} s more; its battery budget has "
                              f"{max(safety.budget_s - s.flown_s, 0.0):.0f} s left ({safety.budget_s:.0f} s less "
                              f"{s.flown_s:.0f} s flown): the rest is for `missionplan replan` after landing")
        mission = track_mission(frame, k, (s.lat, s.lon), surveys[k], here[k], layered, flight_s=flight_s[s.sysid],
                                end="rtl", back_m=backs[k], ground=ground)
        home_amsl = 0.0 if ground is None else float(ground(np.array([s.home[0]]), np.array([s.home[1]]))[0])
        missions[s.sysid] = Mission(items=mission.mission.items, home=(s.home[0], s.home[1], home_amsl))
        photos[s.sysid] = mission.photos
        resume[s.sysid] = 1  # after the NAV_TAKEOFF: the speed, the camera, then the survey
        zone = np.argwhere(field.result.zones.zone == k)
        # Home first: over a DEM the fence's ceiling (above home) rises by the ground's rise above the home's.
        home_m = to_grid_m(frame, [s.home[0]], [s.home[1]])[0]
        points = np.vstack([home_m[None, :], here[k][None, :], routes[k]])
        fences[s.sysid] = drone_fence(frame, zone, points, layered.altitude_of(k), safety.fence_margin_m,
                                      safety.max_altitude_m, ground=ground).mission()
    separation = layering.approach["3d"]
    return RetaskPlan(missions, fences, resume, flight_s, photos, int(len(left)), separation,
                      time.monotonic() - started)



def airborne(track: np.ndarray, altitude: float) -> np.ndarray:
    """A planned track (timeline.planned_track: t, row_m, col_m, up_m) without its take-off: from the
    moment it reaches its altitude, with the clock restarted there."""
    up = np.flatnonzero(track[:, 3] >= altitude - 0.05)
    start = int(up[0]) if len(up) else 0
    cut = track[start:].copy()
    cut[:, 0] -= cut[0, 0]
    return cut
