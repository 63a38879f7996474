"""The multi-drone planning loop (SPEC section 4, thesis flowchart 4.5).

Every step, in a fixed drone order:
1. a drone with a cell it sees as unexplored in its 19 x 19 view lets the policy decide
   (one batched call for all such drones); it takes the best-ranked admissible action;
2. otherwise it follows a path: the nearest unexplored cell it sees (anti-congestion:
   not near another drone's goal), reached by Explorative A*, else classic A*, else the
   next goal; it drops the path when something unexplored enters its view and re-plans
   when someone else photographs its goal;
3. a drone whose next cell is taken hovers. One blocked for DEADLOCK_STEPS steps in a
   row is in a deadlock; the lower-priority drone of the pair (higher index, or the one
   that detected it when the other is not waiting on it) retreats to the nearest cell
   off the other's path, waits there until the other has passed, then re-plans. Without
   such a cell it steps aside at random (seeded).

Beyond the thesis:
- a drone whose own zone is done helps only where it would arrive before the drones
  still busy there (their distance plus their backlog); otherwise it parks, and steps
  aside when another drone needs its cell. This cuts moves without stretching the plan;
- drones keep to the free region (4-connected) they launched in: a goal search counts only
  what the drone sees there and rivals only the drones there, its zone counts as done once
  the part in its region is, and a drone whose region has nothing unexplored left (a
  walled-in courtyard it has covered) is parked for good - no policy call, no search - so
  a drone launched in a pocket costs nothing per step however big the map (the world keeps
  the per-region counts current with every photo);
- a policy-driven drone that photographs nothing new for POLICY_PATIENCE steps (it dithers
  next to cells it cannot reach inside its view) is handed to the path-finder until that
  goal is photographed, so the loop is safe with any policy, an imperfect network too.
  One step is the default: a step that photographs nothing is one the path-finder would
  have spent better (8 steps made plans longer with either policy: docs/neural-policy.md);
- with `lanes`, a drone whose zone lies on open ground (grid.lanes: nothing blocked in the box
  of its zone and launch cell) sweeps it in footprint-wide lanes instead of exploring cell by
  cell, then helps or parks like any drone done with its zone; it waits, yields and steps aside
  like any drone. With lanes closer than a footprint (`lane_spacing` cells: a side overlap) it flies
  every lane of its sweep, and the run goes on after full coverage until every such sweep is over.

The run ends when nothing reachable is left unexplored, or fails at the step cap or when
coverage stops growing for too long (both reported, never called success).
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Protocol, Sequence

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..maps.gridmap import Cell
from .metrics import SteadyStateSampler, compute_metrics, mdu_stride
from .lanes import BLOCK, LaneSweep, obstacle_shares, sweepable
from .pathfinding import FlightSearch, SortedCells, find_goal
from .world import ACTION_DELTAS, ACTION_OF_DELTA, ACTION_STEPS, HOVER, PAD, CoverageWorld

DEADLOCK_STEPS = 3
MAX_GOAL_TRIES = 4
POLICY_PATIENCE = 1  # bench/gap_bench.py --patience N measures another
REFUGE_SEARCH_LIMIT = 4000  # cells examined when looking for a place to let another drone pass
# Cells a busy drone photographs per move, to turn its zone backlog into steps of work
# (about 9 x a typical trajectory efficiency of 35 %).
CELLS_PER_MOVE = 3.0


class Policy(Protocol):
    """Ranks the four actions for each asked drone: (len(drones), 4) scores, higher is better."""

    name: str

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray: ...


@dataclass
class _Navigation:
    """A drone's path-finder state."""

    goal: Cell | None = None
    path: list[Cell] = field(default_factory=list)  # cells still to fly, next first
    blocked_steps: int = 0
    fruitless_steps: int = 0  # policy steps in a row that photographed nothing
    forced: bool = False  # on a path because the policy stopped making progress
    avoid_drones: bool = False  # next plan treats the other drones as obstacles
    retreat_wait: int = 0  # > 0: retreating to let another drone pass, then waiting this long

    def clear(self) -> None:
        self.goal, self.path, self.forced, self.retreat_wait = None, [], False, 0

    @property
    def retreating(self) -> bool:
        return self.retreat_wait > 0


@dataclass
class PlanRun:
    """Everything a run produced; `paths` include the start and every hover."""

    paths: np.ndarray  # (K, T+1, 2)
    new_cells: np.ndarray  # (K, T)
    metrics: dict[str, float | None]
    policy_decisions: np.ndarray  # (T,) drones decided by the policy at each step
    pathfinder_decisions: np.ndarray  # (T,) drones on a path-finder (or retreating) at each step
    idle_decisions: np.ndarray  # (T,) drones parked: nothing left that they would reach first
    success: bool
    failure: str | None
    steps: int
    deadlocks_broken: int
    plan_seconds: float
    lane_drones: int = 0  # drones that swept an open-ground zone in lanes (grid.lanes)
    sweepers: tuple[bool, ...] = ()  # for each drone, whether it swept its zone in lanes


def _action_towards(position: np.ndarray | Cell, cell: Cell) -> int:
    """The action that moves from `position` to the neighbouring `cell`; HOVER if it is not one."""
    return ACTION_OF_DELTA.get((int(cell[0]) - int(position[0]), int(cell[1]) - int(position[1])), HOVER)


class Planner:
    """Drives a CoverageWorld with a policy and the path-finders until full coverage."""

    def __init__(self, world: CoverageWorld, policy: Policy, seed: int = 0, progress: bool = False,
                 stall_limit: int | None = None, lanes: bool = False, patience: int = POLICY_PATIENCE,
                 lane_spacing: int = BLOCK, tours: list[list[Cell]] | None = None,
                 tour_origin: Cell = (0, 0)) -> None:
        self.world = world
        self.patience = patience
        self.lanes = lanes
        self.tours = tours  # a whole fleet on open ground: each drone's block tour (grid/fleet_blocks.py)
        self.tour_origin = tour_origin  # a corner of their block grid
        self.lane_spacing = lane_spacing  # cells between open-ground lanes (BLOCK: one footprint)
        # Lanes closer than a footprint are flown whole, past full coverage: that repeat is the side overlap.
        self.every_lane = lanes and lane_spacing < BLOCK
        self.policy = policy
        self.rng = np.random.default_rng(seed)
        self.progress = progress
        rows, cols = world.gmap.shape
        # Far more than any honest detour takes; only a livelock hits it.
        self.stall_limit = stall_limit if stall_limit is not None else 4 * (rows + cols) + 200
        self.free = world.gmap.free
        self.search = FlightSearch(self.free, pad=PAD)  # numbered like the world's padded arrays
        drones = np.arange(world.num_drones)
        # The other drones in each drone's free region, in index order (regions never change).
        self._region_mates = [drones[(world.drone_region == world.drone_region[k]) & (drones != k)] for k in drones]
        self._unexplored_cells: tuple[int, SortedCells] | None = None  # (step, cells) cache
        self.nav = [_Navigation() for _ in range(world.num_drones)]
        self.deadlocks_broken = 0
        self._by_policy = [False] * world.num_drones
        self.sweeps: list[LaneSweep | None] = [None] * world.num_drones  # set per run
        self._sweeping = [False] * world.num_drones  # the drones that flew their sweep this step

    def _plan_sweeps(self) -> None:
        """A lane sweep for each drone whose zone lies on open ground, or nearly (with `lanes`), else None."""
        world = self.world
        self.sweeps = [None] * world.num_drones
        if not self.lanes:
            return
        shares = obstacle_shares(world.gmap.obstacle, world.zone_of, world.starts)
        # A whole fleet sweeping open ground (its zones drawn block by block by lanes.fleet_zones) keeps
        # to the map's block grid, so no block is split between two drones; one drone alone, to its zone's.
        origin = (0, 0) if all(share == 0.0 for share in shares) else None
        for k, share in enumerate(shares):
            if not sweepable(share):
                continue
            if self.tours is not None and share == 0.0:
                self.sweeps[k] = LaneSweep.along(self.tours[k], world.gmap.shape, self.tour_origin)
                continue
            cells = np.argwhere(world.zone_of == k)
            # Around obstacles, legs and centres are checked against the free cells.
            free = None if share == 0.0 else self.free
            self.sweeps[k] = LaneSweep.plan(cells, world.starts[k], world.gmap.shape, origin, free,
                                            self.lane_spacing)

    # ----------------------------------------------------------- path-finding
    def _unexplored_now(self) -> SortedCells:
        """Every unexplored cell, as numbered in the world's padded arrays and in self.search; scanned
        once per step however many drones ask."""
        world = self.world
        if self._unexplored_cells is None or self._unexplored_cells[0] != world.t:
            self._unexplored_cells = (world.t, SortedCells(world.unexplored_flat()))
        return self._unexplored_cells[1]

    def _plan_path(self, k: int) -> bool:
        world, nav = self.world, self.nav[k]
        seen_count = world.seen_in_region(k)
        if seen_count == 0:  # nothing it sees lies where it can fly: no search would find a goal
            nav.clear()
            nav.avoid_drones = False
            return False
        start = tuple(int(v) for v in world.positions[k])
        taken = [n.goal for i, n in enumerate(self.nav) if i != k and n.goal is not None]
        free = self.free
        if nav.avoid_drones:
            free = free.copy()
            free[tuple(np.delete(world.positions, k, axis=0).T)] = False
            nav.avoid_drones = False
        # A drone done with its own zone helps only where it would arrive before the
        # others, counting the work each still has in its own zone; drones in other
        # regions never get here, so they are no rivals.
        rivals = backlog = seen_cells = None
        mates = self._region_mates[k]
        if world.zone_done(k) and len(mates):
            rivals = world.positions[mates]
            backlog = world.region_zone_remaining[world.drone_region[k], mates] / CELLS_PER_MOVE
            seen_cells = self._unexplored_now()
        excluded: set[Cell] = set()
        seen = world.seen_lookup(k)  # nothing changes the world while k plans
        for _ in range(MAX_GOAL_TRIES):
            goal = find_goal(self.search, start, seen, taken, excluded,
                             rivals, backlog, seen_count=seen_count, seen_cells=seen_cells)
            if goal is None:
                break
            # Around the other drones (this once): a search over the copy, numbered as the world is.
            search = self.search if free is self.free else FlightSearch(free, pad=PAD)
            path = search.path(start, goal, seen) or search.path(start, goal)
            if path is not None:
                nav.goal, nav.path = goal, path[1:]
                return True
            excluded.add(goal)
        nav.clear()
        return False

    def _path_action(self, k: int) -> int:
        """The action that follows drone k's path, planning one first when needed."""
        world, nav = self.world, self.nav[k]
        if nav.retreating:
            if not nav.path:
                nav.retreat_wait -= 1  # in the refuge: wait for the other drone to pass
                if not nav.retreating:
                    nav.clear()
                return HOVER
        elif nav.goal is None or not world.unexplored[nav.goal] or not nav.path:
            if not self._plan_path(k):
                return HOVER
        action = _action_towards(world.positions[k], nav.path[0])
        if action == HOVER:  # the path no longer starts next to us (we were pushed aside)
            nav.clear()
        return action

    # -------------------------------------------------------------- deadlocks
    def _refuge_path(self, k: int, keep_clear: set[Cell]) -> list[Cell] | None:
        """Shortest path from drone k to the nearest free cell outside `keep_clear`."""
        world = self.world
        start = tuple(int(v) for v in world.positions[k])
        others = {tuple(p) for i, p in enumerate(world.positions) if i != k}
        parent: dict[Cell, Cell | None] = {start: None}
        queue = deque([start])
        while queue and len(parent) < REFUGE_SEARCH_LIMIT:
            cell = queue.popleft()
            if cell not in keep_clear and cell != start:
                path = [cell]
                while parent[path[-1]] != start:
                    path.append(parent[path[-1]])  # type: ignore[arg-type]
                return path[::-1]
            for dr, dc in ACTION_DELTAS:
                nxt = (cell[0] + int(dr), cell[1] + int(dc))
                if nxt not in parent and nxt not in others and world.is_free(nxt):
                    parent[nxt] = cell
                    queue.append(nxt)
        return None

    def _break_deadlock(self, k: int, actions: np.ndarray) -> None:
        """Drone k has been blocked for DEADLOCK_STEPS steps: one of the pair makes room."""
        world = self.world
        self.deadlocks_broken += 1
        self.nav[k].blocked_steps = 0
        wanted = tuple(world.positions[k] + ACTION_DELTAS[actions[k]]) if actions[k] != HOVER else None
        blocker = next((i for i, p in enumerate(world.positions) if tuple(p) == wanted), None)
        yielder, other = k, blocker
        if blocker is not None and actions[blocker] != HOVER and \
                tuple(world.positions[blocker] + ACTION_DELTAS[actions[blocker]]) == tuple(world.positions[k]):
            yielder, other = max(k, blocker), min(k, blocker)  # head-on: the lower priority gives way
        nav = self.nav[yielder]
        if other is not None:
            keep_clear = {tuple(int(v) for v in world.positions[other]), *self.nav[other].path}
            refuge = self._refuge_path(yielder, keep_clear)
            if refuge:
                nav.clear()
                nav.path = refuge
                nav.retreat_wait = 2 + len(refuge)  # long enough for the other to pass
                actions[yielder] = _action_towards(world.positions[yielder], refuge[0])
                return
        # No refuge (or nobody in the way): a random free neighbour, then a plan around drones.
        occupied = {tuple(p) for p in world.positions}
        options = [a for a in range(4)
                   if world.is_free(cell := tuple(world.positions[yielder] + ACTION_DELTAS[a]))
                   and cell not in occupied]
        nav.clear()
        nav.avoid_drones = True
        actions[yielder] = int(self.rng.choice(options)) if options else HOVER

    # ------------------------------------------------------------------- loop
    def _choose_actions(self) -> tuple[np.ndarray, int, int, int]:
        """One action per drone, and how many drones the policy / path-finders / nobody decided."""
        world = self.world
        num = world.num_drones
        # Per drone flags as Python lists: a handful of drones, read one at a time.
        # Nothing left in its region: parked for good, hovering; no policy, no search.
        parked = world.region_done().tolist()
        if self.every_lane:  # a drone still on its lanes flies them, whatever is photographed already
            parked = [done and sweep is None for done, sweep in zip(parked, self.sweeps)]
        positions: list[Cell] = [(r, c) for r, c in world.positions.tolist()]  # Python ints: a handful of drones
        sweeping = [False] * num
        for k, sweep in enumerate(self.sweeps):
            if sweep is not None and not parked[k] and not self.nav[k].retreating:
                cell = sweep.next_cell(positions[k], world.unexplored, self.search)
                if cell is None:
                    self.sweeps[k] = None  # swept: from now on it helps (or parks) as any drone done with its zone
                else:
                    sweeping[k] = True
        sees = world.sees_unexplored().tolist()
        for k in range(num):
            nav = self.nav[k]
            if parked[k]:
                nav.clear()
                nav.blocked_steps = 0
                sees[k] = False
            elif sweeping[k]:
                sees[k] = False
            elif sees[k] and (nav.retreating or (nav.forced and nav.goal is not None and world.unexplored[nav.goal])):
                sees[k] = False  # keeps to the path it is on
            elif sees[k] and nav.fruitless_steps >= self.patience:
                nav.clear()
                nav.forced = True
                nav.fruitless_steps = 0
                sees[k] = False
        policy_drones = [k for k in range(num) if sees[k]]
        scores = self.policy.action_scores(world, policy_drones).tolist() if policy_drones else []
        actions = [HOVER] * num
        claimed: set[Cell] = set()
        occupied = set(positions)
        is_free = world.is_free
        row_of = {k: i for i, k in enumerate(policy_drones)}
        for k in range(num):
            if sees[k]:
                self.nav[k].clear()
                row = scores[row_of[k]]
                r, c = positions[k]
                # Best first, ties in action order (a stable sort, as argsort's); a blocked move is -inf.
                for action in sorted(range(4), key=lambda a: -row[a]):
                    if not math.isfinite(row[action]):
                        break
                    dr, dc = ACTION_STEPS[action]
                    cell = (r + dr, c + dc)
                    if is_free(cell) and cell not in occupied and cell not in claimed:
                        actions[k] = action
                        claimed.add(cell)
                        break
            elif sweeping[k]:
                cell = self.sweeps[k].leg[0]  # type: ignore[union-attr]
                action = _action_towards(positions[k], cell)
                if cell in claimed:
                    action = HOVER
                else:
                    claimed.add(cell)  # a drone standing there moves on, makes way, or blocks it
                actions[k] = action
            elif not parked[k]:
                action = self._path_action(k)
                if action != HOVER:
                    dr, dc = ACTION_STEPS[action]
                    cell = (positions[k][0] + dr, positions[k][1] + dc)
                    if cell in claimed:
                        action = HOVER
                    else:
                        claimed.add(cell)
                actions[k] = action
        idle = sum(1 for k in range(num) if not sees[k] and not sweeping[k] and self.nav[k].goal is None
                   and not self.nav[k].retreating)
        self._make_way(actions, claimed, positions)
        self._by_policy = sees
        self._sweeping = sweeping
        return np.array(actions, dtype=np.int64), len(policy_drones), num - len(policy_drones) - idle, idle

    def _lanes_left(self) -> bool:
        """With lanes closer than a footprint: some drone has lanes left to fly (within the step cap)."""
        if not self.every_lane or self.world.t >= self.world.step_cap:
            return False
        positions = self.world.positions.tolist()
        return any(sweep is not None and not sweep.over_at(tuple(positions[k])) for k, sweep in enumerate(self.sweeps))

    def _make_way(self, actions: list[int], claimed: set[Cell], positions: list[Cell]) -> None:
        """A parked drone whose cell another drone wants to enter steps to a free neighbour."""
        world = self.world
        occupied = {p: k for k, p in enumerate(positions)}
        for k in range(world.num_drones):
            if actions[k] == HOVER:
                continue
            dr, dc = ACTION_STEPS[actions[k]]
            j = occupied.get((positions[k][0] + dr, positions[k][1] + dc))
            if j is None or actions[j] != HOVER or self.nav[j].goal is not None or self.nav[j].retreating:
                continue  # free, or a drone that moves or waits on its own path
            for action in self.rng.permutation(4).tolist():
                dr, dc = ACTION_STEPS[action]
                cell = (positions[j][0] + dr, positions[j][1] + dc)
                if world.is_free(cell) and cell not in occupied and cell not in claimed:
                    actions[j] = action
                    claimed.add(cell)
                    break

    def run(self) -> PlanRun:
        # Every product in the loop is small (a few drones x a 19 x 19 view): a second BLAS
        # thread only spins, doubling the CPU seconds of a network-driven plan for no wall time.
        with threadpool_limits(limits=1, user_api="blas"):
            return self._run()

    def _run(self) -> PlanRun:
        world = self.world
        world.reset()
        started = time.perf_counter()
        self._plan_sweeps()
        lane_drones = sum(sweep is not None for sweep in self.sweeps)
        num = world.num_drones
        path_log = [world.positions.copy()]
        cells_log: list[np.ndarray] = []
        decision_log: list[tuple[int, int, int]] = []
        sampler = SteadyStateSampler(stride=mdu_stride(world.num_targets))
        hover_steps = 0
        stalled_for = 0
        failure = None
        # Coverage reached and the time left at the recent rate (tqdm's smoothed ETA).
        bar = tqdm(total=world.num_targets, initial=world.num_targets - world.remaining, unit="cell",
                   desc="planning", disable=not self.progress, leave=False, mininterval=0.5,
                   bar_format="{desc}: {percentage:5.1f} % covered |{bar}| {n:,}/{total:,} cells "
                              "[{elapsed} elapsed, ETA {remaining}]")
        while not world.done or self._lanes_left():
            actions, by_policy, by_finder, idle = self._choose_actions()
            for k in range(num):
                if self.nav[k].blocked_steps >= DEADLOCK_STEPS:
                    self._break_deadlock(k, actions)
            outcome = world.step(actions)
            blocked, new_cells, moved = outcome.blocked.tolist(), outcome.new_cells.tolist(), outcome.moved.tolist()
            by_policy_now = self._by_policy
            positions = world.positions.tolist()
            for k in range(num):
                nav = self.nav[k]
                nav.blocked_steps = nav.blocked_steps + 1 if blocked[k] else 0
                if by_policy_now[k]:
                    nav.fruitless_steps = 0 if new_cells[k] else nav.fruitless_steps + 1
                if moved[k] and nav.path and nav.path[0] == tuple(positions[k]):
                    nav.path.pop(0)
            hover_steps += num - sum(moved)
            path_log.append(world.positions.copy())
            cells_log.append(outcome.new_cells)
            decision_log.append((by_policy, by_finder, idle))
            sampler.observe(world.coverage, world.positions, world.unexplored)
            bar.update(sum(new_cells))
            # A drone flying its overlapping lanes makes progress though it photographs nothing new.
            progressed = any(new_cells) or (self.every_lane and any(m and s for m, s in zip(moved, self._sweeping)))
            stalled_for = 0 if progressed else stalled_for + 1
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
        decisions = np.array(decision_log, dtype=np.int64).reshape(-1, 3)
        metrics = compute_metrics(paths, new_cells, sampler, world.coverage, hover_steps)
        return PlanRun(paths=paths, new_cells=new_cells, metrics=metrics,
                       policy_decisions=decisions[:, 0], pathfinder_decisions=decisions[:, 1],
                       idle_decisions=decisions[:, 2], success=failure is None and world.done,
                       failure=failure, steps=world.t, deadlocks_broken=self.deadlocks_broken,
                       plan_seconds=seconds, lane_drones=lane_drones,
                       sweepers=tuple(sweep is not None for sweep in self.sweeps))
