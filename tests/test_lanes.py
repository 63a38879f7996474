"""Open ground swept in lanes (missionplan/grid/lanes.py) and the planner flying those sweeps.

The blocks' photos are recounted here cell by cell; the planner's sweeps are checked for full
coverage with random fields and launch points (drones meeting, waiting and yielding), against the
snake they come from (never longer) and against exploring cell by cell (shorter on an open field,
and round a few tall buildings); legs go round obstacles, a blocked or unreachable photo centre is left
to exploration, a zone with much building in its box is explored; `plan --open-ground` chooses and
says so.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from missionplan.cli import main
from missionplan.grid.lanes import (BLOCK, MAX_OBSTACLE_SHARE, LaneSweep, block_centres, fleet_zones, l_leg,
                                    obstacle_shares, open_zones, snake_order, sweepable_zones, zone_is_open)
from missionplan.grid.pathfinding import FlightSearch
from missionplan.grid.world import FOOTPRINT_RADIUS, reachable_targets
from missionplan.grid.zones import split_zones
from missionplan.maps.gridmap import GridMap, save_map
from missionplan.maps.launches import spread_launches
from missionplan.planning.pipeline import make_policy, plan_map

UP, RIGHT, DOWN, LEFT = 0, 1, 2, 3


def field(rows: int, cols: int, launches: list[tuple[int, int]], obstacle: np.ndarray | None = None) -> GridMap:
    blocked = np.zeros((rows, cols), dtype=bool) if obstacle is None else obstacle
    return GridMap("field", blocked, ~blocked, launches, {})


def test_block_photos_cover_every_zone_cell_even_at_the_map_edge() -> None:
    rng = np.random.default_rng(1)
    shape = (40, 31)  # not a multiple of the block: the last blocks stick out of the map
    for _ in range(20):
        zone = rng.random(shape) < rng.uniform(0.05, 0.9)
        cells = np.argwhere(zone)
        centres, blocks = block_centres(cells, shape)
        seen = np.zeros(shape, dtype=bool)
        for r, c in centres:
            assert 0 <= r < shape[0] and 0 <= c < shape[1]
            seen[max(r - FOOTPRINT_RADIUS, 0): r + FOOTPRINT_RADIUS + 1, max(c - FOOTPRINT_RADIUS, 0): c + FOOTPRINT_RADIUS + 1] = True
        assert seen[zone].all()
        assert len(centres) == len({tuple(b) for b in blocks})  # one photo per block


def test_the_snake_is_the_shortest_of_its_eight_and_flies_lanes() -> None:
    cells = np.argwhere(np.ones((27, 45), dtype=bool))  # 3 block rows x 5 block columns
    centres, blocks = block_centres(cells, (27, 45))
    moves, order = snake_order((0, 0), centres, blocks)
    path = np.vstack([[0, 0], centres[order]])
    assert moves == int(np.abs(np.diff(path, axis=0)).sum())
    # From the corner: 4 + 4 to the first centre, then 14 blocks one footprint apart.
    assert moves == 8 + 14 * BLOCK
    assert len({tuple(c) for c in centres[order]}) == len(centres)


def test_legs_put_the_corner_where_it_turns_least() -> None:
    assert l_leg((0, 0), (0, 3), None, None) == [(0, 1), (0, 2), (0, 3)]
    # Flying right, next lane back to the left, 9 rows down and 3 columns right: go on right, then down.
    leg = l_leg((0, 0), (9, 3), RIGHT, LEFT)
    assert leg[:3] == [(0, 1), (0, 2), (0, 3)] and leg[-1] == (9, 3) and len(leg) == 12
    # Flying right, next lane to the left, 9 down and 3 columns left: down first, then left along the lane.
    leg = l_leg((0, 0), (9, -3), RIGHT, LEFT)
    assert leg[0] == (1, 0) and leg[-3:] == [(9, -1), (9, -2), (9, -3)]


def test_open_zone_needs_an_obstacle_free_box() -> None:
    obstacle = np.zeros((30, 30), dtype=bool)
    zone = np.argwhere(np.pad(np.ones((10, 10), dtype=bool), ((5, 15), (5, 15))))
    assert zone_is_open(obstacle, zone, (0, 0))
    obstacle[16, 16] = True  # inside the box (the zone ends at 14, photos reach 4 further)
    assert not zone_is_open(obstacle, zone, (0, 0))
    obstacle[:] = False
    obstacle[29, 29] = True
    assert zone_is_open(obstacle, zone, (0, 0))
    assert not zone_is_open(obstacle, zone[:0], (0, 0))  # no targets: nothing to sweep


def test_open_zones_agrees_with_zone_is_open_zone_by_zone() -> None:
    rng = np.random.default_rng(5)
    for _ in range(30):
        rows, cols = (int(v) for v in rng.integers(20, 80, 2))
        obstacle = rng.random((rows, cols)) < rng.choice([0.0, 0.0005, 0.002, 0.01])
        zone = rng.integers(-1, 4, (rows, cols))  # -1: no zone; drone 3 gets no zone sometimes
        zone[rng.random((rows, cols)) < 0.5] = -1
        if rng.random() < 0.5:
            zone[zone == 3] = -1
        starts = [(int(rng.integers(0, rows)), int(rng.integers(0, cols))) for _ in range(4)]
        expected = [zone_is_open(obstacle, np.argwhere(zone == k), start) for k, start in enumerate(starts)]
        assert open_zones(obstacle, zone, starts) == expected


def _longest_snake(zone: np.ndarray, starts: list[tuple[int, int]], origin: tuple[int, int] | None) -> int:
    longest = 0
    for k, start in enumerate(starts):
        cells = np.argwhere(zone == k)
        if len(cells):
            longest = max(longest, snake_order(start, *block_centres(cells, zone.shape, origin))[0])
    return longest


@pytest.mark.parametrize("seed", range(4))
def test_fleet_zones_give_whole_blocks_and_a_shorter_longest_snake(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(40, 100, 2))
    targets = rng.random((rows, cols)) < 0.8
    launches = [(int(r), int(c)) for r, c in zip(rng.integers(0, rows, 5), rng.integers(0, cols, 5))]
    free = np.ones((rows, cols), dtype=bool)
    zone = split_zones(targets, free, launches, balance=True).zone
    redrawn = fleet_zones(zone, targets, launches)
    assert (redrawn[targets] >= 0).all() and (redrawn[~targets] == zone[~targets]).all()
    for r in range(0, rows, BLOCK):  # every block belongs to one drone
        for c in range(0, cols, BLOCK):
            assert len(np.unique(redrawn[r:r + BLOCK, c:c + BLOCK][targets[r:r + BLOCK, c:c + BLOCK]])) <= 1
    before = _longest_snake(zone, launches, None)
    assert _longest_snake(redrawn, launches, (0, 0)) <= before


@pytest.mark.parametrize("seed", range(12))
def test_sweeps_cover_random_fields_with_drones_in_each_others_way(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(20, 70, 2))
    uavs = int(rng.integers(2, 9))
    if seed % 3 == 0:  # launch cells side by side: drones wait for and make way for each other
        launches = [(rows // 2, int(c)) for c in range(cols // 2 - uavs // 2, cols // 2 - uavs // 2 + uavs)]
    else:
        flat = rng.choice(rows * cols, size=uavs, replace=False)
        launches = [(int(i) // cols, int(i) % cols) for i in flat]
    result = plan_map(field(rows, cols, launches), uavs, policy="expert", lanes=True)
    run = result.run
    assert run.success and run.metrics["coverage"] == 100.0, run.failure
    assert run.lane_drones == uavs
    steps = np.abs(np.diff(run.paths, axis=1)).sum(axis=2)
    assert set(np.unique(steps)) <= {0, 1}  # one cell per step, or a hover


def test_a_lone_drone_flies_no_longer_than_its_snake() -> None:
    gmap = field(60, 45, [(3, 40)])
    run = plan_map(gmap, 1, policy="expert", lanes=True).run
    snake_moves, _ = snake_order((3, 40), *block_centres(np.argwhere(gmap.target), gmap.shape))
    assert run.success and run.metrics["makespan"] <= snake_moves


def test_lanes_beat_cell_by_cell_exploration_on_an_open_field() -> None:
    free = np.ones((128, 128), dtype=bool)
    gmap = field(128, 128, spread_launches(free, 6))
    policy = make_policy("expert")
    lanes = plan_map(gmap, 6, policy=policy, lanes=True).run
    explored = plan_map(gmap, 6, policy=policy, lanes=False).run
    assert lanes.success and explored.success and explored.lane_drones == 0
    # Measured: 337 against 499 moves (bench/sweep_bench.py's open 128 rows).
    assert lanes.metrics["makespan"] < 0.8 * explored.metrics["makespan"]
    assert lanes.metrics["MNT"] < explored.metrics["MNT"]  # fewer turns per move


def test_a_zone_with_much_building_in_its_box_is_explored() -> None:
    obstacle = np.zeros((60, 60), dtype=bool)
    obstacle[4:20, 4:20] = True  # one big tall building in the north-west
    gmap = field(60, 60, [(2, 30), (57, 2), (57, 57)], obstacle)
    reachable = reachable_targets(gmap, gmap.launch)
    zones = split_zones(reachable, gmap.free, gmap.launch, balance=True).zone
    expected = sum(sweepable_zones(obstacle, zones, gmap.launch))
    run = plan_map(gmap, 3, policy="expert", lanes=True).run
    assert 0 < expected < 3 and run.lane_drones == expected
    assert max(obstacle_shares(obstacle, zones, gmap.launch)) > MAX_OBSTACLE_SHARE  # the explored one
    assert run.success and run.metrics["coverage"] == 100.0


def test_a_few_obstacles_still_sweep_and_open_zones_are_the_obstacle_free_ones() -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        obstacle = rng.random((50, 50)) < rng.uniform(0.0, 0.12)
        starts = [(0, 0), (49, 49), (0, 49)]
        zone = np.full((50, 50), -1)
        zone[:, :20], zone[:, 20:] = 0, 1  # drone 2 has no zone: nothing to sweep
        shares = obstacle_shares(obstacle, zone, starts)
        assert shares[2] is None
        # Each box reaches FOOTPRINT_RADIUS past its zone (where a photo centre may stand); the
        # launch cells lie inside.
        assert shares[0] == pytest.approx(obstacle[:, :20 + FOOTPRINT_RADIUS].mean())
        assert shares[1] == pytest.approx(obstacle[:, 20:].mean())
        assert sweepable_zones(obstacle, zone, starts) == [s is not None and s <= MAX_OBSTACLE_SHARE for s in shares]
        assert open_zones(obstacle, zone, starts) == [s == 0.0 for s in shares]


def test_a_sweep_flies_round_obstacles_and_leaves_blocked_centres_to_exploration() -> None:
    shape = (27, 27)  # 3 x 3 blocks, centres at rows and columns 4, 13, 22
    obstacle = np.zeros(shape, dtype=bool)
    obstacle[13, 13] = True  # the middle block's centre: no photo from there
    obstacle[2:7, 8] = True  # a wall across the lane between the first two centres
    obstacle[20:25, 17:19] = True  # and another across the last lane
    free = ~obstacle
    search = FlightSearch(free)
    sweep = LaneSweep.plan(np.argwhere(free), (4, 0), shape, free=free)
    assert (13, 13) not in sweep.centres and len(sweep.centres) == 8
    wanted = list(sweep.centres)
    position, visited, unexplored = (4, 0), [], np.ones(shape, dtype=bool)
    for _ in range(400):
        cell = sweep.next_cell(position, unexplored, search)
        if cell is None:
            break
        assert free[cell] and abs(cell[0] - position[0]) + abs(cell[1] - position[1]) == 1
        position = cell
        if position in wanted:
            visited.append(position)
    assert sweep.finished and visited == wanted  # every flyable centre, in the snake's order


def test_a_centre_out_of_reach_is_dropped() -> None:
    shape = (9, 27)
    obstacle = np.zeros(shape, dtype=bool)
    obstacle[:, 17] = True  # the last block's centre (4, 22) lies behind a wall from side to side
    free = ~obstacle
    sweep = LaneSweep.plan(np.argwhere(free), (4, 0), shape, free=free)
    assert sweep.centres == [(4, 4), (4, 13), (4, 22)]
    position, unexplored = (4, 0), np.ones(shape, dtype=bool)
    for _ in range(100):
        cell = sweep.next_cell(position, unexplored, FlightSearch(free))
        if cell is None:
            break
        position = cell
    assert sweep.finished and position == (4, 13)


def test_lanes_round_a_few_tall_buildings_beat_exploring() -> None:
    rng = np.random.default_rng(7)
    obstacle = np.zeros((128, 128), dtype=bool)
    for _ in range(12):  # twelve 4 x 5 towers: 1.5 % of the field
        r, c = rng.integers(10, 118, size=2)
        obstacle[r:r + 4, c:c + 5] = True
    free = ~obstacle
    gmap = field(128, 128, spread_launches(free, 6), obstacle)
    policy = make_policy("expert")
    lanes = plan_map(gmap, 6, policy=policy, lanes=True).run
    explored = plan_map(gmap, 6, policy=policy, lanes=False).run
    assert lanes.success and lanes.metrics["coverage"] == 100.0 and lanes.lane_drones == 6
    # Measured: 408 against 485 moves.
    assert lanes.metrics["makespan"] < 0.9 * explored.metrics["makespan"]


def test_sweep_skips_blocks_photographed_already() -> None:
    cells = np.argwhere(np.ones((9, 27), dtype=bool))  # three blocks in a row
    sweep = LaneSweep.plan(cells, (4, 0), (9, 27))
    unexplored = np.ones((9, 27), dtype=bool)
    unexplored[:, 9:18] = False  # the middle block is done (another drone)
    assert sweep.next_cell((4, 0), unexplored) == (4, 1)
    assert sweep.centres == [(4, 4), (4, 13), (4, 22)]
    unexplored[:, :9] = False  # now the first too: on to the last, from where it is
    assert sweep.next_cell((4, 1), unexplored) == (4, 2)
    assert sweep.centres == [(4, 22)] and sweep.leg[-1] == (4, 22)
    unexplored[:] = False
    assert sweep.next_cell((4, 2), unexplored) is None and sweep.finished


def test_plan_open_ground_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "open.map"
    save_map(field(40, 40, [(0, 0), (39, 39), (0, 39)]), path)
    assert main(["plan", "--map", str(path), "--uavs", "3", "--out", str(tmp_path / "lanes"), "--quiet"]) == 0
    assert "open ground: 3 of 3 drones sweep their zone in footprint-wide lanes" in capsys.readouterr().out
    assert main(["plan", "--map", str(path), "--uavs", "3", "--open-ground", "explore",
                 "--out", str(tmp_path / "explore"), "--quiet"]) == 0
    assert "open ground" not in capsys.readouterr().out
    lanes = json.loads((tmp_path / "lanes" / "report.json").read_text())
    explore = json.loads((tmp_path / "explore" / "report.json").read_text())
    assert (lanes["lane_drones"], explore["lane_drones"]) == (3, 0)
    assert lanes["metrics"]["coverage"] == explore["metrics"]["coverage"] == 100.0
    assert lanes["metrics"]["makespan"] < explore["metrics"]["makespan"]
