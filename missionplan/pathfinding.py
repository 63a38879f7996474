"""Path-finders for drones with nothing unexplored in view (SPEC section 4, thesis 4.4).

- `astar`: classic A*, 4-connected, unit step cost, Manhattan heuristic.
- `explorative_astar`: the same search with a cost that prefers unexplored cells.
  Cost we chose: entering a cell costs 1 if the drone sees it as unexplored and
  1 + EXPLORED_PENALTY otherwise. With the penalty at 0.5 the path it returns is at
  most 1.5 x the shortest one, and among paths of similar length it takes the one that
  runs over unexplored ground. Manhattan distance stays an admissible heuristic because
  no step costs less than 1. A search that expands more than its budget gives up
  ("does not converge") and the caller falls back to classic A*.
- `find_goal`: the outward search for the nearest cell the drone sees as unexplored
  (breadth-first along free cells, so "nearest" means by flight, not through walls),
  skipping goals near another drone's goal (anti-congestion).
"""

from __future__ import annotations

import heapq

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order

from .gridmap import Cell

EXPLORED_PENALTY = 0.5
CONGESTION_RADIUS = 4  # goals within this Chebyshev distance of another drone's goal are skipped

_NEIGHBOURS = ((-1, 0), (0, 1), (1, 0), (0, -1))


def astar(free: np.ndarray, start: Cell, goal: Cell, step_cost: np.ndarray | None = None,
          max_expansions: int | None = None) -> list[Cell] | None:
    """Cheapest 4-connected path from start to goal over `free` cells, both ends included.

    `step_cost[r, c]` is the cost of entering (r, c) (>= 1; None means 1 everywhere).
    Returns None when no path exists or the expansion budget runs out.
    """
    rows, cols = free.shape
    if not (free[start] and free[goal]):
        return None
    goal_r, goal_c = goal
    best_cost = {start: 0.0}
    parent: dict[Cell, Cell] = {}
    # Ties on f broken by larger g: prefers nodes nearer the goal, fewer expansions.
    frontier: list[tuple[float, float, Cell]] = [(abs(start[0] - goal_r) + abs(start[1] - goal_c), 0.0, start)]
    closed: set[Cell] = set()
    budget = max_expansions if max_expansions is not None else rows * cols
    while frontier:
        _, neg_g, node = heapq.heappop(frontier)
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
        r, c = node
        for dr, dc in _NEIGHBOURS:
            nr, nc = r + dr, c + dc
            if not (0 <= nr < rows and 0 <= nc < cols) or not free[nr, nc]:
                continue
            nxt = (nr, nc)
            cost = g + (1.0 if step_cost is None else float(step_cost[nr, nc]))
            if cost < best_cost.get(nxt, np.inf):
                best_cost[nxt] = cost
                parent[nxt] = node
                heapq.heappush(frontier, (cost + abs(nr - goal_r) + abs(nc - goal_c), -cost, nxt))
    return None


def explorative_astar(free: np.ndarray, seen_unexplored: np.ndarray, start: Cell, goal: Cell,
                      max_expansions: int | None = None) -> list[Cell] | None:
    """A short path that runs over cells the drone sees as unexplored where it can."""
    step_cost = np.where(seen_unexplored, 1.0, 1.0 + EXPLORED_PENALTY)
    if max_expansions is None:
        # Budget: a few times what plain A* needs on an open map; past it, fall back.
        max_expansions = 8 * (abs(start[0] - goal[0]) + abs(start[1] - goal[1]) + 10) ** 2
    return astar(free, start, goal, step_cost, max_expansions)


def find_goal(graph: csr_matrix, shape: tuple[int, int], start: Cell, seen_unexplored: np.ndarray,
              taken_goals: list[Cell], excluded: set[Cell] | None = None,
              rivals: np.ndarray | None = None, rival_backlog: np.ndarray | None = None) -> Cell | None:
    """Nearest (by flight along free cells) cell seen as unexplored that nobody else is heading for.

    Goals within CONGESTION_RADIUS of a goal in `taken_goals` are skipped; if every
    candidate is congested, the nearest congested one is returned rather than nothing.
    With `rivals` (other drones' cells), only cells that `start` reaches no later than
    every rival are candidates: a rival needs its Manhattan distance plus its
    `rival_backlog` (steps of work it still has elsewhere). So a drone that has finished
    its own zone helps where it would get there first, and gets None (stay put) where not.
    """
    cols = shape[1]
    order = breadth_first_order(graph, start[0] * cols + start[1], directed=True,
                                return_predecessors=False)
    candidates = order[seen_unexplored.ravel()[order]]  # in order of growing distance
    if excluded:
        keep = [i for i, idx in enumerate(candidates) if divmod(int(idx), cols) not in excluded]
        candidates = candidates[keep]
    if candidates.size == 0:
        return None
    cand_rc = np.stack(np.divmod(candidates, cols), axis=1)
    if rivals is not None and len(rivals):
        mine = np.abs(cand_rc - np.asarray(start)).sum(axis=1)
        backlog = np.zeros(len(rivals)) if rival_backlog is None else np.asarray(rival_backlog, dtype=float)
        theirs = (np.abs(cand_rc[:, None, :] - np.asarray(rivals)[None, :, :]).sum(axis=2) + backlog).min(axis=1)
        cand_rc = cand_rc[mine <= theirs]
        if len(cand_rc) == 0:
            return None
    if taken_goals:
        taken = np.array(taken_goals)
        near = np.abs(cand_rc[:, None, :] - taken[None, :, :]).max(axis=2) <= CONGESTION_RADIUS
        clear = ~near.any(axis=1)
        if clear.any():
            r, c = cand_rc[np.argmax(clear)]
            return int(r), int(c)
    r, c = cand_rc[0]
    return int(r), int(c)
