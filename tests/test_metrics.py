"""Each metric against a small run computed by hand."""

import numpy as np
import pytest

from missionplan.grid import metrics
from missionplan.grid.metrics import (SteadyStateSampler, compute_metrics, mdu_stride, mean_distance_to_nearest,
                                 mean_pairwise_distance, move_count, turn_sum)


def test_moves_skip_hovers():
    path = np.array([[0, 0], [0, 1], [0, 1], [1, 1], [1, 1]])
    assert move_count(path) == 2


def test_turns_weighted_half_for_90_and_one_for_180():
    # right, right, down (90), left (90), right (180), hover, right (straight)
    path = np.array([[0, 0], [0, 1], [0, 2], [1, 2], [1, 1], [1, 2], [1, 2], [1, 3]])
    assert turn_sum(path) == pytest.approx(0.5 + 0.5 + 1.0)


def test_pairwise_and_nearest_distances():
    assert mean_pairwise_distance(np.array([[0, 0], [3, 4], [0, 4]])) == pytest.approx((5 + 4 + 3) / 3)
    cells = np.zeros((6, 11), dtype=bool)
    cells[0, 0] = cells[0, 10] = cells[5, 5] = True
    drones = np.array([[0, 1], [0, 7]])
    assert mean_distance_to_nearest(cells, drones) == pytest.approx((1 + 3 + np.hypot(5, 2)) / 3)
    # A drone outside the cells' grid still counts; no cell gives 0.
    assert mean_distance_to_nearest(cells[:1, :1], np.array([[3, -4]])) == pytest.approx(5.0)
    assert mean_distance_to_nearest(np.zeros((2, 2), dtype=bool), drones) == 0.0


@pytest.mark.parametrize("direct", [True, False])
def test_nearest_distance_the_same_float_either_way(monkeypatch: pytest.MonkeyPatch, direct: bool) -> None:
    """MDU* takes the direct way (cells x drones) or the distance transform by cost: both give the
    very same float, so a plan's reported MDU* does not depend on which one ran."""
    rng = np.random.default_rng(7)
    monkeypatch.setattr(metrics, "DIRECT_PAIRS_PER_BOX_CELL", 10**9 if direct else 0)  # one way, whatever the sizes
    for share in (0.02, 0.3, 0.9):
        for drones in (1, 6, 50):
            unexplored, positions = rng.random((40, 57)) < share, rng.integers(-5, 60, (drones, 2))
            cells = np.argwhere(unexplored)
            squared = ((cells[:, None, :] - positions[None, :, :]) ** 2).sum(axis=2).min(axis=1)
            assert mean_distance_to_nearest(unexplored, positions) == float(np.sqrt(squared.astype(np.float64)).mean())


def test_mdu_on_every_stride_th_steady_step():
    sampler = SteadyStateSampler(stride=3)
    unexplored = np.ones((4, 4), dtype=bool)
    for step in range(7):
        sampler.observe(0.5, np.array([[0, 0], [step % 4, 3]]), unexplored)
    assert len(sampler.mud) == 7 and len(sampler.mdu) == 3  # window steps 0, 3, 6
    assert mdu_stride(15_714) == 1 and mdu_stride(20_001) == 2 and mdu_stride(400_000) == 40


def test_run_metrics_by_hand():
    # Two drones, three steps. Drone 1: R, R, D  (one 90 deg turn). Drone 2: R, hover, L (one reversal).
    paths = np.array([
        [[0, 0], [0, 1], [0, 2], [1, 2]],
        [[5, 0], [5, 1], [5, 1], [5, 0]],
    ])
    new_cells = np.array([[9, 9, 9], [9, 0, 0]])
    sampler = SteadyStateSampler()
    metrics = compute_metrics(paths, new_cells, sampler, coverage=1.0, hover_steps=1)
    # M = (3, 2): MMN = 2.5. TE = (36 / 9) / (2 * 2.5) = 80 %. MNT = (0.5 + 1) / 5 = 30 %.
    assert metrics["MMN"] == pytest.approx(2.5)
    assert metrics["TE"] == pytest.approx(80.0)
    assert metrics["MNT"] == pytest.approx(30.0)
    assert metrics["makespan"] == 3
    assert metrics["hover_steps"] == 1
    assert metrics["coverage"] == pytest.approx(100.0)
    assert metrics["MUD"] is None and metrics["MDU"] is None


def test_steady_state_window_is_40_to_70_percent():
    sampler = SteadyStateSampler()
    drones = np.array([[0, 0], [0, 4]])
    unexplored = np.zeros((3, 5), dtype=bool)
    unexplored[2, 0] = True  # distance 2 to drone 1
    sampler.observe(0.39, drones, unexplored)  # outside: ignored
    sampler.observe(0.40, drones, unexplored)
    unexplored[2, 0], unexplored[0, 2] = False, True  # distance 2 to either drone
    sampler.observe(0.70, drones + [[0, 0], [0, 2]], unexplored)  # drones (0,0) and (0,6): MUD 6, MDU 2
    sampler.observe(0.71, drones, unexplored)  # outside: ignored
    metrics = compute_metrics(np.zeros((2, 1, 2), int), np.zeros((2, 0), int), sampler, 0.71, 0)
    assert metrics["MUD"] == pytest.approx((4 + 6) / 2)
    assert metrics["MDU"] == pytest.approx((2 + 2) / 2)
