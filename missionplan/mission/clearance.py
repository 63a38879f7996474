"""Clearance from obstacles: the band drones may not fly in, and how far each track really stays out.

By construction: the grid planner flies the map with the *clearance band* - every free cell whose
centre is closer than --clearance to an obstacle cell's square - made an obstacle too (`flight_map`).
Grid moves go between cell centres outside the band, and along such a move the distance to a
square is smallest at an end, so every grid move keeps the clearance; the trajectory corrector keeps
it on its shortcuts (margin = clearance against the original obstacles, see flightplan). Targets in
the band stay targets: they are photographed from outside it, by the 4-cell footprint radius
(`band_coverage` counts which were, and the rest are reported, not hidden).

Measured: the track is the polyline the drone flies (launch point, then its waypoints in every
sortie); the obstacles are the grid's obstacle cells as squares, so `track_clearance` is a lower
bound of the distance to the buildings themselves (a cell is an obstacle when it touches one).
"""

from __future__ import annotations

from typing import Any

import dataclasses
from dataclasses import replace

import numpy as np
from scipy import ndimage

from missionplan.base.naming import Named

from ..grid.world import FOOTPRINT_RADIUS
from ..maps.gridmap import GridMap, MapError
from .plan_blocks import BandCounts, cells_of
from .plan_record import PlanRecord


def band_structure(clearance_cells: float) -> np.ndarray:
    """Offsets (dr, dc) of the obstacle cells whose square is closer than `clearance_cells` to a cell centre."""
    reach = int(np.ceil(clearance_cells + 0.5))
    d = np.arange(-reach, reach + 1)
    dr, dc = np.meshgrid(d, d, indexing="ij")
    gap = np.hypot(np.maximum(np.abs(dr) - 0.5, 0.0), np.maximum(np.abs(dc) - 0.5, 0.0))
    return gap < clearance_cells - 1e-9


def clearance_band(obstacle: np.ndarray, clearance_cells: float) -> np.ndarray:
    """Free cells whose centre lies closer than `clearance_cells` to an obstacle cell's square."""
    if clearance_cells <= 0.5 or not obstacle.any():  # a cell centre is always half a cell from its neighbours
        return np.zeros_like(obstacle, dtype=bool)
    return ndimage.binary_dilation(obstacle, structure=band_structure(clearance_cells)) & ~obstacle


def flight_map(gmap: GridMap, clearance_m: float, uavs: int) -> tuple[GridMap, np.ndarray]:
    """(the map the grid planner flies: the clearance band made obstacle, the band). MapError naming the
    drone when a launch cell lies in the band (it could not leave it without breaking the clearance)."""
    if gmap.cell_m is None:
        raise MapError(Named("map {0}: no georeference, so no cell size to keep {clearance} {1:g} m in", gmap.name,
                             clearance_m))
    band = clearance_band(gmap.obstacle, clearance_m / gmap.cell_m)
    for k, cell in enumerate(gmap.launch[:uavs], start=1):
        if gmap.inside(cell) and band[cell]:
            raise MapError(Named("map {0}: the launch point of drone {1} (cell {2},{3}) is closer than {clearance} "
                                 "{4:g} m to an obstacle: move it into the open or lower {clearance}", gmap.name, k,
                                 cell[0], cell[1], clearance_m))
    if not band.any():
        return gmap, band
    return dataclasses.replace(gmap, obstacle=gmap.obstacle | band, target=gmap.target & ~band), band


def footprint_union(paths: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Cells inside the footprint (the 9 x 9 block) of any cell of any drone's path (K, T+1, 2)."""
    visited = np.zeros(shape, dtype=bool)
    cells = np.asarray(paths).reshape(-1, 2)
    visited[cells[:, 0], cells[:, 1]] = True
    size = 2 * FOOTPRINT_RADIUS + 1
    return ndimage.binary_dilation(visited, structure=np.ones((size, size), dtype=bool))


def band_coverage(record: PlanRecord, gmap: GridMap, band: np.ndarray,
                  paths: np.ndarray) -> tuple[PlanRecord, BandCounts]:
    """The plan record with the band's targets put back: the grid is the map as given (not the planner's),
    band targets no footprint of the plan holds join `unreachable_cells`, the ones it holds join
    `targets`; and the counts for report.json `clearance`."""
    band_targets = gmap.target & band
    held = footprint_union(paths, gmap.shape)
    photographed, missed = band_targets & held, band_targets & ~held
    unreachable = record.unreachable_cells + cells_of(np.argwhere(missed).tolist())
    record = replace(record, grid=tuple(gmap.rows_text()), targets=int(record.targets) + int(photographed.sum()),
                     unreachable_cells=unreachable, unreachable=len(unreachable))
    return record, BandCounts(int(band.sum()), int(band_targets.sum()), int(photographed.sum()), int(missed.sum()))


def obstacle_shape(obstacle: np.ndarray, cell_m: float) -> Any:
    """The union of the obstacle cells' squares, in grid metres (x = row_m, y = col_m)."""
    import shapely

    cells = np.argwhere(obstacle).astype(float) * cell_m
    half = cell_m / 2.0
    return shapely.union_all(shapely.box(cells[:, 0] - half, cells[:, 1] - half, cells[:, 0] + half, cells[:, 1] + half))


def track_clearance(obstacles: Any, points_m: np.ndarray) -> tuple[float, np.ndarray]:
    """(smallest horizontal distance of the polyline `points_m` (n, 2 grid metres) from `obstacles`,
    the track point where it happens)."""
    import shapely
    from shapely.ops import nearest_points

    points = np.asarray(points_m, dtype=float).reshape(-1, 2)
    if obstacles.is_empty or len(points) == 0:
        return float("inf"), points[:1].reshape(-1)
    line = shapely.LineString(points) if len(points) > 1 else shapely.Point(points[0])
    where, _ = nearest_points(line, obstacles)
    return float(shapely.distance(line, obstacles)), np.array([where.x, where.y])


def steps_toward(free: np.ndarray, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breadth-first over `free` from every cell of `sources` at once: (steps to the nearest source, -1
    where none is reachable; for each cell the flat index of its next cell toward that source)."""
    from collections import deque

    rows, cols = free.shape
    dist = np.full(free.shape, -1, dtype=np.int64)
    nxt = np.full(free.shape, -1, dtype=np.int64)
    queue = deque()
    for r, c in np.argwhere(sources & free):
        dist[r, c] = 0
        queue.append((int(r), int(c)))
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
            if 0 <= nr < rows and 0 <= nc < cols and free[nr, nc] and dist[nr, nc] < 0:
                dist[nr, nc] = dist[r, c] + 1
                nxt[nr, nc] = r * cols + c
                queue.append((nr, nc))
    return dist, nxt


def way_to_source(nxt: np.ndarray, cell: tuple[int, int]) -> list[tuple[int, int]]:
    """The cells from `cell` to the source steps_toward reached it from, both included (`nxt` its next-cell
    grid; just `cell` for a source or a cell no source reaches)."""
    cols = nxt.shape[1]
    way = [cell]
    while (flat := int(nxt[way[-1]])) >= 0:
        way.append((flat // cols, flat % cols))
    return way


def insert_detours(tracks: list[list[tuple[int, int]]],
                   detours: dict[tuple[int, int], list[tuple[int, int]]]) -> list[list[tuple[int, int]]]:
    """Each drone's track with the detour keyed (drone k, index i) flown right after its i-th cell."""
    out = []
    for k, track in enumerate(tracks):
        new: list[tuple[int, int]] = []
        for i, cell in enumerate(track):
            new.append(cell)
            new.extend(detours.get((k, i), ()))
        out.append(new)
    return out


def padded_paths(tracks: list[list[tuple[int, int]]], dtype: Any) -> np.ndarray:
    """The tracks as paths (K, T+1, 2), the shorter ones hovering at their end."""
    length = max(len(t) for t in tracks)
    return np.array([t + [t[-1]] * (length - len(t)) for t in tracks], dtype=dtype)


def photograph_band(paths: np.ndarray, flight: GridMap, gmap: GridMap, band: np.ndarray,
                    zone: np.ndarray) -> tuple[np.ndarray, int]:
    """Extend the drones' grid paths (K, T+1, 2) so every band target a footprint can reach from outside
    the band is photographed. A target the survey left out is visited by a detour out of the survey
    path, where the path passes nearest to a cell that sees it, and back to the path (so the plan's
    order and end stay as they were). Returns the new paths (the others hover at their end) and the
    moves added.

    Why a separate pass: the planner's world tracks only targets it can fly to; a band target is seen
    from up to FOOTPRINT_RADIUS cells away, from outside the band."""
    r = FOOTPRINT_RADIUS
    square = np.ones((2 * r + 1, 2 * r + 1), dtype=bool)
    starts = [tuple(int(v) for v in p[0]) for p in paths]
    labels, _ = ndimage.label(flight.free)
    flyable = np.isin(labels, [labels[s] for s in starts if labels[s] > 0]) & flight.free
    pending = gmap.target & band & ~footprint_union(paths, gmap.shape)
    pending &= ndimage.binary_dilation(flyable, structure=square)  # seen from some flyable cell
    tracks = [list(map(tuple, p.tolist())) for p in paths]
    added = 0

    def sees_pending(cell: tuple[int, int]) -> bool:
        return bool(pending[max(cell[0] - r, 0):cell[0] + r + 1, max(cell[1] - r, 0):cell[1] + r + 1].any())

    for _ in range(1000):  # rounds; each photographs at least one pending target or stops
        if not pending.any():
            break
        dist, nxt = steps_toward(flyable, ndimage.binary_dilation(pending, structure=square))
        # Every drone's path cell with its distance to a cell that sees a pending target.
        options = sorted((int(dist[cell]), k, i) for k, track in enumerate(tracks)
                         for i, cell in enumerate(track) if dist[cell] >= 0)
        if not options:
            break
        detours: dict[tuple[int, int], list[tuple[int, int]]] = {}
        progress = False
        for d, k, i in options:
            route = way_to_source(nxt, tracks[k][i])
            if not sees_pending(route[-1]):
                continue
            for cr, cc in route:
                pending[max(cr - r, 0):cr + r + 1, max(cc - r, 0):cc + r + 1] = False
            detours[(k, i)] = detours.get((k, i), []) + route[1:] + route[-2::-1]
            progress = True
        if not progress:
            break
        tracks = insert_detours(tracks, detours)
        added += sum(len(extra) for extra in detours.values())
    return padded_paths(tracks, paths.dtype), added
