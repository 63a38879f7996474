"""report.json: the machine-readable record of a plan, enough to replay and check it.

Keys: map, uavs, policy, zones, zones_balanced, zone_sizes, seed, success, failure, metrics (MMN, TE, MNT, MUD, MDU,
coverage, makespan, hover_steps; TE, MNT and coverage in percent), targets (reachable
target cells U), unreachable (count) and unreachable_cells, floor (U / (9 A)), steps,
deadlocks_broken, lane_drones (drones that swept an open-ground zone in lanes), decisions (drones
per step decided by the policy, on a path-finder or a lane sweep, or parked idle), timing
(zones_s, plan_s), launch, paths (per drone, one [row, col] per step, start and hovers
included), and grid (one string per row: '#' obstacle, '.' target, 'o' free non-target).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from missionplan.bridge.atomic import write_text_atomic
from missionplan.geo.camera import CELLS_PER_FOOTPRINT

from ..grid.planresult import PlanResult


def build_report(result: PlanResult, seed: int) -> dict[str, Any]:
    run, world = result.run, result.world
    uavs = len(result.starts)
    return {
        "map": result.gmap.name,
        "uavs": uavs,
        "policy": result.policy,
        "zones": result.zones.method,
        "zones_balanced": result.zones.balanced,
        "zone_sizes": result.zones.sizes().tolist(),
        "seed": seed,
        "success": run.success,
        "failure": run.failure,
        "metrics": run.metrics,
        "targets": world.num_targets,
        "unreachable": int(len(result.unreachable)),
        "unreachable_cells": result.unreachable.tolist(),
        "floor": world.num_targets / (CELLS_PER_FOOTPRINT * uavs),
        "steps": run.steps,
        "deadlocks_broken": run.deadlocks_broken,
        "lane_drones": run.lane_drones,
        "decisions": {"policy": run.policy_decisions.tolist(), "pathfinder": run.pathfinder_decisions.tolist(),
                      "idle": run.idle_decisions.tolist()},
        "timing": {"zones_s": round(result.zone_seconds, 4),
                   "plan_s": round(result.zone_seconds + run.plan_seconds, 4)},
        "launch": [list(cell) for cell in result.starts],
        "paths": run.paths.tolist(),
        "grid": result.gmap.rows_text(),
    }


def write_report(report: dict[str, Any], path: str | os.PathLike[str]) -> None:
    write_text_atomic(Path(path), json.dumps(report, indent=1) + "\n")
