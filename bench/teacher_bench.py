"""Teachers a network could imitate to beat the expert, measured against the expert on development cities.

The network learns by imitating the expert (missionplan/learn/), so it can beat the expert only by imitating
something better: a slower, deeper teacher run at training time. This bench plans generated cities (never the
MovingAI maps that bench/gap_bench.py reports as held out) with the expert and with candidate policies, and
prints each candidate's mean makespan against the expert's:

- `nn`: the shipped network;
- `nn-sym`: the network's probabilities averaged over the 8 symmetries of the square (each state turned and
  mirrored, the answer turned back: learn/features.py's transforms);
- `rollout-H`: one step of policy improvement over the expert (a rollout, as in Bertsekas' rollout
  algorithms). For each drone and each first move, the expert flies that drone alone H moves further on
  the drone's own copy of what it sees within VIEW_RADIUS + H + 1 cells, the other drones held where they
  stand; the move is worth the expert's own reward along the way (new cells / 9, less its turn and revisit
  penalties, discounted by the expert's GAMMA) plus the expert's look-ahead score where the rollout ends.
  H = 0 scores a move by its own reward and the look-ahead after it;
- `nn-best-K`: a search with the network as its prior, the teacher of expert iteration: K plans in which every
  drone's every decision is drawn from the network's softmax (the Gumbel-max trick on its log-probabilities,
  each plan's draws seeded by the seed and its number), the shortest at full coverage kept. Its CPU time is
  the K plans'.

Cities: `--cities N` random cities of learn/random_cities.random_city from seeds no training run uses and N
Voronoi cities of bench/unseen_cities.py, each `--size` cells square, launch cells drawn from the free cells.
Each city and fleet is planned with `--seeds` seeds by every policy; a row prints the expert's mean makespan
and each candidate's gap of the means. The last lines give each candidate's mean gap over the rows with a 95 %
interval from a paired bootstrap over the seeds (as bench/gap_bench.py) and its CPU seconds per plan. Run by
hand:

    .venv/bin/python bench/teacher_bench.py [--size 128] [--cities 3] [--uavs 3,6] [--seeds 3]
                                            [--horizons 0,2,8] [--samples 8] [--workers 2] [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Sequence

import numpy as np

from missionplan.grid.expert import GAMMA, ExpertPolicy
from missionplan.grid.planner import Policy
from missionplan.grid.world import ACTION_DELTAS, FOOTPRINT_RADIUS, HOVER, VIEW_RADIUS, CoverageWorld, turn_weight
from missionplan.learn.features import ACTION_PERMS, NUM_SYMMETRIES, STATE_PERMS, encode_states
from missionplan.learn.network import load_weights
from missionplan.learn.trainmaps import heldout_cities
from missionplan.maps.gridmap import GridMap
from missionplan.planning.pipeline import POLICIES, make_policy, plan_map

import doctable  # bench/doctable.py: --write-doc
from gap_bench import interval, resampled_gaps
from machine import machine_line
from unseen_cities import random_free_launches, voronoi_city

CITY_SEED = 7000  # random_city seeds from here on: training uses 0 .. a few hundred, its held-out score 1
# A turn's penalty by (previous action + 1, action): HOVER (row 0) turns nothing, as in the expert's tables.
TURNS = np.array([[0.0] * 4] + [[turn_weight(a, b) for b in range(4)] for a in range(4)])


class RolloutTeacher:
    """The expert improved by a rollout of itself H moves deep (see the module docstring)."""

    name = "expert"  # the planner drives it as it drives the expert

    def __init__(self, horizon: int, expert: ExpertPolicy | None = None) -> None:
        self.horizon = horizon
        self.expert = expert if expert is not None else ExpertPolicy()

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        asked = np.asarray(drones, dtype=np.int64).reshape(-1)
        if len(asked) == 0:
            return np.zeros((0, 4))
        radius = VIEW_RADIUS + self.horizon + 1  # every view of the rollout fits in the patch
        unexplored, blocked = world.views(asked, radius=radius)
        flown = world.flown_views(asked, radius=radius)
        # One rollout per drone and first move: drone i's move a is row 4 i + a.
        unexplored, blocked, flown = (np.repeat(a, 4, axis=0) for a in (unexplored, blocked, flown))
        rows = np.arange(len(unexplored))
        position = np.full((len(rows), 2), radius, dtype=np.int64)
        previous = np.repeat(world.last_actions[asked, 0], 4)
        action = np.tile(np.arange(4), len(asked))
        value = np.zeros(len(rows))
        flying = np.ones(len(rows), dtype=bool)
        discount = 1.0
        expert = self.expert
        for step in range(self.horizon + 2):
            if step > 0:  # the expert chooses (or, after the last move, says what the rest is worth)
                look = self._look_ahead(unexplored, blocked, flown, position, previous)
                best = look.max(axis=1)
                if step == self.horizon + 1:
                    value += np.where(flying & np.isfinite(best), discount * np.where(np.isfinite(best), best, 0.0), 0.0)
                    break
                action = look.argmax(axis=1)  # ties to the lowest action, as the planner breaks them
                flying &= np.isfinite(best)
            target = position + ACTION_DELTAS[action]
            free = ~blocked[rows, target[:, 0], target[:, 1]]
            if step == 0:
                value[~free] = -np.inf  # a first move into something is no move
            moving = free & flying
            flying = moving
            position = np.where(moving[:, None], target, position)
            new_cells = np.zeros(len(rows))
            f = FOOTPRINT_RADIUS
            for m in np.flatnonzero(moving):
                r, c = position[m]
                footprint = unexplored[m, r - f:r + f + 1, c - f:c + f + 1]
                new_cells[m] = footprint.sum()
                footprint[...] = False
            revisit = flown[rows, position[:, 0], position[:, 1]] & moving
            flown[rows[moving], position[moving, 0], position[moving, 1]] = True
            reward = (new_cells / 9.0 - expert.turn_weight * TURNS[previous + 1, action]
                      - expert.revisit_weight * revisit)
            value += np.where(moving, discount * reward, 0.0)
            previous = np.where(moving, action, previous)
            discount *= GAMMA
        return value.reshape(len(asked), 4)

    def _look_ahead(self, unexplored: np.ndarray, blocked: np.ndarray, flown: np.ndarray,
                    position: np.ndarray, previous: np.ndarray) -> np.ndarray:
        """(n, 4) the expert's action scores for each rollout where it stands."""
        v = VIEW_RADIUS
        views = [np.stack([a[m, r - v:r + v + 1, c - v:c + v + 1] for m, (r, c) in enumerate(position)])
                 for a in (unexplored, blocked, flown)]
        views[1][:, v, v] = False  # the drone stands on its own cell
        scores = self.expert.view_scores(views[0], views[1], views[2], previous)
        return scores.reshape(len(position), 4, -1).max(axis=2).astype(np.float64)


class SymmetricNetwork:
    """The shipped network, its probabilities averaged over the 8 symmetries of the square."""

    name = "nn"

    def __init__(self) -> None:
        self.weights = load_weights()

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        if not drones:
            return np.zeros((0, 4))
        states = encode_states(world, drones)
        n = len(states)
        turned = np.concatenate([states[:, STATE_PERMS[sym]] for sym in range(NUM_SYMMETRIES)])
        probabilities = self.weights.probabilities(turned).reshape(NUM_SYMMETRIES, n, 4)
        # Action a here is action ACTION_PERMS[sym, a] in the turned world.
        mean = sum(probabilities[sym][:, ACTION_PERMS[sym]] for sym in range(NUM_SYMMETRIES)) / NUM_SYMMETRIES
        return np.log(np.maximum(mean, 1e-12))


class SampledNetwork:
    """The shipped network, each decision drawn from its softmax: its log-probabilities plus Gumbel noise, so the
    planner's best-first order is a draw (the first choice with the network's probabilities)."""

    name = "nn"

    def __init__(self, seed: int | tuple[int, ...]) -> None:
        self.network = make_policy("nn")
        self.rng = np.random.default_rng(seed)

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        scores = self.network.action_scores(world, drones)
        return scores + self.rng.gumbel(size=scores.shape)


def candidate_policy(name: str) -> Policy:
    """A policy by its column name: the planner's own (expert, nn) or a candidate above."""
    if name in POLICIES:
        return make_policy(name)
    if name == "nn-sym":
        return SymmetricNetwork()
    return RolloutTeacher(int(name.removeprefix("rollout-")))


def city(kind: str, index: int, size: int, uavs: int) -> GridMap:
    """A development city with `uavs` random launch cells (seeded by the city)."""
    if kind == "random":
        gmap = heldout_cities(CITY_SEED + index, 1, side=size)[0]
    else:
        gmap = voronoi_city(size, CITY_SEED + index)
    return GridMap(f"{kind}-{index}", gmap.obstacle, gmap.target, random_free_launches(gmap, uavs, index), gmap.meta)


def plan_one(kind: str, index: int, size: int, uavs: int, seed: int, policy: str) -> tuple[int, float, float]:
    """Makespan, coverage % and CPU seconds of one plan (of nn-best-K: its kept plan, and its K plans' time)."""
    gmap = city(kind, index, size, uavs)
    cpu = time.process_time()
    if policy.startswith("nn-best-"):
        runs = [plan_map(gmap, uavs, policy=SampledNetwork((seed, k)), seed=seed).run
                for k in range(int(policy.removeprefix("nn-best-")))]
        run = min(runs, key=lambda r: (r.metrics["coverage"] < 100.0, r.metrics["makespan"]))
    else:
        run = plan_map(gmap, uavs, policy=candidate_policy(policy), seed=seed).run
    return int(run.metrics["makespan"]), float(run.metrics["coverage"]), time.process_time() - cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128, help="cells on a side of every city")
    parser.add_argument("--cities", type=int, default=3, help="random cities and as many Voronoi cities")
    parser.add_argument("--uavs", default="3,6", help="comma list of fleet sizes")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0 .. N-1 per city and fleet")
    parser.add_argument("--horizons", default="0,2,8", help="comma list of rollout depths H ('' for none)")
    parser.add_argument("--samples", default="8", help="comma list of K for nn-best-K ('' for none)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="planning processes")
    doctable.add_option(parser)
    args = parser.parse_args()
    candidates = (["nn", "nn-sym"] + [f"rollout-{h}" for h in args.horizons.split(",") if h]
                  + [f"nn-best-{k}" for k in args.samples.split(",") if k])
    with doctable.Recorder(args.write_doc, __file__):
        return table(args, candidates)


def table(args: argparse.Namespace, candidates: list[str]) -> int:
    policies = ["expert", *candidates]
    rows = [(kind, i, uavs) for uavs in (int(u) for u in args.uavs.split(",")) for kind in ("random", "voronoi")
            for i in range(args.cities)]
    jobs = [(kind, i, args.size, uavs, seed, policy) for kind, i, uavs in rows for policy in policies
            for seed in range(args.seeds)]
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        results = iter(list(pool.map(plan_one, *zip(*jobs))))
    header = f"{'city':<10} {'A':>3} {'expert':>8} " + " ".join(f"{name:>10}" for name in candidates)
    print(header)
    print("-" * len(header))
    makespans: dict[str, list[np.ndarray]] = {policy: [] for policy in policies}
    cpu = {policy: 0.0 for policy in policies}
    least_coverage = 100.0
    for kind, i, uavs in rows:
        for policy in policies:
            plans = np.array([next(results) for _ in range(args.seeds)])
            makespans[policy].append(plans[:, 0])
            least_coverage = min(least_coverage, float(plans[:, 1].min()))
            cpu[policy] += float(plans[:, 2].sum())
        expert = makespans["expert"][-1]
        gaps = " ".join(f"{100 * (makespans[name][-1].mean() / expert.mean() - 1):>+9.1f}%" for name in candidates)
        print(f"{f'{kind}-{i}':<10} {uavs:>3} {expert.mean():>8.1f} {gaps}")
    print("-" * len(header))
    plans = len(rows) * args.seeds
    rng = np.random.default_rng(0)
    for name in candidates:
        gaps = [100 * (ours.mean() / theirs.mean() - 1) for ours, theirs in zip(makespans[name], makespans["expert"])]
        resamples = np.mean([resampled_gaps(theirs, ours, rng)
                             for ours, theirs in zip(makespans[name], makespans["expert"])], axis=0)
        low, high = interval(resamples)
        print(f"{name:<10} mean gap {np.mean(gaps):+5.1f} % (95 % interval {low:+.1f}..{high:+.1f} %), "
              f"{cpu[name] / plans:.2f} CPU s per plan (expert {cpu['expert'] / plans:.2f})")
    print(f"{len(rows)} city x fleet rows, {args.seeds} seeds each; least coverage {least_coverage:.1f} %")
    print(machine_line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
