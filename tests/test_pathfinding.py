import numpy as np
from scipy.sparse.csgraph import shortest_path

from missionplan.pathfinding import CONGESTION_RADIUS, astar, explorative_astar, find_goal
from missionplan.zones import grid_graph


def maze(seed=3, size=31):
    rng = np.random.default_rng(seed)
    free = rng.random((size, size)) > 0.28
    free[0, 0] = free[-1, -1] = True
    return free


def valid_path(free, path, start, goal):
    assert path[0] == start and path[-1] == goal
    for a, b in zip(path, path[1:]):
        assert abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1
        assert free[b]


def test_astar_is_shortest_on_random_mazes():
    for seed in range(6):
        free = maze(seed)
        dist = shortest_path(grid_graph(free), unweighted=True, indices=[0])[0]
        goal = (30, 30)
        path = astar(free, (0, 0), goal)
        hops = dist[30 * 31 + 30]
        if np.isinf(hops):
            assert path is None
        else:
            valid_path(free, path, (0, 0), goal)
            assert len(path) - 1 == hops


def test_explorative_astar_prefers_unexplored_and_stays_short():
    free = np.ones((11, 11), dtype=bool)
    free[1:10, 5] = False  # a wall with gaps at the top and bottom rows
    seen = np.zeros_like(free)
    seen[10, :] = True  # unexplored strip along the bottom
    start, goal = (5, 0), (5, 10)
    plain = astar(free, start, goal)
    explorative = explorative_astar(free, seen, start, goal)
    valid_path(free, explorative, start, goal)
    assert sum(seen[c] for c in explorative) > sum(seen[c] for c in plain)
    assert len(explorative) - 1 <= 1.5 * (len(plain) - 1)


def test_no_path_and_budget_give_none():
    free = np.ones((5, 5), dtype=bool)
    free[:, 2] = False
    assert astar(free, (0, 0), (0, 4)) is None
    free[:, 2] = True
    assert astar(free, (0, 0), (4, 4), max_expansions=2) is None


def test_find_goal_nearest_by_flight_and_anti_congestion():
    free = np.ones((9, 20), dtype=bool)
    free[0:8, 3] = False  # wall: the cell just behind it is far by flight
    seen = np.zeros_like(free)
    seen[0, 4] = True  # 4 cells away as the crow flies, 20 moves around the wall
    seen[8, 1] = True  # 9 cells away, 9 moves
    graph = grid_graph(free)
    assert find_goal(graph, free.shape, (0, 0), seen, []) == (8, 1)
    start = (8, 10)
    seen2 = np.zeros_like(free)
    seen2[8, 12] = True
    seen2[8, 19] = True
    assert find_goal(graph, free.shape, start, seen2, []) == (8, 12)
    # Another drone already heads for (8, 13): (8, 12) is too close, take the next one.
    assert find_goal(graph, free.shape, start, seen2, [(8, 13)]) == (8, 19)
    assert abs(19 - 13) > CONGESTION_RADIUS
    # Every candidate congested: still returns the nearest rather than nothing.
    assert find_goal(graph, free.shape, start, seen2, [(8, 12), (8, 19)]) == (8, 12)
    assert find_goal(graph, free.shape, start, np.zeros_like(free), []) is None
