"""The network against the expert on street maps it never saw: makespan over several seeds.

One plan's makespan is a noisy sample: the fleet's drones meet, wait and hand work to each other, so
a small change early (where the zones' Lloyd iterations start, which drone makes way) moves the
busiest drone's last cell by several percent, for either policy. So each map and fleet is planned
with `plan_map(seed=s)` for several seeds s (the seed sets the zones' random sample points and the
planner's tie-breaks; the launch cells stay as `plan --map` picks them) with the expert and with the
shipped network, and the network is judged on the mean makespan.

Maps: the MovingAI street maps in ../shared/maps/movingai/ (real OpenStreetMap cities, 256 x 256,
none of them seen in training). Per map and fleet it prints the expert's and the network's mean
makespan with their least and most, the gap of the means (network over expert), a 95 % interval for
that gap, the least and most gap of a single seed, and on how many seeds the network was within
GAP_GOAL_PERCENT of the expert; then the mean gap over every row, with its interval, and what the
interval says of the goal. The intervals come from a paired bootstrap over the seeds (each resample
draws seeds with replacement and keeps both policies' plans of a seed together), so they say how far
another set of seeds could move the gap; they narrow as --seeds grows. Plans run in parallel worker
processes (--workers); the plans do not depend on it. Run by hand:

    .venv/bin/python bench/gap_bench.py [--seeds 5] [--uavs 6,20] [--workers 2]
                                        [--movingai-dir ../shared/maps/movingai] [--weights FILE]
                                        [--patience N] [--write-doc FILE]

`--patience N` plans both policies with another patience than the planner's (how many steps a
policy may photograph nothing before the path-finder takes the drone over), to measure what it costs.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np


from missionplan.grid.planner import POLICY_PATIENCE, Policy
from missionplan.maps.gridmap import read_map_text
from missionplan.maps.movingai import parse_movingai
from missionplan.planning.pipeline import make_policy, plan_map

import doctable  # bench/doctable.py: --write-doc

ROOT = Path(__file__).resolve().parent.parent
MOVINGAI_DIR = ROOT.parent / "shared" / "maps" / "movingai"
GAP_GOAL_PERCENT = 3.0  # the network's makespan at most this much above the expert's
POLICIES = ("expert", "nn")
BOOTSTRAP_RESAMPLES = 10_000
BOOTSTRAP_SEED = 0  # the intervals are part of the printed table, so they repeat run to run

@functools.cache
def loaded_policy(policy: str, weights: str | None) -> Policy:
    """A worker's policy, loaded once per policy and weights file."""
    return make_policy(policy, weights)


def plan_makespan(path: str, uavs: int, seed: int, policy: str, weights: str | None,
                  patience: int) -> tuple[int, float]:
    """The makespan of one plan, and its coverage of the reachable targets in percent."""
    gmap = parse_movingai(read_map_text(path), path, launches=uavs)
    planner = loaded_policy(policy, weights if policy == "nn" else None)
    run = plan_map(gmap, uavs, policy=planner, seed=seed, patience=patience).run
    return int(run.metrics["makespan"]), float(run.metrics["coverage"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds 0 .. N-1 per map and fleet")
    parser.add_argument("--uavs", default="6,20", help="comma list of fleet sizes")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="planning processes")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--weights", help="the network's weights (default: the shipped ones), to judge a retrained network")
    parser.add_argument("--patience", type=int, default=POLICY_PATIENCE,
                        help=f"fruitless policy steps before the path-finder takes over (default {POLICY_PATIENCE})")
    doctable.add_option(parser)
    args = parser.parse_args()
    maps = sorted(Path(args.movingai_dir).glob("*.map"))
    if not maps:
        print(f"gap_bench: no .map files in {args.movingai_dir}", file=sys.stderr)
        return 2
    with doctable.Recorder(args.write_doc, __file__):
        return table(maps, [int(u) for u in args.uavs.split(",")], args.seeds, args.workers, args.weights,
                     args.patience)


def spread(values: np.ndarray) -> str:
    """Mean (least-most) of makespans."""
    return f"{values.mean():>7.1f} ({values.min():>4}-{values.max():>4})"


def gap_percent(expert: np.ndarray, network: np.ndarray) -> np.ndarray:
    """The gap of the mean makespans in percent, along the last axis (the seeds)."""
    return 100 * (network.mean(axis=-1) / expert.mean(axis=-1) - 1)


def resampled_gaps(expert: np.ndarray, network: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """BOOTSTRAP_RESAMPLES gaps of one row, each from its seeds drawn with replacement (pairs kept)."""
    picks = rng.integers(0, len(expert), size=(BOOTSTRAP_RESAMPLES, len(expert)))
    return gap_percent(expert[picks], network[picks])


def interval(samples: np.ndarray) -> tuple[float, float]:
    """The central 95 % of bootstrap samples."""
    low, high = np.percentile(samples, [2.5, 97.5])
    return float(low), float(high)


def verdict(low: float, high: float) -> str:
    """What a 95 % interval of the gap says of the goal."""
    if high <= GAP_GOAL_PERCENT:
        return f"met, the whole interval of the mean gap is within {GAP_GOAL_PERCENT:g} %"
    if low > GAP_GOAL_PERCENT:
        return f"not met, the whole interval of the mean gap is above {GAP_GOAL_PERCENT:g} %"
    return f"undecided, the interval of the mean gap spans {GAP_GOAL_PERCENT:g} % (more seeds narrow it)"


def table(maps: list[Path], fleets: list[int], seeds: int, workers: int, weights: str | None,
          patience: int) -> int:
    header = (f"{'map':<14} {'A':>3} {'expert mkspan':>19} {'network mkspan':>19} {'gap':>7} "
              f"{'95 % interval':>15} {'seed gaps':>15} {'within':>7} {'cov %':>6}")
    print(header)
    print("-" * len(header), flush=True)
    rows = [(path, uavs) for uavs in fleets for path in maps]
    jobs = [(str(path), uavs, seed, policy, weights, patience) for path, uavs in rows for policy in POLICIES for seed in range(seeds)]
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        results = iter(list(pool.map(plan_makespan, *zip(*jobs))))
    gaps, resamples = [], []
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    for path, uavs in rows:
        makespan = {policy: np.array([next(results) for _ in range(seeds)]) for policy in POLICIES}
        expert, network = makespan["expert"][:, 0].astype(int), makespan["nn"][:, 0].astype(int)
        coverage = min(makespan["expert"][:, 1].min(), makespan["nn"][:, 1].min())
        gap = float(gap_percent(expert, network))
        per_seed = 100 * (network / expert - 1)
        gaps.append(gap)
        resamples.append(resampled_gaps(expert, network, rng))
        low, high = interval(resamples[-1])
        within = int((per_seed <= GAP_GOAL_PERCENT).sum())

        print(f"{path.stem:<14} {uavs:>3} {spread(expert):>19} {spread(network):>19} {gap:>+6.1f}% "
              f"{f'{low:+.1f}..{high:+.1f}%':>15} {f'{per_seed.min():+.1f}..{per_seed.max():+.1f}%':>15} "
              f"{f'{within}/{seeds}':>7} {coverage:>6.1f}", flush=True)
    met = sum(g <= GAP_GOAL_PERCENT for g in gaps)
    # The rows' seeds are drawn independently, so the mean gap's resamples are the rows' resamples averaged.
    low, high = interval(np.mean(resamples, axis=0))
    print(f"mean gap {np.mean(gaps):+.1f} % (95 % interval {low:+.1f}..{high:+.1f} %); {met} of {len(gaps)} "
          f"map x fleet rows within {GAP_GOAL_PERCENT:g} % on the mean of {seeds} seeds")
    print(f"goal: {verdict(low, high)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
