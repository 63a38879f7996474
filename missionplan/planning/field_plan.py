"""A georeferenced plan made field-safe, as one call: the stages `plan` runs between the map and the files.

1. the grid planner flies the map with the clearance band made obstacle (clearance.flight_map);
2. the band's targets the survey left out are photographed by detours (clearance.photograph_band);
3. the flight plans: corrected tracks, battery sorties, altitude layers that keep the separation,
   geofences (flightplan.make_flight_plans); where lanes lie closer than a footprint (a side overlap) the
   corrector keeps their turns;
3a. with the overlap fill (plan --overlap-fill), for up to FILL_ROUNDS rounds: the reachable target points
   the planned photos leave short of the implied count get detours (mission/overlap_fill.py), and 3 runs
   again;
4. when some drone flies several sorties and the drones' total times differ, the zones are
   re-balanced once to each drone's measured rate (sorties.sortie_shares) and 1-3 run again;
5. with a time budget (plan --improve SECONDS), local search on the zone split, each candidate 1-3 again,
   the best kept (planning/improve.py).
Without safety settings (a map without georeference) only the plain grid plan is made.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.geo.frame import GridFrame

from ..maps.gridmap import GridMap
from ..mission.clearance import band_coverage, flight_map, photograph_band
from ..mission.drone_missions import GroundHeights, MissionSettings
from ..mission.plan_blocks import OverlapFill, SafetyPromise
from ..mission.plan_improvement import PlanImprovement
from ..mission.plan_record import PlanRecord
from ..mission.safety import SafetySettings
from ..mission.sorties import sortie_shares
from .improve import check_budget, improve
from .pipeline import PlanResult, plan_map

REBALANCE_ROUNDS = 1  # each is a whole re-plan (Turin, 2 drones, 10 min: a second round gained nothing)
FILL_ROUNDS = 6  # photos fall where the trigger distance puts them; a later round fills what is still short
WHOLE_DETOURS_FROM = 2  # from this round (0-based) a detour's start is kept too (overlap_fill: FilledPaths.anchor)
REVERSAL_S = 2.0  # what turning back at a detour's end costs a multicopter (braking to a stop, accelerating)


@dataclass
class FieldPlan:
    result: PlanResult
    plans: Any = None  # flightplan.FlightPlans, or None (no georeference, or the grid plan failed)
    band: np.ndarray | None = None
    band_moves_added: int | None = None  # grid moves added to photograph the band's targets (None: no band)
    zone_shares: list[float] | None = None  # set when the zones were re-balanced for sorties
    overlap_fill: OverlapFill | None = None  # what the overlap fill did (None: not asked)
    keep: np.ndarray | None = None  # cells the corrector keeps as waypoints: close lanes' turns, the fill's detours
    improvement: PlanImprovement | None = None  # what plan --improve tried (None: not asked)

    def fill_record(self, record: PlanRecord, gmap: GridMap, frame: GridFrame | None) -> PlanRecord:
        """The plan record with the band's targets put back (see clearance.band_coverage), and the
        field-safety blocks: the drones and the safety promise (separation, clearance)."""
        band = None
        if self.band is not None and self.band.any():
            record, band = band_coverage(record, gmap, self.band, self.result.run.paths)
        if self.zone_shares is not None:
            record = replace(record, zone_shares=tuple(round(s, 4) for s in self.zone_shares))
        if self.overlap_fill is not None:
            record = replace(record, overlap_fill=self.overlap_fill)
        if self.improvement is not None:
            record = replace(record, improve=self.improvement)
        if self.plans is not None and frame is not None:
            clearance = replace(self.plans.clearance(gmap, frame), band_moves_added=self.band_moves_added, band=band)
            record = replace(record, drones=self.plans.drone_plans(),
                             promise=SafetyPromise(self.plans.separation(), clearance))
        return record


def plan_field(gmap: GridMap, uavs: int, frame: GridFrame | None, settings: MissionSettings | None,
               safety: SafetySettings | None, balance_zones: bool = True, ground: GroundHeights | None = None,
               overlap_fill: bool = False, side_overlap: float | None = None, improve_s: float | None = None,
               improve_rounds: int | None = None, **planning: Any) -> FieldPlan:
    """Plan `gmap` for `uavs` drones; `ground`: over a DEM (flightplan.make_flight_plans); `overlap_fill`: fly
    fill runs where the planned photos leave reachable points short, judged against the settings' front
    overlap and `side_overlap` (a fraction; None: not asked); `improve_s`: seconds of local search on the
    finished plan, at most `improve_rounds` candidates (planning/improve.py; None: none); `planning`: plan_map's
    policy, zone_method, seed, progress, lanes."""
    plan_gmap, band = flight_map(gmap, safety.clearance_m, uavs) if safety is not None else (gmap, None)
    if improve_s is not None:  # a budget out of range fails before the first plan, not after it
        check_budget(improve_s, improve_rounds)

    def attempt(shares: np.ndarray | None, seed: int | None = None) -> FieldPlan:
        asked = planning if seed is None else {**planning, "seed": seed}
        result = plan_map(plan_gmap, uavs, balance_zones=balance_zones, zone_shares=shares, **asked)
        done = FieldPlan(result, band=band, zone_shares=None if shares is None else shares.tolist())
        if band is not None and band.any() and result.run.success:
            result.run.paths, done.band_moves_added = photograph_band(
                result.run.paths, plan_gmap, gmap, band, result.zones.zone)
        if frame is not None and settings is not None and result.run.success:
            from ..mission.flightplan import make_flight_plans

            def flight_plans(keep: np.ndarray | None) -> Any:
                return make_flight_plans(result, frame, settings, safety, base=gmap, ground=ground, keep=keep)

            done.keep = _lane_turns(result.run, gmap.shape, int(planning.get("lane_spacing", CELLS_PER_FOOTPRINT)))
            done.plans = flight_plans(done.keep)
            if overlap_fill and safety is not None:
                done.overlap_fill = _fill(done, gmap, plan_gmap, frame, flight_plans, side_overlap)
        return done

    best = _rebalanced(attempt(None), attempt, balance_zones, safety)
    if improve_s is None:
        return best
    shares = None if best.zone_shares is None else np.array(best.zone_shares)
    kept, record = improve(best, shares, attempt, improve_s, int(planning.get("seed", 0)), improve_rounds)
    assert isinstance(kept, FieldPlan)
    kept.improvement = record
    return kept


def _rebalanced(best: FieldPlan, attempt: Callable[[np.ndarray | None], FieldPlan], balance_zones: bool,
                safety: SafetySettings | None) -> FieldPlan:
    """Step 4 of the module docstring: the zones re-balanced to the drones' measured rates when sorties differ."""
    if best.plans is None or not balance_zones or safety is None:
        return best
    current, shares = best, None
    for _ in range(REBALANCE_ROUNDS):
        times = current.plans.drone_flight_s()
        sizes = current.result.zones.sizes()
        # Each drone's cells in proportion to its measured rate (cells per second of flight).
        shares = sortie_shares(sizes, times, np.array([len(d) for d in current.plans.sorties]))
        if shares is None:
            break
        current = attempt(shares)
        if current.plans is None:
            break
        if _busiest(current) < _busiest(best):  # keep a re-balance only when it shortens the longest day
            best = current
    return best


def _lane_turns(run: Any, shape: tuple[int, int], spacing: int) -> np.ndarray | None:
    """Where the lane-sweeping drones' paths turn, when their lanes lie closer than a footprint (a side overlap):
    the corrector keeps them as waypoints. Its shortcuts keep every target's one photo, so across lanes a
    footprint apart they change nothing, but across closer ones they would fly every other lane and drop the
    side overlap asked. None: no such lanes."""
    from ..mission.corrector import drop_hovers, merge_straight

    if spacing >= CELLS_PER_FOOTPRINT or not any(run.sweepers):
        return None
    keep = np.zeros(shape, dtype=bool)
    for path, sweeps in zip(run.paths, run.sweepers):
        if sweeps:
            turns = merge_straight(drop_hovers(path))
            keep[turns[:, 0], turns[:, 1]] = True
    return keep


def _fill(done: FieldPlan, gmap: GridMap, plan_gmap: GridMap, frame: GridFrame, remake: Callable[[np.ndarray], Any],
          side_overlap: float | None) -> OverlapFill:
    """Detours for the reachable points the planned photos leave short (mission/overlap_fill.py), for up to
    FILL_ROUNDS rounds, each measured on the flight plans `remake` gives for the extended paths (done.plans,
    done.keep and the paths updated)."""
    from ..mission.clearance import footprint_union
    from ..mission.overlap_fill import fill_paths
    from ..mission.photo_overlap import reachable_deficits, window_half_cells

    result = done.result
    targets = gmap.target.copy()
    if len(result.unreachable):
        targets[tuple(np.asarray(result.unreachable).T)] = False
    if done.band is not None:  # band targets no footprint holds are reported unreachable (band_coverage)
        targets &= ~done.band | footprint_union(result.run.paths, gmap.shape)
    cells = np.argwhere(targets)
    settings = done.plans.settings
    half = window_half_cells(settings.footprint_m, frame.cell_m)
    turn_cells = REVERSAL_S * settings.speed_m_s / frame.cell_m  # a reversal's time, in moves

    def deficits() -> np.ndarray:
        centres, runs = done.plans.photo_centres(frame)
        return reachable_deficits(centres, runs, settings.footprint_m, cells, frame.cell_m, settings.overlap,
                                  side_overlap, ~gmap.obstacle)

    lacking = deficits()
    before, span_before = int((lacking > 0).sum()), _busiest(done)
    rounds = stubs = runs = moves = unserved = 0
    if done.keep is None:
        done.keep = np.zeros(gmap.shape, dtype=bool)
    while (lacking > 0).any() and rounds < FILL_ROUNDS:
        short = lacking > 0
        filled = fill_paths(result.run.paths, plan_gmap.free, cells[short], lacking[short], half, turn_cells)
        unserved = filled.unserved
        if not filled.moves_added:
            break
        filled.anchor(done.keep, starts=rounds >= WHOLE_DETOURS_FROM)
        result.run.paths = filled.paths
        done.plans = remake(done.keep)
        rounds, stubs, runs, moves = rounds + 1, stubs + filled.stubs, runs + filled.runs, moves + filled.moves_added
        lacking = deficits()
    return OverlapFill(rounds, stubs, runs, moves, before, int((lacking > 0).sum()), unserved,
                       round(span_before, 1), round(_busiest(done), 1))


def _busiest(field: FieldPlan) -> float:
    """The longest total flight time of any drone, all its sorties together."""
    return float(field.plans.drone_flight_s().max())
