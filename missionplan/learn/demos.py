"""Demonstrations: (state, expert action) pairs recorded from coverage runs.

The expert plays single-drone coverage on the training maps inside the ordinary planner
loop (so the states are exactly the ones the planner asks a policy about: a drone with
something unexplored in view). Every time the policy is asked, the 376-value state and
the expert's choice are recorded.

The same recorder does DAgger: the network drives, the expert only labels. The states
then come from where the network's own mistakes take the drone, which is what plain
imitation never shows it. DAgger plays fleets (`fleet_starts`, balanced zones), so the
network also meets zone borders and other drones, as it does when planning.

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
from scipy import ndimage
from tqdm import tqdm

from missionplan.geo.camera import CELLS_PER_FOOTPRINT

from ..grid.expert import ExpertPolicy
from ..grid.planner import Planner, Policy
from ..grid.world import CoverageWorld, reachable_targets
from ..grid.zones import split_zones
from ..maps.gridmap import Cell, GridMap
from ..maps.launches import spread_launches
from .features import STATE_SIZE, encode_states
from .network import NeuralPolicy, PolicyWeights

# Training's runs (recorded, and those judging a network) let a policy go this many
# fruitless steps before the path-finder takes over, where planning allows one: the states
# met while dithering are the ones DAgger must label for the network to learn its way out
# of them. The shipped weights were trained so.
ROLLOUT_PATIENCE = 8


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
    """One coverage run: its MMN, the floor U / (9 A), and whether it finished."""

    moves: int
    floor: float
    success: bool


def fleet_starts(gmap: GridMap, uavs: int) -> list[Cell]:
    """The map's launch cell and up to `uavs` - 1 more, spread over the streets of its free region."""
    labels, _ = ndimage.label(gmap.free)
    home = gmap.launch[0]
    starts = [home]
    for cell in spread_launches(labels == labels[home], uavs):
        if len(starts) < uavs and cell != home:
            starts.append(cell)
    return starts


def play_map(gmap: GridMap, driver: Policy | None = None, expert_share: float = 0.0, uavs: int = 1,
             record: bool = True) -> tuple[Demonstrations, CoverageRun]:
    """Drones from the map's launch cells to full coverage; returns what was recorded.

    One drone by default (the thesis's demonstrations); with `uavs` > 1 a fleet on balanced
    zones, so the states also show zone borders and other drones, as planning does.
    `driver` None: the expert drives. `record` False: nothing is labelled, only the run counts
    (how a trained network is judged).
    """
    if record:
        policy: Policy = LabellingPolicy(ExpertPolicy(), driver, expert_share)
    else:
        policy = driver if driver is not None else ExpertPolicy()
    if uavs == 1:
        world = CoverageWorld(gmap, [gmap.launch[0]])
    else:
        starts = fleet_starts(gmap, uavs)
        zones = split_zones(reachable_targets(gmap, starts), gmap.free, starts, balance=True)
        world = CoverageWorld(gmap, starts, zones.zone)
    run = Planner(world, policy, patience=ROLLOUT_PATIENCE).run()
    if isinstance(policy, LabellingPolicy) and policy.states:
        states, actions = np.concatenate(policy.states), np.concatenate(policy.actions)
    else:
        states, actions = np.zeros((0, STATE_SIZE), np.int8), np.zeros(0, np.int8)
    demos = Demonstrations(states, actions, np.zeros(len(actions), np.int32))
    floor = world.num_targets / CELLS_PER_FOOTPRINT / len(world.positions)
    return demos, CoverageRun(moves=int(run.metrics["MMN"]), floor=floor, success=run.success)


def _play_job(job: tuple[GridMap, PolicyWeights | None, float, int]) -> tuple[Demonstrations, CoverageRun]:
    gmap, weights, expert_share, uavs = job
    driver = NeuralPolicy(weights) if weights is not None else None  # DAgger: the network drives
    return play_map(gmap, driver, expert_share, uavs)


def collect(maps: Sequence[GridMap], weights: PolicyWeights | None = None, workers: int = 2,
            expert_share: float = 0.0, progress: bool = True, desc: str = "demonstrations",
            fleets: Sequence[int] | None = None) -> tuple[Demonstrations, list[CoverageRun]]:
    """Play every map once: the expert drives, or (DAgger) the network with `weights`
    drives and the expert takes over a random `expert_share` of the decisions.
    `fleets`: drones per map (default one each)."""
    fleets = [1] * len(maps) if fleets is None else list(fleets)
    jobs = [(gmap, weights, expert_share, uavs) for gmap, uavs in zip(maps, fleets)]
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
