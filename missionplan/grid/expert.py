"""The algorithmic expert: the policy the neural network imitates (SPEC section 5).

It sees only what the network sees (the drone's 19 x 19 view, its zone sight and its
last action) and follows the thesis's three rules for its human expert:
explore as much as possible as early as possible, turn as little as possible, do not
pass the same cell twice.

How: a look-ahead over every sequence of LOOKAHEAD moves (4^5 = 1024 sequences). A
sequence scores

    sum_t gamma^(t-1) * new_cells_t / 9        newly photographed cells, discounted
  - TURN_WEIGHT * sum_t gamma^(t-1) * turn_t   0.5 per 90 deg turn, 1 per reversal
  - REVISIT_WEIGHT * (steps onto cells this drone already flew over)
  - DISTANCE_WEIGHT * gamma^D * (flight distance from the sequence's end to the nearest
                                 cell seen as unexplored, inside the view)

and each action is worth the best sequence that starts with it. The trick that keeps it
fast: with 5 moves and a 9 x 9 footprint everything stays inside the 19 x 19 view, and
which view cells each sequence newly photographs at each step does not depend on the
map. So that is precomputed once into a (1024, 361) matrix of discount weights, and
scoring every sequence against the current view is one matrix-vector product.
Sequences that hit an obstacle, another drone or the map edge are discarded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np

from .world import ACTION_DELTAS, FOOTPRINT_RADIUS, VIEW_RADIUS, CoverageWorld, turn_weight

LOOKAHEAD = 5
GAMMA = 0.9
TURN_WEIGHT = 0.25
REVISIT_WEIGHT = 0.15
DISTANCE_WEIGHT = 0.08

_VIEW = 2 * VIEW_RADIUS + 1


@dataclass(frozen=True)
class _SequenceTables:
    first_action: np.ndarray  # (S,)
    cells: np.ndarray  # (S, D) flat view index of the drone after each move
    new_weights: np.ndarray  # (S, 361) discounted count of newly photographed cells, per view cell
    turn_cost: np.ndarray  # (5, S) discounted turn cost, row = previous action + 1 (row 0: none)
    self_revisits: np.ndarray  # (S,) moves onto a cell the sequence already stood on
    cells_by_move: np.ndarray  # (D * S,) cells.T flattened: move t of every sequence, then move t + 1


@lru_cache(maxsize=None)
def sequence_tables(depth: int = LOOKAHEAD, gamma: float = GAMMA) -> _SequenceTables:
    """Map-independent tables for every action sequence of length `depth`."""
    if depth + FOOTPRINT_RADIUS > VIEW_RADIUS:
        raise ValueError("the look-ahead must keep the footprint inside the view")
    sequences = np.array(np.meshgrid(*[np.arange(4)] * depth, indexing="ij")).reshape(depth, -1).T
    num = len(sequences)
    offsets = np.cumsum(ACTION_DELTAS[sequences], axis=1) + VIEW_RADIUS  # (S, D, 2) in view coords
    cells = offsets[..., 0] * _VIEW + offsets[..., 1]
    new_weights = np.zeros((num, _VIEW * _VIEW), dtype=np.float32)
    self_revisits = np.zeros(num, dtype=np.float32)
    turn_cost = np.zeros((5, num), dtype=np.float32)
    f = FOOTPRINT_RADIUS
    for s in range(num):
        covered = np.zeros((_VIEW, _VIEW), dtype=bool)
        covered[VIEW_RADIUS - f: VIEW_RADIUS + f + 1, VIEW_RADIUS - f: VIEW_RADIUS + f + 1] = True
        stood = {VIEW_RADIUS * _VIEW + VIEW_RADIUS}
        for t in range(depth):
            r, c = offsets[s, t]
            footprint = np.zeros_like(covered)
            footprint[r - f: r + f + 1, c - f: c + f + 1] = True
            new_weights[s] += gamma ** t * (footprint & ~covered).ravel()
            covered |= footprint
            self_revisits[s] += cells[s, t] in stood
            stood.add(int(cells[s, t]))
        for prev in range(-1, 4):
            chain = [prev, *sequences[s]]
            turn_cost[prev + 1, s] = sum(gamma ** t * turn_weight(chain[t], chain[t + 1]) for t in range(depth))
    # action_scores relies on this order: each first move owns one contiguous quarter.
    assert np.array_equal(sequences[:, 0], np.arange(num) // (num // 4))
    return _SequenceTables(sequences[:, 0].copy(), cells, new_weights, turn_cost, self_revisits,
                           np.ascontiguousarray(cells.T).ravel())


def flight_distance_field(goals: np.ndarray, blocked: np.ndarray, limit: int,
                          needed: np.ndarray | None = None) -> np.ndarray:
    """Steps from every cell to the nearest `goals` cell through unblocked cells (capped at `limit`).

    Works on one (rows, cols) grid or a stack (..., rows, cols) of independent grids at
    once: the expert runs it for every drone of a step in one go. With `needed` (a
    (rows, cols) mask), the search stops once every needed open cell has its distance:
    the field is then exact on the needed cells only.
    """
    *stack, rows, cols = goals.shape
    count, width = math.prod(stack), cols + 1
    # Every grid laid out flat, row after row, each row followed by one closed cell and the
    # stack framed by a closed row of `width` above and below: the four neighbours of every
    # cell are then the flat array shifted by 1 or `width`, so each shift is a contiguous
    # slice (several times faster per call than 2-D strided slices; the loop is all calls).
    size = count * (rows + 1) * width + 2 * width
    padded = np.zeros(size + 2 * width, dtype=bool)  # the frontier, with a margin for the shifts
    frontier = padded[width: width + size]
    up, down = padded[:size], padded[2 * width:]
    left, right = padded[width - 1: width - 1 + size], padded[width + 1: width + 1 + size]
    open_cells = np.zeros(size, dtype=bool)
    open_grids = _grids(open_cells, count, rows, cols)
    np.logical_not(blocked.reshape(count, rows, cols), out=open_grids)
    np.logical_and(goals.reshape(count, rows, cols), open_grids, out=_grids(frontier, count, rows, cols))
    fresh = open_cells ^ frontier  # open cells not reached yet
    grown = np.empty_like(fresh)
    # A cell's distance is the number of rings grown before it was reached, so each ring
    # adds one to every open cell still unreached (one add, not a masked write per ring).
    dist = np.zeros(size, dtype=np.uint8 if limit < 256 else np.int32)
    pending = None
    if needed is not None:
        pending = np.zeros(size, dtype=bool)
        np.logical_and(needed, open_grids, out=_grids(pending, count, rows, cols))
    for ring in range(limit):
        # The early stops are checked every other ring: stopping a ring late changes no
        # distance the field promises, and saves three calls on every other ring.
        if ring % 2 == 0:
            if not np.count_nonzero(frontier):  # count_nonzero: far cheaper than any() on small arrays
                break
            if pending is not None:
                pending &= fresh
                if not np.count_nonzero(pending):
                    break
        dist += fresh
        np.bitwise_or(up, down, out=grown)
        grown |= left
        grown |= right
        grown &= fresh
        fresh ^= grown
        frontier[...] = grown
    dist[fresh] = limit  # never reached (or not searched for: only `needed` is exact)
    field = _grids(dist, count, rows, cols).astype(np.float32).reshape(goals.shape)
    field[blocked] = limit
    return field


def _grids(flat: np.ndarray, count: int, rows: int, cols: int) -> np.ndarray:
    """The (count, rows, cols) cells of flight_distance_field's flat layout, as a view."""
    width = cols + 1
    return flat[width: width + count * (rows + 1) * width].reshape(count, rows + 1, width)[:, :rows, :cols]


def visited_views(world: CoverageWorld, drones: np.ndarray) -> np.ndarray:
    """(n, 361) float32: 1 where drone drones[i] has already flown over that cell of its view."""
    return world.flown_views(drones).reshape(len(drones), -1).astype(np.float32)


class ExpertPolicy:
    """Look-ahead expert. `action_scores` ranks the four actions for each asked drone."""

    name = "expert"

    def __init__(self, depth: int = LOOKAHEAD, gamma: float = GAMMA, turn_weight: float = TURN_WEIGHT,
                 revisit_weight: float = REVISIT_WEIGHT, distance_weight: float = DISTANCE_WEIGHT) -> None:
        self.tables = sequence_tables(depth, gamma)
        self.terminal_discount = gamma ** depth
        # The view cells where a sequence can end: the only distances the score reads.
        self._ends = np.zeros(_VIEW * _VIEW, dtype=bool)
        self._ends[self.tables.cells[:, -1]] = True
        self._ends = self._ends.reshape(_VIEW, _VIEW)
        self.turn_weight = turn_weight
        self.revisit_weight = revisit_weight
        self.distance_weight = distance_weight

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        """(len(drones), 4) scores, higher is better; -inf for a move that is blocked now.

        Every asked drone is scored at once: one gather of the views, one flight-distance
        search over the stack of views, one gather of the tables. Only the gain stays one
        matrix-vector product per drone, so each drone's sums are the very float32 sums of
        a single-drone call (a matrix-matrix product may add in another order).
        """
        if len(drones) == 0:
            return np.zeros((0, 4))
        tables = self.tables
        drones = np.asarray(drones, dtype=np.int64).reshape(-1)
        n = len(drones)
        unexplored, blocked = world.views(drones)
        flat_unexplored = unexplored.reshape(n, -1).astype(np.float32)
        gain = np.empty((n, len(tables.first_action)), dtype=np.float32)
        for i in range(n):
            np.matmul(tables.new_weights, flat_unexplored[i], out=gain[i])
        gain /= 9.0
        prev = world.last_actions[drones, 0]
        score = gain - self.turn_weight * tables.turn_cost[prev + 1]
        # One gather for both per-sequence counts: visited cells + 8 x blocked cells along it
        # (at most 5 + 8 x 5, all small integers, so the float32 sum is exact and splits back).
        # Gathered move by move, (n, D, S), the sum runs over whole rows: several times faster
        # than summing the 5 cells of each sequence.
        flat_blocked = blocked.reshape(n, -1)
        eight = np.float32(8.0)  # float32 throughout: the scores must be the very same floats
        counts = visited_views(world, drones) + eight * flat_blocked
        along = np.take(counts, tables.cells_by_move, axis=1).reshape(n, tables.cells.shape[1], -1).sum(axis=1)
        blocked_along = np.floor(along / eight)
        revisits = (along - eight * blocked_along) + tables.self_revisits
        score -= self.revisit_weight * revisits
        distance = flight_distance_field(unexplored, blocked, limit=2 * _VIEW, needed=self._ends).reshape(n, -1)
        score -= self.distance_weight * self.terminal_discount * np.take(distance, tables.cells[:, -1], axis=1)
        valid = blocked_along == 0
        score = np.where(valid, score, -np.inf)
        # Sequences are numbered with the first move as the leading base-4 digit, so each
        # action's sequences are one contiguous quarter of the table.
        return score.reshape(n, 4, -1).max(axis=2).astype(np.float64)
