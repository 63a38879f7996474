import numpy as np
from scipy.sparse.csgraph import breadth_first_order, shortest_path

from missionplan.grid.pathfinding import CONGESTION_RADIUS, FlightSearch, astar, explorative_astar, find_goal
from missionplan.grid.zones import grid_graph


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


def test_flight_search_paths_are_the_astar_paths_of_the_same_grid():
    # The planner searches FlightSearch's padded grid in place; astar / explorative_astar pad a
    # copy. Same grid, same costs, same tie-breaks: the same cells, step for step.
    for seed in range(8):
        free = maze(seed, size=25)
        rng = np.random.default_rng(seed)
        seen = free & (rng.random(free.shape) < 0.5)
        search = FlightSearch(free, pad=3)
        padded_seen = np.pad(seen, 3).ravel()
        cells = np.argwhere(free)
        for start, goal in rng.choice(cells, size=(6, 2)):
            start, goal = tuple(int(v) for v in start), tuple(int(v) for v in goal)
            assert search.path(start, goal) == astar(free, start, goal)
            assert search.path(start, goal, lambda i: bool(padded_seen[i])) == explorative_astar(free, seen, start, goal)


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
    search = FlightSearch(free)
    assert find_goal(search, (0, 0), seen, []) == (8, 1)
    start = (8, 10)
    seen2 = np.zeros_like(free)
    seen2[8, 12] = True
    seen2[8, 19] = True
    assert find_goal(search, start, seen2, []) == (8, 12)
    # Another drone already heads for (8, 13): (8, 12) is too close, take the next one.
    assert find_goal(search, start, seen2, [(8, 13)]) == (8, 19)
    assert abs(19 - 13) > CONGESTION_RADIUS
    # Every candidate congested: still returns the nearest rather than nothing.
    assert find_goal(search, start, seen2, [(8, 12), (8, 19)]) == (8, 12)
    assert find_goal(search, start, np.zeros_like(free), []) is None


def test_flight_search_rings_are_scipys_breadth_first_order():
    """The ring-by-ring search meets cells in exactly the order of scipy's BFS on grid_graph,
    so the goals find_goal picks are the ones the whole-grid search picked."""
    rng = np.random.default_rng(3)
    for trial in range(20):
        free = rng.random((23, 31)) > 0.3
        start = tuple(int(v) for v in np.argwhere(free)[rng.integers(free.sum())])
        search = FlightSearch(free, pad=trial % 3 + 1)
        rings = [search.cells(r) for r in search.rings(start)]
        ours = np.concatenate([r[:, 0] * free.shape[1] + r[:, 1] for r in rings])
        theirs = breadth_first_order(grid_graph(free), start[0] * free.shape[1] + start[1], directed=True,
                                     return_predecessors=False)
        assert np.array_equal(ours, theirs)
        # Ring i holds exactly the cells at flight distance i.
        dist = shortest_path(grid_graph(free), unweighted=True, indices=[ours[0]])[0]
        for i, ring in enumerate(rings):
            assert (dist[ring[:, 0] * free.shape[1] + ring[:, 1]] == i).all()


def test_find_goal_with_rivals_and_a_seen_function():
    """A drone helps only where it arrives first; the function form gives the mask form's answers."""
    free = np.ones((10, 30), dtype=bool)
    seen = np.zeros_like(free)
    seen[5, 2] = seen[5, 27] = True
    search = FlightSearch(free)
    start = (5, 10)
    rival = np.array([[5, 25]])
    assert find_goal(search, start, seen, [], rivals=rival, rival_backlog=np.array([0.0])) == (5, 2)
    # The rival is busy for 30 more steps, so (5, 27) is ours too; (5, 2) is congested by a goal at (5, 3).
    assert find_goal(search, start, seen, [(5, 3)], rivals=rival, rival_backlog=np.array([30.0])) == (5, 27)
    seen[5, 2] = False
    assert find_goal(search, start, seen, [], rivals=rival, rival_backlog=np.array([0.0])) is None
    def seen_flat(flat):
        cells = search.cells(flat)
        return seen[cells[:, 0], cells[:, 1]]

    as_function = find_goal(search, start, seen_flat, [], rivals=rival, rival_backlog=np.array([30.0]),
                            seen_count=int(seen.sum()), seen_cells=np.argwhere(seen))
    assert as_function == (5, 27)
    assert find_goal(search, start, seen_flat, [], excluded={(5, 27)}, seen_count=1) is None
    assert find_goal(search, start, seen_flat, [], seen_count=1) == (5, 27)
