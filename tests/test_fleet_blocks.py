"""A whole fleet on open ground: block tours (grid/block_tours.py) and the fleet's blocks shared out and balanced on
the longest tour (grid/fleet_blocks.py), flown by the planner."""

from __future__ import annotations

import numpy as np
import pytest

from missionplan.grid.block_tours import block_tour, insertion_cost, path_moves, polish, removal_gain
from missionplan.grid.fleet_blocks import fleet_blocks
from missionplan.grid.lanes import BLOCK, block_centres, fleet_zones, snake_order
from missionplan.grid.world import FOOTPRINT_RADIUS, reachable_targets
from missionplan.grid.zones import split_zones
from missionplan.maps.gridmap import GridMap
from missionplan.planning.pipeline import plan_map


def centres_of(blocks: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    return np.minimum(blocks * BLOCK + FOOTPRINT_RADIUS, np.array(shape) - 1)


def open_field(rows: int, cols: int, launches: list[tuple[int, int]], holes: int = 0, seed: int = 0) -> GridMap:
    """A field, every cell a target; with `holes`, that many random 9 x 9 patches with nothing to photograph."""
    target = np.ones((rows, cols), dtype=bool)
    rng = np.random.default_rng(seed)
    for _ in range(holes):
        r, c = rng.integers(0, rows // BLOCK), rng.integers(0, cols // BLOCK)
        target[r * BLOCK:(r + 1) * BLOCK, c * BLOCK:(c + 1) * BLOCK] = False
    for r, c in launches:
        target[r, c] = True
    return GridMap(f"field {rows}x{cols}", np.zeros_like(target), target, launches)


def test_a_rectangle_s_tour_is_as_short_as_any() -> None:
    """6 x 8 blocks from a corner: every leg one block (9 moves), the least any tour can fly."""
    blocks = np.argwhere(np.ones((6, 8), dtype=bool))
    centres = centres_of(blocks, (54, 72))
    moves, order = block_tour((4, 4), centres, blocks)
    assert moves == 9 * (len(blocks) - 1)
    assert sorted(order.tolist()) == list(range(len(blocks)))


@pytest.mark.parametrize("seed", range(4))
def test_an_irregular_zone_s_tour_is_never_longer_than_its_best_snake(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mask = rng.random((12, 12)) < 0.7
    blocks = np.argwhere(mask)
    centres = centres_of(blocks, (108, 108))
    start = (int(centres[0, 0]), int(centres[0, 1]) + 2)
    moves, order = block_tour(start, centres, blocks, seed=seed)
    snake, _ = snake_order(start, centres, blocks)
    assert moves <= snake
    assert sorted(order.tolist()) == list(range(len(blocks)))  # every block once
    assert moves == path_moves(np.vstack([np.array(start)[None, :], centres[order]]))
    assert block_tour(start, centres, blocks, seed=seed)[1].tolist() == order.tolist()  # deterministic


def test_polish_never_lengthens_and_keeps_the_launch_first() -> None:
    rng = np.random.default_rng(5)
    path = rng.integers(0, 100, size=(40, 2))
    polished = polish(path)
    assert path_moves(polished) <= path_moves(path)
    assert polished[0].tolist() == path[0].tolist()
    assert sorted(map(tuple, polished.tolist())) == sorted(map(tuple, path.tolist()))


def test_the_prices_of_a_hand_over() -> None:
    path = np.array([[0, 0], [0, 9], [0, 18], [0, 27]])
    assert removal_gain(path, 3) == 9  # the last: its leg saved
    assert removal_gain(path, 1) == 0  # between two on a line: the path passes it anyway
    assert insertion_cost(path, np.array([0, 36])) == (9, 3)  # after the last
    cost, where = insertion_cost(path, np.array([9, 9]))
    assert (cost, where) == (18, 1) or (cost, where) == (18, 0)


@pytest.mark.parametrize("seed", range(3))
def test_every_block_is_one_drone_s_and_on_its_tour(seed: int) -> None:
    gmap = open_field(90, 117, [(0, 0), (89, 116), (45, 60), (0, 116)], holes=6, seed=seed)
    starts = list(gmap.launch)
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, balance=True, seed=seed)
    fleet = fleet_blocks(zones.zone, targets, starts, zones.centroids, seed)
    blocks_with_targets = {tuple(b) for b in np.unique(np.argwhere(targets) // BLOCK, axis=0).tolist()}
    toured = [(r // BLOCK, c // BLOCK) for tour in fleet.tours for r, c in tour]
    assert sorted(toured) == sorted(blocks_with_targets)  # each block once, in one drone's tour
    for k, tour in enumerate(fleet.tours):
        owned = fleet.zone[targets] == k
        assert {(r // BLOCK, c // BLOCK) for r, c in tour} == \
               {tuple(b) for b in (np.argwhere(targets)[owned] // BLOCK).tolist()}
        assert fleet.moves[k] == path_moves(np.array([starts[k], *tour]))


@pytest.mark.parametrize("seed", range(3))
def test_the_longest_tour_is_no_longer_than_the_longest_snake_of_the_snake_zones(seed: int) -> None:
    """Against lanes.fleet_zones (blocks balanced on the longest snake, flown as snakes)."""
    gmap = open_field(108, 126, [(4, 4), (100, 120), (50, 60), (4, 120), (100, 4)], holes=8, seed=seed)
    starts = list(gmap.launch)
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, balance=True, seed=seed)
    fleet = fleet_blocks(zones.zone, targets, starts, zones.centroids, seed)
    snakes = fleet_zones(zones.zone, targets, starts)
    longest_snake = max(snake_order(s, *block_centres(np.argwhere(snakes == k), gmap.shape, (0, 0)))[0]
                        for k, s in enumerate(starts) if (snakes == k).any())
    assert max(fleet.moves) <= longest_snake


def test_the_planner_flies_the_tours_to_full_coverage() -> None:
    gmap = open_field(72, 99, [(0, 0), (71, 98), (36, 50)], holes=3)
    result = plan_map(gmap, 3)
    assert result.zones.tours is not None and result.run.lane_drones == 3
    assert result.run.success and result.run.metrics["coverage"] == 100.0
    fleet_longest = max(path_moves(np.array([s, *t])) for s, t in zip(result.starts, result.zones.tours))
    # A drone skips a block another has photographed already, and may wait for a drone in its way.
    assert result.run.metrics["makespan"] <= fleet_longest + 2 * BLOCK


def test_the_planner_keeps_the_snakes_where_they_are_shorter() -> None:
    """The split flown is never longer than either: block tours, or fleet_zones' zones in snakes."""
    from missionplan.grid.lanes import longest_snake

    for launches in ([(0, 0), (0, 98), (71, 0), (71, 98)], [(0, 0), (71, 98), (36, 50)]):
        gmap = open_field(72, 99, launches)
        starts = list(gmap.launch)
        targets = reachable_targets(gmap, starts)
        zones = split_zones(targets, gmap.free, starts, balance=True)
        tours = max(fleet_blocks(zones.zone, targets, starts, zones.centroids).moves)
        snakes = longest_snake(fleet_zones(zones.zone, targets, starts), starts)
        result = plan_map(gmap, len(starts))
        flown = (max(path_moves(np.array([s, *t])) for s, t in zip(starts, result.zones.tours))
                 if result.zones.tours is not None else longest_snake(result.zones.zone, starts))
        assert flown == min(tours, snakes)
        assert result.run.metrics["makespan"] <= flown + 2 * BLOCK and result.run.metrics["coverage"] == 100.0


def test_lanes_closer_than_a_footprint_are_flown_in_snakes() -> None:
    gmap = open_field(72, 99, [(0, 0), (71, 98), (36, 50)])
    result = plan_map(gmap, 3, lane_spacing=5)
    assert result.zones.tours is None and result.run.success


def test_plan_s_default_flies_the_tours_and_snakes_are_asked_for() -> None:
    """`plan` flies a whole open-ground fleet in block tours; fleet_tours=False (the benches' `ls` rows) in snakes."""
    gmap = open_field(72, 99, [(0, 0), (71, 98), (36, 50)], holes=3)
    toured, snaked = plan_map(gmap, 3), plan_map(gmap, 3, fleet_tours=False)
    assert toured.zones.tours is not None and toured.run.lane_drones == 3 and toured.run.success
    assert snaked.zones.tours is None and snaked.run.lane_drones == 3 and snaked.run.success
