"""Demonstrations: (state, expert action) pairs recorded from single-drone coverage runs.

The expert plays single-drone coverage on the training maps inside the ordinary planner
loop (so the states are exactly the ones the planner asks a policy about: a drone with
something unexplored in view). Every time the policy is asked, the 376-value state and
the expert's choice are recorded.

The same recorder does DAgger: the network drives, the expert only labels. The states
then come from where the network's own mistakes take the drone, which is what plain
imitation never shows it.

Runs are independent per map, so they are spread over worker processes; each map's run
is deterministic, and results come back in map order, so the data do not depend on how
many workers there were. The network drives with the numpy `PolicyWeights` planning uses,
so the workers need no PyTorch.
"""

from __future__ import annotations

import multiprocessing
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from tqdm import tqdm

from ..grid.expert import ExpertPolicy
from ..grid.planner import Planner, Policy
from ..grid.world import CoverageWorld
from ..maps.gridmap import GridMap
from .features import STATE_SIZE, encode_states
from .network import NeuralPolicy, PolicyWeights


@dataclass
class Demonstrations:
    """Recorded pairs: `states` (n, 376) int8 in {-1, 0, 1}, `actions` (n,) int8, `source` (n,) map index."""

    states: np.ndarray
    actions: np.ndarray
    source: np.ndarray

    def __len__(self) -> int:
        return len(self.actions)

    @staticmethod
    def concatenate(parts: Sequence["Demonstrations"]) -> "Demonstrations":
        if not parts:
            return Demonstrations(np.zeros((0, STATE_SIZE), np.int8), np.zeros(0, np.int8), np.zeros(0, np.int32))
        return Demonstrations(np.concatenate([p.states for p in parts]),
                              np.concatenate([p.actions for p in parts]),
                              np.concatenate([p.source for p in parts]))


class LabellingPolicy:
    """Lets `driver` decide, and records every asked state with the expert's label.

    With the expert as driver this is plain demonstration; with the network it is DAgger.
    """

    name = "labelling"

    def __init__(self, expert: ExpertPolicy, driver: Policy | None = None, expert_share: float = 0.0,
                 seed: int = 0) -> None:
        self.expert = expert
        self.driver = driver
        self.expert_share = expert_share  # DAgger's beta: how often the expert still drives
        self.rng = np.random.default_rng(seed)
        self.states: list[np.ndarray] = []
        self.actions: list[np.ndarray] = []

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        expert_scores = self.expert.action_scores(world, drones)
        labelled = np.isfinite(expert_scores).any(axis=1)  # a drone boxed in on all sides has no label
        if labelled.any():
            states = encode_states(world, [k for k, ok in zip(drones, labelled) if ok])
            self.states.append(states.astype(np.int8))
            self.actions.append(np.argmax(expert_scores[labelled], axis=1).astype(np.int8))
        if self.driver is None:
            return expert_scores
        scores = self.driver.action_scores(world, drones)
        by_expert = self.rng.random(len(drones)) < self.expert_share
        return np.where(by_expert[:, None], expert_scores, scores)


@dataclass
class CoverageRun:
    """One single-drone coverage run: its moves, the map's floor U/9, and whether it finished."""

    moves: int
    floor: float
    success: bool


def play_single(gmap: GridMap, driver: Policy | None = None,
                expert_share: float = 0.0) -> tuple[Demonstrations, CoverageRun]:
    """One drone from the map's first launch cell to full coverage; returns what it recorded."""
    labeller = LabellingPolicy(ExpertPolicy(), driver, expert_share)
    world = CoverageWorld(gmap, [gmap.launch[0]])
    run = Planner(world, labeller).run()
    if labeller.states:
        states, actions = np.concatenate(labeller.states), np.concatenate(labeller.actions)
    else:
        states, actions = np.zeros((0, STATE_SIZE), np.int8), np.zeros(0, np.int8)
    demos = Demonstrations(states, actions, np.zeros(len(actions), np.int32))
    return demos, CoverageRun(moves=int(run.metrics["MMN"]), floor=world.num_targets / 9, success=run.success)


def _play_job(job: tuple[GridMap, PolicyWeights | None, float]) -> tuple[Demonstrations, CoverageRun]:
    gmap, weights, expert_share = job
    driver = NeuralPolicy(weights) if weights is not None else None  # DAgger: the network drives
    return play_single(gmap, driver, expert_share)


def collect(maps: Sequence[GridMap], weights: PolicyWeights | None = None, workers: int = 2,
            expert_share: float = 0.0, progress: bool = True,
            desc: str = "demonstrations") -> tuple[Demonstrations, list[CoverageRun]]:
    """Play every map once: the expert drives, or (DAgger) the network with `weights`
    drives and the expert takes over a random `expert_share` of the decisions."""
    jobs = [(gmap, weights, expert_share) for gmap in maps]
    results: list[tuple[Demonstrations, CoverageRun]] = []
    bar = tqdm(total=len(jobs), desc=desc, unit="map", disable=not progress, leave=False)
    if workers > 1 and len(jobs) > 1:
        # spawn, not fork: a forked child of a process that has used torch's thread pool can hang.
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            for result in pool.imap(_play_job, jobs):
                results.append(result)
                bar.update()
            pool.close()
            pool.join()
    else:
        for job in jobs:
            results.append(_play_job(job))
            bar.update()
    bar.close()
    parts = []
    for index, (demos, _) in enumerate(results):
        demos.source[:] = index
        parts.append(demos)
    return Demonstrations.concatenate(parts), [run for _, run in results]
