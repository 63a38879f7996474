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
scoring every sequence against the current view is one matrix-vector product. The other
terms are small integers times a weight, looked up in tables of float32 products, and the
flight distances come from a breadth-first search on bitboards that stops once every cell
where a sequence can end has its distance.
Sequences that hit an obstacle, another drone or the map edge are discarded.
"""

from __future__ import annotations

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


# The expert's distance search runs on bitboards, Python ints: each view row is _ROW bits (its
# 19 cells and one closed bit), each view _ROW rows (the last closed), the views of a step one
# after another. A neighbour is then a shift by 1 or _ROW bits, and one ring of the search is a
# dozen integer operations, each far cheaper than a numpy call on so few cells.
_ROW = _VIEW + 1
_BOARD = _ROW * _ROW


def end_distances(goals: np.ndarray, blocked: np.ndarray, ends: np.ndarray, limit: int) -> np.ndarray:
    """(n, len(ends)) uint8: the flight distances on the view cells `ends` (flat view
    numbers) of each of the n (19, 19) views: steps to the nearest open goal through open cells,
    capped at `limit` (< 256), `limit` on a blocked or unreached cell. Searches only as many rings
    as the ends need."""
    n = len(goals)
    boards = np.zeros((2, n, _ROW, _ROW), dtype=bool)
    np.logical_not(blocked, out=boards[0, :, :_VIEW, :_VIEW])
    boards[1, :, :_VIEW, :_VIEW] = goals
    packed = np.packbits(boards, bitorder="little").tobytes()
    size = len(packed) // 2
    open_cells = int.from_bytes(packed[:size], "little")
    frontier = int.from_bytes(packed[size:], "little") & open_cells
    bits = _end_bits(n, ends)
    fresh = open_cells ^ frontier
    pending = bits.mask & fresh
    # The distances in binary, one bitboard per bit: a cell reached at depth d joins the boards of d's bits.
    planes = [0] * limit.bit_length()
    depth = 0
    while pending and frontier and depth < limit:
        depth += 1
        frontier = ((frontier << 1) | (frontier >> 1) | (frontier << _ROW) | (frontier >> _ROW)) & fresh
        fresh ^= frontier
        reached = frontier & pending
        if reached:
            pending ^= reached
            for bit in _BITS[depth]:
                planes[bit] |= reached
    capped = pending | (bits.mask & ~open_cells)  # never reached, or blocked
    for bit in _BITS[limit]:
        planes[bit] |= capped
    flags = np.unpackbits(np.frombuffer(b"".join(plane.to_bytes(size, "little") for plane in planes),
                                        dtype=np.uint8).reshape(len(planes), size), axis=1, bitorder="little")
    return (_PLACE[: len(planes)] @ flags.take(bits.index, axis=1)).reshape(n, len(ends))


_PLACE = (1 << np.arange(8)).astype(np.uint8)  # the value of each bit plane


_BITS = [[bit for bit in range(8) if value >> bit & 1] for value in range(256)]  # the set bits of each byte value


@dataclass(frozen=True)
class _EndBits:
    index: np.ndarray  # (n * len(ends),) bit numbers of the end cells, view by view
    mask: int  # the same cells as one bitboard


@lru_cache(maxsize=64)
def _end_bits_cached(n: int, ends: bytes) -> _EndBits:
    cells = np.frombuffer(ends, dtype=np.int64)
    index = (np.arange(n)[:, None] * _BOARD + (cells // _VIEW) * _ROW + cells % _VIEW).ravel()
    flags = np.zeros(n * _BOARD, dtype=bool)
    flags[index] = True
    return _EndBits(index, int.from_bytes(np.packbits(flags, bitorder="little").tobytes(), "little"))


def _end_bits(n: int, ends: np.ndarray) -> _EndBits:
    return _end_bits_cached(n, np.ascontiguousarray(ends, dtype=np.int64).tobytes())


class ExpertPolicy:
    """Look-ahead expert. `action_scores` ranks the four actions for each asked drone."""

    name = "expert"

    def __init__(self, depth: int = LOOKAHEAD, gamma: float = GAMMA, turn_weight: float = TURN_WEIGHT,
                 revisit_weight: float = REVISIT_WEIGHT, distance_weight: float = DISTANCE_WEIGHT) -> None:
        self.tables = tables = sequence_tables(depth, gamma)
        self.terminal_discount = gamma ** depth
        self.turn_weight = turn_weight
        self.revisit_weight = revisit_weight
        self.distance_weight = distance_weight
        # Every penalty is a float32 product of a weight and a small integer (a turn cost of the
        # tables, a revisit count, a distance), so each is looked up, made once by the very
        # float32 operation that would make it per sequence: the scores are the same floats.
        self._turn_penalty = turn_weight * tables.turn_cost  # (5, S), row = previous action + 1
        # The view cells where a sequence can end: the only distances the score reads.
        self._ends, self._end_of = np.unique(tables.cells[:, -1], return_inverse=True)
        self._distance_penalty = distance_weight * self.terminal_discount * np.arange(2 * _VIEW + 1, dtype=np.float32)
        # Along a sequence, a view cell counts 1 if this drone flew over it and 8 if blocked:
        # they sum to v = visited + 8 x blocked < 9 x depth + 1 = stride. The revisit penalty of
        # v with the sequence's own revisits r <= depth - 1 is then one lookup at v + stride x r
        # (a uint8 below 256 for any look-ahead the view allows), +inf when something
        # blocks the sequence: its score is then -inf, as a discarded one's.
        stride = 9 * depth + 1
        if stride * depth > 256:
            raise ValueError("the look-ahead is too deep for uint8 revisit keys")
        self._revisit_key = (stride * tables.self_revisits).astype(np.uint8)
        key = np.arange(stride * depth)
        along = key % stride
        revisits = (along % 8 + key // stride).astype(np.float32)  # float32 before the product, as per sequence
        self._revisit_penalty = np.where(along < 8, revisit_weight * revisits, np.float32(np.inf)).astype(np.float32)

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        """(len(drones), 4) scores, higher is better; -inf for a move that is blocked now.

        Every asked drone is scored at once: one gather of the views, one distance search over
        all their views, one gather of the tables. Only the gain stays one matrix-vector
        product per drone, so each drone's sums are the very float32 sums of a single-drone
        call (a matrix-matrix product may add in another order).
        """
        if len(drones) == 0:
            return np.zeros((0, 4))
        asked = np.asarray(drones, dtype=np.int64).reshape(-1)
        unexplored, blocked = world.views(asked)
        scores = self.view_scores(unexplored, blocked, world.flown_views(asked), world.last_actions[asked, 0])
        # Sequences are numbered with the first move as the leading base-4 digit, so each
        # action's sequences are one contiguous quarter of the table.
        return scores.reshape(len(asked), 4, -1).max(axis=2).astype(np.float64)

    def view_scores(self, unexplored: np.ndarray, blocked: np.ndarray, flown: np.ndarray,
                    last_actions: np.ndarray) -> np.ndarray:
        """(n, 4^depth) float32 score of every sequence, from n drones' (19, 19) bool views: what each
        sees as unexplored, what blocks it, where it has flown; and each one's last action (HOVER: none).
        -inf for a sequence that something blocks. What action_scores reads from the world; a search
        that imagines views of its own (bench/teacher_bench.py's rollouts) scores them here."""
        tables = self.tables
        n = len(unexplored)
        # The penalties first, while the views and the tables are still in cache (the
        # products below stream a 1.5 MB matrix through it, once per drone).
        turn = self._turn_penalty[np.asarray(last_actions) + 1]
        # Visited + 8 x blocked along each sequence, gathered move by move, (n, D, S), and summed
        # over whole rows: several times faster than summing the cells of each sequence.
        counts = flown.view(np.uint8) | (blocked.view(np.uint8) << 3)
        along = np.add.reduce(counts.reshape(n, -1).take(tables.cells_by_move, axis=1)
                              .reshape(n, tables.cells.shape[1], -1), axis=1, dtype=np.uint8)
        along += self._revisit_key
        revisit = self._revisit_penalty.take(along)
        distance = end_distances(unexplored, blocked, self._ends, 2 * _VIEW)
        far = self._distance_penalty.take(distance).take(self._end_of, axis=1)
        flat_unexplored = unexplored.reshape(n, -1).astype(np.float32)
        score = np.empty((n, len(tables.first_action)), dtype=np.float32)
        # One matrix-vector product per drone, so each drone's sums are the very float32 sums of a
        # single-drone call (a matrix-matrix product may add in another order).
        for i in range(n):
            np.matmul(tables.new_weights, flat_unexplored[i], out=score[i])
        # In the order the score was always summed: gain / 9 - turns - revisits - distance (float32).
        score /= 9.0
        score -= turn
        score -= revisit
        score -= far
        return score
