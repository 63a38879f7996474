import itertools

import numpy as np
import pytest

from missionplan.learn.features import (
    DETECTOR_RANGE,
    NUM_SYMMETRIES,
    STATE_SIZE,
    VIEW_CELLS,
    augment,
    encode_states,
    inverse_symmetry,
    transform_actions,
    transform_cell,
    transform_grid,
    transform_states,
)
from missionplan.maps.gridmap import GridMap
from missionplan.grid.world import ACTION_DELTAS, DOWN, HOVER, LEFT, RIGHT, UP, VIEW_RADIUS, CoverageWorld

MEMORY = 360  # first memory value
UNEXPLORED_DET = 368  # first "unexplored further along" detector
OBSTACLE_DET = 372  # first "obstacle ahead" detector


def view_index(dr: int, dc: int) -> int:
    """Index in the state vector of the view cell at offset (dr, dc) from the drone."""
    flat = (dr + VIEW_RADIUS) * (2 * VIEW_RADIUS + 1) + (dc + VIEW_RADIUS)
    centre = (2 * VIEW_RADIUS + 1) ** 2 // 2
    assert flat != centre
    return flat - 1 if flat > centre else flat


def column_zones(shape, split_col):
    return np.where(np.arange(shape[1])[None, :] < split_col, 0, 1) * np.ones(shape, dtype=np.int64)


def small_world():
    """25 x 25 open map, one obstacle cell, two drones near the top-left, zones split at column 13."""
    obstacle = np.zeros((25, 25), dtype=bool)
    obstacle[6, 10] = True
    gmap = GridMap(name="t", obstacle=obstacle, target=~obstacle, launch=[(3, 3), (3, 8)])
    return CoverageWorld(gmap, gmap.launch, column_zones(gmap.shape, 13))


def view_from_world(world, k):
    """The view part of the state built from the world's own view_unexplored / view_blocked."""
    grid = np.where(world.view_blocked(k), -1.0, world.view_unexplored(k).astype(float)).ravel()
    return np.delete(grid, grid.size // 2)


# ---------------------------------------------------------------------------- encoding
def test_state_size_and_dtype():
    world = small_world()
    states = encode_states(world, [0, 1])
    assert STATE_SIZE == 376 and VIEW_CELLS == 360
    assert states.shape == (2, 376)
    assert states.dtype == np.float32
    assert encode_states(world, []).shape == (0, 376)
    assert VIEW_RADIUS + 1 + DETECTOR_RANGE <= 32


def test_view_entries_by_hand():
    world = small_world()
    s = encode_states(world, [0])[0]
    assert s[view_index(3, 7)] == -1  # the obstacle at (6, 10)
    assert s[view_index(-4, 0)] == -1  # row -1: outside the map
    assert s[view_index(0, -4)] == -1  # column -1: outside the map
    assert s[view_index(0, 5)] == -1  # drone 2 at (3, 8)
    assert s[view_index(7, 0)] == 1  # (10, 3): unexplored, own zone
    assert s[view_index(9, 9)] == 1  # (12, 12): last column of zone 0
    assert s[view_index(0, 9)] == 0  # (3, 12): photographed by drone 2 at launch
    assert s[view_index(1, 1)] == 0  # (4, 4): under drone 1's own footprint
    # The view holds only -1, 0, +1.
    assert set(np.unique(s[:VIEW_CELLS])) <= {-1.0, 0.0, 1.0}


def test_memory_one_hots_follow_the_last_two_moves():
    world = small_world()
    assert not encode_states(world, [0])[0, MEMORY:MEMORY + 8].any()  # HOVER, HOVER: all zeros
    world.step([DOWN, HOVER])
    memory = encode_states(world, [0])[0, MEMORY:MEMORY + 8]
    assert np.flatnonzero(memory).tolist() == [DOWN]  # previous = down, one before = none
    world.step([RIGHT, HOVER])
    memory = encode_states(world, [0])[0, MEMORY:MEMORY + 8]
    assert np.flatnonzero(memory).tolist() == [RIGHT, 4 + DOWN]
    world.step([UP, HOVER])  # (4, 4) -> (3, 4): free
    world.step([RIGHT, HOVER])  # (3, 4) -> (3, 5)
    memory = encode_states(world, [0, 1])[:, MEMORY:MEMORY + 8]
    assert np.flatnonzero(memory[0]).tolist() == [RIGHT, 4 + UP]
    assert not memory[1].any()  # drone 2 only hovered


def test_blocked_move_leaves_the_memory_alone():
    world = small_world()
    world.step([RIGHT, HOVER])  # (3, 3) -> (3, 4)
    for _ in range(3):
        world.step([RIGHT, HOVER])  # ... -> (3, 7), next to drone 2
    before = encode_states(world, [0])[0, MEMORY:MEMORY + 8]
    outcome = world.step([RIGHT, HOVER])  # into drone 2: hovers
    assert outcome.blocked.tolist() == [True, False]
    assert np.array_equal(encode_states(world, [0])[0, MEMORY:MEMORY + 8], before)


def detector_world(target_cells=(), obstacle_cells=(), size=70, drone=(35, 35)):
    """One drone on a big open map whose only targets / obstacles are the given cells."""
    obstacle = np.zeros((size, size), dtype=bool)
    target = np.zeros((size, size), dtype=bool)
    for cell in obstacle_cells:
        obstacle[cell] = True
    for cell in target_cells:
        target[cell] = True
    gmap = GridMap(name="det", obstacle=obstacle, target=target, launch=[drone])
    return CoverageWorld(gmap, gmap.launch)


def test_detectors_off_on_an_empty_map():
    s = encode_states(detector_world(), [0])[0]
    assert not s[UNEXPLORED_DET:].any()
    assert not s[:VIEW_CELLS].any()


@pytest.mark.parametrize("action", [UP, RIGHT, DOWN, LEFT])
def test_unexplored_detector_band_depth(action):
    centre = np.array([35, 35])
    delta = ACTION_DELTAS[action]
    side = delta[::-1]  # across the band
    cases = {
        VIEW_RADIUS + 1: True,  # first cell past the view
        VIEW_RADIUS + DETECTOR_RANGE: True,  # last cell of the band
        VIEW_RADIUS + DETECTOR_RANGE + 1: False,  # one beyond the band
    }
    for distance, expect in cases.items():
        for across in (-VIEW_RADIUS, 0, VIEW_RADIUS):  # the band is as wide as the view
            cell = tuple(centre + distance * delta + across * side)
            s = encode_states(detector_world(target_cells=[cell]), [0])[0]
            detectors = s[UNEXPLORED_DET:UNEXPLORED_DET + 4]
            assert detectors.tolist() == [float(expect and a == action) for a in range(4)], (distance, across)
            assert not s[:VIEW_CELLS].any()  # the cell is beyond the view
    # Just wider than the view: in no band.
    cell = tuple(centre + (VIEW_RADIUS + 5) * delta + (VIEW_RADIUS + 1) * side)
    assert not encode_states(detector_world(target_cells=[cell]), [0])[0, UNEXPLORED_DET:].any()


@pytest.mark.parametrize("action", [UP, RIGHT, DOWN, LEFT])
def test_obstacle_detector_looks_at_one_cell_on_the_centre_line(action):
    centre = np.array([35, 35])
    delta = ACTION_DELTAS[action]
    for distance, expect in ((VIEW_RADIUS, False), (VIEW_RADIUS + 1, True), (VIEW_RADIUS + 2, False)):
        cell = tuple(centre + distance * delta)
        s = encode_states(detector_world(obstacle_cells=[cell]), [0])[0]
        assert s[OBSTACLE_DET:OBSTACLE_DET + 4].tolist() == [float(expect and a == action) for a in range(4)]
        if distance <= VIEW_RADIUS:
            assert s[view_index(*(distance * delta))] == -1  # inside the view: seen there instead
    # Off the centre line by one: off.
    cell = tuple(centre + (VIEW_RADIUS + 1) * delta + delta[::-1])
    assert not encode_states(detector_world(obstacle_cells=[cell]), [0])[0, OBSTACLE_DET:].any()


def test_obstacle_detector_counts_outside_the_map_but_not_drones():
    # Drone at row 9, column 60 of a 70 x 70 map: row -1 is just past the view, up;
    # column 70 is exactly VIEW_RADIUS + 1 to the right.
    s = encode_states(detector_world(drone=(9, 60)), [0])[0]
    assert s[OBSTACLE_DET:OBSTACLE_DET + 4].tolist() == [1.0, 1.0, 0.0, 0.0]
    # Another drone at the "ahead" cell is not a static obstacle.
    gmap = GridMap(name="two", obstacle=np.zeros((40, 40), bool), target=np.zeros((40, 40), bool),
                   launch=[(20, 20), (10, 20)])
    world = CoverageWorld(gmap, gmap.launch, np.zeros((40, 40), dtype=np.int64))
    assert not encode_states(world, [0])[0, OBSTACLE_DET:].any()


def play_random(world, steps, seed):
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        world.step(rng.integers(-1, 4, size=world.num_drones))


def random_map(rows, cols, seed, density=0.12):
    rng = np.random.default_rng(seed)
    obstacle = rng.random((rows, cols)) < density
    target = rng.random((rows, cols)) < 0.85
    return obstacle, target


def test_batched_encoding_equals_one_drone_at_a_time_and_the_world_view():
    obstacle, target = random_map(30, 36, seed=1)
    launch = [(5, 5), (6, 5), (24, 30)]
    obstacle[tuple(np.array(launch).T)] = False
    gmap = GridMap(name="r", obstacle=obstacle, target=target, launch=launch)
    zone = np.minimum(np.arange(36) // 12, 2)[None, :] * np.ones((30, 36), dtype=np.int64)
    world = CoverageWorld(gmap, launch, zone)
    for _ in range(4):
        play_random(world, 5, seed=world.t)
        batch = encode_states(world, [0, 1, 2])
        for k in range(3):
            assert np.array_equal(batch[k], encode_states(world, [k])[0])
            assert np.array_equal(batch[k, :VIEW_CELLS], view_from_world(world, k))
        # Any order and repeats are fine.
        assert np.array_equal(encode_states(world, [2, 0, 2]), batch[[2, 0, 2]])


def test_zone_sight_hides_other_zones_until_the_own_zone_is_done():
    obstacle = np.zeros((25, 25), dtype=bool)
    gmap = GridMap(name="z", obstacle=obstacle, target=~obstacle, launch=[(3, 3), (3, 8)])
    # Drone 2's zone (columns >= 13) is large: not done, so it sees only its own cells.
    world = CoverageWorld(gmap, gmap.launch, column_zones(gmap.shape, 13))
    s = encode_states(world, [1])[0]
    assert s[view_index(7, 6)] == 1  # (10, 14): own zone, unexplored
    assert s[view_index(7, -3)] == 0  # (10, 5): unexplored, but drone 1's zone
    assert s[UNEXPLORED_DET + DOWN] == 1  # rows 13.. of its zone lie below the view
    # Now drone 2's zone is exactly its launch footprint: done at once, it sees everything.
    zone = np.zeros(gmap.shape, dtype=np.int64)
    zone[0:8, 4:13] = 1
    world = CoverageWorld(gmap, gmap.launch, zone)
    assert world.zone_done(1) and not world.zone_done(0)
    s = encode_states(world, [0, 1])
    assert s[1, view_index(7, -3)] == 1  # (10, 5) now seen
    assert s[1, view_index(7, 6)] == 1
    assert s[0, view_index(7, 0)] == 1  # drone 1's zone is not done: still its own cells only
    for k in range(2):
        assert np.array_equal(s[k, :VIEW_CELLS], view_from_world(world, k))


def test_detector_respects_zone_sight():
    # Two drones; the only far target lies in drone 2's zone, 15 cells above drone 1.
    size = 60
    obstacle = np.zeros((size, size), dtype=bool)
    target = np.zeros((size, size), dtype=bool)
    target[20, 40] = True
    target[50, 55] = True  # keeps drone 2's zone unfinished
    gmap = GridMap(name="zd", obstacle=obstacle, target=target, launch=[(35, 40), (55, 10)])
    zone = np.ones((size, size), dtype=np.int64)
    zone[35:, :30] = 0
    world = CoverageWorld(gmap, gmap.launch, zone)
    assert world.zone_remaining.tolist() == [0, 2]  # drone 1's zone has no targets: done
    assert encode_states(world, [0])[0, UNEXPLORED_DET + UP] == 1  # zone done: sees it
    zone[50:, 50:] = 0  # give drone 1 an unfinished zone: the target at (50, 55)
    world = CoverageWorld(gmap, gmap.launch, zone)
    assert world.zone_remaining.tolist() == [1, 1]
    assert encode_states(world, [0])[0, UNEXPLORED_DET + UP] == 0  # drone 2's cell: hidden


# -------------------------------------------------------------------------- symmetries
def test_transform_grid_and_cell_agree_on_a_non_square_grid():
    shape = (5, 8)
    for sym in range(NUM_SYMMETRIES):
        for cell in [(0, 0), (1, 6), (4, 7), (3, 2)]:
            grid = np.zeros(shape, dtype=bool)
            grid[cell] = True
            out = transform_grid(grid, sym)
            assert np.argwhere(out).tolist() == [list(transform_cell(cell, shape, sym))]
    assert np.array_equal(transform_grid(np.arange(6).reshape(2, 3), 1), np.rot90(np.arange(6).reshape(2, 3)))


def test_transform_actions_by_hand():
    actions = [UP, RIGHT, DOWN, LEFT, HOVER]
    assert transform_actions(actions, 0).tolist() == actions
    assert transform_actions(actions, 1).tolist() == [LEFT, UP, RIGHT, DOWN, HOVER]  # 90 deg ccw
    assert transform_actions(actions, 2).tolist() == [DOWN, LEFT, UP, RIGHT, HOVER]
    assert transform_actions(actions, 4).tolist() == [UP, LEFT, DOWN, RIGHT, HOVER]  # mirror
    with pytest.raises(ValueError):
        transform_actions(actions, 8)


def test_symmetry_then_inverse_is_identity():
    rng = np.random.default_rng(3)
    states = rng.normal(size=(5, STATE_SIZE)).astype(np.float32)
    grid = rng.random((6, 9))
    actions = np.array([UP, RIGHT, DOWN, LEFT, HOVER])
    for sym in range(NUM_SYMMETRIES):
        inv = inverse_symmetry(sym)
        assert np.array_equal(transform_states(transform_states(states, sym), inv), states)
        assert np.array_equal(transform_grid(transform_grid(grid, sym), inv), grid)
        assert np.array_equal(transform_actions(transform_actions(actions, sym), inv), actions)
        out_shape = transform_grid(grid, sym).shape
        assert transform_cell(transform_cell((2, 7), grid.shape, sym), out_shape, inv) == (2, 7)


def test_eight_versions_of_an_asymmetric_state_are_pairwise_different():
    state = np.random.default_rng(4).normal(size=(1, STATE_SIZE)).astype(np.float32)
    versions = [transform_states(state, sym)[0] for sym in range(NUM_SYMMETRIES)]
    for a, b in itertools.combinations(range(NUM_SYMMETRIES), 2):
        assert not np.array_equal(versions[a], versions[b]), (a, b)
        # A permutation of the same values, nothing lost or duplicated.
        assert np.array_equal(np.sort(versions[a]), np.sort(state[0]))


def test_augment_stacks_all_symmetries_with_matching_labels():
    rng = np.random.default_rng(5)
    states = rng.normal(size=(7, STATE_SIZE)).astype(np.float32)
    actions = np.array([UP, RIGHT, DOWN, LEFT, HOVER, UP, LEFT])
    big_states, big_actions = augment(states, actions)
    assert big_states.shape == (8 * 7, STATE_SIZE) and big_states.dtype == np.float32
    assert big_actions.shape == (8 * 7,)
    for sym in range(NUM_SYMMETRIES):
        rows = slice(sym * 7, (sym + 1) * 7)
        assert np.array_equal(big_states[rows], transform_states(states, sym))
        assert np.array_equal(big_actions[rows], transform_actions(actions, sym))


def commutation_setup():
    """A 24 x 30 random-ish map, 2 drones, drone 2 owning a thin strip on the right."""
    obstacle, target = random_map(24, 30, seed=7)
    obstacle[:, 25:] = False  # keep drone 2's strip passable so its zone gets done
    launch = [(12, 6), (3, 27)]
    gmap = GridMap(name="c", obstacle=obstacle, target=target, launch=launch)
    zone = column_zones(gmap.shape, 26)
    rng = np.random.default_rng(11)
    actions = np.stack([rng.integers(-1, 4, size=20), np.full(20, DOWN)], axis=1)
    actions[::7, 1] = RIGHT  # drone 2 sidesteps too; the third one runs into the map edge
    return gmap, zone, actions


def test_encoding_commutes_with_every_symmetry():
    gmap, zone, actions = commutation_setup()
    base = CoverageWorld(gmap, gmap.launch, zone)
    original = [encode_states(base, [0, 1])]
    positions = [base.positions.tolist()]
    zone_done_seen = False
    for step in actions:
        base.step(step)
        original.append(encode_states(base, [0, 1]))
        positions.append(base.positions.tolist())
        zone_done_seen |= base.zone_done(1)
    assert zone_done_seen  # the run crosses the "own zone done" switch
    assert any(s[:, UNEXPLORED_DET:].any() for s in original)  # detectors do fire
    assert any(s[:, OBSTACLE_DET:].any() for s in original)

    for sym in range(NUM_SYMMETRIES):
        launch = [transform_cell(cell, gmap.shape, sym) for cell in gmap.launch]
        tmap = GridMap(name=f"c{sym}", obstacle=transform_grid(gmap.obstacle, sym),
                       target=transform_grid(gmap.target, sym), launch=launch)
        world = CoverageWorld(tmap, launch, transform_grid(zone, sym))
        assert np.array_equal(encode_states(world, [0, 1]), transform_states(original[0], sym))
        for t, step in enumerate(actions, start=1):
            world.step(transform_actions(step, sym))
            # Same run seen through the symmetry: drones where the original ones map to ...
            assert [tuple(p) for p in world.positions.tolist()] == [
                transform_cell(p, gmap.shape, sym) for p in positions[t]]
            # ... and the encoding of the transformed world is the transformed encoding.
            assert np.array_equal(encode_states(world, [0, 1]), transform_states(original[t], sym)), (sym, t)


def test_augment_labels_of_a_played_run_are_the_transformed_actions():
    gmap, zone, actions = commutation_setup()
    world = CoverageWorld(gmap, gmap.launch, zone)
    states = []
    for step in actions:
        states.append(encode_states(world, [0])[0])
        world.step(step)
    big_states, labels = augment(np.array(states), actions[:, 0])
    n = len(actions)
    for sym in range(NUM_SYMMETRIES):
        assert np.array_equal(labels[sym * n:(sym + 1) * n], transform_actions(actions[:, 0], sym))
        assert np.array_equal(big_states[sym * n:(sym + 1) * n], transform_states(np.array(states), sym))
