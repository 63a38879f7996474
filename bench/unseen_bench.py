"""Cities the planner was never tuned on: CPU seconds and coverage with either policy.

Two kinds of map, neither made by missionplan's own generators:
- `voronoi`: bench/unseen_cities.py's Voronoi-block cities (streets 3-10 cells wide at every
  angle, parks, walled courtyards), several seeds per size, launch cells drawn uniformly from
  all free cells (so a drone may start walled in a courtyard);
- `movingai`: the MovingAI street maps in ../shared/maps/movingai/ (real OpenStreetMap
  cities, 256 x 256), read as `plan --map` reads them, launch cells from the map reader (the
  open streets of the largest free region).

Each row plans in a fresh child process and prints: targets reachable from the launch cells, how
many launch cells lie outside the largest free region, the CPU seconds (user + system of the
child: zones + plan, weights not included; with --repeat N the least of N runs, and the most),
the goal of that size and fleet (256 x 256 with 6 drones: 1 CPU s; 1024 x 1024 with 20: 60 CPU s,
judged on the least: the plans are identical, what varies is the machine), the wall seconds of
zones + plan, MMN / floor
(floor = reachable targets / 9A), the makespan (the busiest drone's moves) and, on a network row,
how much longer it is than the expert's on the same map and fleet, coverage of the reachable targets, steps, and the 1-minute load
when it finished. Run by hand:

    .venv/bin/python bench/unseen_bench.py [--voronoi 256x6,1024x20] [--seeds 1,2,3]
                                           [--movingai-uavs 6,20] [--policy expert,nn]
                                           [--movingai-dir ../shared/maps/movingai] [--repeat N]
                                           [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path


from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.maps.gridmap import GridMap, read_map_text
from missionplan.maps.launches import largest_region
from missionplan.maps.movingai import parse_movingai
from missionplan.planning.pipeline import POLICIES, make_policy, plan_map

import doctable  # bench/doctable.py: --write-doc
from child_row import run_child_row
from machine import machine_line
from unseen_cities import random_free_launches, voronoi_city

ROOT = Path(__file__).resolve().parent.parent
MOVINGAI_DIR = ROOT.parent / "shared" / "maps" / "movingai"
GOAL_CPU_S = {(256, 6): 1.0, (1024, 20): 60.0}


def load_row_map(kind: str, name: str, uavs: int, seed: int) -> GridMap:
    """The row's map with its launch cells."""
    if kind == "voronoi":
        gmap = voronoi_city(int(name), seed)
        return GridMap(gmap.name, gmap.obstacle, gmap.target, random_free_launches(gmap, uavs, seed), gmap.meta)
    return parse_movingai(read_map_text(name), name, launches=uavs)


def run_row(kind: str, name: str, uavs: int, seed: int, policy: str) -> dict[str, object]:
    """Plan one row in this process; what the table prints."""
    gmap = load_row_map(kind, name, uavs, seed)
    ready = make_policy(policy)  # loading the weights is not planning
    cpu0, wall0 = time.process_time(), time.perf_counter()
    result = plan_map(gmap, uavs, policy=ready)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    world, run = result.world, result.run
    main_region = largest_region(gmap.free)
    outside = sum(not main_region[r, c] for r, c in result.starts)
    return {"map": gmap.name, "shape": list(gmap.obstacle.shape), "targets": world.num_targets, "outside": outside,
            "cpu_s": cpu, "wall_s": wall, "mmn_floor": run.metrics["MMN"] / (world.num_targets / (CELLS_PER_FOOTPRINT * uavs)),
            "makespan": int(run.metrics["makespan"]),
            "coverage": run.metrics["coverage"], "steps": run.steps, "success": run.success,
            "failure": run.failure or "", "load": os.getloadavg()[0]}


def rows(args: argparse.Namespace) -> list[tuple[str, str, int, int]]:
    """(kind, size or map path, drones, seed) of every row, policies aside."""
    out: list[tuple[str, str, int, int]] = []
    for pair in filter(None, args.voronoi.split(",")):
        size, uavs = pair.split("x")
        out += [("voronoi", size, int(uavs), int(seed)) for seed in args.seeds.split(",")]
    folder = Path(args.movingai_dir)
    maps = sorted(folder.glob("*.map")) if folder.is_dir() else []
    for path in maps:
        out += [("movingai", str(path), int(uavs), 0) for uavs in filter(None, args.movingai_uavs.split(","))]
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--voronoi", default="256x6,1024x20", help="comma list of SIZExDRONES (empty: none)")
    parser.add_argument("--seeds", default="1,2,3", help="seeds of the Voronoi cities")
    parser.add_argument("--movingai-uavs", default="6,20", help="drones on each MovingAI map (empty: none)")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--policy", default=",".join(POLICIES), help=f"comma list of {', '.join(POLICIES)}")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds allowed per row")
    parser.add_argument("--repeat", type=int, default=1,
                        help="plan each row this many times (each in a fresh child): least and most CPU seconds")
    parser.add_argument("--row", help=argparse.SUPPRESS)  # internal: kind,name,uavs,seed,policy in a child
    doctable.add_option(parser)
    args = parser.parse_args()
    if args.row:
        kind, name, uavs, seed, policy = args.row.split(",")
        print(json.dumps(run_row(kind, name, int(uavs), int(seed), policy)))
        return 0
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:
    header = (f"{'map':<16} {'size':>9} {'A':>3} {'policy':<7} {'targets':>8} {'walled':>6} {'cpu s':>7} {'most':>5} "
              f"{'goal':>6} {'wall s':>7} {'MMN/floor':>9} {'mkspan':>6} {'vs exp':>6} {'cov %':>6} {'steps':>6} {'load':>5}")
    print(header)
    print("-" * len(header), flush=True)
    # The expert first, so that a network row can say how its makespan compares.
    policies = sorted(args.policy.split(","), key=lambda name: name != "expert")
    for kind, name, uavs, seed in rows(args):
        expert_makespan = None
        for policy in policies:
            label_name = f"voronoi seed {seed}" if kind == "voronoi" else Path(name).stem
            command = [sys.executable, __file__, "--row", f"{kind},{name},{uavs},{seed},{policy}"]
            runs = [run_child_row(command, args.timeout) for _ in range(max(1, args.repeat))]
            failed = next((r for r in runs if isinstance(r, str)), None)
            if failed is not None:
                print(f"{label_name:<16} {uavs:>13} {policy:<7} {failed}", flush=True)
                continue
            r = min(runs, key=lambda run: run["cpu_s"])  # the plans are the same; the machine is not
            most = f"{max(run['cpu_s'] for run in runs):>5.1f}" if len(runs) > 1 else f"{'-':>5}"
            rows_, cols = r["shape"]
            goal = GOAL_CPU_S.get((max(rows_, cols), uavs))
            verdict = "-" if goal is None else ("ok" if r["cpu_s"] <= goal else "OVER")
            if policy == "expert":
                expert_makespan = r["makespan"]
            versus = (f"{100 * (r['makespan'] / expert_makespan - 1):>+5.1f}%"
                      if policy != "expert" and expert_makespan else f"{'-':>6}")
            line = (f"{label_name:<16} {f'{rows_}x{cols}':>9} {uavs:>3} {policy:<7} {r['targets']:>8} {r['outside']:>6} "
                    f"{r['cpu_s']:>7.1f} {most} {verdict:>6} {r['wall_s']:>7.1f} {r['mmn_floor']:>9.2f} {r['makespan']:>6} "
                    f"{versus} {r['coverage']:>6.1f} "
                    f"{r['steps']:>6} {r['load']:>5.1f}")
            print(line + ("" if r["success"] else f"  FAILED: {r['failure']}"), flush=True)
    print(machine_line())  # CPU seconds drift between hours: the table says how fast this one was
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
