"""A georeferenced plan made field-safe, as one call: the stages `plan` runs between the map and the files.

1. the grid planner flies the map with the clearance band made obstacle (clearance.flight_map);
2. the band's targets the survey left out are photographed by detours (clearance.photograph_band);
3. the flight plans: corrected tracks, battery sorties, altitude layers that keep the separation,
   geofences (flightplan.make_flight_plans);
4. when some drone flies several sorties and the drones' total times differ, the zones are
   re-balanced once to each drone's measured rate (sorties.sortie_shares) and 1-3 run again.
Without safety settings (a map without georeference) only the plain grid plan is made.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from missionplan.geo.frame import GridFrame

from ..maps.gridmap import GridMap
from ..mission.clearance import band_coverage, flight_map, photograph_band
from ..mission.drone_missions import GroundHeights, MissionSettings
from ..mission.plan_blocks import SafetyPromise
from ..mission.plan_record import PlanRecord
from ..mission.safety import SafetySettings
from ..mission.sorties import sortie_shares
from .pipeline import PlanResult, plan_map

REBALANCE_ROUNDS = 1  # each is a whole re-plan (Turin, 2 drones, 10 min: a second round gained nothing)


@dataclass
class FieldPlan:
    result: PlanResult
    plans: Any = None  # flightplan.FlightPlans, or None (no georeference, or the grid plan failed)
    band: np.ndarray | None = None
    band_moves_added: int | None = None  # grid moves added to photograph the band's targets (None: no band)
    zone_shares: list[float] | None = None  # set when the zones were re-balanced for sorties

    def fill_record(self, record: PlanRecord, gmap: GridMap, frame: GridFrame | None) -> PlanRecord:
        """The plan record with the band's targets put back (see clearance.band_coverage), and the
        field-safety blocks: the drones and the safety promise (separation, clearance)."""
        band = None
        if self.band is not None and self.band.any():
            record, band = band_coverage(record, gmap, self.band, self.result.run.paths)
        if self.zone_shares is not None:
            record = replace(record, zone_shares=tuple(round(s, 4) for s in self.zone_shares))
        if self.plans is not None and frame is not None:
            clearance = replace(self.plans.clearance(gmap, frame), band_moves_added=self.band_moves_added, band=band)
            record = replace(record, drones=self.plans.drone_plans(),
                             promise=SafetyPromise(self.plans.separation(), clearance))
        return record


def plan_field(gmap: GridMap, uavs: int, frame: GridFrame | None, settings: MissionSettings | None,
               safety: SafetySettings | None, balance_zones: bool = True, ground: GroundHeights | None = None,
               **planning: Any) -> FieldPlan:
    """Plan `gmap` for `uavs` drones; `ground`: over a DEM (flightplan.make_flight_plans); `planning`: plan_map's
    policy, zone_method, seed, progress, lanes."""
    plan_gmap, band = flight_map(gmap, safety.clearance_m, uavs) if safety is not None else (gmap, None)

    def attempt(shares: np.ndarray | None) -> FieldPlan:
        result = plan_map(plan_gmap, uavs, balance_zones=balance_zones, zone_shares=shares, **planning)
        done = FieldPlan(result, band=band, zone_shares=None if shares is None else shares.tolist())
        if band is not None and band.any() and result.run.success:
            result.run.paths, done.band_moves_added = photograph_band(
                result.run.paths, plan_gmap, gmap, band, result.zones.zone)
        if frame is not None and settings is not None and result.run.success:
            from ..mission.flightplan import make_flight_plans

            done.plans = make_flight_plans(result, frame, settings, safety, base=gmap, ground=ground)
        return done

    best = attempt(None)
    if best.plans is None or not balance_zones or safety is None:
        return best
    current, shares = best, None
    for _ in range(REBALANCE_ROUNDS):
        times = np.array([sum(m.flight_s for m in d) for d in current.plans.sorties])
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


def _busiest(field: FieldPlan) -> float:
    """The longest total flight time of any drone, all its sorties together."""
    return max(sum(m.flight_s for m in d) for d in field.plans.sorties)
