import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse.csgraph import shortest_path

from missionplan.grid import zones
from missionplan.grid.zones import balanced_by_passes, grid_graph, nearest_seed, split_zones


def two_banks(rows=40, cols=60):
    """Two banks split by a horizontal river, joined by one bridge at the far right."""
    free = np.ones((rows, cols), dtype=bool)
    free[18:22, :] = False
    free[18:22, cols - 4:] = True  # the only bridge
    return free


def test_every_target_gets_exactly_one_zone_and_is_seeded():
    free = np.ones((30, 40), dtype=bool)
    starts = [(0, 0), (29, 39), (0, 39)]
    a = split_zones(free, free, starts, "euclidean", seed=7)
    b = split_zones(free, free, starts, "euclidean", seed=7)
    assert np.array_equal(a.zone, b.zone)
    assert set(np.unique(a.zone)) == {0, 1, 2}
    assert (a.zone >= 0).sum() == free.sum()
    assert a.iterations >= 2


def test_non_targets_get_no_zone():
    free = np.ones((10, 10), dtype=bool)
    targets = free.copy()
    targets[:, :3] = False
    z = split_zones(targets, free, [(5, 5), (5, 9)], "geodesic")
    assert (z.zone[:, :3] == -1).all()
    assert (z.zone[:, 3:] >= 0).all()


def test_geodesic_zones_do_not_straddle_the_river():
    free = two_banks()
    starts = [(2, 5), (37, 5)]  # one drone per bank, both far from the bridge
    geo = split_zones(free, free, starts, "geodesic", seed=1)
    north, south = geo.zone[:18], geo.zone[22:]
    # Along free cells the far bank is 40+ moves away: each bank is one zone (bar the bridge end).
    assert (north[:, :40] == 0).all() and (south[:, :40] == 1).all()


def test_lloyd_moves_centroids_away_from_a_shared_corner():
    free = np.ones((40, 40), dtype=bool)
    z = split_zones(free, free, [(0, 0), (0, 1)], "euclidean", seed=0)
    sizes = np.bincount(z.zone.ravel())
    assert sizes.min() > 0.35 * free.sum()  # close to an even split, not one sliver


def test_unknown_method():
    free = np.ones((4, 4), dtype=bool)
    with pytest.raises(ValueError, match="unknown zone method"):
        split_zones(free, free, [(0, 0), (3, 3)], "manhattan")


def test_nearest_seed_is_argmin_of_per_seed_distances_with_lowest_index_ties():
    """One multi-source search gives what K single-source searches and an argmin gave."""
    rng = np.random.default_rng(5)
    for trial in range(10):
        free = rng.random((25, 33)) > 0.25
        cells = np.argwhere(free)
        seeds = cells[rng.choice(len(cells), size=5)]
        seeds[4] = seeds[1]  # a shared cell: the lower index keeps it
        levels = rng.integers(0, 6, size=5) if trial % 2 else np.zeros(5, dtype=np.int64)
        label, dist = nearest_seed(free, seeds, levels)
        field = shortest_path(grid_graph(free), unweighted=True, indices=seeds[:, 0] * 33 + seeds[:, 1])
        weighted = field + levels[:, None]
        best = weighted.min(axis=0).reshape(free.shape)
        expected = np.where(np.isfinite(best), np.argmin(weighted, axis=0).reshape(free.shape), -1)
        assert np.array_equal(label, expected)
        assert np.array_equal(dist, np.where(np.isfinite(best), best, -1))


def test_nearest_seed_ring_with_many_ties_and_late_seeds_on_reached_cells():
    """Open grids tie everywhere; seeds sharing cells or joining on cells an earlier ring met."""
    free = np.ones((30, 30), dtype=bool)
    seeds = np.array([[0, 0], [0, 29], [29, 0], [29, 29], [15, 15], [15, 15], [3, 3], [5, 0]])
    # seed 5 shares seed 4's cell; seed 6 starts on a cell seed 0 met at level 6; seed 7 on
    # a cell seed 0's ring meets at its very start level
    levels = np.array([0, 0, 0, 0, 4, 4, 9, 5])
    label, dist = nearest_seed(free, seeds, levels)
    field = shortest_path(grid_graph(free), unweighted=True, indices=seeds[:, 0] * 30 + seeds[:, 1])
    weighted = field + levels[:, None]
    assert np.array_equal(label.ravel(), np.argmin(weighted, axis=0))
    assert np.array_equal(dist.ravel(), weighted.min(axis=0))


def test_lloyd_update_of_all_clusters_matches_one_cluster_at_a_time():
    """The vectorised update gives the numbers of the per-cluster loop it replaced (means,
    the member nearest the mean with ties to the first, empty clusters kept)."""
    rng = np.random.default_rng(3)
    for trial in range(50):
        points = rng.integers(0, 12, size=(int(rng.integers(1, 60)), 2))  # a small box: many ties
        centroids = rng.random((6, 2)) * 12
        assignment = rng.integers(0, 6 if trial % 2 else 3, size=len(points))  # clusters 3-5 empty half the time
        for snap in (False, True):
            expected = centroids.copy()
            for k in range(6):
                members = points[assignment == k]
                if len(members) == 0:
                    continue
                mean = members.mean(axis=0)
                if snap:
                    mean = members[np.argmin(np.linalg.norm(members - mean, axis=1))].astype(float)
                expected[k] = mean
            assert np.array_equal(zones._lloyd_centroids(points, assignment, centroids, snap), expected)


@pytest.mark.parametrize("blocks", [False, True])
def test_balancing_by_passes_evens_zones_and_keeps_them_connected(blocks, monkeypatch):
    if blocks:  # the rounds on 2 x 2 blocks that grids past COARSE_BALANCE_CELLS get
        monkeypatch.setattr(zones, "COARSE_BALANCE_CELLS", 1000)
    free = np.ones((60, 90), dtype=bool)
    free[20:23, 10:80] = False  # a long block
    starts = np.array([[5, 5], [15, 60], [59, 89], [30, 45]])  # plain Voronoi sizes 703 to 2045
    zone = np.full(free.shape, -1)
    zone[free] = balanced_by_passes(free, free, starts)
    sizes = np.bincount(zone[free], minlength=4)
    plain = np.bincount(nearest_seed(free, starts)[0][free], minlength=4)
    assert np.ptp(sizes) < np.ptp(plain)  # more even than the plain Voronoi
    assert np.abs(sizes - free.sum() / 4).max() <= 0.05 * free.sum() / 4
    for k in range(4):
        assert ndimage.label(zone == k)[1] == 1  # one piece each


def test_lloyd_stops_when_snapped_centroids_cycle(monkeypatch):
    """Centroids that come back to an earlier state would cycle until MAX_LLOYD_ITERATIONS
    (the 1024 x 1024 bench city did, in a 2-cycle): Lloyd stops at the repeat instead."""
    free = np.ones((20, 20), dtype=bool)
    calls = []

    def alternating(free_cells, seeds, start_levels=None):  # nearest centroid flips every call
        calls.append(1)
        label = np.zeros(free_cells.shape, dtype=np.int32)
        label[:, 10:] = 1
        if len(calls) % 2 == 0:
            label[:10, :] = 1 - label[:10, :]
        return label, np.zeros(free_cells.shape, dtype=np.int32)

    monkeypatch.setattr(zones, "nearest_seed", alternating)
    z = split_zones(free, free, [(0, 0), (19, 19)], "geodesic", balance=False)
    assert z.iterations <= 4
    assert z.iterations < zones.MAX_LLOYD_ITERATIONS
