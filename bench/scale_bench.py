"""City scale: seeded generated cities of 256² to 2048² cells, 6 / 20 / 50 drones, both policies.

Each row plans one (size, seed, drones, policy) in a fresh child process, so its peak RSS is its
own, and prints: the city's street width in cells (median / 90th percentile over the streets'
ridges, bench/streets.py), zone seconds, plan seconds, zones as a share of the plan time, CPU seconds
(user + system of the child, zones + plan: compare these when the machine is shared), the
zones' CPU seconds as a share of the plan's, peak RSS, MMN / floor, coverage, steps, and the
1-minute load average when the row finished. Maps are
`trainmaps.random_city` with seed = side length (--seeds N: also side + 1 ... side + N - 1),
launch cells by mapgen's greedy k-median
(the first A of them for A drones); generated maps are cached under the temp directory.
--movingai adds the MovingAI street maps of ../shared/maps/movingai/ (real OpenStreetMap cities,
256 x 256, read and given launch cells as `plan --map` does), after the generated cities.
Run by hand, piecewise if you like:

    .venv/bin/python bench/scale_bench.py [--sizes 256,512,1024,2048] [--uavs 6,20,50] [--seeds 1]
                                          [--movingai all|NAME,...] [--movingai-dir DIR]
                                          [--policy expert,nn] [--timeout 1800] [--progress]
                                          [--mdu-check] [--write-doc docs/scale.md]

--mdu-check also computes MDU* at every steady-state step (slow on big maps) and prints
how far the sampled MDU* (every mdu_stride(U)-th step, see missionplan/grid/metrics.py) is from it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


from missionplan.grid import metrics, planner
from missionplan.planning import pipeline
from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.base.atomic import atomic_path
from missionplan.maps.gridmap import GridMap, read_map_text
from missionplan.maps.movingai import parse_movingai
from missionplan.maps.mapgen import CITY_LAUNCH_EDGE_MARGIN, launch_candidates, median_launch_cells
from missionplan.planning.pipeline import POLICIES, make_policy, plan_map
from missionplan.learn.trainmaps import TARGET, kind_of, random_city

import doctable  # bench/doctable.py: --write-doc
from child_row import peak_rss_mb, run_child_row
from machine import machine_line
from streets import street_width_summary

SIZES = (256, 512, 1024, 2048)
UAVS = (6, 20, 50)
MAX_UAVS = max(UAVS)
CACHE = Path(tempfile.gettempdir()) / "missionplan-scale-maps"
MOVINGAI_DIR = Path(__file__).resolve().parent.parent.parent / "shared" / "maps" / "movingai"


def city(size: int, seed: int | None = None) -> GridMap:
    """The bench's city of size x size cells with MAX_UAVS launch cells (cached on disk); seed: size."""
    seed = size if seed is None else seed
    path = CACHE / (f"city-{size}-v1.npz" if seed == size else f"city-{size}-seed{seed}-v1.npz")
    if path.is_file():
        data = np.load(path)
        return GridMap(name=f"city{size}", obstacle=data["obstacle"], target=data["target"],
                       launch=[(int(r), int(c)) for r, c in data["launch"]], meta={})
    gmap = random_city(np.random.default_rng(seed), (size, size), name=f"city{size}")
    kind = kind_of(gmap)
    launch = median_launch_cells(launch_candidates(kind, CITY_LAUNCH_EDGE_MARGIN), kind == TARGET, MAX_UAVS)
    CACHE.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:  # np.savez would append .npz to a bare temp name
            np.savez_compressed(handle, obstacle=gmap.obstacle, target=gmap.target, launch=np.array(launch))
    return GridMap(name=gmap.name, obstacle=gmap.obstacle, target=gmap.target, launch=launch, meta={})


def record_every_mdu() -> list[float]:
    """Make the planner's sampler also compute MDU* at every steady-state step; returns that list."""
    every: list[float] = []

    class Recording(metrics.SteadyStateSampler):
        def observe(self, coverage: float, positions: np.ndarray, unexplored: np.ndarray) -> None:
            if metrics.STEADY_LOW <= coverage <= metrics.STEADY_HIGH:
                every.append(metrics.mean_distance_to_nearest(unexplored, positions))
            super().observe(coverage, positions, unexplored)

    planner.SteadyStateSampler = Recording  # type: ignore[misc]
    return every


def time_zones_cpu() -> list[float]:
    """Make plan_map's zone split count its CPU seconds into the returned one-item list."""
    spent = [0.0]
    split = pipeline.split_zones

    def timed(*args, **kwargs):  # type: ignore[no-untyped-def]
        began = time.process_time()
        try:
            return split(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - began

    pipeline.split_zones = timed  # type: ignore[assignment]
    return spent


def movingai_map(path: str, uavs: int) -> GridMap:
    """A MovingAI street map with the launch cells `plan --map PATH --uavs A` gives it."""
    return parse_movingai(read_map_text(path), path, launches=uavs)


def row_map(source: str, seed: str, uavs: int) -> GridMap:
    """A row's map: `source` is a city's side length (with its seed) or "movingai:PATH"."""
    if source.startswith("movingai:"):
        return movingai_map(source.removeprefix("movingai:"), uavs)
    return city(int(source), int(seed))


def run_row(source: str, seed: str, uavs: int, policy: str, progress: bool,
            mdu_check: bool = False) -> dict[str, float | str | bool]:
    """Plan one row in this process; what the table prints."""
    gmap = row_map(source, seed, uavs)
    every = record_every_mdu() if mdu_check else None
    ready = make_policy(policy)  # loading the weights is not planning
    zone_cpu = time_zones_cpu()
    cpu0 = time.process_time()
    result = plan_map(gmap, uavs, policy=ready, progress=progress)
    cpu = time.process_time() - cpu0
    m, world = result.run.metrics, result.world
    floor = world.num_targets / (CELLS_PER_FOOTPRINT * uavs)
    return {"targets": world.num_targets, "zones_s": result.zone_seconds, "plan_s": result.run.plan_seconds,
            "cpu_s": cpu, "zones_cpu_s": zone_cpu[0], "rss_mb": peak_rss_mb(),
            "mmn_floor": m["MMN"] / floor, "coverage": m["coverage"], "success": result.run.success,
            "failure": result.run.failure or "", "steps": result.run.steps, "load": os.getloadavg()[0],
            "mdu": m["MDU"], "mdu_every": float(np.mean(every)) if every else None,
            "mdu_stride": metrics.mdu_stride(world.num_targets), "window": len(every) if every else None}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)))
    parser.add_argument("--uavs", default=",".join(map(str, UAVS)))
    parser.add_argument("--seeds", type=int, default=1, help="cities per size (seeds size, size + 1, ...)")
    parser.add_argument("--movingai", default="",
                        help="MovingAI maps to add: all, or a comma list of names such as Berlin_1_256 (default none)")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--policy", default=",".join(POLICIES), help=f"comma list of {', '.join(POLICIES)}")
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds allowed per row")
    parser.add_argument("--progress", action="store_true", help="show each row's progress bar")
    parser.add_argument("--mdu-check", action="store_true",
                        help="also compute MDU* at every steady-state step and print how far the sampled one is")
    parser.add_argument("--row", help=argparse.SUPPRESS)  # internal: size|movingai:PATH,seed,uavs,policy in a child
    doctable.add_option(parser)
    args = parser.parse_args()
    if args.row:
        source, seed, uavs, policy = args.row.split(",")
        print(json.dumps(run_row(source, seed, int(uavs), policy, args.progress, args.mdu_check)))
        return 0
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def movingai_paths(args: argparse.Namespace) -> list[Path]:
    """The MovingAI maps --movingai asks for (all, or by name), in name order; an unknown name is an error."""
    if not args.movingai:
        return []
    folder = Path(args.movingai_dir)
    found = {path.stem: path for path in sorted(folder.glob("*.map"))} if folder.is_dir() else {}
    if args.movingai == "all":
        if not found:
            raise SystemExit(f"--movingai-dir {folder}: no .map files there")
        return list(found.values())
    names = args.movingai.split(",")
    unknown = [name for name in names if name not in found]
    if unknown:
        raise SystemExit(f"--movingai {','.join(unknown)}: not in {folder} (there: {', '.join(found) or 'no .map files'})")
    return [found[name] for name in names]


COLUMNS = (f"{'A':>3} {'policy':<7} {'U':>8} {'zones s':>8} {'plan s':>8} {'zones %':>7} {'cpu s':>8} "
           f"{'zones cpu %':>11} {'peak MB':>8} {'MMN/floor':>9} {'cov %':>6} {'steps':>6} {'load':>5}")


def table(args: argparse.Namespace) -> int:
    drones = [int(u) for u in args.uavs.split(",")]
    cities = [(f"{int(s)}x{int(s):<4} {int(s) + i:>5}", s, str(int(s) + i))
              for s in filter(None, args.sizes.split(",")) for i in range(max(1, args.seeds))]
    if cities:
        print_rows(args, f"{'size':>9} {'seed':>5}", cities, drones)
    street_maps = [(f"{path.stem:<16}", f"movingai:{path}", "-") for path in movingai_paths(args)]
    if street_maps:
        print("" if not cities else "\n", end="")
        print_rows(args, f"{'MovingAI map':<16}", street_maps, drones)
    print(machine_line())  # CPU seconds drift between hours: the table says how fast this one was
    return 0


def print_rows(args: argparse.Namespace, first_columns: str, maps: list[tuple[str, str, str]],
               drones: list[int]) -> None:
    """One table: a row per (map, drones, policy), each planned in a child; maps are (label, source, seed)."""
    # Street widths are measured here, not in the timed children (launch cells do not change the streets).
    streets = {source + seed: street_width_summary(row_map(source, seed, drones[0]).free) for _, source, seed in maps}
    header = f"{first_columns} {'streets':>7} {COLUMNS}"
    print(header)
    print("-" * len(header), flush=True)
    for label_start, source, seed in maps:
        for uavs in drones:
            for policy in args.policy.split(","):
                command = [sys.executable, __file__, "--row", f"{source},{seed},{uavs},{policy}"]
                command += ["--progress"] if args.progress else []
                command += ["--mdu-check"] if args.mdu_check else []
                label = f"{label_start} {streets[source + seed]:>7} {uavs:>3} {policy:<7}"
                r = run_child_row(command, args.timeout)
                if isinstance(r, str):
                    print(f"{label} {r}", flush=True)
                    continue
                share = 100 * r["zones_s"] / max(r["plan_s"], 1e-9)
                cpu_share = 100 * r["zones_cpu_s"] / max(r["cpu_s"] - r["zones_cpu_s"], 1e-9)
                row = (f"{label} {r['targets']:>8} {r['zones_s']:>8.2f} {r['plan_s']:>8.2f} {share:>7.1f} "
                       f"{r['cpu_s']:>8.1f} {cpu_share:>11.1f} {r['rss_mb']:>8.0f} {r['mmn_floor']:>9.2f} {r['coverage']:>6.1f} "
                       f"{r['steps']:>6} {r['load']:>5.1f}")
                print(row + ("" if r["success"] else f"  FAILED: {r['failure']}"), flush=True)
                if r["mdu_every"]:
                    print(f"{'':>9} MDU* at all {r['window']} steady steps {r['mdu_every']:.3f}, sampled every "
                          f"{r['mdu_stride']} steps {r['mdu']:.3f}: {100 * (r['mdu'] / r['mdu_every'] - 1):+.2f} %",
                          flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
