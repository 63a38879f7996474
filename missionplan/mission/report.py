"""The grid plan's part of a plan record: `build_report` turns a PlanResult into the PlanRecord that
report.json starts from (plan_record.py holds the record, its keys and how it is written and read).
"""

from __future__ import annotations

from missionplan.geo.camera import CELLS_PER_FOOTPRINT

from ..grid.planresult import PlanResult
from .plan_blocks import Decisions, PlanMetrics, Timing, cells_of
from .plan_record import PlanRecord
from .plan_tours import TourPlan


def build_report(result: PlanResult, seed: int) -> PlanRecord:
    """The record of a grid plan: zones, metrics, targets, the drones' paths and the grid; a georeferenced
    plan adds its drones, promise, settings and georeference (planning: plan_folder, field_plan)."""
    run, world = result.run, result.world
    uavs = len(result.starts)
    return PlanRecord(
        map=result.gmap.name, uavs=uavs, policy=result.policy, zones=result.zones.method,
        zones_balanced=result.zones.balanced, zone_sizes=tuple(result.zones.sizes().tolist()), seed=seed,
        success=run.success, failure=run.failure, metrics=PlanMetrics.from_json(run.metrics),
        targets=world.num_targets, unreachable=int(len(result.unreachable)),
        unreachable_cells=cells_of(result.unreachable.tolist()), floor=world.num_targets / (CELLS_PER_FOOTPRINT * uavs),
        steps=run.steps, deadlocks_broken=run.deadlocks_broken, lane_drones=run.lane_drones,
        decisions=Decisions(tuple(run.policy_decisions.tolist()), tuple(run.pathfinder_decisions.tolist()),
                            tuple(run.idle_decisions.tolist())),
        timing=Timing(round(result.zone_seconds, 4), round(result.zone_seconds + run.plan_seconds, 4)),
        launch=tuple((int(r), int(c)) for r, c in result.starts),
        paths=tuple(cells_of(path) for path in run.paths.tolist()), grid=tuple(result.gmap.rows_text()),
        tours=TourPlan.of(result.zones.fleet) if result.zones.fleet is not None else None)
