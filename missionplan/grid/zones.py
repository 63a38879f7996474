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

At city scale (measured in docs/scale.md): geodesic Lloyd steps use one multi-source
breadth-first search per iteration (`nearest_seed`: every cell learns its nearest
centroid, ties to the lowest index, as argmin over per-centroid distances did) instead
of one full-grid Dijkstra per drone. Balancing keeps its dense K x U distance matrix
while K x U <= DENSE_BALANCE_LIMIT (every shipped map, so their zones are unchanged);
beyond that, where its 500 rounds would cost more than the plan, each round is one multi-source
search in which centroid k starts late by its offset w_k rounded to whole cells, at
most MAX_BALANCE_PASSES rounds, keeping the most even one. The search runs ring by ring in
numpy without sorting (`_search`); Lloyd's update moves all centroids at once.

Drones launched in separate free regions (one in a walled courtyard) are balanced region by
region: a region's targets go to the drones launched in it, in proportion to their shares.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from ..maps.gridmap import Cell
from .block_tours import FleetBlocks

ZONE_METHODS = ("geodesic", "euclidean")
DEFAULT_ZONE_METHOD = "geodesic"
NUM_SAMPLE_POINTS = 2000
MAX_LLOYD_ITERATIONS = 100
BALANCE_TOLERANCE = 0.03
MAX_BALANCE_ITERATIONS = 500
DENSE_BALANCE_LIMIT = 250_000  # K x U entries of the dense balancing matrix: shipped maps <= 94k
MAX_BALANCE_PASSES = 24
BALANCE_PASS_GAIN = 0.3
COARSE_BALANCE_CELLS = 16_384  # past this (128 x 128), balancing rounds run on 2 x 2 blocks
REFINE_PASSES = 6  # full-resolution rounds after the block rounds


@dataclass
class Zones:
    """zone[r, c] is the drone index owning target cell (r, c), -1 elsewhere."""

    zone: np.ndarray
    centroids: np.ndarray  # (K, 2) final centroid positions (row, col)
    iterations: int
    method: str
    balanced: bool = False
    fleet: FleetBlocks | None = None  # a whole fleet on open ground flying block tours (grid/fleet_blocks.py)

    @property
    def tours(self) -> list[list[Cell]] | None:
        """Each drone's block tour, when the fleet flies tours."""
        return self.fleet.tours if self.fleet is not None else None

    @property
    def tour_origin(self) -> Cell:
        """A corner of the tours' block grid."""
        return self.fleet.origin if self.fleet is not None else (0, 0)

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


def _padded_free(free: np.ndarray) -> np.ndarray:
    """free with a blocked border, flattened: a cell's four neighbours are at -w, -1, +1, +w."""
    padded = np.zeros((free.shape[0] + 2, free.shape[1] + 2), dtype=bool)
    padded[1:-1, 1:-1] = free
    return padded.ravel()


def _padded_index(cells: np.ndarray, width: int) -> np.ndarray:
    """Flat indices of (row, col) cells in a grid padded by one cell of `width` columns."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    return (cells[:, 0] + 1) * width + cells[:, 1] + 1


def _search(padded_free: np.ndarray, width: int, sources: np.ndarray, levels: np.ndarray, with_dist: bool = True
            ) -> tuple[np.ndarray, np.ndarray | None]:
    """nearest_seed on the flat padded grid: (label, dist) per padded cell, label len(sources) where unreached;
    dist None unless `with_dist`."""
    num_seeds = len(sources)
    open_ = padded_free.copy()  # free and not yet met by any ring
    label = np.full(open_.size, num_seeds, dtype=np.int32)  # above every seed index: unreached
    dist = np.full(open_.size, -1, dtype=np.int32) if with_dist else None
    slot = np.empty(open_.size, dtype=np.int64)  # which copy of a cell its scatter kept
    steps = np.array([[-width], [-1], [1], [width]], dtype=np.int64)
    entry = np.lexsort((np.arange(num_seeds), levels))  # by start level, then index
    ring = np.zeros(0, dtype=np.int64)
    waiting, level = 0, 0
    while True:
        while waiting < num_seeds and levels[entry[waiting]] <= level:
            k = int(entry[waiting])
            cell = int(sources[k])
            waiting += 1
            if open_[cell]:  # a free cell no ring has met: the seed starts a ring there
                open_[cell], label[cell] = False, k
                ring = np.append(ring, cell)
                if dist is not None:
                    dist[cell] = level
            elif (ring == cell).any():  # met by this very ring: the lower label keeps it
                label[cell] = min(int(label[cell]), k)
        if ring.size == 0:
            if waiting >= num_seeds:
                break
            level = int(levels[entry[waiting]])  # nothing in flight: jump to the next seed's start
            continue
        # The four neighbours of every ring cell as a (4, n) block (fast in numpy; (n, 4) is not).
        nxt = (steps + ring).ravel()
        nxt_label = np.empty((4, ring.size), dtype=np.int32)
        nxt_label[:] = label.take(ring)
        keep = np.flatnonzero(open_.take(nxt))
        nxt, nxt_label = nxt.take(keep), nxt_label.ravel().take(keep)
        np.minimum.at(label, nxt, nxt_label)  # the lowest label among a cell's ring neighbours
        open_[nxt] = False
        order = np.arange(nxt.size)
        slot[nxt] = order  # one copy of each cell wins the scatter: that copy is the ring's
        ring = nxt.compress(slot.take(nxt) == order)
        level += 1
        if dist is not None:
            dist[ring] = level
    return label, dist


def nearest_seed(free: np.ndarray, seeds: np.ndarray, start_levels: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Multi-source breadth-first search over the 4-connected free cells.

    Returns (label, dist), both (rows, cols) int32: the index of the nearest seed (ties
    go to the lowest index) and the hop distance to it; -1 where no seed reaches. With
    `start_levels`, seed k enters the search only at level start_levels[k] (>= 0), so
    the label is argmin_k (distance_k + start_levels[k]) - an additively weighted Voronoi -
    and dist is that sum.
    Ring by ring in numpy: a cell's label is the lowest label among its neighbours in the
    previous ring (one `np.minimum.at`), which is exactly the lowest index among its
    nearest seeds. No sort: a ring's cells are made unique by letting each cell's scatter
    keep one of its copies.
    """
    rows, cols = free.shape
    seeds = np.asarray(seeds, dtype=np.int64).reshape(-1, 2)
    levels = np.zeros(len(seeds), dtype=np.int64) if start_levels is None else np.asarray(start_levels, np.int64)
    label, dist = _search(_padded_free(free), cols + 2, _padded_index(seeds, cols + 2), levels)
    label[label == len(seeds)] = -1
    shape = (rows + 2, cols + 2)
    return label.reshape(shape)[1:-1, 1:-1], dist.reshape(shape)[1:-1, 1:-1]


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
    nearest = np.argmin(finite, axis=0)
    # A cell whose second-nearest centroid is farther than the nearest by more than the
    # spread of the offsets keeps its nearest: only the cells with a small gap are
    # re-decided each round (exactly the same argmin, on far fewer columns).
    two = np.partition(finite, 1, axis=0)[:2] if num_zones > 1 else np.vstack([finite[:1], finite[:1] + np.inf])
    with np.errstate(invalid="ignore"):
        gap = np.nan_to_num(two[1] - two[0], nan=np.inf)
    by_gap = np.argsort(gap, kind="stable")
    sorted_gap = gap[by_gap]
    contested_distances = finite[:, by_gap]
    best, best_spread = nearest, np.inf
    for _ in range(MAX_BALANCE_ITERATIONS):
        count = int(np.searchsorted(sorted_gap, offsets.max() - offsets.min(), side="right"))
        assignment = nearest.copy()
        assignment[by_gap[:count]] = np.argmin(contested_distances[:, :count] + offsets[:, None], axis=0)
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


def _coarsened(grid: np.ndarray, factor: int) -> np.ndarray:
    """(ceil(rows / f), ceil(cols / f)) counts of True cells per f x f block."""
    rows, cols = grid.shape
    padded = np.zeros((-(-rows // factor) * factor, -(-cols // factor) * factor), dtype=np.int64)
    padded[:rows, :cols] = grid
    return padded.reshape(padded.shape[0] // factor, factor, padded.shape[1] // factor, factor).sum(axis=(1, 3))


def _offset_rounds(free: np.ndarray, weight: np.ndarray, seeds: np.ndarray, offsets: np.ndarray, gain: float,
                   rounds: int, tolerance: float, shares: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, float]:
    """Balancing rounds on one grid; returns (best assignment of the weighted cells, its offsets, its spread)."""
    num_zones = len(seeds)
    width = free.shape[1] + 2
    padded_free = _padded_free(free)  # made once, searched every round
    sources = _padded_index(seeds, width)
    weighted = np.argwhere(weight > 0)
    cell_weight = weight[weight > 0]
    at = _padded_index(weighted, width)  # the weighted cells, row-major, in the padded grid

    def assign(offsets_now: np.ndarray, with_dist: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        levels = np.rint(offsets_now - offsets_now.min()).astype(np.int64)
        label, dist = _search(padded_free, width, sources, levels, with_dist)
        assignment = label.take(at)
        return np.where(assignment < num_zones, assignment, -1), None if dist is None else dist.take(at)

    assignment, dist = assign(offsets, with_dist=True)  # the first round's distances set the offsets' scale
    reached = dist[assignment >= 0]
    scale = (float(np.median(reached)) if reached.size else 1.0) or 1.0
    target = cell_weight.sum() / num_zones if shares is None else cell_weight.sum() * np.asarray(shares, float)
    offsets = offsets.copy()
    gains = np.full(num_zones, gain)
    last_error = np.zeros(num_zones)
    best, best_offsets, best_spread = assignment, offsets.copy(), np.inf
    for round_ in range(rounds):
        sizes = np.bincount(assignment[assignment >= 0], weights=cell_weight[assignment >= 0], minlength=num_zones)
        error = (sizes - target) / target
        spread = float(np.abs(error).max())
        if spread < best_spread:
            best, best_offsets, best_spread = assignment, offsets.copy(), spread
        if spread <= tolerance or round_ == rounds - 1:
            break
        gains[np.sign(error) * np.sign(last_error) < 0] *= 0.5  # overshot: finer steps for that zone
        offsets += gains * scale * error
        last_error = error
        assignment = assign(offsets)[0]
    return best, best_offsets, best_spread


def balanced_by_passes(free: np.ndarray, targets: np.ndarray, seeds: np.ndarray,
                       tolerance: float = BALANCE_TOLERANCE, shares: np.ndarray | None = None) -> np.ndarray:
    """balanced_assignment's offsets loop without its K x U matrix: (U,) zone of each target cell.

    Each round is one `nearest_seed` search with seed k starting late by its offset w_k
    rounded to whole cells. Offsets move like the dense loop's, three times bolder (each
    round is a whole-grid search, so there are few), halved for a zone that overshoots;
    rounds stop within `tolerance` or after MAX_BALANCE_PASSES, keeping the most even
    split. On grids past COARSE_BALANCE_CELLS the rounds run on blocks of 2 x 2 cells (a
    block is free when any of its cells is, and weighs its target cells), then at most
    REFINE_PASSES full-resolution rounds start from the offsets found, times 2.
    """
    seeds = np.asarray(seeds, dtype=np.int64)
    factor = 1
    if free.size > COARSE_BALANCE_CELLS:
        factor = 2  # 4 x 4 blocks were measured to merge streets across thin blocks: 3x less even
    offsets = np.zeros(len(seeds))
    gain = BALANCE_PASS_GAIN
    if factor > 1:
        _, offsets, _ = _offset_rounds(_coarsened(free, factor) > 0, _coarsened(targets, factor), seeds // factor,
                                       offsets, gain, MAX_BALANCE_PASSES, tolerance, shares)
        offsets, gain = offsets * factor, gain / 2
    rounds = REFINE_PASSES if factor > 1 else MAX_BALANCE_PASSES
    best, _, _ = _offset_rounds(free, targets.astype(np.int64), seeds, offsets, gain, rounds, tolerance, shares)
    return np.where(best >= 0, best, 0)


def _lloyd_centroids(points: np.ndarray, assignment: np.ndarray, centroids: np.ndarray, snap: bool) -> np.ndarray:
    """One Lloyd update: each cluster's mean (snapped: the member nearest it, first in `points` on a tie);
    an empty cluster keeps its centroid.

    All clusters at once; the same numbers as a loop over clusters: the coordinates are
    integers, so their float64 sums are exact in any order, and each member's distance
    is computed by the same formula.
    """
    num_zones = len(centroids)
    counts = np.bincount(assignment, minlength=num_zones)
    sums = np.stack([np.bincount(assignment, weights=points[:, axis], minlength=num_zones) for axis in (0, 1)], axis=1)
    filled = counts > 0
    means = centroids.copy()
    means[filled] = sums[filled] / counts[filled, None]
    if not snap:
        return means
    # Geodesic distances need a centroid on a free cell: the member nearest the mean.
    gap = np.linalg.norm(points - means[assignment], axis=1)
    order = np.lexsort((np.arange(len(points)), gap, assignment))  # per cluster: nearest, then first
    first = order[np.r_[True, assignment[order][1:] != assignment[order][:-1]]]
    snapped = centroids.copy()
    snapped[assignment[first]] = points[first]
    return snapped


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
    geodesic = method == "geodesic"

    labels_of: list = [b"", None]  # (centroid cells, their nearest_seed labels) of the last search

    def nearest_centroid(cells_rc: np.ndarray, centres: np.ndarray) -> np.ndarray:
        """(len(cells_rc),) index of the nearest centre to each cell; ties to the lowest index."""
        if not geodesic:  # in chunks: a K x U matrix of a whole city would not fit
            chunk = max(1, 4_000_000 // len(centres))
            return np.concatenate([np.argmin(np.linalg.norm(part[None, :, :] - centres[:, None, :], axis=2), axis=0)
                                   for part in np.array_split(cells_rc, max(1, -(-len(cells_rc) // chunk)))])
        seeds = np.rint(centres).astype(np.int64)
        if labels_of[0] != seeds.tobytes():  # the last Lloyd step's labels serve the final split too
            labels_of[:] = [seeds.tobytes(), nearest_seed(free, seeds)[0]]
        label = labels_of[1][cells_rc[:, 0], cells_rc[:, 1]]
        return np.where(label >= 0, label, 0)  # reached by no centre: argmin over all-inf gave 0

    assignment = None
    iterations = 0
    visited: set[bytes] = set()
    for iterations in range(1, MAX_LLOYD_ITERATIONS + 1):
        new_assignment = nearest_centroid(points, centroids)
        if assignment is not None and np.array_equal(new_assignment, assignment):
            break
        # Snapped (geodesic) centroids can cycle, e.g. two states in turn for ever: stop
        # when the centroids repeat, rather than at MAX_LLOYD_ITERATIONS.
        state = centroids.tobytes()
        if state in visited:
            break
        visited.add(state)
        assignment = new_assignment
        centroids = _lloyd_centroids(points, assignment, centroids, geodesic)
    seeds = np.rint(centroids).astype(np.int64)
    if not balance:
        zone[targets] = nearest_centroid(target_cells, centroids)
        return Zones(zone, centroids, iterations, method, balance)
    labels, _ = ndimage.label(free)  # 4-connected free regions, as the drones move
    launch = np.array(starts, dtype=np.int64).reshape(-1, 2)
    region = labels[launch[:, 0], launch[:, 1]]  # 0: a launch on a blocked cell
    if len(set(region.tolist()) - {0}) > 1:
        # Drones launched in separate free regions (a walled courtyard): each region's targets are
        # shared among the drones that can reach them; an equal share of the whole map for a
        # pocket drone would leave the others unbalanced and the offsets loop never converging.
        zone[targets] = nearest_centroid(target_cells, centroids)  # targets no drone reaches keep their Voronoi
        _balance_by_region(zone, targets, labels, centroids, region, method, shares)
    elif geodesic and num_zones * len(target_cells) > DENSE_BALANCE_LIMIT:
        zone[targets] = balanced_by_passes(free, targets, seeds, shares=shares)
    elif geodesic:  # the sparse graph only for the dense balancing of small maps; Lloyd searches the grid
        field = _geodesic_from(grid_graph(free), seeds, cols)
        zone[targets] = balanced_assignment(field[:, target_cells[:, 0] * cols + target_cells[:, 1]], shares=shares)
    else:
        zone[targets] = balanced_assignment(np.linalg.norm(target_cells[None, :, :] - centroids[:, None, :], axis=2),
                                            shares=shares)
    return Zones(zone, centroids, iterations, method, balance)


def _balance_by_region(zone: np.ndarray, targets: np.ndarray, labels: np.ndarray, centroids: np.ndarray,
                       seed_region: np.ndarray, method: str, shares: np.ndarray | None) -> None:
    """Balance, in place, each launch region's targets among the drones launched in it (their shares
    renormalised); a drone alone in its region takes all of it. `labels`: the free regions."""
    weights = None if shares is None else np.asarray(shares, dtype=float)
    cols = labels.shape[1]
    for region in sorted(set(seed_region.tolist()) - {0}):
        members = np.flatnonzero(seed_region == region)
        inside = labels == region
        region_targets = targets & inside
        cells = np.argwhere(region_targets)
        if len(cells) == 0:
            continue
        if len(members) == 1:
            zone[region_targets] = members[0]
            continue
        part = None
        if weights is not None and weights[members].sum() > 0:
            part = weights[members] / weights[members].sum()
        seeds = np.rint(centroids[members]).astype(np.int64)
        if method == "geodesic" and len(members) * len(cells) > DENSE_BALANCE_LIMIT:
            local = balanced_by_passes(inside, region_targets, seeds, shares=part)
        elif method == "geodesic":
            field = _geodesic_from(grid_graph(inside), seeds, cols)
            local = balanced_assignment(field[:, cells[:, 0] * cols + cells[:, 1]], shares=part)
        else:
            local = balanced_assignment(np.linalg.norm(cells[None, :, :] - centroids[members][:, None, :], axis=2),
                                        shares=part)
        zone[region_targets] = members[local]
