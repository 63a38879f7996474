"""Where a grid plan's CPU seconds go: zones + plan of one map, split by stage, optionally with cProfile.

The stages are timed by wrapping the planner's entry points with CPU clocks (time.process_time), so the
split costs a few percent of the total and agrees with bench/unseen_bench.py's `cpu s` to that. A stage
inside another is shown indented and counted in its parent. With --repeat N the plan runs N times in this
process and the least total is kept (the machine is shared; the plans are the same every time). Run by hand:

    .venv/bin/python bench/expert_profile.py --map ../shared/maps/movingai/Boston_0_256.map --uavs 6
    .venv/bin/python bench/expert_profile.py --map voronoi:256 --seed 1 --uavs 6 --policy nn --repeat 3
    .venv/bin/python bench/expert_profile.py --map voronoi:1024 --uavs 20 --profile 30   # + cProfile's top 30
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import pstats
import sys
import time
from collections.abc import Callable
from typing import Any

from missionplan.grid import expert, pathfinding, planner, world
from missionplan.maps.gridmap import GridMap, read_map_text
from missionplan.maps.movingai import parse_movingai
from missionplan.planning import pipeline
from missionplan.planning.pipeline import make_policy, plan_map

from unseen_cities import random_free_launches, voronoi_city

# (label, owner, attribute, parent label or None): what is timed, nested as it runs.
STAGES: list[tuple[str, Any, str, str | None]] = [
    ("zones", pipeline, "split_zones", None),
    ("planning loop", planner.Planner, "_run", None),
    ("policy (expert or network)", expert.ExpertPolicy, "action_scores", "planning loop"),
    ("path-finder: plan a path", planner.Planner, "_plan_path", "planning loop"),
    ("goal search (find_goal)", planner, "find_goal", "path-finder: plan a path"),
    ("A* (FlightSearch.path)", pathfinding.FlightSearch, "path", "path-finder: plan a path"),
    ("world step", world.CoverageWorld, "step", "planning loop"),
    ("who sees something", world.CoverageWorld, "sees_unexplored", "planning loop"),
    ("steady-state metrics", planner.SteadyStateSampler, "observe", "planning loop"),
]


def load(spec: str, uavs: int, seed: int) -> GridMap:
    """A MovingAI map file (launch cells from the map reader) or voronoi:SIZE (bench/unseen_cities.py)."""
    if spec.startswith("voronoi:"):
        gmap = voronoi_city(int(spec.split(":", 1)[1]), seed)
        return GridMap(gmap.name, gmap.obstacle, gmap.target, random_free_launches(gmap, uavs, seed), gmap.meta)
    return parse_movingai(read_map_text(spec), spec, launches=uavs)


def timed(spent: dict[str, float], label: str, function: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        began = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            spent[label] = spent.get(label, 0.0) + time.process_time() - began
    return wrapper


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", required=True, help="a MovingAI .map file, or voronoi:SIZE")
    parser.add_argument("--uavs", type=int, default=6)
    parser.add_argument("--seed", type=int, default=1, help="the Voronoi city's seed")
    parser.add_argument("--policy", default="expert", choices=pipeline.POLICIES)
    parser.add_argument("--repeat", type=int, default=1, help="plan this many times, keep the least total")
    parser.add_argument("--profile", type=int, default=0, help="also print cProfile's top N functions (own time)")
    args = parser.parse_args()
    gmap = load(args.map, args.uavs, args.seed)
    policy = make_policy(args.policy)  # loading the weights is not planning
    if args.policy == "nn":
        from missionplan.learn.network import NeuralPolicy
        STAGES[2] = ("policy (expert or network)", NeuralPolicy, "action_scores", "planning loop")
    spent: dict[str, float] = {}
    for label, owner, name, _ in STAGES:
        setattr(owner, name, timed(spent, label, getattr(owner, name)))
    best: tuple[float, dict[str, float]] | None = None
    for _ in range(max(1, args.repeat)):
        spent.clear()
        began = time.process_time()
        plan_map(gmap, args.uavs, policy=policy)
        total = time.process_time() - began
        if best is None or total < best[0]:
            best = (total, dict(spent))
    assert best is not None
    total, split = best
    print(f"{gmap.name}: {args.uavs} drones, {args.policy}; CPU s of zones + plan: {total:.3f} (least of {args.repeat})")
    depth: dict[str, int] = {}
    for label, _, _, parent in STAGES:
        depth[label] = 0 if parent is None else depth[parent] + 1
        seconds = split.get(label, 0.0)
        print(f"  {'  ' * depth[label]}{label:<{34 - 2 * depth[label]}} {seconds:7.3f} s {100 * seconds / total:5.1f} %")
    if args.profile:
        profiler = cProfile.Profile()
        profiler.runcall(plan_map, gmap, args.uavs, policy=policy)
        pstats.Stats(profiler, stream=sys.stdout).sort_stats("tottime").print_stats(args.profile)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
