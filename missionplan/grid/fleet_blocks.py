"""A whole fleet sweeping open ground: the map's footprint blocks shared out, and each drone's tour through its own.

When every drone's zone lies on open ground (a field, or a city whose buildings are all overflown), the plan is
a set of block tours, and its makespan the longest of them. This module makes that set:

1. blocks: the map's 9 x 9 block grid, aligned on cell (0, 0) so no block is split between two drones, each
   block that holds a target;
2. a first split balanced on block counts: each block to the launch nearest it in a straight line plus an
   offset per drone, the offsets moved until the counts are within `COUNT_TOLERANCE` of equal
   (zones.balanced_assignment: an additively weighted Voronoi diagram, whose cells are compact, so tours
   through them turn little);
3. each drone's tour through its blocks from its launch cell (block_tours.block_tour);
4. local search on the makespan, as LS-MCPP does on its spanning trees: while handing one of the longest
   tour's blocks to a drone whose blocks touch it (or to one of the CALMEST least busy) leaves both tours
   shorter than the longest was (priced by what leaving the one tour saves and the cheapest place in the
   other), the best such block changes hands, and both tours are polished (2-opt, Or-opt). A block inside a
   tour saves nothing by that price (the tour still passes it), so when no priced hand-over helps, a few
   border blocks are tried with the giver's tour polished without them; when none of those helps either,
   the longest tour is built again from scratch with another seed, and the search goes on while that
   shortens it.

Deterministic for a seed. The tours are handed to the planner with the zones (Zones.tours), which flies them
as lane sweeps (grid/lanes.py LaneSweep.along).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..maps.gridmap import Cell
from .block_tours import block_tour, blocks_beside, insertion_cost, path_moves, polish, removal_gain
from .lanes import BLOCK
from .world import FOOTPRINT_RADIUS
from .zones import balanced_assignment

COUNT_TOLERANCE = 0.005
MAX_HANDOVERS = 400  # blocks handed over at most
REBUILDS = 3
POLISHED_TRIES = 12  # border blocks of the longest tour tried with a polish when no priced hand-over helps
CALMEST = 3  # drones with the shortest tours, offered every block of the longest beside its neighbours  # fresh tours tried for the longest drone once no hand-over helps


@dataclass
class FleetBlocks:
    """zone[r, c]: the drone whose block holds target cell (r, c) (other cells as given); tours[k]: the centres
    drone k photographs its blocks from, in order; moves[k]: that tour's length from its launch cell."""

    zone: np.ndarray
    tours: list[list[Cell]]
    moves: list[int]


class _Tours:
    """Each drone's tour as a path of cells (its launch first, kept: the local search reads the tours far more often
    than it changes them) and of block numbers."""

    def __init__(self, starts: list[Cell], centres: np.ndarray, owner: np.ndarray, seed: int) -> None:
        self.starts, self.centres, self.owner, self.seed = starts, centres, owner, seed
        self.number = {(int(r), int(c)): b for b, (r, c) in enumerate(centres)}  # a centre's block
        self.order: list[np.ndarray] = []
        for k, start in enumerate(starts):
            mine = np.flatnonzero(owner == k)
            self.order.append(mine[self.built(k, mine, seed)[1]])
        self.paths = [self._path_of(k) for k in range(len(starts))]
        self.cost = [path_moves(path) for path in self.paths]

    def built(self, k: int, mine: np.ndarray, seed: int) -> tuple[int, np.ndarray]:
        return block_tour(self.starts[k], self.centres[mine], self.centres[mine] // BLOCK, seed)

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


def _first_split(centres: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Step 2 of the module docstring: each block's drone, counts balanced."""
    distances = np.linalg.norm(centres[None, :, :].astype(float) - np.asarray(seeds, dtype=float)[:, None, :], axis=2)
    return balanced_assignment(distances, tolerance=COUNT_TOLERANCE)


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
    cells = np.argwhere(targets)
    shape = targets.shape
    if not len(cells):
        return FleetBlocks(zone, [[] for _ in starts], [0 for _ in starts])
    blocks, inverse = np.unique(cells // BLOCK, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    centres = np.minimum(blocks * BLOCK + FOOTPRINT_RADIUS, np.array(shape) - 1).astype(np.int64)
    beside = blocks_beside(blocks)
    seeds = np.asarray(starts if centroids is None else centroids, dtype=float)
    owner = _first_split(centres, seeds) if len(starts) > 1 else np.zeros(len(blocks), dtype=np.int64)
    tours = _Tours(starts, centres, owner, seed)
    rebuilds = 0
    for _ in range(MAX_HANDOVERS):
        longest = int(np.argmax(tours.cost))
        best = _best_handover(tours, longest, beside)
        if best is None:
            polished = _polished_handover(tours, longest, beside)
            if polished is not None:
                _hand_over(tours, polished[0], longest, polished[1])
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
    return FleetBlocks(out, centre_cells, list(tours.cost))
