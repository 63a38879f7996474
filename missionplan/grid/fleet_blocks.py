"""A whole fleet sweeping open ground: the map's footprint blocks shared out, and each drone's tour through its own.

When every drone's zone lies on open ground (a field, or a city whose buildings are all overflown), the plan is
a set of block tours, and its makespan the longest of them. This module makes that set:

1. blocks: a 9 x 9 block grid over the whole map, so no block is split between two drones, each block that
   holds a target; of the 81 ways to place the grid, the one with the fewest such blocks (cell (0, 0) a block
   corner on a tie): on the MovingAI street maps 0.4-0.7 % fewer blocks than with the grid on (0, 0);
2. a first split balanced on block counts: each block to the launch nearest it in a straight line plus an
   offset per drone, the offsets moved until the counts are within `COUNT_TOLERANCE` of equal
   (zones.balanced_assignment: an additively weighted Voronoi diagram, whose cells are compact, so tours
   through them turn little);
3. each drone's tour through its blocks from its launch cell (block_tours.block_tour), and the split balanced
   on the tours rather than the counts: a drone far from its blocks, or whose blocks lie scattered, flies
   longer for as many blocks, so each drone's share of the blocks is scaled by the mean tour over its own and
   the split and tours made again, SPLIT_ROUNDS times at most (fewer when two rounds in a row find no shorter
   longest tour); the split whose longest tour is shortest is kept (the count-balanced one among them);
4. local search on the makespan, as LS-MCPP does on its spanning trees: while handing one of the longest
   tour's blocks to a drone whose blocks touch it (or to one of the CALMEST least busy) leaves both tours
   shorter than the longest was (priced by what leaving the one tour saves and the cheapest place in the
   other), the best such block changes hands, and both tours are polished (2-opt, Or-opt). A block inside a
   tour saves nothing by that price (the tour still passes it), so when no priced hand-over helps, a few
   border blocks are tried with the giver's tour polished without them. Where every neighbour of the longest
   is about as busy (many drones), a block goes on through one: the longest hands a block to a neighbour,
   which hands one of its own to a drone of its neighbours with room, when the prices say that leaves all
   three shorter than the longest was; the CHAIN_TRIES best-priced such chains are made and kept only when
   the polished tours agree. When none of those helps either, the longest tour is built again from scratch
   with another seed, and the search goes on while that shortens it.

Deterministic for a seed. The tours are handed to the planner with the zones (Zones.tours), which flies them
as lane sweeps (grid/lanes.py LaneSweep.along).
"""

from __future__ import annotations

import time

import numpy as np

from ..maps.gridmap import Cell
from .block_tours import FleetBlocks, block_tour, blocks_beside, insertion_cost, path_moves, polish, removal_gain
from .lanes import BLOCK, centres_of_blocks
from .zones import balanced_assignment

COUNT_TOLERANCE = 0.005
SPLIT_ROUNDS = 6  # splits tried, the count-balanced first, each later one's shares scaled by the tours before
MAX_HANDOVERS = 400  # blocks handed over at most
REBUILDS = 3  # fresh tours tried for the longest drone once no hand-over helps
POLISHED_TRIES = 12  # border blocks of the longest tour tried with a polish when no priced hand-over helps
CHAIN_TRIES = 4  # priced chains of two hand-overs made and checked per step, at most
CALMEST = 3  # drones with the shortest tours, offered every block of the longest beside its neighbours


class _Tours:
    """Each drone's tour as a path of cells (its launch first, kept: the local search reads the tours far more often
    than it changes them) and of block numbers."""

    def __init__(self, starts: list[Cell], centres: np.ndarray, blocks: np.ndarray, owner: np.ndarray,
                 seed: int, made: dict[tuple[int, int, bytes], tuple[int, np.ndarray]] | None = None) -> None:
        self.starts, self.centres, self.blocks, self.owner, self.seed = starts, centres, blocks, owner, seed
        # Tours already made, by (drone, seed, its blocks): a tour depends on nothing else, and the splits of
        # _balanced_tours leave many drones the blocks they had (on Berlin x 6, 10 of 25 tours).
        self.made = {} if made is None else made
        self.number = {(int(r), int(c)): b for b, (r, c) in enumerate(centres)}  # a centre's block
        self.order: list[np.ndarray] = []
        for k, start in enumerate(starts):
            mine = np.flatnonzero(owner == k)
            self.order.append(mine[self.built(k, mine, seed)[1]])
        self.paths = [self._path_of(k) for k in range(len(starts))]
        self.cost = [path_moves(path) for path in self.paths]

    def built(self, k: int, mine: np.ndarray, seed: int) -> tuple[int, np.ndarray]:
        key = (k, seed, mine.tobytes())
        if key not in self.made:
            self.made[key] = block_tour(self.starts[k], self.centres[mine], self.blocks[mine], seed)
        return self.made[key]

    def _path_of(self, k: int) -> np.ndarray:
        return np.vstack([np.asarray(self.starts[k], dtype=np.int64)[None, :], self.centres[self.order[k]]])

    def path(self, k: int) -> np.ndarray:
        """Drone k's tour as cells, its launch first (read only)."""
        return self.paths[k]

    def set_path(self, k: int, path: np.ndarray) -> None:
        """Drone k's tour from a path of its launch and block centres."""
        self.order[k] = np.array([self.number[(int(r), int(c))] for r, c in path[1:]], dtype=np.int64)
        self.paths[k] = path
        self.cost[k] = path_moves(path)

    def rebuild(self, k: int, seed: int) -> bool:
        """Drone k's tour built again with another seed; kept (True) only when shorter."""
        mine = self.order[k]
        moves, order = self.built(k, mine, seed)
        if moves >= self.cost[k]:
            return False
        self.order[k], self.cost[k] = mine[order], moves
        self.paths[k] = self._path_of(k)
        return True


def grid_origin(targets: np.ndarray) -> Cell:
    """Step 1's placing of the block grid: the corner (0 .. BLOCK - 1 each way) leaving the fewest blocks that hold
    a target, the first in row-major order on a tie, so (0, 0) where it is as good as any."""
    rows, cols = targets.shape
    # One empty block's width before the map and two after, so every placing's blocks cover it whole.
    padded = np.zeros((rows + 3 * BLOCK, cols + 3 * BLOCK), dtype=bool)
    padded[BLOCK:BLOCK + rows, BLOCK:BLOCK + cols] = targets
    spans = [(size + 2 * BLOCK - 1) // BLOCK * BLOCK for size in (rows, cols)]
    best: tuple[int, Cell] | None = None
    for dr in range(BLOCK):
        # Rows of blocks first (any target in each block's rows), then columns: a reshape each.
        by_rows = padded[dr: dr + spans[0]].reshape(-1, BLOCK, padded.shape[1]).any(axis=1)
        for dc in range(BLOCK):
            part = by_rows[:, dc: dc + spans[1]]
            count = int(part.reshape(part.shape[0], -1, BLOCK).any(axis=2).sum())
            if best is None or count < best[0]:
                best = (count, (dr, dc))
    assert best is not None
    return best[1]


def _balanced_tours(starts: list[Cell], centres: np.ndarray, blocks: np.ndarray, seeds: np.ndarray,
                    seed: int) -> _Tours:
    """Steps 2 and 3 of the module docstring: the tours of the split whose longest tour is shortest."""
    distances = np.linalg.norm(centres[None, :, :].astype(float) - np.asarray(seeds, dtype=float)[:, None, :], axis=2)
    shares = np.full(len(starts), 1.0 / len(starts))
    best: _Tours | None = None
    stale = 0
    made: dict[tuple[int, int, bytes], tuple[int, np.ndarray]] = {}
    for _ in range(SPLIT_ROUNDS):
        tours = _Tours(starts, centres, blocks, balanced_assignment(distances, COUNT_TOLERANCE, shares), seed, made)
        if best is None or max(tours.cost) < max(best.cost):
            best, stale = tours, 0
        else:
            stale += 1
            if stale == 2:
                break
        cost = np.maximum(np.asarray(tours.cost, dtype=float), 1.0)
        # A drone whose tour is longer than the mean gets proportionally fewer blocks next round.
        shares = shares * cost.mean() / cost
        shares /= shares.sum()
    assert best is not None
    return best


def _best_handover(tours: _Tours, longest: int, beside: list[list[int]]) -> tuple[int, int, int, int, int] | None:
    """(new longer of the two, block, receiver, its new cost, the longest's new cost) of the best hand-over."""
    top = tours.cost[longest]
    path = tours.path(longest)
    position = {int(b): i + 1 for i, b in enumerate(tours.order[longest])}
    best: tuple[int, int, int, int, int] | None = None
    calmest = {int(k) for k in np.argsort(tours.cost, kind="stable")[:CALMEST]}
    for b, at in position.items():
        receivers = ({int(tours.owner[n]) for n in beside[b]} | calmest) - {longest}
        left = top - removal_gain(path, at)
        if left >= top:
            continue
        for j in sorted(receivers):
            added, _ = insertion_cost(tours.path(j), tours.centres[b])
            longer = max(left, tours.cost[j] + added)
            if longer < top and (best is None or (longer, b, j) < best[:3]):
                best = (longer, b, j, tours.cost[j] + added, left)
    return best


def _polished_handover(tours: _Tours, longest: int, beside: list[list[int]]) -> tuple[int, int] | None:
    """(block, receiver) of a hand-over that the prices miss: a block inside the longest tour saves nothing by
    itself (the tour still passes it), but the tour polished without it may be shorter. Tried on the
    POLISHED_TRIES border blocks farthest from the longest drone's launch, each to its least busy neighbour."""
    top = tours.cost[longest]
    launch = np.asarray(tours.starts[longest])
    border = [int(b) for b in tours.order[longest] if any(tours.owner[n] != longest for n in beside[b])]
    border.sort(key=lambda b: (-int(np.abs(tours.centres[b] - launch).sum()), b))
    path = tours.path(longest)
    for b in border[:POLISHED_TRIES]:
        receiver = min({int(tours.owner[n]) for n in beside[b]} - {longest}, key=lambda j: (tours.cost[j], j))
        added, _ = insertion_cost(tours.path(receiver), tours.centres[b])
        if tours.cost[receiver] + added >= top:
            continue
        at = 1 + int(np.flatnonzero(tours.order[longest] == b)[0])
        if path_moves(polish(np.delete(path, at, axis=0))) < top:
            return b, receiver
    return None


def _chained_handover(tours: _Tours, longest: int, beside: list[list[int]]) -> bool:
    """Step 4's chain of two hand-overs (the module docstring), made for real; True when one was kept."""
    top = tours.cost[longest]
    path = tours.path(longest)
    chains: list[tuple[int, int, int, int, int]] = []  # (priced longest of the three, block, via, block, to)
    for at, b in enumerate(tours.order[longest].tolist(), start=1):
        left = top - removal_gain(path, at)
        if left >= top:
            continue
        for j in sorted({int(tours.owner[n]) for n in beside[b]} - {longest}):
            added, _ = insertion_cost(tours.path(j), tours.centres[b])
            grown = tours.cost[j] + added
            if grown < top:
                continue  # a single hand-over, priced by _best_handover
            via = tours.path(j)
            for at2, b2 in enumerate(tours.order[j].tolist(), start=1):
                eased = grown - removal_gain(via, at2)
                if eased >= top:
                    continue
                for k in sorted({int(tours.owner[n]) for n in beside[b2]} - {longest, j}):
                    added2, _ = insertion_cost(tours.path(k), tours.centres[b2])
                    longer = max(left, eased, tours.cost[k] + added2)
                    if longer < top:
                        chains.append((longer, b, j, b2, k))
    for _, b, j, b2, k in sorted(chains)[:CHAIN_TRIES]:
        kept = {d: (tours.order[d], tours.paths[d], tours.cost[d]) for d in (longest, j, k)}
        _hand_over(tours, b, longest, j)
        _hand_over(tours, b2, j, k)
        if max(tours.cost[d] for d in kept) < top:
            return True
        for d, (order, path_d, cost) in kept.items():  # the polished tours disagree with the prices: undone
            tours.order[d], tours.paths[d], tours.cost[d] = order, path_d, cost
        tours.owner[b], tours.owner[b2] = longest, j
    return False


def _hand_over(tours: _Tours, block: int, giver: int, receiver: int) -> None:
    """Block moves from the giver's tour to the cheapest place in the receiver's; both tours polished."""
    giver_path = tours.path(giver)
    at = 1 + int(np.flatnonzero(tours.order[giver] == block)[0])
    tours.set_path(giver, polish(np.delete(giver_path, at, axis=0)))
    receiver_path = tours.path(receiver)
    _, where = insertion_cost(receiver_path, tours.centres[block])
    grown = np.insert(receiver_path, where + 1, tours.centres[block], axis=0)
    tours.owner[block] = receiver
    tours.set_path(receiver, polish(grown))


def fleet_blocks(zone: np.ndarray, targets: np.ndarray, starts: list[Cell], centroids: np.ndarray | None = None,
                 seed: int = 0) -> FleetBlocks:
    """The fleet's blocks and tours (the module docstring); `zone` gives the labels of the cells that are no
    target, kept as they are; `centroids` the zones' Lloyd centroids the first split grows from (default: the
    launch cells)."""
    began = time.process_time()
    cells = np.argwhere(targets)
    shape = targets.shape
    if not len(cells):
        return FleetBlocks(zone, [[] for _ in starts], [0 for _ in starts])
    origin = grid_origin(targets)
    blocks, inverse = np.unique((cells - origin) // BLOCK, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    # A block cut by the map's edge is photographed from the nearest cell on the map to its centre.
    centres = centres_of_blocks(blocks, origin, shape).astype(np.int64)
    beside = blocks_beside(blocks)
    seeds = np.asarray(starts if centroids is None else centroids, dtype=float)
    if len(starts) > 1:
        tours = _balanced_tours(starts, centres, blocks, seeds, seed)
    else:
        tours = _Tours(starts, centres, blocks, np.zeros(len(blocks), dtype=np.int64), seed)
    rebuilds = 0
    for _ in range(MAX_HANDOVERS):
        longest = int(np.argmax(tours.cost))
        best = _best_handover(tours, longest, beside)
        if best is None:
            polished = _polished_handover(tours, longest, beside)
            if polished is not None:
                _hand_over(tours, polished[0], longest, polished[1])
                continue
            if _chained_handover(tours, longest, beside):
                continue
            if rebuilds >= REBUILDS or not tours.rebuild(longest, seed + 1 + rebuilds):
                break
            rebuilds += 1
            continue
        _, block, receiver, _, _ = best
        _hand_over(tours, block, longest, receiver)
    out = zone.copy()
    out[cells[:, 0], cells[:, 1]] = tours.owner[inverse]
    centre_cells = [[(int(r), int(c)) for r, c in tours.centres[order]] for order in tours.order]
    return FleetBlocks(out, centre_cells, list(tours.cost), origin, time.process_time() - began)
