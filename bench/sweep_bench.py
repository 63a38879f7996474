"""Ground that may be overflown: our planner's lanes and its cell-by-cell exploration against DARP-like and LS-MCPP-like baselines.

Where nothing blocks the drones (open ground, or a city whose buildings are low enough to fly
over: buildings become free cells with nothing to photograph), the classic planners cover an area
in lanes one footprint apart. DARP (Kapoutsis et al., 2017) splits the area into equal connected
parts and covers each with a spanning-tree path; on an obstacle-free grid that path visits each
footprint-sized block once, as a boustrophedon sweep does. The first baseline (`sweep`) measures that, with
nothing of ours but the zones, so the two differ only in how a zone is flown:

- zones: `zones.split_zones` (balanced geodesic Lloyd), the very zones our planner gets;
- each zone is cut into 9 x 9 blocks (the footprint) aligned on the zone's corner; every block
  holding a target is photographed from its centre (clipped into the map), so one photo covers it;
- the drone visits those centres in a snake, by block rows or block columns, from whichever of the
  eight corners and directions makes its flight shortest, launch cell included; the legs are
  taxicab distances, flyable because no cell is blocked. Drones never meet or wait (our planner's
  do), which can only flatter the baseline.

A second baseline, LS-MCPP-like (`ls`): the map's own block grid (aligned on cell (0, 0), so no
block is split between two zones), each block to the zone holding most of its targets, then local
search on the makespan, handing the longest snake's border blocks to neighbouring drones while that
shortens it (`lanes.fleet_zones`); again every centre visited, no waiting.

The blocks, the snake and the local search are missionplan.grid.lanes's, which our planner flies on
open ground (`plan --open-ground lanes`, the default; a whole fleet on open ground gets the `ls`
zones): the baselines visit every centre, the planner skips each block its own passes or another
drone have photographed already, and its drones wait for each other. The baselines check
themselves: coverage is recounted from the photo centres. Per map and fleet it prints, for our
planner with lanes (`lanes`), for it exploring cell by cell with the expert and with the network
(`--open-ground explore`), and for both baselines: makespan (the longest drone's moves),
total moves, coverage of the targets, CPU seconds, the makespan over the floor U / (9 A), and the
makespan against the sweep's and the ls baseline's. Maps:
open ground (every cell a target) and the MovingAI street maps in ../shared/maps/movingai/ with
every building overflown. Run by hand:

    .venv/bin/python bench/sweep_bench.py [--open 128,256] [--uavs 6,20]
                                          [--movingai-dir ../shared/maps/movingai] [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from missionplan.grid.lanes import block_centres, fleet_zones, snake_order  # noqa: E402
from missionplan.grid.world import FOOTPRINT_RADIUS, reachable_targets  # noqa: E402
from missionplan.grid.zones import split_zones  # noqa: E402
from missionplan.maps.gridmap import Cell, GridMap, read_map_text  # noqa: E402
from missionplan.maps.launches import spread_launches  # noqa: E402
from missionplan.maps.movingai import parse_movingai  # noqa: E402
from missionplan.pipeline import make_policy, plan_map  # noqa: E402

import doctable  # noqa: E402  (bench/doctable.py: --write-doc)

ROOT = Path(__file__).resolve().parent.parent
MOVINGAI_DIR = ROOT.parent / "shared" / "maps" / "movingai"


def open_ground(size: int, uavs: int) -> GridMap:
    """A size x size field with nothing on it: every cell a target; launch cells spread over it."""
    free = np.ones((size, size), dtype=bool)
    return GridMap(f"open {size}", ~free, free.copy(), spread_launches(free, uavs))


def overflown(gmap: GridMap) -> GridMap:
    """The same map with every obstacle flown over: free, with nothing to photograph."""
    blocked = np.zeros_like(gmap.obstacle)
    return GridMap(f"{gmap.name} overflown", blocked, gmap.target & gmap.free, list(gmap.launch), dict(gmap.meta))


def sweep_plan(shape: tuple[int, int], targets: np.ndarray, starts: list[Cell], zone: np.ndarray,
               origin: Cell | None = None) -> dict[str, float]:
    """A baseline on the given zones of the `targets` mask, every block centre visited (blocks aligned on
    each zone's corner, or on `origin`): makespan, total moves, coverage %."""
    covered = np.zeros_like(targets)
    moves = []
    for k, start in enumerate(starts):
        mine = zone == k
        if not mine.any():
            moves.append(0)
            continue
        centres, blocks = block_centres(np.argwhere(mine), shape, origin)
        flown, _ = snake_order(start, centres, blocks)
        moves.append(flown)
        for r, c in centres:
            covered[max(r - FOOTPRINT_RADIUS, 0): r + FOOTPRINT_RADIUS + 1,
                    max(c - FOOTPRINT_RADIUS, 0): c + FOOTPRINT_RADIUS + 1] = True
    count = int(targets.sum())
    return {"makespan": max(moves), "total": sum(moves),
            "coverage": 100.0 * int((covered & targets).sum()) / count if count else 100.0}


def maps(args: argparse.Namespace) -> list[tuple[str, int]]:
    """(map key, drones) of every row."""
    keys = [f"open:{size}" for size in filter(None, args.open.split(","))]
    folder = Path(args.movingai_dir)
    keys += [str(path) for path in sorted(folder.glob("*.map"))] if folder.is_dir() else []
    return [(key, int(uavs)) for key in keys for uavs in filter(None, args.uavs.split(","))]


def load(key: str, uavs: int) -> GridMap:
    if key.startswith("open:"):
        return open_ground(int(key.split(":")[1]), uavs)
    return overflown(parse_movingai(read_map_text(key), key))


def table(args: argparse.Namespace) -> int:
    header = (f"{'map':<22} {'A':>3} {'planner':<8} {'targets':>8} {'makespan':>8} {'total':>8} {'cov %':>6} "
              f"{'cpu s':>6} {'span/floor':>10} {'vs sweep':>8} {'vs ls':>7}")
    print(header)
    print("-" * len(header), flush=True)
    policies = {name: make_policy(name) for name in ("expert", "nn")}
    for key, uavs in maps(args):
        gmap = load(key, uavs)
        starts = list(gmap.launch[:uavs])
        name = gmap.name if not key.startswith("/") else f"{Path(key).stem} overflown"
        cpu = time.process_time()
        reachable = reachable_targets(gmap, starts)
        zones = split_zones(reachable, gmap.free, starts, balance=True)
        sweep = sweep_plan(gmap.shape, reachable, starts, zones.zone)
        sweep["cpu"] = time.process_time() - cpu
        cpu = time.process_time()
        searched = sweep_plan(gmap.shape, reachable, starts, fleet_zones(zones.zone, reachable, starts), (0, 0))
        searched["cpu"] = sweep["cpu"] + time.process_time() - cpu  # the zones are its too
        rows = []
        for label, policy, lanes in (("lanes", "expert", True), ("expert", "expert", False), ("nn", "nn", False)):
            cpu = time.process_time()
            result = plan_map(gmap, uavs, policy=policies[policy], starts=starts, lanes=lanes)
            m = result.run.metrics
            rows.append((label, {"makespan": m["makespan"], "total": round(uavs * m["MMN"]),
                                 "coverage": m["coverage"], "cpu": time.process_time() - cpu}))
        rows += [("ls", searched), ("sweep", sweep)]
        targets = int(reachable.sum())
        floor = targets / (9 * uavs)
        for label, r in rows:
            versus = f"{100 * (r['makespan'] / sweep['makespan'] - 1):+7.1f}%" if label != "sweep" else f"{'-':>8}"
            versus_ls = f"{100 * (r['makespan'] / searched['makespan'] - 1):+6.1f}%" if label != "ls" else f"{'-':>7}"
            print(f"{name:<22} {uavs:>3} {label:<8} {targets:>8} {r['makespan']:>8} {r['total']:>8} "
                  f"{r['coverage']:>6.1f} {r['cpu']:>6.1f} {r['makespan'] / floor:>10.2f} {versus} {versus_ls}", flush=True)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--open", default="128,256", help="comma list of open-ground sizes (empty: none)")
    parser.add_argument("--uavs", default="6,20", help="comma list of fleet sizes")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


if __name__ == "__main__":
    raise SystemExit(main())
