"""Trajectory corrector: hand cases, and on shipped plans coverage kept, obstacles avoided, fewer waypoints."""
import numpy as np
import pytest

from missionplan.maps.catalog import load_shipped
from missionplan.mission.corrector import chebyshev_to_segment, correct_path, path_length, total_turning
from missionplan.planning.pipeline import plan_map

R = 4


# --- independent checkers (dense sampling, no shared code with the corrector) ----------------

def dense_points(waypoints, step=0.05):
    pts = [waypoints[:1].astype(float)]
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        n = int(np.ceil(np.linalg.norm(b - a) / step)) + 1
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(a + t * (b - a))
    return np.concatenate(pts)


def polyline_coverage(waypoints, shape, step=0.05):
    """Cells whose centre is within R (Chebyshev, inclusive) of a densely sampled point."""
    covered = np.zeros(shape, dtype=bool)
    for p in dense_points(np.asarray(waypoints, dtype=float), step):
        r0, r1 = int(np.ceil(p[0] - R - 1e-9)), int(np.floor(p[0] + R + 1e-9))
        c0, c1 = int(np.ceil(p[1] - R - 1e-9)), int(np.floor(p[1] + R + 1e-9))
        covered[max(r0, 0):r1 + 1, max(c0, 0):c1 + 1] = True
    return covered


def grid_coverage(path, shape):
    covered = np.zeros(shape, dtype=bool)
    for r, c in np.asarray(path):
        covered[max(r - R, 0):r + R + 1, max(c - R, 0):c + R + 1] = True
    return covered


def crosses_obstacle(waypoints, obstacle, step=0.05):
    cells = np.round(dense_points(np.asarray(waypoints, dtype=float), step)).astype(int)
    return bool(obstacle[cells[:, 0], cells[:, 1]].any())


def stair(start, steps):
    r, c = start
    cells = [(r, c)]
    for _ in range(steps):
        c += 1
        cells.append((r, c))
        r += 1
        cells.append((r, c))
    return np.array(cells)


# --- hand cases ------------------------------------------------------------------------------

def test_chebyshev_distance_matches_brute_force():
    rng = np.random.default_rng(0)
    for _ in range(50):
        a, b = rng.integers(-5, 6, 2).astype(float), rng.integers(-5, 6, 2).astype(float)
        q = rng.uniform(-8, 8, (20, 2))
        t = np.linspace(0, 1, 20001)[:, None]
        seg = a + t * (b - a)
        brute = np.abs(seg[None, :, :] - q[:, None, :]).max(axis=2).min(axis=1)
        assert np.allclose(chebyshev_to_segment(q, a, b), brute, atol=1e-3)


def test_l_path_keeps_three_waypoints():
    obstacle = np.zeros((30, 30), dtype=bool)
    path = np.array([(5, c) for c in range(5, 16)] + [(r, 15) for r in range(6, 16)])
    out = correct_path(path, obstacle, ~obstacle)
    assert out.waypoints.tolist() == [[5, 5], [5, 15], [15, 15]]
    assert out.before == {"waypoints": 21, "length_cells": 20.0, "turning_deg": 90.0}
    assert out.after["waypoints"] == 3 and out.after["turning_deg"] == pytest.approx(90.0)


def test_straight_path_with_hovers_is_two_waypoints():
    obstacle = np.zeros((10, 10), dtype=bool)
    path = np.array([(3, 3), (3, 3), (3, 4), (3, 5), (3, 5), (3, 5), (3, 6)])
    out = correct_path(path, obstacle, ~obstacle)
    assert out.waypoints.tolist() == [[3, 3], [3, 6]]
    assert out.before["waypoints"] == 4 and out.before["length_cells"] == 3.0
    assert out.after["length_cells"] == 3.0 and out.after["turning_deg"] == 0.0


def test_stair_in_open_space_becomes_one_diagonal():
    obstacle = np.zeros((30, 30), dtype=bool)
    path = stair((10, 10), 6)
    out = correct_path(path, obstacle, np.zeros_like(obstacle))
    assert out.waypoints.tolist() == [[10, 10], [16, 16]]
    assert out.before["turning_deg"] == pytest.approx(90.0 * 11)
    assert out.after["length_cells"] == pytest.approx(6 * np.sqrt(2))
    assert out.after["turning_deg"] == 0.0


def test_stair_next_to_obstacle_corner_is_not_cut_through_it():
    obstacle = np.zeros((30, 30), dtype=bool)
    obstacle[13:, :13] = True  # corner cell (13, 12) lies half a cell from the diagonal
    path = stair((10, 10), 6)
    assert not obstacle[path[:, 0], path[:, 1]].any()
    out = correct_path(path, obstacle, np.zeros_like(obstacle))
    assert len(out.waypoints) > 2
    assert not crosses_obstacle(out.waypoints, obstacle)
    # the widened segments keep half a cell clear of the obstacle: no sample within 1 cell (box)
    pts = dense_points(out.waypoints)
    centres = np.argwhere(obstacle)
    gap = np.abs(pts[:, None, :] - centres[None, :, :]).max(axis=2).min()
    assert gap >= 1.0 - 1e-9
    # with no margin the corner only touches the diagonal's neighbour cells, so it may be cut
    loose = correct_path(path, obstacle, np.zeros_like(obstacle), margin_cells=0.0)
    assert len(loose.waypoints) < len(out.waypoints)


def test_straightening_that_loses_a_target_is_refused():
    obstacle = np.zeros((30, 30), dtype=bool)
    path = np.array([(5, c) for c in range(5, 16)] + [(r, 15) for r in range(6, 16)])
    targets = np.zeros_like(obstacle)
    assert len(correct_path(path, obstacle, targets).waypoints) == 2  # nothing to keep: cut the corner
    targets[1, 19] = True  # seen only from the corner cell (5, 15)
    out = correct_path(path, obstacle, targets)
    assert out.waypoints.tolist() == [[5, 5], [5, 15], [15, 15]]
    assert polyline_coverage(out.waypoints, obstacle.shape)[1, 19]


# --- shipped maps ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def leonardo():
    result = plan_map(load_shipped("leonardo"), 5)
    corrected = [correct_path(p, result.gmap.obstacle, result.world.reachable) for p in result.run.paths]
    return result, corrected


def test_leonardo_waypoints_at_least_five_times_fewer(leonardo):
    result, corrected = leonardo
    paths = result.run.paths
    after = sum(c.after["waypoints"] for c in corrected)
    assert after * 5 <= paths.shape[0] * paths.shape[1]
    for c in corrected:
        assert c.after["waypoints"] * 5 <= paths.shape[1]
        assert c.after["waypoints"] * 5 <= c.before["waypoints"]


def test_leonardo_coverage_kept_obstacles_avoided_and_no_worse(leonardo):
    result, corrected = leonardo
    obstacle, targets = result.gmap.obstacle, result.world.reachable
    for path, c in zip(result.run.paths, corrected):
        must = grid_coverage(path, obstacle.shape) & targets
        got = polyline_coverage(c.waypoints, obstacle.shape)
        assert not (must & ~got).any()
        assert not crosses_obstacle(c.waypoints, obstacle)
        assert c.after["length_cells"] <= c.before["length_cells"] + 1e-9
        assert c.after["turning_deg"] <= c.before["turning_deg"] + 1e-6
        assert c.after["length_cells"] == pytest.approx(path_length(c.waypoints))
        assert c.after["turning_deg"] == pytest.approx(total_turning(c.waypoints))
        assert c.waypoints[0].tolist() == path[0].tolist() and c.waypoints[-1].tolist() == path[-1].tolist()


def test_grid_city_six_drones_keeps_coverage():  # speed is measured by hand, not asserted
    result = plan_map(load_shipped("grid-city"), 6)
    obstacle, targets = result.gmap.obstacle, result.world.reachable
    corrected = [correct_path(p, obstacle, targets) for p in result.run.paths]
    for path, c in zip(result.run.paths, corrected):
        must = grid_coverage(path, obstacle.shape) & targets
        assert not (must & ~polyline_coverage(c.waypoints, obstacle.shape, step=0.1)).any()
        assert not crosses_obstacle(c.waypoints, obstacle)
