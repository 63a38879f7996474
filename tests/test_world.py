import numpy as np
import pytest

from missionplan.maps.gridmap import GridMap, MapError
from missionplan.grid.world import DOWN, HOVER, LEFT, PAD, RIGHT, UP, CoverageWorld, reachable_targets


def open_map(rows=20, cols=30, launch=((10, 10), (10, 11))):
    obstacle = np.zeros((rows, cols), dtype=bool)
    return GridMap("open", obstacle, ~obstacle, list(launch))


def two_zones(gmap, split_col):
    zone = np.where(np.arange(gmap.shape[1])[None, :] < split_col, 0, 1) * np.ones(gmap.shape, dtype=int)
    return zone


def test_start_footprint_is_explored():
    gmap = open_map(launch=((10, 10),))
    world = CoverageWorld(gmap, gmap.launch)
    assert world.num_targets == 600
    assert world.remaining == 600 - 81
    assert not world.unexplored[6:15, 6:15].any()
    assert world.unexplored[5, 10] and world.unexplored[10, 15]


def test_footprint_clipped_at_map_edge_and_new_cells_counted():
    gmap = open_map(launch=((0, 0),))
    world = CoverageWorld(gmap, gmap.launch)
    assert world.remaining == 600 - 25
    outcome = world.step([RIGHT])
    assert outcome.moved.tolist() == [True]
    assert outcome.new_cells.tolist() == [5]  # column 5, rows 0..4


def test_unreachable_targets_are_set_explored_and_reported():
    obstacle = np.zeros((12, 12), dtype=bool)
    obstacle[3:8, 3:8] = True
    obstacle[5, 5] = False  # a courtyard nobody can enter
    gmap = GridMap("pocket", obstacle, ~obstacle, [(0, 0)])
    world = CoverageWorld(gmap, gmap.launch)
    assert world.unreachable_cells.tolist() == [[5, 5]]
    assert not world.unexplored[5, 5]
    assert world.num_targets == int((~obstacle).sum()) - 1
    assert reachable_targets(gmap, gmap.launch)[5, 5] == np.False_


def test_blocked_move_hovers_and_drones_never_share_a_cell():
    gmap = open_map()
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 15))
    outcome = world.step([RIGHT, HOVER])  # drone 1 runs into drone 2
    assert outcome.moved.tolist() == [False, False]
    assert outcome.blocked.tolist() == [True, False]
    assert world.positions.tolist() == [[10, 10], [10, 11]]


def test_swap_is_refused_but_following_is_allowed():
    gmap = open_map()
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 15))
    outcome = world.step([RIGHT, LEFT])  # a swap
    assert outcome.moved.tolist() == [False, False]
    outcome = world.step([RIGHT, RIGHT])  # drone 1 follows drone 2 into its old cell
    assert outcome.moved.tolist() == [True, True]
    assert world.positions.tolist() == [[10, 11], [10, 12]]


def test_two_drones_asking_for_one_cell_lower_index_wins():
    gmap = open_map(launch=((10, 10), (10, 12)))
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 15))
    outcome = world.step([RIGHT, LEFT])
    assert outcome.moved.tolist() == [True, False]


def test_obstacles_and_edges_block():
    obstacle = np.zeros((5, 5), dtype=bool)
    obstacle[1, 2] = True
    gmap = GridMap("tiny", obstacle, ~obstacle, [(0, 2)])
    world = CoverageWorld(gmap, gmap.launch)
    assert world.step([UP]).blocked.tolist() == [True]
    assert world.step([DOWN]).blocked.tolist() == [True]
    assert world.positions.tolist() == [[0, 2]]


def test_zone_sight_until_zone_done():
    gmap = open_map(rows=9, cols=40, launch=((4, 16), (4, 35)))
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 20))
    view = world.view_unexplored(0)  # map columns 7..25 -> view columns 0..18
    assert view[:, :5].any()  # columns 7..11: drone 1's own zone, still unexplored
    assert not view[:, 13:].any()  # columns 20..25 belong to drone 2's zone: not seen
    world.zone_remaining[0] = 0  # drone 1's zone done: it now sees every zone
    assert world.view_unexplored(0)[:, 14:].any()


def test_every_form_of_what_a_drone_sees_agrees():
    gmap = open_map(rows=9, cols=40, launch=((4, 16), (4, 35)))
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 20))
    world.step([RIGHT, LEFT])
    cells = np.argwhere(np.ones(gmap.shape, dtype=bool))
    flat = (cells[:, 0] + PAD) * (gmap.shape[1] + 2 * PAD) + cells[:, 1] + PAD  # FlightSearch(pad=PAD) numbers
    def mask(k):  # what drone k sees as unexplored, by the rule: its zone's unexplored cells, all once done
        return world.unexplored & ((world.zone_of == k) | bool(world.zone_done(k)))

    for zone_done in (False, True):
        if zone_done:
            world.zone_remaining[0] = 0
        for k in range(2):
            lookup = world.seen_lookup(k)
            as_array = np.asarray(lookup.flags)[lookup.values[flat]]  # read a box at a time, as find_goal does
            one_by_one = [bool(lookup.flags[lookup.values[int(i)]]) for i in flat]  # as Explorative A* does
            assert mask(k).any() and not mask(k).all()
            assert np.array_equal(mask(k)[tuple(cells.T)], as_array)
            assert one_by_one == mask(k)[tuple(cells.T)].tolist()
    lookup = world.seen_lookup(0)
    seen_by_1 = np.asarray(lookup.flags)[lookup.values[flat]]
    assert seen_by_1.reshape(gmap.shape)[:, 25:].any()  # done with its zone: drone 1 sees drone 2's


def test_flown_views_mark_where_each_drone_flew_and_nothing_off_the_map():
    gmap = open_map(rows=9, cols=40, launch=((0, 0), (4, 35)))
    world = CoverageWorld(gmap, gmap.launch, two_zones(gmap, 20))
    world.step([RIGHT, LEFT])
    world.step([DOWN, HOVER])
    flown = world.flown_views(np.array([0, 1]))
    centre = flown.shape[1] // 2
    assert flown[0, centre, centre] and flown[0, centre - 1, centre] and flown[0, centre - 1, centre - 1]
    assert flown[0].sum() == 3  # (0, 0), (0, 1), (1, 1); off the map reads as never flown
    assert flown[1].sum() == 2 and flown[1, centre, centre] and flown[1, centre, centre + 1]


def test_step_cap_is_a_failure_not_success():
    gmap = open_map(launch=((10, 10),))
    world = CoverageWorld(gmap, gmap.launch, step_cap=3)
    for _ in range(2):
        assert not world.step([HOVER]).truncated
    outcome = world.step([HOVER])
    assert outcome.truncated and not outcome.done


def test_bad_launch_cells():
    obstacle = np.zeros((5, 5), dtype=bool)
    obstacle[0, 0] = True
    gmap = GridMap("tiny", obstacle, ~obstacle, [])
    with pytest.raises(MapError, match="inside an obstacle"):
        CoverageWorld(gmap, [(0, 0)])
    with pytest.raises(MapError, match="outside"):
        CoverageWorld(gmap, [(9, 0)])
    with pytest.raises(MapError, match="share"):
        CoverageWorld(gmap, [(1, 1), (1, 1)], np.zeros((5, 5), dtype=int))
