"""Path-finders for drones with nothing unexplored in view (SPEC section 4, thesis 4.4).

- `astar`: classic A*, 4-connected, unit step cost, Manhattan heuristic.
- `explorative_astar`: the same search with a cost that prefers unexplored cells.
  Cost we chose: entering a cell costs 1 if the drone sees it as unexplored and
  1 + EXPLORED_PENALTY otherwise. With the penalty at 0.5 the path it returns is at
  most 1.5 x the shortest one, and among paths of similar length it takes the one that
  runs over unexplored ground. Manhattan distance stays an admissible heuristic because
  no step costs less than 1. A search that expands more than its budget gives up
  ("does not converge") and the caller falls back to classic A*. Both search cell numbers
  of a grid padded with blocked cells (no bounds check per neighbour); the planner runs
  them on `FlightSearch`'s padded grid (`FlightSearch.path`), so a search copies nothing.
- `find_goal`: the outward search for the nearest cell the drone sees as unexplored
  (breadth-first along free cells, so "nearest" means by flight, not through walls),
  skipping goals near another drone's goal (anti-congestion). `FlightSearch` runs that
  breadth-first search one distance ring at a time in numpy and stops as soon as the
  answer is known, instead of ordering the whole grid on every call; its order (the
  queue order of a textbook BFS visiting neighbours up, left, right, down) is the order
  scipy's `breadth_first_order` gives on `zones.grid_graph`, so the goals are the same.
  Most goals lie a few dozen steps away: `find_goal` first runs the same search in a box
  around the start as bitboards (Python ints, a ring a handful of integer operations) and
  picks the ring's first cell in that queue order from the ring's shortest paths; only a
  goal beyond the boxes falls to the ring-by-ring search.
  It labels the free regions (4-connected) once, so `find_goal` counts and filters only
  the cells and rivals in the start's region: what lies elsewhere can never be flown to,
  and a search that waits to meet it would sweep the whole region for nothing.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Iterator, Sequence
from functools import cached_property
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from ..maps.gridmap import Cell

EXPLORED_PENALTY = 0.5
CONGESTION_RADIUS = 4  # goals within this Chebyshev distance of another drone's goal are skipped
_NEVER = np.iinfo(np.int32).max  # FlightSearch's visit stamp of a blocked cell


def astar(free: np.ndarray, start: Cell, goal: Cell, max_expansions: int | None = None) -> list[Cell] | None:
    """Shortest 4-connected path from start to goal over `free` cells, both ends included.

    Returns None when no path exists or the expansion budget runs out.
    """
    return FlightSearch(free).path(start, goal, max_expansions=max_expansions)


def explorative_astar(free: np.ndarray, seen_unexplored: np.ndarray, start: Cell, goal: Cell,
                      max_expansions: int | None = None) -> list[Cell] | None:
    """A short path that runs over cells the drone sees as unexplored (a (rows, cols) mask) where it can."""
    seen = np.pad(np.asarray(seen_unexplored, dtype=bool), 1).ravel()  # numbered as FlightSearch(free) numbers
    return FlightSearch(free).path(start, goal, SeenLookup(seen, (False, True)), max_expansions)


def explorative_budget(start: Cell, goal: Cell) -> int:
    """Expansions Explorative A* may spend: a few times what plain A* needs on an open map;
    past it, the caller falls back to plain A*."""
    return 8 * (abs(start[0] - goal[0]) + abs(start[1] - goal[1]) + 10) ** 2


class SeenLookup(NamedTuple):
    """Which cells a drone sees as unexplored, as Explorative A* and find_goal read it: cell i
    (a padded flat number of the search) is seen when `flags[values[i]]`, `values` being a flat
    array over the search's padded grid (e.g. the world's zone of each cell; a flag's index may
    be negative). Read as arrays, a box of the grid at a time, or one cell at a time."""

    values: np.ndarray
    flags: Sequence[bool]


class SortedCells(NamedTuple):
    """Cells as sorted padded flat numbers of the FlightSearch they are given to (find_goal's
    `seen_cells`: the planner's unexplored cells, read as they lie in the world's arrays)."""

    flat: np.ndarray


class _Predicate:
    """A `flat -> bool` predicate read by index, as _astar_flat reads a SeenLookup's values."""

    __slots__ = ("seen",)

    def __init__(self, seen: Callable[[int], bool]) -> None:
        self.seen = seen

    def __getitem__(self, flat: int) -> bool:
        return bool(self.seen(flat))


def _astar_flat(free: memoryview, width: int, start: int, goal: int, values: Sequence[int] | _Predicate | None,
                costs: Sequence[float], budget: int) -> list[int] | None:
    """A* over flat numbers of a padded grid (blocked border, row-major, `width` columns).

    Entering cell i costs costs[values[i]]: 1 on a seen cell and 1 + EXPLORED_PENALTY elsewhere
    for Explorative A*, 1 everywhere without `values` (classic A*). Flat numbers order cells as
    (row, col) tuples do, so ties break exactly as on cells. Returns the flat numbers from start
    to goal, or None.
    """
    goal_r, goal_c = divmod(goal, width)
    start_r, start_c = divmod(start, width)
    best_cost = {start: 0.0}
    best = best_cost.get
    parent: dict[int, int] = {}
    # Ties on f broken by larger g: prefers nodes nearer the goal, fewer expansions.
    frontier: list[tuple[float, float, int]] = [(abs(start_r - goal_r) + abs(start_c - goal_c), 0.0, start)]
    unknown = float("inf")
    push, pop = heapq.heappush, heapq.heappop
    if values is None:
        values, costs = free, (1.0, 1.0)  # every free cell costs 1
    while frontier:
        _, neg_g, node = pop(frontier)
        g = -neg_g
        # Popped before: a cell's costs only fall, and the heuristic is consistent (no step costs
        # less than 1), so its first pop carries its lowest cost and any later one a higher.
        if g > best_cost[node]:
            continue
        if node == goal:
            path = [node]
            while node in parent:
                node = parent[node]
                path.append(node)
            return path[::-1]
        budget -= 1
        if budget < 0:
            return None
        r, c = divmod(node, width)
        dr, dc = r - goal_r, c - goal_c
        h = (dr if dr > 0 else -dr) + (dc if dc > 0 else -dc)  # a neighbour's is h - 1 or h + 1
        # Up, right, down, left: the order the neighbours were always tried in (written out:
        # this loop is the planner's hottest Python). Every f is exact (halves and integers).
        nxt = node - width
        if free[nxt]:
            cost = g + costs[values[nxt]]
            if cost < best(nxt, unknown):
                best_cost[nxt] = cost
                parent[nxt] = node
                push(frontier, (cost + (h - 1 if dr > 0 else h + 1), -cost, nxt))
        nxt = node + 1
        if free[nxt]:
            cost = g + costs[values[nxt]]
            if cost < best(nxt, unknown):
                best_cost[nxt] = cost
                parent[nxt] = node
                push(frontier, (cost + (h - 1 if dc < 0 else h + 1), -cost, nxt))
        nxt = node + width
        if free[nxt]:
            cost = g + costs[values[nxt]]
            if cost < best(nxt, unknown):
                best_cost[nxt] = cost
                parent[nxt] = node
                push(frontier, (cost + (h - 1 if dr < 0 else h + 1), -cost, nxt))
        nxt = node - 1
        if free[nxt]:
            cost = g + costs[values[nxt]]
            if cost < best(nxt, unknown):
                best_cost[nxt] = cost
                parent[nxt] = node
                push(frontier, (cost + (h - 1 if dc > 0 else h + 1), -cost, nxt))
    return None


class FlightSearch:
    """Breadth-first search along the free cells of one grid, ring by ring, reusable.

    Cells are numbered row-major in the grid padded by `pad` blocked cells on every side
    (`flat_index`), so neighbours need no bounds checks, and with the world's padding a
    ring indexes the world's padded arrays directly; a visit stamp per cell (instead of a
    fresh visited array) makes starting a search O(1) whatever the grid size. The free
    cells never change, so their regions are labelled once (`region`).
    """

    def __init__(self, free: np.ndarray, pad: int = 1) -> None:
        rows, cols = free.shape
        self.shape = (rows, cols)
        self.pad = pad
        self.width = cols + 2 * pad
        padded = np.zeros((rows + 2 * pad, self.width), dtype=bool)
        padded[pad:pad + rows, pad:pad + cols] = free
        self._free = padded.ravel()
        self._free_view = self._free.data  # Python-level reads: several times faster than numpy's
        # Ascending index order = up, left, right, down: the order of the CSR rows of grid_graph.
        self._steps = np.array([[-self.width, -1, 1, self.width]], dtype=np.int64)
        # A visit stamp per cell: the search that last met it. Blocked cells hold the largest
        # stamp for good, so one read (stamp < generation) asks "free and not met yet".
        self._stamp = np.where(self._free, 0, _NEVER).astype(np.int32)
        self._generation = 0
        # Per cell, a running count stamped by the last ring that listed it (see rings).
        self._listed = np.zeros(self._free.size, dtype=np.int64)
        self._listings = 0

    def flat_index(self, cells: np.ndarray) -> np.ndarray:
        """Padded flat numbers of (n, 2) cells."""
        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        return (cells[:, 0] + self.pad) * self.width + cells[:, 1] + self.pad

    def is_free(self, cells: np.ndarray) -> np.ndarray:
        """Whether each of (n, 2) cells is free (off the grid, within the padding, counts as blocked)."""
        return self._free[self.flat_index(cells)]

    @cached_property
    def _region(self) -> np.ndarray:
        """4-connected free-region labels, flat; 0 on blocked cells. Labelled on first use: a
        search made for one path never needs them."""
        return ndimage.label(self._free.reshape(-1, self.width))[0].ravel()

    def region(self, flat: np.ndarray) -> np.ndarray:
        """Free-region label of padded flat numbers (0 for a blocked cell): equal labels, reachable."""
        return self._region[flat]

    def cells(self, flat: np.ndarray) -> np.ndarray:
        """(n, 2) cells of padded flat numbers."""
        rows, cols = np.divmod(flat, self.width)
        return np.stack([rows, cols], axis=1) - self.pad

    def path(self, start: Cell, goal: Cell, seen: Callable[[int], bool] | SeenLookup | None = None,
             max_expansions: int | None = None) -> list[Cell] | None:
        """A* from start to goal on this grid's free cells; with `seen` (of a padded flat number:
        does the drone see that cell as unexplored; a SeenLookup reads fastest) Explorative A*, by default within
        `explorative_budget`, else classic A*. The grid is searched in place, nothing copied."""
        start_i, goal_i = (int(i) for i in self.flat_index(np.array([start, goal])))
        if not (self._free[start_i] and self._free[goal_i]):
            return None
        if max_expansions is None:
            max_expansions = explorative_budget(start, goal) if seen is not None else self._free.size
        values: Sequence[int] | _Predicate | None = None
        costs: Sequence[float] = ()
        if isinstance(seen, SeenLookup):
            values = seen.values.data  # a memoryview: Python-level reads several times faster than numpy's
            costs = [1.0 if flag else 1.0 + EXPLORED_PENALTY for flag in seen.flags]
        elif seen is not None:
            values, costs = _Predicate(seen), (1.0 + EXPLORED_PENALTY, 1.0)  # indexed by the predicate's bool
        found = _astar_flat(self._free_view, self.width, start_i, goal_i, values, costs, max_expansions)
        return None if found is None else [(i // self.width - self.pad, i % self.width - self.pad) for i in found]

    def rings(self, start: Cell) -> Iterator[np.ndarray]:
        """Yield padded flat numbers of the cells at flight distance 0, 1, 2, ... in BFS queue order."""
        self._generation += 1
        stamp, generation, listed = self._stamp, self._generation, self._listed
        ring = self.flat_index(np.array([start]))
        if self._free[ring[0]]:  # a blocked start keeps its mark
            stamp[ring] = generation
        while ring.size:
            yield ring
            nxt = (ring[:, None] + self._steps).ravel()
            nxt = nxt[stamp[nxt] < generation]
            if nxt.size > 1:
                # Keep each cell's first listing, in listing order, in O(n) where np.unique
                # sorts: listing i gets the number base + n - i, larger than any earlier
                # ring's, so the largest a cell receives is its first listing's.
                mark = np.arange(self._listings + nxt.size, self._listings, -1)
                self._listings += nxt.size
                np.maximum.at(listed, nxt, mark)
                nxt = nxt[listed[nxt] == mark]
            stamp[nxt] = generation
            ring = nxt


def find_goal(search: FlightSearch, start: Cell,
              seen_unexplored: np.ndarray | Callable[[np.ndarray], np.ndarray] | SeenLookup,
              taken_goals: list[Cell], excluded: set[Cell] | None = None,
              rivals: np.ndarray | None = None, rival_backlog: np.ndarray | None = None,
              seen_count: int | None = None, seen_cells: np.ndarray | SortedCells | None = None) -> Cell | None:
    """Nearest (by flight along free cells) cell seen as unexplored that nobody else is heading for.

    Goals within CONGESTION_RADIUS of a goal in `taken_goals` are skipped; if every
    candidate is congested, the nearest congested one is returned rather than nothing.
    With `rivals` (other drones' cells), only cells that `start` reaches no later than
    every rival are candidates: a rival needs its Manhattan distance plus its
    `rival_backlog` (steps of work it still has elsewhere). So a drone that has finished
    its own zone helps where it would get there first, and gets None (stay put) where not.
    Only cells and rivals in start's free region count: no one gets anywhere else from here.

    `seen_unexplored` is a (rows, cols) mask, or a function of `search`'s padded flat
    numbers returning their flags, or a SeenLookup (the fastest), with `seen_count` = how
    many seen cells lie in start's region (more only lengthens a fruitless search) and (with
    `rivals`) `seen_cells` = the seen cells as (n, 2) or SortedCells, anywhere, so that the
    candidates are known up front. The search stops at the first uncongested candidate, or
    once every candidate has been met.
    """
    home = int(search._region[(start[0] + search.pad) * search.width + start[1] + search.pad])  # 0: blocked, no region
    box: Callable[[tuple[slice, slice]], np.ndarray] | None = None  # the seen flags of a box of the padded grid
    if isinstance(seen_unexplored, SeenLookup):
        lookup, values = np.array(seen_unexplored.flags, dtype=bool), seen_unexplored.values
        by_row = values.reshape(-1, search.width)
        is_seen, count = (lambda flat: lookup[values[flat]]), int(seen_count if seen_count is not None else -1)
        box = lambda index: lookup[by_row[index]]  # noqa: E731
    elif callable(seen_unexplored):
        is_seen, count = seen_unexplored, int(seen_count if seen_count is not None else -1)
    else:
        flat = search.flat_index(np.argwhere(np.asarray(seen_unexplored, dtype=bool)))
        if home:
            flat = flat[search.region(flat) == home]
        padded = np.zeros(search._free.size, dtype=bool)
        padded[flat] = True
        is_seen, count = padded.__getitem__, len(flat)
        seen_cells = SortedCells(flat)
        box = padded.reshape(-1, search.width).__getitem__
    if rivals is not None and len(rivals) and home:
        rivals = np.asarray(rivals).reshape(-1, 2)
        elsewhere = search.region(search.flat_index(rivals)) != home  # can never get here
        if elsewhere.any():
            if rival_backlog is not None:
                rival_backlog = np.asarray(rival_backlog, dtype=float)[~elsewhere]
            rivals = rivals[~elsewhere]
    candidates: np.ndarray | None = None  # sorted flat numbers of every candidate, when known up front
    if rivals is not None and len(rivals):
        backlog = np.zeros(len(rivals)) if rival_backlog is None else np.asarray(rival_backlog, dtype=float)
        if isinstance(seen_cells, SortedCells):
            flat = seen_cells.flat
        else:
            flat = np.sort(search.flat_index(np.asarray(seen_cells).reshape(-1, 2)))
        flat = _first_to_reach(search, start, np.asarray(rivals).reshape(-1, 2), backlog, flat)
        if home:  # after the rivals: they leave few cells to look up
            flat = flat[search.region(flat) == home]
        candidates = flat
        count = len(candidates)
    gone = search.flat_index(np.array(sorted(excluded), dtype=np.int64)) if excluded else np.zeros(0, dtype=np.int64)
    if gone.size and count > 0:
        if candidates is not None:
            candidates = candidates[~np.isin(candidates, gone)]
            count = len(candidates)
        else:
            count -= int(is_seen(gone).sum())
    if count == 0:
        return None
    taken = np.array(taken_goals, dtype=np.int64).reshape(-1, 2)
    for radius in WINDOW_RADII:
        near = _search_window(search, start, is_seen, box, candidates, gone, taken, count, radius)
        if near is not _BEYOND:
            return near  # type: ignore[return-value]
    nearest: Cell | None = None
    met = 0
    for ring in search.rings(start):
        flags = is_seen(ring)
        if gone.size:
            flags &= ~np.isin(ring, gone)
        if candidates is not None:
            at = np.minimum(np.searchsorted(candidates, ring), len(candidates) - 1)
            flags &= candidates[at] == ring
        if not np.count_nonzero(flags):  # count_nonzero: far cheaper than any() on small arrays
            continue
        found = search.cells(ring[flags])
        if nearest is None:
            nearest = (int(found[0, 0]), int(found[0, 1]))
        if not len(taken):
            return nearest
        clear = ~(np.abs(found[:, None, :] - taken[None, :, :]).max(axis=2) <= CONGESTION_RADIUS).any(axis=1)
        if clear.any():
            r, c = found[np.argmax(clear)]
            return int(r), int(c)
        met += len(found)
        if 0 <= count <= met:
            break  # every candidate met, all congested
    return nearest


def _first_to_reach(search: FlightSearch, start: Cell, rivals: np.ndarray, backlog: np.ndarray,
                    seen: np.ndarray) -> np.ndarray:
    """The cells of `seen` (sorted padded flat numbers) that `start` reaches no later than every
    rival, |r - r0| + |c - c0| <= |r - r_j| + |c - c_j| + backlog_j, as sorted flat numbers.

    The distances are integers, so the test is against floor(backlog_j) in integer arithmetic."""
    bound = sum(search.shape) + 1  # past any distance difference: a backlog beyond it rules nothing out
    limits = [max(-bound, min(bound, math.floor(extra))) if extra == extra else -bound  # NaN: nothing passes
              for extra in np.asarray(backlog, dtype=float).tolist()]
    pad = search.pad
    row0, col0 = start[0] + pad, start[1] + pad
    rows, cols = np.divmod(seen, search.width)
    mine = np.abs(rows - row0)
    mine += np.abs(cols - col0)
    padded = (rivals + pad).tolist()
    if len(seen) * len(padded) <= _ALL_RIVALS_AT_ONCE:
        rival = np.array(padded, dtype=np.int64)
        theirs = np.abs(rows - rival[:, :1])
        theirs += np.abs(cols - rival[:, 1:])
        np.subtract(mine, theirs, out=theirs)
        return seen[(theirs <= np.array(limits)[:, None]).all(axis=0)]
    # Many cells: one rival at a time, the nearest first (it rules out the most), on what is left.
    for (rival_row, rival_col), limit in sorted(zip(padded, limits),
                                                key=lambda rl: abs(rl[0][0] - row0) + abs(rl[0][1] - col0)):
        theirs = np.abs(rows - rival_row)
        theirs += np.abs(cols - rival_col)
        np.subtract(mine, theirs, out=theirs)
        keep = theirs <= limit
        rows, cols, mine, seen = rows[keep], cols[keep], mine[keep], seen[keep]
    return seen


_ALL_RIVALS_AT_ONCE = 16384  # cells x rivals up to which _first_to_reach tests every pair in one go


# find_goal first searches boxes of these radii around the start as bitboards: most goals lie
# close, and a ring of the search is then a handful of integer operations, not a dozen numpy calls
# (on a big box each operation costs more, so a far goal is looked for in a bigger box second).
WINDOW_RADII = (32, 128)
_BEYOND = object()  # _search_window's answer when the goal may lie outside its box


def _search_window(search: FlightSearch, start: Cell, is_seen: Callable[[np.ndarray], np.ndarray],
                   box: Callable[[tuple[slice, slice]], np.ndarray] | None, candidates: np.ndarray | None,
                   gone: np.ndarray, taken: np.ndarray, count: int, radius: int) -> object:
    """find_goal's search within `radius` steps of `start`: its goal, None, or _BEYOND.

    The box around the start (clipped to the padded grid, whose border is blocked) holds every
    path of up to `radius` steps, so its rings are the grid's. Each is a bitboard, a Python
    int with one bit per cell, row after row, each row followed by one closed bit: a ring's
    neighbours are the ring shifted by 1 or by a row. The first cell of a ring in the queue order
    of FlightSearch.rings (neighbours up, left, right, down) is the one whose shortest path,
    spelled as moves from the start, comes first in that order (_first_in_queue). `box` reads
    the seen flags of a box at once; without it `is_seen` is asked what a search meets (free
    cells and the start) and nothing else, as the ring search asks it."""
    width, pad = search.width, search.pad
    row, col = start[0] + pad, start[1] + pad
    top, left = max(row - radius, 0), max(col - radius, 0)
    bottom = min(row + radius, search._free.size // width - 1)
    right = min(col + radius, width - 1)
    rows, cols = bottom - top + 1, right - left + 1
    stride = cols + 1  # the closed bit ending every row
    size = -(-rows * stride // 8)  # bytes per board
    whole = np.zeros((2, 8 * size), dtype=bool)  # each board padded to whole bytes
    boards = whole[:, :rows * stride].reshape(2, rows, stride)  # free, goal
    in_box = slice(top, bottom + 1), slice(left, right + 1)
    boards[0, :, :cols] = search._free.reshape(-1, width)[in_box]
    if box is not None:
        boards[1, :, :cols] = box(in_box)
    else:
        asked = boards[0, :, :cols].copy()
        asked[row - top, col - left] = True
        flat = (np.arange(top, bottom + 1) * width)[:, None] + np.arange(left, right + 1)
        boards[1, :, :cols][asked] = is_seen(flat[asked])
    for cells, keep in ((candidates, True), (gone, False)):
        if cells is None or not cells.size:
            continue
        at, col_at = np.divmod(cells, width)
        inside = (at >= top) & (at <= bottom) & (col_at >= left) & (col_at <= right)
        mask = np.zeros((rows, stride), dtype=bool)
        mask[at[inside] - top, col_at[inside] - left] = True
        boards[1] &= mask if keep else ~mask
    packed = np.packbits(whole, bitorder="little").tobytes()
    unmet, goals = int.from_bytes(packed[:size], "little"), int.from_bytes(packed[size:], "little")
    origin = (row - top) * stride + col - left
    frontier = 1 << origin
    unmet &= ~frontier
    rings = [frontier]
    taken_at = [(r - top, c - left) for r, c in (taken + pad).tolist()]  # in the box's rows and columns
    nearest = None
    met = 0
    while frontier:
        found = frontier & goals
        if found:
            if nearest is None:
                nearest = _first_in_queue(rings, found, origin, stride)
            if not taken_at:
                break
            clear = _uncongested(found, stride, taken_at)
            if clear:
                nearest = _first_in_queue(rings, clear, origin, stride)
                break
            met += found.bit_count()
            if 0 <= count <= met:
                break  # every candidate met, all congested
        if len(rings) > radius:
            return _BEYOND  # the next ring may leave the box
        frontier = ((frontier << 1) | (frontier >> 1) | (frontier << stride) | (frontier >> stride)) & unmet
        unmet ^= frontier
        rings.append(frontier)
    if nearest is None:
        return None
    r, c = divmod(nearest, stride)
    return top + r - pad, left + c - pad


def _uncongested(found: int, stride: int, taken: list[tuple[int, int]]) -> int:
    """The bits of `found` (a few cells of one ring) farther than CONGESTION_RADIUS from every taken goal."""
    clear = 0
    rest = found
    while rest:
        bit = rest & -rest
        rest ^= bit
        r, c = divmod(bit.bit_length() - 1, stride)
        if all(abs(r - tr) > CONGESTION_RADIUS or abs(c - tc) > CONGESTION_RADIUS for tr, tc in taken):
            clear |= bit
    return clear


def _first_in_queue(rings: list[int], targets: int, origin: int, stride: int) -> int:
    """The bit of `targets` (cells of the last ring) that breadth-first search lists first.

    Its queue order lists a ring's cells by their first-listed parent, then by direction (up,
    left, right, down): so by the earliest-spelled shortest path to them. That path is walked
    from the start, taking at each step the earliest direction that still leads to a target."""
    if targets & (targets - 1) == 0:  # a single target
        return targets.bit_length() - 1
    depth = len(rings) - 1
    towards = [0] * depth + [targets]  # per ring: its cells on a shortest path to a target
    for d in range(depth - 1, 0, -1):
        ahead = towards[d + 1]
        towards[d] = ((ahead << 1) | (ahead >> 1) | (ahead << stride) | (ahead >> stride)) & rings[d]
    cell = origin
    for d in range(1, depth + 1):
        for step in (-stride, -1, 1, stride):  # up, left, right, down
            if cell + step >= 0 and towards[d] >> (cell + step) & 1:
                cell += step
                break
    return cell
