"""Launch points for grids that come without any: a deterministic, well-spread sequence in the open.

`spread_launches(free, count)` owns the choice. It works on any boolean free-cell grid (a MovingAI
street map, or any other launchless grid), and its sequence does not depend on `count`: the first N
launches of `spread_launches(free, 64)` are `spread_launches(free, N)`, so a map can store one
list and `--uavs N` takes its first N.

How launches are chosen:

* only in the largest 4-connected free region (the one the drones can fly through: the planner's
  moves are 4-connected too), so every launch reaches the bulk of the targets;
* preferably on *open* cells, whose 5x5 neighbourhood is free (else 3x3, else any free cell of the
  region, once every more open cell is taken), so no drone is jammed into a 1-cell alley or a
  dead-end at the map's edge;
* the first at the open cell nearest the region's centroid; each next one at the open cell farthest,
  by geodesic (BFS, 4-connected, along free cells) distance, from the launches chosen so far
  (farthest-point sampling); ties go to the first cell in row-major order.

Speed: the distance-to-nearest-launch field is updated per new launch by a breadth-first expansion
in numpy, pruned where an earlier launch is already as close; the explored part shrinks as launches
are added, so 64 launches cost a few full BFS passes (about 1 s on a 1024 x 1024 street grid).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

Cell = tuple[int, int]

_FAR = np.iinfo(np.int32).max  # not yet reached from any launch
_OFF = -1                      # obstacle, padding, or a free cell outside the region: never entered


def largest_region(free: np.ndarray) -> np.ndarray:
    """The largest 4-connected region of `free` (ties: the one whose first cell comes first)."""
    labels, count = ndimage.label(free)  # default structure: 4-connectivity
    if count == 0:
        return np.zeros_like(free, dtype=bool)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == int(np.argmax(sizes))


def openness(region: np.ndarray) -> np.ndarray:
    """Per cell of `region`: 2 if its 5x5 neighbourhood is in the region, 1 if its 3x3 is, else 0; -1 outside."""
    level = np.where(region, 0, -1).astype(np.int8)
    for size, rank in ((3, 1), (5, 2)):
        # border_value 0: the map's edge counts as closed (a launch there has half a neighbourhood)
        level[ndimage.binary_erosion(region, np.ones((size, size), bool), border_value=0)] = rank
    return level


def spread_launches(free: np.ndarray, count: int) -> list[Cell]:
    """Up to `count` distinct launch cells, well spread over the largest free region (see the module)."""
    free = np.asarray(free, dtype=bool)
    if free.ndim != 2:
        raise ValueError(f"free must be a 2-D grid, got shape {free.shape}")
    region = largest_region(free)
    if count < 1 or not region.any():
        return []
    rows, cols = free.shape
    # Pad by one closed cell on each side so the flat neighbour offsets never wrap a row.
    width = cols + 2
    dist = np.full((rows + 2, width), _OFF, dtype=np.int32)
    dist[1:-1, 1:-1][region] = _FAR
    dist = dist.ravel()
    level = np.full((rows + 2, width), -1, dtype=np.int8)
    level[1:-1, 1:-1] = openness(region)
    level = level.ravel()
    tiers = [np.flatnonzero(level >= rank) for rank in (2, 1, 0)]
    steps = np.array([-1, 1, -width, width], dtype=np.int64)

    r, c = np.nonzero(region)
    centre = np.array([r.mean(), c.mean()]) + 1.0  # in padded coordinates
    first_tier = next(t for t in tiers if t.size)
    d2 = (first_tier // width - centre[0]) ** 2 + (first_tier % width - centre[1]) ** 2
    source = int(first_tier[np.argmin(d2)])

    chosen: list[int] = []
    while True:
        chosen.append(source)
        _expand(dist, source, steps)
        if len(chosen) == count:
            break
        source = _farthest(dist, tiers)
        if source < 0:  # every cell of the region is a launch already
            break
    return [(s // width - 1, s % width - 1) for s in chosen]


def _expand(dist: np.ndarray, source: int, steps: np.ndarray) -> None:
    """Lower `dist` (flat, padded) to the BFS distance from `source` wherever that is smaller.

    Pruning is exact: a cell the new launch is strictly closer to is reached through cells it is
    strictly closer to as well, so the expansion may stop wherever an earlier launch is as close."""
    dist[source] = 0
    frontier = np.array([source], dtype=np.int64)
    step = 0
    while frontier.size:
        step += 1
        around = (frontier[:, None] + steps).ravel()
        around = around[dist[around] > step]  # _OFF cells are never > step
        if not around.size:
            break
        frontier = np.unique(around)
        dist[frontier] = step


def _farthest(dist: np.ndarray, tiers: list[np.ndarray]) -> int:
    """The not-yet-chosen cell of the most open tier that has one, farthest from every launch; -1 if none."""
    for tier in tiers:
        if not tier.size:
            continue
        d = dist[tier]
        best = int(np.argmax(d))  # first maximum: the first such cell in row-major order
        if d[best] > 0:
            return int(tier[best])
    return -1
