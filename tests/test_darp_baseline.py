"""The DARP + STC comparison peer (bench/darp.py) on small grids: DARP's division meets its stopping rule
(regions of the fair size within the threshold, each connected and holding its robot's cell), the
threshold is raised when the iterations run out, each STC tour visits every block of its region once in
a closed ring, and the flown paths photograph every target (the self-check raises when one is missed)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

import darp
from darp import BLOCK, MEGA, check_coverage, darp_plan, stc_tour

OPEN_GRIDS = [  # (rows, cols, launches): 18 x 18 DARP cells, 9 x 9 blocks
    (72, 72, [(0, 0), (0, 71), (71, 0), (71, 71)]),          # 16 cells, 4 drones: 4 each, threshold 0
    (90, 72, [(3, 3), (45, 40), (89, 71)]),                   # 20 cells, 3 drones: threshold 1
    (90, 90, [(10, 80), (20, 20), (60, 30), (80, 85), (45, 45)]),  # 25 cells, 5 drones
    (100, 130, [(5, 5), (95, 125), (50, 64), (10, 120)]),     # edges cut through blocks and cells
]


def _adjacent(a: tuple[int, int], b: tuple[int, int]) -> bool:
    return abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1


@pytest.mark.parametrize("rows, cols, launches", OPEN_GRIDS)
def test_open_grid_regions_are_fair_connected_and_hold_their_robot(rows: int, cols: int,
                                                                   launches: list[tuple[int, int]]) -> None:
    target = np.ones((rows, cols), dtype=bool)
    result = darp_plan(target, np.zeros_like(target), launches, seed=3)
    division = result.division
    area = division.owner >= 0
    assert area.sum() == (-(-rows // MEGA)) * (-(-cols // MEGA))  # open ground: every cell is in the area
    fair = area.sum() / len(launches)
    assert division.fair_share == fair
    assert result.converged and division.threshold == (0 if area.sum() % len(launches) == 0 else 1)
    sizes = np.bincount(division.owner[area], minlength=len(launches))
    assert (np.abs(sizes - fair) <= division.threshold).all()
    for i, (robot, launch) in enumerate(zip(result.robot_cells, launches)):
        region = division.owner == i
        assert robot == (launch[0] // MEGA, launch[1] // MEGA) and region[robot]
        assert ndimage.label(region)[1] == 1  # 4-connected


@pytest.mark.parametrize("rows, cols, launches", OPEN_GRIDS)
def test_stc_tour_is_a_closed_ring_over_every_block_of_the_region_once(rows: int, cols: int,
                                                                       launches: list[tuple[int, int]]) -> None:
    target = np.ones((rows, cols), dtype=bool)
    result = darp_plan(target, np.zeros_like(target), launches, seed=1)
    for i, (tour, launch) in enumerate(zip(result.tours, launches)):
        region = np.argwhere(result.division.owner == i)
        blocks = {(2 * r + a, 2 * c + b) for r, c in region for a in (0, 1) for b in (0, 1)}
        assert len(tour) == len(set(tour)) == len(blocks) and set(tour) == blocks
        assert tour[0] == (launch[0] // BLOCK, launch[1] // BLOCK)
        assert all(_adjacent(a, b) for a, b in zip(tour, tour[1:] + tour[:1]))  # closes back to its start
        path = result.paths[i]
        assert path[0] == launch and result.moves[i] == len(path) - 1
        assert all(_adjacent(a, b) for a, b in zip(path, path[1:]))
    assert result.makespan == max(result.moves) and result.total_moves == sum(result.moves)


def test_stc_goes_round_a_hole() -> None:
    region = np.ones((4, 4), dtype=bool)
    region[1:3, 1:3] = False  # a ring of 12 cells
    tour = stc_tour(region, darp.spanning_tree(region, 1), (0, 0))
    assert len(tour) == len(set(tour)) == 48
    assert all(_adjacent(a, b) for a, b in zip(tour, tour[1:] + tour[:1]))


def test_scattered_targets_are_all_photographed_and_recounted() -> None:
    rng = np.random.default_rng(7)
    target = rng.random((120, 150)) < 0.02  # a few scattered targets: most blocks hold none
    target[60:64, :] = True  # and a street
    launches = [(0, 0), (119, 149), (60, 75)]
    result = darp_plan(target, np.zeros_like(target), launches, seed=0)
    assert result.coverage == 100.0
    seen = np.zeros_like(target)
    for path in result.paths:
        for r, c in path:
            seen[max(r - 4, 0): r + 5, max(c - 4, 0): c + 5] = True
    assert not (target & ~seen).any()
    # a cell of the area is a DARP cell holding a target, or a robot's own
    holds = darp._pooled_any(darp._pooled_any(target, BLOCK), 2)
    robot_cell = np.zeros_like(holds)
    robot_cell[tuple(np.array(result.robot_cells).T)] = True
    assert ((result.division.owner >= 0) == (holds | robot_cell)).all()


def test_a_missed_target_raises() -> None:
    target = np.zeros((30, 30), dtype=bool)
    target[25, 25] = True
    path = [(0, 0), (1, 0), (2, 0)]
    with pytest.raises(AssertionError, match="1 of 1 targets"):
        check_coverage([path], target, np.zeros_like(target))
    with pytest.raises(AssertionError, match="jumps"):
        check_coverage([[(0, 0), (2, 0)]], target, np.zeros_like(target))
    assert check_coverage([[(21, 21), (22, 21)]], target, np.zeros_like(target)) == 100.0


def test_two_launches_in_one_cell_and_targets_in_two_pieces() -> None:
    target = np.zeros((108, 126), dtype=bool)
    target[:54, :54] = True    # two fields of streets ...
    target[72:, 90:] = True    # ... with untargeted ground between them
    launches = [(2, 2), (5, 10), (100, 120)]  # the first two share an 18 x 18 cell
    # (a narrow bridge: DARP's Euclidean distances need the fall-back there, so few iterations per threshold)
    result = darp_plan(target, np.zeros_like(target), launches, seed=0, max_iterations=500)
    assert result.robot_cells == [(0, 0), (0, 1), (5, 6)]  # the second robot moved to the nearest free cell
    assert result.coverage == 100.0
    area = result.division.owner >= 0
    assert ndimage.label(area)[1] == 1  # joined by the cells between the pieces
    for i in range(3):
        assert ndimage.label(result.division.owner == i)[1] == 1


def test_the_fall_back_raises_the_threshold_when_the_iterations_run_out() -> None:
    target = np.ones((72, 90), dtype=bool)  # 20 cells, 3 drones: threshold 1, not met by the first assignment
    launches = [(0, 0), (41, 41), (59, 77)]
    result = darp_plan(target, np.zeros_like(target), launches, seed=0, max_iterations=0, max_threshold=1)
    division = result.division
    assert division.iterations == 0 and division.threshold > 1 and not result.converged
    sizes = np.bincount(division.owner[division.owner >= 0])
    assert (np.abs(sizes - 20 / 3) <= division.threshold).all() and result.coverage == 100.0
    patient = darp_plan(target, np.zeros_like(target), launches, seed=0)
    assert patient.converged and patient.division.threshold == 1 and patient.iterations > 0
