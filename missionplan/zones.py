"""Splitting the target cells among the drones (SPEC section 3, thesis 4.3).

Lloyd's iterations (k-means) over about 2000 random points drawn on the target cells,
with the centroids starting at the drones' launch cells, until no point changes cluster;
then every target cell goes to its nearest final centroid (a Voronoi partition). Two
distances are offered behind one interface:

- `euclidean`: straight-line distance between cells, as in the thesis;
- `geodesic`: distance along free cells (4-connected), so a zone never straddles a
  river or a long block; centroids are snapped to the nearest sample point so that they
  stay on free cells.

Beyond the thesis, optional balancing: Lloyd's zones can differ 2x in size, and the
biggest zone sets the makespan. Balancing keeps the Lloyd centroids but assigns each cell
to the zone minimising distance + w_k, raising w_k of zones that are too big until every
zone is within BALANCE_TOLERANCE of the mean size (an additively weighted Voronoi
partition). With geodesic distance each zone stays connected: the cell before x on the
shortest path from a centroid is one step nearer to it and at most one step nearer to any
other, so it belongs to the same zone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from .gridmap import Cell

ZONE_METHODS = ("geodesic", "euclidean")
DEFAULT_ZONE_METHOD = "geodesic"
NUM_SAMPLE_POINTS = 2000
MAX_LLOYD_ITERATIONS = 100
BALANCE_TOLERANCE = 0.03
MAX_BALANCE_ITERATIONS = 500


@dataclass
class Zones:
    """zone[r, c] is the drone index owning target cell (r, c), -1 elsewhere."""

    zone: np.ndarray
    centroids: np.ndarray  # (K, 2) final centroid positions (row, col)
    iterations: int
    method: str
    balanced: bool = False

    def sizes(self) -> np.ndarray:
        return np.bincount(self.zone[self.zone >= 0], minlength=len(self.centroids))


def grid_graph(free: np.ndarray) -> csr_matrix:
    """The 4-connected graph of free cells, nodes numbered row-major."""
    rows, cols = free.shape
    index = np.arange(rows * cols).reshape(rows, cols)
    right = free[:, :-1] & free[:, 1:]
    down = free[:-1, :] & free[1:, :]
    src = np.concatenate([index[:, :-1][right], index[:-1, :][down]])
    dst = np.concatenate([index[:, 1:][right], index[1:, :][down]])
    data = np.ones(2 * src.size, dtype=np.float32)
    return csr_matrix((data, (np.concatenate([src, dst]), np.concatenate([dst, src]))),
                      shape=(rows * cols, rows * cols))


def _geodesic_from(graph: csr_matrix, cells: np.ndarray, cols: int) -> np.ndarray:
    """(len(cells), N) hop distances along free cells; inf where unreachable."""
    sources = cells[:, 0] * cols + cells[:, 1]
    return shortest_path(graph, method="D", unweighted=True, indices=sources)


def balanced_assignment(distances: np.ndarray, tolerance: float = BALANCE_TOLERANCE,
                        shares: np.ndarray | None = None) -> np.ndarray:
    """argmin_k (distances[k] + w_k) with offsets w chosen so zone sizes are near equal, or near
    `shares` (K fractions summing to 1) of the cells when given.

    distances: (K, n) distance from each centroid to each cell (inf = unreachable).
    """
    num_zones, num_cells = distances.shape
    offsets = np.zeros(num_zones)
    finite = np.where(np.isfinite(distances), distances, np.inf)
    scale = float(np.median(np.min(finite, axis=0)[np.isfinite(np.min(finite, axis=0))]) or 1.0)
    target = num_cells / num_zones if shares is None else num_cells * np.asarray(shares, dtype=float)
    best, best_spread = np.argmin(finite, axis=0), np.inf
    for _ in range(MAX_BALANCE_ITERATIONS):
        assignment = np.argmin(finite + offsets[:, None], axis=0)
        sizes = np.bincount(assignment, minlength=num_zones)
        spread = float((np.abs(sizes - target) / target).max())
        if spread < best_spread:
            best, best_spread = assignment, spread
        if spread <= tolerance:
            break
        # Push big zones' boundaries in, pull small zones' out; a small fixed gain converges
        # without oscillating because sizes change smoothly with the offsets.
        offsets += 0.1 * scale * (sizes - target) / target
    return best


def split_zones(targets: np.ndarray, free: np.ndarray, starts: list[Cell], method: str = DEFAULT_ZONE_METHOD,
                seed: int = 0, num_points: int = NUM_SAMPLE_POINTS, balance: bool = False,
                shares: np.ndarray | None = None) -> Zones:
    """Partition the `targets` cells into len(starts) zones, one per drone (balanced: to `shares` of the
    cells when given, e.g. less for a drone whose battery sorties spend more time in transit)."""
    if method not in ZONE_METHODS:
        raise ValueError(f"unknown zone method {method!r} (choose {', '.join(ZONE_METHODS)})")
    num_zones = len(starts)
    zone = np.full(targets.shape, -1, dtype=np.int64)
    target_cells = np.argwhere(targets)
    if num_zones == 1 or len(target_cells) == 0:
        zone[targets] = 0
        return Zones(zone, np.array(starts, dtype=float).reshape(-1, 2), 0, method)

    rng = np.random.default_rng(seed)
    picks = rng.choice(len(target_cells), size=min(num_points, len(target_cells)), replace=False)
    points = target_cells[picks]
    centroids = np.array(starts, dtype=float)
    cols = targets.shape[1]
    graph = grid_graph(free) if method == "geodesic" else None

    def distances_to(cells_rc: np.ndarray, centres: np.ndarray) -> np.ndarray:
        """(K, len(cells_rc)) distance from each centre to each cell."""
        if graph is None:
            return np.linalg.norm(cells_rc[None, :, :] - centres[:, None, :], axis=2)
        field = _geodesic_from(graph, np.rint(centres).astype(np.int64), cols)
        return field[:, cells_rc[:, 0] * cols + cells_rc[:, 1]]

    assignment = None
    iterations = 0
    for iterations in range(1, MAX_LLOYD_ITERATIONS + 1):
        new_assignment = np.argmin(distances_to(points, centroids), axis=0)
        if assignment is not None and np.array_equal(new_assignment, assignment):
            break
        assignment = new_assignment
        for k in range(num_zones):
            members = points[assignment == k]
            if len(members) == 0:
                continue  # an empty cluster keeps its centroid
            mean = members.mean(axis=0)
            if graph is not None:
                # Geodesic distances need a centroid on a free cell: the member nearest the mean.
                mean = members[np.argmin(np.linalg.norm(members - mean, axis=1))].astype(float)
            centroids[k] = mean
    final = distances_to(target_cells, centroids)
    zone[targets] = balanced_assignment(final, shares=shares) if balance else np.argmin(final, axis=0)
    return Zones(zone, centroids, iterations, method, balance)
