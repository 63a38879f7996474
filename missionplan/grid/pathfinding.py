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
  It labels the free regions (4-connected) once, so `find_goal` counts and filters only
  the cells and rivals in the start's region: what lies elsewhere can never be flown to,
  and a search that waits to meet it would sweep the whole region for nothing.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator
from functools import cached_property

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
    return FlightSearch(free).path(start, goal, seen.data.__getitem__, max_expansions)


def explorative_budget(start: Cell, goal: Cell) -> int:
    """Expansions Explorative A* may spend: a few times what plain A* needs on an open map;
    past it, the caller falls back to plain A*."""
    return 8 * (abs(start[0] - goal[0]) + abs(start[1] - goal[1]) + 10) ** 2


def _astar_flat(free: memoryview, width: int, start: int, goal: int, seen: Callable[[int], bool] | None,
                budget: int) -> list[int] | None:
    """A* over flat numbers of a padded grid (blocked border, row-major, `width` columns).

    Entering cell i costs 1, or with `seen` (Explorative A*) 1 where seen(i) and 1 +
    EXPLORED_PENALTY elsewhere. Flat numbers order cells as (row, col) tuples do, so ties
    break exactly as on cells. Returns the flat numbers from start to goal, or None.
    """
    goal_r, goal_c = divmod(goal, width)
    start_r, start_c = divmod(start, width)
    best_cost = {start: 0.0}
    parent: dict[int, int] = {}
    # Ties on f broken by larger g: prefers nodes nearer the goal, fewer expansions.
    frontier: list[tuple[float, float, int]] = [(abs(start_r - goal_r) + abs(start_c - goal_c), 0.0, start)]
    closed: set[int] = set()
    explored_cost = 1.0 + EXPLORED_PENALTY
    unknown = float("inf")
    push, pop = heapq.heappush, heapq.heappop
    while frontier:
        _, neg_g, node = pop(frontier)
        if node in closed:
            continue
        if node == goal:
            path = [node]
            while node in parent:
                node = parent[node]
                path.append(node)
            return path[::-1]
        closed.add(node)
        budget -= 1
        if budget < 0:
            return None
        g = -neg_g
        r, c = divmod(node, width)
        # Up, right, down, left: the order the neighbours were always tried in.
        for nxt, nr, nc in ((node - width, r - 1, c), (node + 1, r, c + 1), (node + width, r + 1, c),
                            (node - 1, r, c - 1)):
            if not free[nxt]:
                continue
            cost = g + (1.0 if seen is None or seen(nxt) else explored_cost)
            if cost < best_cost.get(nxt, unknown):
                best_cost[nxt] = cost
                parent[nxt] = node
                push(frontier, (cost + abs(nr - goal_r) + abs(nc - goal_c), -cost, nxt))
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

    def path(self, start: Cell, goal: Cell, seen: Callable[[int], bool] | None = None,
             max_expansions: int | None = None) -> list[Cell] | None:
        """A* from start to goal on this grid's free cells; with `seen` (of a padded flat number:
        does the drone see that cell as unexplored) Explorative A*, by default within
        `explorative_budget`, else classic A*. The grid is searched in place, nothing copied."""
        start_i, goal_i = (int(i) for i in self.flat_index(np.array([start, goal])))
        if not (self._free[start_i] and self._free[goal_i]):
            return None
        if max_expansions is None:
            max_expansions = explorative_budget(start, goal) if seen is not None else self._free.size
        found = _astar_flat(self._free_view, self.width, start_i, goal_i, seen, max_expansions)
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


def find_goal(search: FlightSearch, start: Cell, seen_unexplored: np.ndarray | Callable[[np.ndarray], np.ndarray],
              taken_goals: list[Cell], excluded: set[Cell] | None = None,
              rivals: np.ndarray | None = None, rival_backlog: np.ndarray | None = None,
              seen_count: int | None = None, seen_cells: np.ndarray | None = None) -> Cell | None:
    """Nearest (by flight along free cells) cell seen as unexplored that nobody else is heading for.

    Goals within CONGESTION_RADIUS of a goal in `taken_goals` are skipped; if every
    candidate is congested, the nearest congested one is returned rather than nothing.
    With `rivals` (other drones' cells), only cells that `start` reaches no later than
    every rival are candidates: a rival needs its Manhattan distance plus its
    `rival_backlog` (steps of work it still has elsewhere). So a drone that has finished
    its own zone helps where it would get there first, and gets None (stay put) where not.
    Only cells and rivals in start's free region count: no one gets anywhere else from here.

    `seen_unexplored` is a (rows, cols) mask, or a function of `search`'s padded flat
    numbers returning their flags, with `seen_count` = how many seen cells lie in start's
    region (more only lengthens a fruitless search) and (with `rivals`) `seen_cells` = the
    seen cells as (n, 2), anywhere, so that the candidates are known up front. The search
    stops at the first uncongested candidate, or once every candidate has been met.
    """
    home = int(search.region(search.flat_index(np.array([start])))[0])  # 0: a blocked start, no region to keep to
    if callable(seen_unexplored):
        is_seen, count = seen_unexplored, int(seen_count if seen_count is not None else -1)
    else:
        flat = search.flat_index(np.argwhere(np.asarray(seen_unexplored, dtype=bool)))
        if home:
            flat = flat[search.region(flat) == home]
        padded = np.zeros(search._free.size, dtype=bool)
        padded[flat] = True
        is_seen, count = padded.__getitem__, len(flat)
        seen_cells = search.cells(flat) if rivals is not None else None
    if rivals is not None and len(rivals) and home:
        rivals = np.asarray(rivals).reshape(-1, 2)
        elsewhere = search.region(search.flat_index(rivals)) != home  # can never get here
        if rival_backlog is not None:
            rival_backlog = np.asarray(rival_backlog, dtype=float)[~elsewhere]
        rivals = rivals[~elsewhere]
    candidates: np.ndarray | None = None  # sorted flat numbers of every candidate, when known up front
    if rivals is not None and len(rivals):
        backlog = np.zeros(len(rivals)) if rival_backlog is None else np.asarray(rival_backlog, dtype=float)
        cells = np.asarray(seen_cells).reshape(-1, 2)
        # Rows and columns apart: 1-D arithmetic is several times faster than summing pairs.
        rows, cols = cells[:, 0].copy(), cells[:, 1].copy()
        mine = np.abs(rows - start[0]) + np.abs(cols - start[1])
        for (rival_row, rival_col), extra in zip(np.asarray(rivals).tolist(), backlog.tolist()):
            theirs = np.abs(rows - rival_row)
            theirs += np.abs(cols - rival_col)
            keep = mine <= theirs + extra  # each rival rules out most cells: shrink as we go
            rows, cols, mine = rows[keep], cols[keep], mine[keep]
        flat = (rows + search.pad) * search.width + cols + search.pad  # search.flat_index
        if home:  # after the rivals: they leave few cells to look up
            flat = flat[search.region(flat) == home]
        candidates = np.sort(flat)
        count = len(candidates)
    gone = search.flat_index(np.array(sorted(excluded or ()), dtype=np.int64))
    if gone.size and count > 0:
        if candidates is not None:
            candidates = candidates[~np.isin(candidates, gone)]
            count = len(candidates)
        else:
            count -= int(is_seen(gone).sum())
    if count == 0:
        return None
    taken = np.array(taken_goals, dtype=np.int64).reshape(-1, 2)
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
