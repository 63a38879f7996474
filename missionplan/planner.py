"""The multi-drone planning loop (SPEC section 4, thesis flowchart 4.5).

Every step, in a fixed drone order:
1. a drone with a cell it sees as unexplored in its 19 x 19 view lets the policy decide
   (one batched call for all such drones); it takes the best-ranked admissible action;
2. otherwise it follows a path: the nearest unexplored cell it sees (anti-congestion:
   not near another drone's goal), reached by Explorative A*, else classic A*, else the
   next goal; it drops the path when something unexplored enters its view and re-plans
   when someone else photographs its goal;
3. a drone whose next cell is taken hovers; one blocked for DEADLOCK_STEPS steps in a row
   is in a deadlock: it steps aside at random (seeded) and re-plans around the drones;
4. beyond the thesis: a policy-driven drone that photographs nothing new for
   POLICY_PATIENCE steps (it dithers next to cells it cannot reach inside its view) is
   handed to the path-finder, which keeps it until that goal is photographed. This makes
   the loop safe for any policy, including an imperfect network.
The run ends when nothing reachable is left unexplored, or fails at the step cap or when
coverage stops growing for too long (both reported, never called success).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol, Sequence

import numpy as np
from tqdm import tqdm

from .gridmap import Cell
from .metrics import SteadyStateSampler, compute_metrics
from .pathfinding import astar, explorative_astar, find_goal
from .world import ACTION_DELTAS, HOVER, CoverageWorld
from .zones import grid_graph

DEADLOCK_STEPS = 3
MAX_GOAL_TRIES = 4
POLICY_PATIENCE = 8


class Policy(Protocol):
    """Ranks the four actions for each asked drone: (len(drones), 4) scores, higher is better."""

    name: str

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray: ...


@dataclass
class _Navigation:
    """A drone's path-finder state: the cells still to fly to its goal."""

    goal: Cell | None = None
    path: list[Cell] = field(default_factory=list)
    blocked_steps: int = 0
    avoid_drones: bool = False  # re-plan treating the other drones as obstacles (after a deadlock)
    fruitless_steps: int = 0  # policy steps in a row that photographed nothing
    forced: bool = False  # on a path because the policy stopped making progress

    def clear(self) -> None:
        self.goal, self.path, self.forced = None, [], False


@dataclass
class PlanRun:
    """Everything a run produced; `paths` include the start and every hover."""

    paths: np.ndarray  # (K, T+1, 2)
    new_cells: np.ndarray  # (K, T)
    metrics: dict[str, float | None]
    policy_decisions: np.ndarray  # (T,) drones decided by the policy at each step
    pathfinder_decisions: np.ndarray  # (T,) drones on a path-finder at each step
    success: bool
    failure: str | None
    steps: int
    deadlocks_broken: int
    plan_seconds: float


class Planner:
    """Drives a CoverageWorld with a policy and the path-finders until full coverage."""

    def __init__(self, world: CoverageWorld, policy: Policy, seed: int = 0, progress: bool = False,
                 stall_limit: int | None = None) -> None:
        self.world = world
        self.policy = policy
        self.rng = np.random.default_rng(seed)
        self.progress = progress
        rows, cols = world.gmap.shape
        # Far more than any honest detour takes; only a livelock hits it.
        self.stall_limit = stall_limit if stall_limit is not None else 4 * (rows + cols) + 200
        self.free = world.gmap.free
        self.graph = grid_graph(self.free)
        self.nav = [_Navigation() for _ in range(world.num_drones)]
        self.deadlocks_broken = 0
        self._by_policy = np.zeros(world.num_drones, dtype=bool)

    # ----------------------------------------------------------- path-finding
    def _plan_path(self, k: int) -> bool:
        world, nav = self.world, self.nav[k]
        start = tuple(int(v) for v in world.positions[k])
        seen = world.seen_unexplored_map(k)
        taken = [n.goal for i, n in enumerate(self.nav) if i != k and n.goal is not None]
        free = self.free
        if nav.avoid_drones:
            free = free.copy()
            for i, p in enumerate(world.positions):
                if i != k:
                    free[tuple(p)] = False
            nav.avoid_drones = False
        # A drone done with its own zone helps only where it is the nearest drone.
        rivals = np.delete(world.positions, k, axis=0) if world.zone_done(k) and world.num_drones > 1 else None
        excluded: set[Cell] = set()
        for _ in range(MAX_GOAL_TRIES):
            goal = find_goal(self.graph, free.shape, start, seen, taken, excluded, rivals)
            if goal is None:
                break
            path = explorative_astar(free, seen, start, goal) or astar(free, start, goal)
            if path is not None:
                nav.goal, nav.path = goal, path[1:]
                return True
            excluded.add(goal)
        nav.clear()
        return False

    def _path_action(self, k: int) -> int:
        """The action that follows drone k's path, planning one first when needed."""
        world, nav = self.world, self.nav[k]
        if nav.goal is None or not world.unexplored[nav.goal] or not nav.path:
            if not self._plan_path(k):
                return HOVER
        nxt = np.array(nav.path[0])
        delta = nxt - world.positions[k]
        matches = np.flatnonzero(np.all(ACTION_DELTAS == delta, axis=1))
        if matches.size == 0:  # the path no longer starts next to us (we were pushed aside)
            nav.clear()
            return HOVER
        return int(matches[0])

    # ------------------------------------------------------------------- loop
    def _choose_actions(self) -> tuple[np.ndarray, int, int]:
        world = self.world
        num = world.num_drones
        sees = world.sees_unexplored()
        for k in range(num):
            nav = self.nav[k]
            if sees[k] and nav.forced and nav.goal is not None and world.unexplored[nav.goal]:
                sees[k] = False  # stays on the path it was handed when the policy stalled
            elif sees[k] and nav.fruitless_steps >= POLICY_PATIENCE:
                nav.clear()
                nav.forced = True
                nav.fruitless_steps = 0
                sees[k] = False
        policy_drones = [k for k in range(num) if sees[k]]
        scores = self.policy.action_scores(world, policy_drones) if policy_drones else None
        actions = np.full(num, HOVER, dtype=np.int64)
        claimed: set[Cell] = set()
        occupied = {tuple(p) for p in world.positions}
        row_of = {k: i for i, k in enumerate(policy_drones)}
        for k in range(num):
            if sees[k]:
                self.nav[k].clear()
                ranked = np.argsort(-scores[row_of[k]], kind="stable")
                for action in ranked:
                    if not np.isfinite(scores[row_of[k], action]):
                        break
                    cell = tuple(world.positions[k] + ACTION_DELTAS[action])
                    if world.is_free(cell) and cell not in occupied and cell not in claimed:
                        actions[k] = action
                        claimed.add(cell)
                        break
            else:
                action = self._path_action(k)
                if action != HOVER:
                    cell = tuple(world.positions[k] + ACTION_DELTAS[action])
                    if cell in claimed:
                        action = HOVER
                    else:
                        claimed.add(cell)
                actions[k] = action
        self._make_way(actions, claimed)
        self._by_policy = sees
        return actions, len(policy_drones), num - len(policy_drones)

    def _make_way(self, actions: np.ndarray, claimed: set[Cell]) -> None:
        """A hovering drone whose cell another drone wants to enter steps to a free neighbour."""
        world = self.world
        occupied = {tuple(p): k for k, p in enumerate(world.positions)}
        for k in range(world.num_drones):
            if actions[k] == HOVER:
                continue
            wanted = tuple(world.positions[k] + ACTION_DELTAS[actions[k]])
            j = occupied.get(wanted)
            if j is None or actions[j] != HOVER or self.nav[j].goal is not None:
                continue  # free, or a drone that moves or waits on its own path
            for action in self.rng.permutation(4):
                cell = tuple(world.positions[j] + ACTION_DELTAS[action])
                if world.is_free(cell) and cell not in occupied and cell not in claimed:
                    actions[j] = action
                    claimed.add(cell)
                    break

    def _break_deadlock(self, k: int) -> int:
        """Drone k has been blocked too long: a random free neighbour, then a fresh plan."""
        world = self.world
        occupied = {tuple(p) for p in world.positions}
        options = [a for a in range(4)
                   if world.is_free(cell := tuple(world.positions[k] + ACTION_DELTAS[a])) and cell not in occupied]
        self.nav[k].clear()
        self.nav[k].avoid_drones = True
        self.nav[k].blocked_steps = 0
        self.deadlocks_broken += 1
        return int(self.rng.choice(options)) if options else HOVER

    def run(self) -> PlanRun:
        world = self.world
        world.reset()
        started = time.perf_counter()
        num = world.num_drones
        path_log = [world.positions.copy()]
        cells_log: list[np.ndarray] = []
        policy_log: list[int] = []
        finder_log: list[int] = []
        sampler = SteadyStateSampler()
        hover_steps = 0
        stalled_for = 0
        failure = None
        bar = tqdm(total=world.num_targets, initial=world.num_targets - world.remaining, unit="cell",
                   desc="planning", disable=not self.progress, leave=False)
        while not world.done:
            actions, by_policy, by_finder = self._choose_actions()
            for k in range(num):
                if self.nav[k].blocked_steps >= DEADLOCK_STEPS:
                    actions[k] = self._break_deadlock(k)
            outcome = world.step(actions)
            for k in range(num):
                nav = self.nav[k]
                nav.blocked_steps = nav.blocked_steps + 1 if outcome.blocked[k] else 0
                if self._by_policy[k]:
                    nav.fruitless_steps = 0 if outcome.new_cells[k] else nav.fruitless_steps + 1
                if outcome.moved[k] and self.nav[k].path and self.nav[k].path[0] == tuple(world.positions[k]):
                    self.nav[k].path.pop(0)
            hover_steps += int((~outcome.moved).sum())
            path_log.append(world.positions.copy())
            cells_log.append(outcome.new_cells)
            policy_log.append(by_policy)
            finder_log.append(by_finder)
            sampler.observe(world.coverage, world.positions, world.unexplored)
            bar.update(int(outcome.new_cells.sum()))
            stalled_for = 0 if outcome.new_cells.any() else stalled_for + 1
            if outcome.truncated:
                failure = f"step cap of {world.step_cap} steps reached at {100 * world.coverage:.1f} % coverage"
                break
            if stalled_for >= self.stall_limit:
                failure = (f"no new cell photographed for {stalled_for} steps "
                           f"at {100 * world.coverage:.1f} % coverage")
                break
        bar.close()
        seconds = time.perf_counter() - started
        paths = np.stack(path_log, axis=1)
        new_cells = np.stack(cells_log, axis=1) if cells_log else np.zeros((num, 0), dtype=np.int64)
        metrics = compute_metrics(paths, new_cells, sampler, world.coverage, hover_steps)
        return PlanRun(paths=paths, new_cells=new_cells, metrics=metrics,
                       policy_decisions=np.array(policy_log, dtype=np.int64),
                       pathfinder_decisions=np.array(finder_log, dtype=np.int64),
                       success=failure is None and world.done, failure=failure, steps=world.t,
                       deadlocks_broken=self.deadlocks_broken, plan_seconds=seconds)
