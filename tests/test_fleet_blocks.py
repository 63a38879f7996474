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


def test_the_block_grid_is_placed_where_fewest_blocks_hold_a_target() -> None:
    """grid_origin against counting every placing; (0, 0) on a tie."""
    from missionplan.grid.fleet_blocks import grid_origin

    rng = np.random.default_rng(2)
    for _ in range(40):
        rows, cols = (int(v) for v in rng.integers(1, 50, 2))
        targets = rng.random((rows, cols)) < rng.random() * 0.3
        if not targets.any():
            continue
        cells = np.argwhere(targets)
        counts = {(dr, dc): len(np.unique((cells - (dr, dc)) // BLOCK, axis=0))
                  for dr in range(BLOCK) for dc in range(BLOCK)}
        fewest = min(counts.values())
        assert grid_origin(targets) == min(corner for corner, count in counts.items() if count == fewest)
    assert grid_origin(np.ones((27, 36), dtype=bool)) == (0, 0)


def street_strips(rows: int, cols: int, launches: list[tuple[int, int]]) -> GridMap:
    """Targets only on streets 3 cells wide every 9 rows, on rows 7-9, 16-18, ...: a grid on (0, 0) cuts every
    street in two rows of blocks."""
    target = np.zeros((rows, cols), dtype=bool)
    target[7::9] = target[8::9] = target[9::9] = True
    for r, c in launches:
        target[r, c] = True
    return GridMap(f"strips {rows}x{cols}", np.zeros_like(target), target, launches)


def test_tours_on_a_grid_placed_off_the_corner_cover_every_target_once_to_full_coverage() -> None:
    gmap = street_strips(58, 61, [(7, 0), (52, 60), (34, 30)])
    starts = list(gmap.launch)
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, balance=True)
    fleet = fleet_blocks(zones.zone, targets, starts, zones.centroids)
    assert 1 <= fleet.origin[0] <= 7  # any grid whose rows start on rows 1-7 holds each street in one
    corner = np.array(fleet.origin)
    wanted = {tuple(b) for b in np.unique((np.argwhere(targets) - corner) // BLOCK, axis=0).tolist()}
    toured = [tuple(((np.array(cell) - corner) // BLOCK).tolist()) for tour in fleet.tours for cell in tour]
    # The centres of blocks the map's edge cuts are moved onto the map; each still lies in its own block.
    assert sorted(toured) == sorted(wanted)
    for tour in fleet.tours:
        for r, c in tour:
            assert 0 <= r < gmap.shape[0] and 0 <= c < gmap.shape[1]
    result = plan_map(gmap, len(starts))
    assert result.zones.tours is not None and result.zones.tour_origin == fleet.origin
    assert result.run.success and result.run.metrics["coverage"] == 100.0
    fleet_longest = max(path_moves(np.array([s, *t])) for s, t in zip(starts, result.zones.tours))
    assert result.run.metrics["makespan"] <= fleet_longest + 2 * BLOCK


def test_the_split_balanced_on_tours_is_never_worse_than_the_one_balanced_on_counts(monkeypatch) -> None:
    """SPLIT_ROUNDS = 1 is the count-balanced split alone; more rounds keep the best split, so the longest tour
    before the local search is never longer, and on this field shorter."""
    import missionplan.grid.fleet_blocks as fb

    gmap = open_field(108, 126, [(4, 4), (100, 120), (50, 60), (4, 120), (100, 4)], holes=8, seed=1)
    starts = list(gmap.launch)
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, balance=True, seed=1)
    cells = np.argwhere(targets)
    blocks = np.unique(cells // BLOCK, axis=0)
    centres = centres_of(blocks, gmap.shape)
    longest = {}
    for rounds in (1, fb.SPLIT_ROUNDS):
        monkeypatch.setattr(fb, "SPLIT_ROUNDS", rounds)
        longest[rounds] = max(fb._balanced_tours(starts, centres, blocks, zones.centroids, 0).cost)
    assert longest[fb.SPLIT_ROUNDS] < longest[1]


def test_a_tour_s_blocks_are_read_on_its_own_grid() -> None:
    """LaneSweep.along skips a block once its targets are photographed: the block is the grid's, edge cuts included."""
    from missionplan.grid.lanes import LaneSweep

    sweep = LaneSweep.along([(11, 4), (0, 13), (57, 60)], (58, 61), origin=(7, 0))
    assert sweep.blocks == [(slice(7, 16), slice(0, 9)), (slice(0, 7), slice(9, 18)), (slice(52, 58), slice(54, 61))]
    assert LaneSweep.along([(4, 4), (57, 60)], (58, 61)).blocks == [(slice(0, 9), slice(0, 9)),
                                                                    (slice(54, 58), slice(54, 61))]


def test_a_chain_of_two_hand_overs_is_kept_only_when_all_three_tours_end_shorter(monkeypatch) -> None:
    """A fleet where the longest drone's neighbours are as busy as it is: a chain through one of them is kept, the
    tours stay consistent, and the longest tour ends no longer than without chains."""
    import missionplan.grid.fleet_blocks as fb

    gmap = open_field(108, 99, [(29, 30), (4, 7), (1, 17), (87, 64), (98, 49), (65, 96), (78, 62)], holes=5)
    starts = list(gmap.launch)
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, balance=True)
    kept = []
    chained = fb._chained_handover

    def watched(tours, longest, beside):
        top, owners = tours.cost[longest], tours.owner.copy()
        made = chained(tours, longest, beside)
        if made:
            changed = np.flatnonzero(tours.owner != owners)
            assert len(changed) == 2 and set(owners[changed]) >= {longest}
            assert max(tours.cost[int(d)] for d in {longest, *tours.owner[changed].tolist()}) < top
        else:
            assert np.array_equal(tours.owner, owners)  # an unkept chain is undone
        for k in range(len(starts)):
            assert set(tours.order[k].tolist()) == set(np.flatnonzero(tours.owner == k).tolist())
            assert tours.cost[k] == path_moves(tours.path(k))
        kept.append(made)
        return made

    monkeypatch.setattr(fb, "_chained_handover", watched)
    with_chains = fb.fleet_blocks(zones.zone, targets, starts, zones.centroids)
    assert any(kept)
    monkeypatch.setattr(fb, "CHAIN_TRIES", 0)
    without = fb.fleet_blocks(zones.zone, targets, starts, zones.centroids)
    assert max(with_chains.moves) < max(without.moves)


def test_the_plan_record_names_the_tours_solver_grid_moves_and_time(tmp_path, capsys) -> None:
    """report.json `tours`: written when the fleet flies block tours, read back as written; a plan exploring has none."""
    from missionplan.cli.app import main
    from missionplan.mission.plan_record import read_plan_record
    from missionplan.mission.plan_tours import SOLVER

    assert main(["plan", "--map", "tests/golden/open-field.map", "--uavs", "3", "--out", str(tmp_path / "t")]) == 0
    printed = [line.strip() for line in capsys.readouterr().out.splitlines() if "block tours:" in line]
    record = read_plan_record(tmp_path / "t")
    tours = record.tours
    assert tours is not None and tours.solver == SOLVER and tours.cpu_s > 0
    assert tours.blocks == len(np.unique(np.argwhere(np.array([list(row) for row in record.grid]) != "#")
                                         // BLOCK, axis=0))  # the field's grid from (0, 0) has the fewest
    assert tours.grid_origin == (0, 0) and len(tours.moves) == 3
    assert max(tours.moves) >= record.metrics.makespan  # a drone ends once its last block is photographed
    assert printed == [tours.summary()]
    assert main(["plan", "--map", "tests/golden/open-field.map", "--uavs", "3", "--out", str(tmp_path / "e"),
                 "--open-ground", "explore", "--quiet"]) == 0
    assert read_plan_record(tmp_path / "e").tours is None
