"""Splitting the target cells among the drones (SPEC section 3, thesis 4.3).

Lloyd's iterations (k-means) over about 2000 random points drawn on the target cells,
with the centroids starting at the drones' launch cells, until no point changes cluster;
then every target cell goes to its nearest final centroid (a Voronoi partition). Two
distances are offered behind one interface:

- `euclidean`: straight-line distance between cells, as in the thesis;
- `geodesic`: distance along free cells (4-connected), so a zone never straddles a
  river or a long block; centroids are snapped to the nearest sample point so that they
  stay on free cells.
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


@dataclass
class Zones:
    """zone[r, c] is the drone index owning target cell (r, c), -1 elsewhere."""

    zone: np.ndarray
    centroids: np.ndarray  # (K, 2) final centroid positions (row, col)
    iterations: int
    method: str


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


def split_zones(targets: np.ndarray, free: np.ndarray, starts: list[Cell], method: str = DEFAULT_ZONE_METHOD,
                seed: int = 0, num_points: int = NUM_SAMPLE_POINTS) -> Zones:
    """Partition the `targets` cells into len(starts) zones, one per drone."""
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
    zone[targets] = np.argmin(distances_to(target_cells, centroids), axis=0)
    return Zones(zone, centroids, iterations, method)
