"""Tours through a zone's footprint blocks: the order one drone photographs them in, as short as we can make it.

A drone sweeping open ground photographs a whole 9 x 9 block from its centre, so covering a zone is visiting
every block centre once, from the launch cell, ending anywhere: an open travelling-salesman path with taxicab
legs. Neighbouring blocks are 9 moves apart, so no tour of n blocks is shorter than 9 (n - 1) moves plus the
way to the first; the eight snakes of lanes.snake_order reach that on a rectangle, but an irregular zone makes
a snake cross back over itself at every row end.

A tour here is the shortest of:
- the eight snakes;
- `WALKS` Warnsdorff walks from the block under the launch cell: step to the neighbouring block with the fewest
  blocks left beside it (ties: straight on, then by a seeded draw), which rarely strands a corner, and from a
  dead end to the nearest block left;
then polished by 2-opt (reverse a stretch) and Or-opt (move a run of up to OR_OPT_RUN blocks elsewhere, either
way round) until neither shortens it. Deterministic for a seed. On the four MovingAI street maps overflown, zones
of about 138 blocks, its tours are 3-4 % longer than LKH's (bench/sweep_bench.py measures the plans; LKH, through
elkai, is licensed for non-commercial use only, so it is not used).
`insertion_cost` and `removal_gain` price handing one block from one tour to another, for the fleet's local search
(grid/fleet_blocks.py), and `FleetBlocks` holds what that search hands on: the zones and the planner fly it, the
plan record reports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..maps.gridmap import Cell
from .lanes import snake_order

WALKS = 24  # Warnsdorff walks per tour: their best is within a block or two of 64 walks' on the MovingAI zones
OR_OPT_RUN = 3  # the longest run of blocks Or-opt moves


@dataclass
class FleetBlocks:
    """zone[r, c]: the drone whose block holds target cell (r, c) (other cells as given); tours[k]: the centres
    drone k photographs its blocks from, in order; moves[k]: that tour's length from its launch cell; origin: a
    corner of the block grid (a cell, each coordinate 0 .. BLOCK - 1); cpu_s: the CPU seconds it took."""

    zone: np.ndarray
    tours: list[list[Cell]]
    moves: list[int]
    origin: Cell = (0, 0)
    cpu_s: float = 0.0


def path_moves(path: np.ndarray) -> int:
    """Taxicab moves along a (n, 2) path of cells."""
    return int(np.abs(np.diff(path, axis=0)).sum()) if len(path) > 1 else 0


def blocks_beside(blocks: np.ndarray) -> list[list[int]]:
    """For each of the (n, 2) block numbers, the indices of the blocks among them that share a side with it."""
    index = {(int(r), int(c)): i for i, (r, c) in enumerate(blocks)}
    return [[index[n] for n in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)) if n in index]
            for r, c in blocks.tolist()]


def _warnsdorff(first: int, blocks: np.ndarray, centres: np.ndarray, beside: list[list[int]],
                rng: np.random.Generator | None) -> np.ndarray:
    """One walk through every block from block `first` (indices into blocks, `beside` their neighbours), as the
    module docstring says."""
    count = len(blocks)
    left = np.ones(count, dtype=bool)
    free_beside = np.array([len(b) for b in beside])
    order = [first]
    left[first] = False
    for other in beside[first]:
        free_beside[other] -= 1
    here, heading = first, (0, 0)
    draws = rng.random(count) if rng is not None else np.arange(count, dtype=float)
    while len(order) < count:
        options = [b for b in beside[here] if left[b]]
        if options:
            def rank(b: int) -> tuple[int, int, float]:
                step = (int(blocks[b, 0] - blocks[here, 0]), int(blocks[b, 1] - blocks[here, 1]))
                return int(free_beside[b]), 0 if step == heading else 1, float(draws[b])

            nxt = min(options, key=rank)
            heading = (int(blocks[nxt, 0] - blocks[here, 0]), int(blocks[nxt, 1] - blocks[here, 1]))
        else:  # a dead end: on from the nearest block left, the one with fewest free beside it on a tie
            rest = np.flatnonzero(left)
            away = np.abs(centres[rest] - centres[here]).sum(axis=1)
            nearest = rest[away == away.min()]
            nxt = int(min(nearest, key=lambda b: (int(free_beside[b]), float(draws[b]))))
            heading = (0, 0)
        order.append(nxt)
        left[nxt] = False
        for other in beside[nxt]:
            free_beside[other] -= 1
        here = nxt
    return np.array(order, dtype=np.int64)


def _two_opt_sweep(path: np.ndarray) -> bool:
    """One sweep of 2-opt over an open path whose first cell (the launch) stays put; True if it shortened it."""
    last = len(path) - 1
    shortened = False
    for i in range(1, last):
        a, b = path[i - 1], path[i]
        c = path[i + 1:]
        after = np.vstack([path[i + 2:], path[-1:]])  # the cell after each c; the final one has none
        old = np.abs(a - b).sum() + np.abs(c - after).sum(axis=1)
        new = np.abs(a - c).sum(axis=1) + np.abs(b - after).sum(axis=1)
        old[-1], new[-1] = np.abs(a - b).sum(), np.abs(a - c[-1]).sum()
        gain = old - new
        best = int(np.argmax(gain))
        if gain[best] > 0:
            j = i + 1 + best
            path[i:j + 1] = path[i:j + 1][::-1].copy()
            shortened = True
    return shortened


def _or_opt_sweep(path: np.ndarray) -> tuple[np.ndarray, bool]:
    """One sweep of Or-opt: each run of 1..OR_OPT_RUN cells moved to where it costs least, either way round."""
    shortened = False
    for run in range(1, OR_OPT_RUN + 1):
        i = 1
        while i + run - 1 <= len(path) - 1:
            first, last = path[i], path[i + run - 1]
            gain = removal_gain(path, i, run)
            rest = np.vstack([path[:i], path[i + run:]])
            put_forward, put_back = _insertion_costs(rest, first, last)
            cost = np.minimum(put_forward, put_back)
            cost[i - 1] = np.inf  # where it came from
            where = int(np.argmin(cost))
            if gain - cost[where] > 0:
                moved = path[i:i + run].copy()
                if put_back[where] < put_forward[where]:
                    moved = moved[::-1]
                path = np.vstack([rest[:where + 1], moved, rest[where + 1:]])
                shortened = True
            else:
                i += 1
    return path, shortened


def removal_gain(path: np.ndarray, i: int, run: int = 1) -> int:
    """Moves saved by taking path[i : i + run] out of the path (i >= 1: the launch stays)."""
    before, first, last = path[i - 1], path[i], path[i + run - 1]
    if i + run <= len(path) - 1:
        after = path[i + run]
        return int(np.abs(before - first).sum() + np.abs(last - after).sum() - np.abs(before - after).sum())
    return int(np.abs(before - first).sum())


def _insertion_costs(path: np.ndarray, first: np.ndarray, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Extra moves of putting a run (first .. last) after each cell of the path: forwards, and reversed."""
    here = path
    after = np.vstack([path[1:], path[-1:]])
    edge = np.abs(here - after).sum(axis=1)
    forward = (np.abs(here - first).sum(axis=1) + np.abs(last - after).sum(axis=1) - edge).astype(float)
    backward = (np.abs(here - last).sum(axis=1) + np.abs(first - after).sum(axis=1) - edge).astype(float)
    forward[-1] = np.abs(here[-1] - first).sum()  # after the last cell: nothing follows
    backward[-1] = np.abs(here[-1] - last).sum()
    return forward, backward


def insertion_cost(path: np.ndarray, cell: np.ndarray) -> tuple[int, int]:
    """(extra moves, position) of the cheapest place to visit `cell` in the path: after path[position]."""
    cost, _ = _insertion_costs(path, cell, cell)
    where = int(np.argmin(cost))
    return int(cost[where]), where


def polish(path: np.ndarray) -> np.ndarray:
    """2-opt and Or-opt in turn until neither shortens the path; path[0] stays."""
    path = np.array(path, dtype=np.int64)
    while True:
        reversed_any = _two_opt_sweep(path)
        path, moved_any = _or_opt_sweep(path)
        if not (reversed_any or moved_any):
            return path


def block_tour(start: Cell, centres: np.ndarray, blocks: np.ndarray, seed: int = 0,
               walks: int = WALKS) -> tuple[int, np.ndarray]:
    """(moves, order) of the shortest tour found through the block centres from `start` (the module docstring)."""
    if not len(blocks):
        return 0, np.zeros(0, dtype=np.int64)
    launch = np.asarray(start, dtype=np.int64)[None, :]
    centres = np.asarray(centres, dtype=np.int64)
    candidates = [snake_order(start, centres, blocks)[1]]
    first = int(np.argmin(np.abs(centres - launch).sum(axis=1)))
    rng = np.random.default_rng(seed)
    beside = blocks_beside(blocks)  # the same for every walk
    for walk in range(walks):
        candidates.append(_warnsdorff(first, blocks, centres, beside, rng if walk else None))
    lengths = [path_moves(np.vstack([launch, centres[order]])) for order in candidates]
    best = candidates[int(np.argmin(lengths))]
    polished = polish(np.vstack([launch, centres[best]]))
    # Back from cells to block indices: a zone's centres are distinct (one per block).
    position = {(int(r), int(c)): i for i, (r, c) in enumerate(centres)}
    order = np.array([position[(int(r), int(c))] for r, c in polished[1:]], dtype=np.int64)
    return path_moves(polished), order
