"""Ground that may be overflown: our planner's lanes and its cell-by-cell exploration against DARP, LS-MCPP-like and sweep baselines.

Where nothing blocks the drones (open ground, or a city whose buildings are low enough to fly
over: buildings become free cells with nothing to photograph), the classic planners cover an area
one footprint-wide pass at a time. Baselines, each checking its own coverage:

- `darp`: DARP + STC as published (Kapoutsis et al., 2017; bench/darp.py): the area divided on
  18 x 18 cells (2 x 2 footprint blocks) into equal connected regions, each flown as a spanning-tree
  circumnavigation from its robot's block; with --seeds N, the mean of seeds 0 .. N-1 (DARP's random
  perturbation moves its makespan by a few percent);
- `sweep`, DARP-like without DARP's division: the balanced zones our planner starts from
  (`zones.split_zones`), each cut into 9 x 9 blocks aligned on the zone's corner, every block holding
  a target photographed from its centre, visited in the shortest of eight snakes (taxicab legs);
- `ls`, LS-MCPP-like: the map's own block grid (aligned on cell (0, 0)), each block to the zone
  holding most of its targets, then local search on the makespan handing the longest snake's border
  blocks to neighbouring drones while that shortens it (`lanes.fleet_zones`), every centre visited
  in snakes.
Drones of the baselines never meet or wait (our planner's do), which can only flatter them.

Our planner with lanes (`lanes`: a whole fleet on open ground flies block tours, grid/fleet_blocks.py,
or the `ls` zones in snakes where those are shorter; it skips a block once photographed), with
`plan --improve SECONDS` on top (`lanes+Ns`, with --improve N, seed 0), and exploring cell by cell
(`--open-ground explore`) with the expert and with the network. Per map and fleet it prints the
targets, the floor (targets / (9 A): every move photographing 9 new cells, nobody waiting), makespan
(the longest drone's moves), total moves, coverage, CPU seconds, makespan over the floor, and the
makespan against DARP's, the sweep's, the ls baseline's and our expert's exploring (`vs exp`). Maps:
open ground (every cell a target), the MovingAI street maps in ../shared/maps/movingai/ with every
building overflown, and the same maps with every N-th building left standing (`1/N tall`,
--tall-every: the planner sweeps the zones that are at most lanes.MAX_OBSTACLE_SHARE obstacle round
them and explores the rest; the baselines' straight legs would cross them, so those rows have none).
One plan's makespan moves by a few percent with the seed, so --seeds N prints the mean of N plans for
our rows and DARP's (sweep and ls: seed 0). Run by hand:

    .venv/bin/python bench/sweep_bench.py [--open 128,256] [--uavs 6,20] [--seeds N] [--tall-every N]
                                          [--improve SECONDS] [--movingai-dir ../shared/maps/movingai]
                                          [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy import ndimage


from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.grid.lanes import block_centres, fleet_zones, snake_order
from missionplan.grid.world import FOOTPRINT_RADIUS, reachable_targets
from missionplan.grid.zones import split_zones
from missionplan.maps.gridmap import Cell, GridMap, read_map_text
from missionplan.maps.launches import spread_launches
from missionplan.maps.movingai import parse_movingai
from missionplan.planning.field_plan import plan_field
from missionplan.planning.pipeline import make_policy, plan_map

import doctable  # bench/doctable.py: --write-doc
from darp import darp_plan
from machine import machine_line

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


def mostly_overflown(gmap: GridMap, every: int) -> GridMap:
    """The same map with its buildings flown over except every `every`-th (4-connected obstacle
    pieces, in ndimage.label's order), which stay: a few tall buildings among low ones."""
    pieces, count = ndimage.label(gmap.obstacle)
    tall = np.isin(pieces, np.arange(every, count + 1, every))
    return GridMap(f"{gmap.name} 1/{every} tall", tall, gmap.target & gmap.free, list(gmap.launch), dict(gmap.meta))


def maps(args: argparse.Namespace) -> list[tuple[str, int]]:
    """(map key, drones) of every row."""
    keys = [f"open:{size}" for size in filter(None, args.open.split(","))]
    folder = Path(args.movingai_dir)
    found = [str(path) for path in sorted(folder.glob("*.map"))] if folder.is_dir() else []
    keys += found
    if args.tall_every:
        keys += [f"tall:{path}" for path in found]
    return [(key, int(uavs)) for key in keys for uavs in filter(None, args.uavs.split(","))]


def load(key: str, uavs: int, tall_every: int) -> GridMap:
    if key.startswith("open:"):
        return open_ground(int(key.split(":")[1]), uavs)
    if key.startswith("tall:"):
        path = key.split(":", 1)[1]
        return mostly_overflown(parse_movingai(read_map_text(path), Path(path).stem), tall_every)
    return overflown(parse_movingai(read_map_text(key), Path(key).stem))


def table(args: argparse.Namespace) -> int:
    header = (f"{'map':<22} {'A':>3} {'planner':<8} {'targets':>8} {'floor':>6} {'makespan':>8} {'total':>8} "
              f"{'cov %':>6} {'cpu s':>6} {'span/floor':>10} {'vs darp':>8} {'vs sweep':>8} {'vs ls':>7} {'vs exp':>7}")
    print(header)
    print("-" * len(header), flush=True)
    policies = {name: make_policy(name) for name in ("expert", "nn")}
    for key, uavs in maps(args):
        gmap = load(key, uavs, args.tall_every)
        starts = list(gmap.launch[:uavs])
        reachable = reachable_targets(gmap, starts)
        # The baselines fly taxicab legs between block centres: only where nothing stands in the way.
        baselines = not gmap.obstacle.any()
        if baselines:
            cpu = time.process_time()
            zones = split_zones(reachable, gmap.free, starts, balance=True)
            sweep = sweep_plan(gmap.shape, reachable, starts, zones.zone)
            sweep["cpu"] = time.process_time() - cpu
            cpu = time.process_time()
            searched = sweep_plan(gmap.shape, reachable, starts, fleet_zones(zones.zone, reachable, starts), (0, 0))
            searched["cpu"] = sweep["cpu"] + time.process_time() - cpu  # the zones are its too
            darp = darp_row(gmap, starts, reachable, args.seeds)
        rows = []
        for label, policy, lanes in (("lanes", "expert", True), ("expert", "expert", False), ("nn", "nn", False)):
            # With --seeds N, the mean of N plans (seeds 0 .. N-1: zones and tie-breaks), least coverage.
            runs = []
            for seed in range(args.seeds):
                cpu = time.process_time()
                m = plan_map(gmap, uavs, policy=policies[policy], starts=starts, lanes=lanes, seed=seed).run.metrics
                runs.append((m["makespan"], uavs * m["MMN"], m["coverage"], time.process_time() - cpu))
            makespan, total, _, seconds = np.mean(runs, axis=0)
            rows.append((label, {"makespan": round(float(makespan)), "total": round(float(total)),
                                 "coverage": min(run[2] for run in runs), "cpu": float(seconds)}))
            if label == "lanes" and args.improve > 0:
                rows.append((f"lanes+{args.improve:g}s", improved_row(gmap, uavs, args.improve)))
        if baselines:
            rows += [("darp", darp), ("ls", searched), ("sweep", sweep)]
        targets = int(reachable.sum())
        floor = targets / (CELLS_PER_FOOTPRINT * uavs)
        expert = dict(rows)["expert"]

        def against(r: dict[str, float], other: dict[str, float] | None, width: int) -> str:
            if other is None or r is other:
                return f"{'-':>{width}}"
            return f"{100 * (r['makespan'] / other['makespan'] - 1):+{width - 1}.1f}%"

        for label, r in rows:
            print(f"{gmap.name:<22} {uavs:>3} {label:<8} {targets:>8} {floor:>6.0f} {r['makespan']:>8} {r['total']:>8} "
                  f"{r['coverage']:>6.1f} {r['cpu']:>6.1f} {r['makespan'] / floor:>10.2f} "
                  f"{against(r, darp if baselines else None, 8)} "
                  f"{against(r, sweep if baselines else None, 8)} {against(r, searched if baselines else None, 7)} "
                  f"{against(r, expert, 7)}", flush=True)
    improved = f"; lanes+{args.improve:g}s: seed 0" if args.improve > 0 else ""
    print(f"our rows and darp: the mean of {args.seeds} seed{'s' if args.seeds != 1 else ''}{improved}; "
          "floor: targets / (9 A)")
    print(machine_line())
    return 0


def darp_row(gmap: GridMap, starts: list[Cell], reachable: np.ndarray, seeds: int) -> dict[str, float]:
    """DARP + STC (bench/darp.py) with seeds 0 .. seeds-1: the mean makespan and total, the least coverage."""
    runs = []
    for seed in range(seeds):
        cpu = time.process_time()
        result = darp_plan(reachable, gmap.obstacle, starts, seed=seed)
        runs.append((result.makespan, sum(result.moves), result.coverage, time.process_time() - cpu))
    makespan, total, _, seconds = np.mean(runs, axis=0)
    return {"makespan": round(float(makespan)), "total": round(float(total)),
            "coverage": min(run[2] for run in runs), "cpu": float(seconds)}


def improved_row(gmap: GridMap, uavs: int, budget_s: float) -> dict[str, float]:
    """Our lanes with `plan --improve budget_s` (seed 0): its makespan in moves, as the grid planner flies it."""
    cpu = time.process_time()
    field = plan_field(gmap, uavs, None, None, None, lanes=True, improve_s=budget_s, seed=0)
    m = field.result.run.metrics
    return {"makespan": int(m["makespan"]), "total": round(uavs * float(m["MMN"])), "coverage": float(m["coverage"]),
            "cpu": time.process_time() - cpu}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--open", default="128,256", help="comma list of open-ground sizes (empty: none)")
    parser.add_argument("--uavs", default="6,20", help="comma list of fleet sizes")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--seeds", type=int, default=1,
                        help="plan each of our rows with seeds 0 .. N-1 and print the means (baselines: seed 0)")
    parser.add_argument("--improve", type=float, default=0.0, metavar="SECONDS",
                        help="also plan our lanes with `plan --improve SECONDS` (seed 0; 0: not)")
    parser.add_argument("--tall-every", type=int, default=5,
                        help="also plan each MovingAI map with every N-th building left standing (0: not)")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


if __name__ == "__main__":
    raise SystemExit(main())
