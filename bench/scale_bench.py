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
Run by hand, piecewise if you like:

    .venv/bin/python bench/scale_bench.py [--sizes 256,512,1024,2048] [--uavs 6,20,50] [--seeds 1]
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

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from missionplan.grid import metrics, planner  # noqa: E402
from missionplan import pipeline  # noqa: E402
from bridge.atomic import atomic_path  # noqa: E402
from missionplan.maps.gridmap import GridMap  # noqa: E402
from missionplan.maps.mapgen import CITY_LAUNCH_EDGE_MARGIN, launch_candidates, median_launch_cells  # noqa: E402
from missionplan.pipeline import POLICIES, make_policy, plan_map  # noqa: E402
from missionplan.learn.trainmaps import TARGET, kind_of, random_city  # noqa: E402

import doctable  # noqa: E402  (bench/doctable.py: --write-doc)
from child_row import peak_rss_mb, run_child_row  # noqa: E402
from streets import street_width_summary  # noqa: E402

SIZES = (256, 512, 1024, 2048)
UAVS = (6, 20, 50)
MAX_UAVS = max(UAVS)
CACHE = Path(tempfile.gettempdir()) / "missionplan-scale-maps"


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


def run_row(size: int, seed: int, uavs: int, policy: str, progress: bool,
            mdu_check: bool = False) -> dict[str, float | str | bool]:
    """Plan one row in this process; what the table prints."""
    gmap = city(size, seed)
    every = record_every_mdu() if mdu_check else None
    ready = make_policy(policy)  # loading the weights is not planning
    zone_cpu = time_zones_cpu()
    cpu0 = time.process_time()
    result = plan_map(gmap, uavs, policy=ready, progress=progress)
    cpu = time.process_time() - cpu0
    m, world = result.run.metrics, result.world
    floor = world.num_targets / (9 * uavs)
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
    parser.add_argument("--policy", default=",".join(POLICIES), help=f"comma list of {', '.join(POLICIES)}")
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds allowed per row")
    parser.add_argument("--progress", action="store_true", help="show each row's progress bar")
    parser.add_argument("--mdu-check", action="store_true",
                        help="also compute MDU* at every steady-state step and print how far the sampled one is")
    parser.add_argument("--row", help=argparse.SUPPRESS)  # internal: size,seed,uavs,policy in a child
    doctable.add_option(parser)
    args = parser.parse_args()
    if args.row:
        size, seed, uavs, policy = args.row.split(",")
        print(json.dumps(run_row(int(size), int(seed), int(uavs), policy, args.progress, args.mdu_check)))
        return 0
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:
    cities = [(int(s), int(s) + i) for s in args.sizes.split(",") for i in range(max(1, args.seeds))]
    streets = {(size, seed): street_width_summary(city(size, seed).free)  # made here, not in the timed children
               for size, seed in cities}
    header = (f"{'size':>9} {'seed':>5} {'streets':>7} {'A':>3} {'policy':<7} {'U':>8} {'zones s':>8} {'plan s':>8} "
              f"{'zones %':>7} {'cpu s':>8} {'zones cpu %':>11} {'peak MB':>8} {'MMN/floor':>9} {'cov %':>6} "
              f"{'steps':>6} {'load':>5}")
    print(header)
    print("-" * len(header), flush=True)
    for size, seed in cities:
        for uavs in (int(u) for u in args.uavs.split(",")):
            for policy in args.policy.split(","):
                command = [sys.executable, __file__, "--row", f"{size},{seed},{uavs},{policy}"]
                command += ["--progress"] if args.progress else []
                command += ["--mdu-check"] if args.mdu_check else []
                label = f"{size}x{size:<4} {seed:>5} {streets[size, seed]:>7} {uavs:>3} {policy:<7}"
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
