"""The whole planning job as one library call: map -> zones -> coverage plan -> metrics.

The CLI, the benchmarks and the tests all call `plan_map`; each stage is a small
swappable piece chosen by name (zone method, policy).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from missionplan.base.naming import Named

from ..grid.expert import ExpertPolicy
from ..grid.fleet_blocks import fleet_blocks
from ..grid.lanes import BLOCK, fleet_zones, longest_snake, open_zones
from ..grid.planner import POLICY_PATIENCE, Planner, Policy
from ..grid.planresult import PlanResult
from ..grid.world import CoverageWorld, check_starts, reachable_targets
from ..grid.zones import DEFAULT_ZONE_METHOD, ZONE_METHODS, split_zones
from ..maps.gridmap import Cell, GridMap
from .errors import PlanRequestError

POLICIES = ("nn", "expert")
DEFAULT_POLICY = "expert"


def make_policy(name: str, weights: str | Path | None = None) -> Policy:
    """The named policy; `weights` only for nn (default: the shipped weights)."""
    if name == "expert":
        return ExpertPolicy()
    if name == "nn":
        from ..learn.network import SHIPPED_WEIGHTS, NeuralPolicy, load_weights  # numpy only; loaded when asked for

        try:
            return NeuralPolicy(load_weights(weights if weights is not None else SHIPPED_WEIGHTS))
        except ValueError as error:
            raise PlanRequestError(str(error)) from None
    raise PlanRequestError(f"unknown policy {name!r} (choose {', '.join(POLICIES)})")


def launch_cells(gmap: GridMap, uavs: int) -> list[Cell]:
    """The first `uavs` launch cells of the map, checked."""
    if uavs < 1:
        raise PlanRequestError(Named("{uavs} must be at least 1, got {0}", uavs))
    if uavs > len(gmap.launch):
        raise PlanRequestError(f"map {gmap.name} has launch cells for {len(gmap.launch)} drones, {uavs} asked")
    starts = gmap.launch[:uavs]
    check_starts(gmap, starts)
    return starts


def plan_map(gmap: GridMap, uavs: int, policy: str | Policy = DEFAULT_POLICY,
             zone_method: str = DEFAULT_ZONE_METHOD, seed: int = 0, starts: list[Cell] | None = None,
             progress: bool = False, balance_zones: bool = True, weights: str | Path | None = None,
             zone_shares: np.ndarray | None = None, lanes: bool = True,
             patience: int = POLICY_PATIENCE, lane_spacing: int = BLOCK, fleet_tours: bool = True) -> PlanResult:
    """Plan full coverage of `gmap` for `uavs` drones; `policy` is a name or a ready Policy; `zone_shares`:
    the fraction of the targets each balanced zone gets (default equal); `lanes`: a drone whose zone
    lies on open ground sweeps it in footprint-wide lanes (grid.lanes) instead of exploring it, and
    when every zone does (and no shares are asked), the map's blocks are shared out and toured
    (grid.fleet_blocks; with lanes closer than a footprint, zones redrawn block by block for snakes);
    `patience`: fruitless policy steps before the path-finder takes a drone over (grid.planner);
    `lane_spacing`: cells between those lanes (BLOCK, one footprint, unless a side overlap asks closer);
    `fleet_tours`: a whole fleet on open ground flies block tours (grid.fleet_blocks); False flies it in snakes
    on zones balanced on the longest snake (the benches' `ls` rows)."""
    if zone_method not in ZONE_METHODS:
        raise PlanRequestError(f"unknown zone method {zone_method!r} (choose {', '.join(ZONE_METHODS)})")
    chosen = make_policy(policy, weights) if isinstance(policy, str) else policy
    policy = chosen.name
    starts = launch_cells(gmap, uavs) if starts is None else starts
    check_starts(gmap, starts)
    began = time.perf_counter()
    reachable = reachable_targets(gmap, starts)
    zones = split_zones(reachable, gmap.free, starts, zone_method, seed, balance=balance_zones, shares=zone_shares)
    if lanes and zone_shares is None and all(open_zones(gmap.obstacle, zones.zone, starts)):
        if lane_spacing == BLOCK and fleet_tours:
            # The map's blocks shared out and toured, or (where that is shorter: a plain field's rectangles)
            # redrawn and flown in snakes.
            fleet = fleet_blocks(zones.zone, reachable, starts, zones.centroids, seed)
            redrawn = fleet_zones(zones.zone, reachable, starts)
            if longest_snake(redrawn, starts) < max(fleet.moves) and all(open_zones(gmap.obstacle, redrawn, starts)):
                zones = replace(zones, zone=redrawn)
            elif all(open_zones(gmap.obstacle, fleet.zone, starts)):
                zones = replace(zones, zone=fleet.zone, fleet=fleet)
        else:  # zones balanced on the longest snake, flown in snakes (lanes closer than a footprint always are)
            redrawn = fleet_zones(zones.zone, reachable, starts)
            if all(open_zones(gmap.obstacle, redrawn, starts)):
                zones = replace(zones, zone=redrawn)
    zone_seconds = time.perf_counter() - began
    world = CoverageWorld(gmap, starts, zones.zone)
    run = Planner(world, chosen, seed=seed, progress=progress, lanes=lanes, patience=patience,
                  lane_spacing=lane_spacing, tours=zones.tours, tour_origin=zones.tour_origin).run()
    return PlanResult(gmap, starts, policy, zones, world, run, zone_seconds)
