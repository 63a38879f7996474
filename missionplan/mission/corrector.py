"""Trajectory corrector: a drone's cell path -> a few waypoints a real drone flies well (SPEC section 8).

It owns turning one planned grid path into a polyline and nothing else (no planning, no
mission files). Three steps:

1. Drop hovers (consecutive repeats of the same cell).
2. Merge straight runs: keep only the cells where the heading changes (plus both ends).
3. Straighten stair-steps greedily. From waypoint i, scan later waypoints j = i+2, i+3, ...
   and keep the farthest j for which the straight segment i -> j is accepted; stop the
   scan after `patience` rejections in a row. A segment is accepted when all hold:

   * Obstacle clearance. Cell (r, c) is the square [r-0.5, r+0.5] x [c-0.5, c+0.5]; the point
     (r, c) is its centre. The segment is widened to its Chebyshev (axis-aligned square)
     buffer of radius `margin_cells`. A cell is touched when its open square overlaps that
     open buffer, i.e. when the Chebyshev distance from its centre to the segment is
     < 0.5 + margin_cells (computed exactly, not sampled). No touched cell may be an
     obstacle. With the default margin 0.5 that is every cell whose centre is closer than
     one cell (box distance) to the segment, so the drone keeps half a cell of clearance.
     Cells outside the map are not tested: both ends are map cells, so the segment itself
     stays inside the (rectangular) map.
   * Coverage. The footprint of a point p is the cells whose centre is within
     `footprint_radius` of p (Chebyshev, inclusive): the 9 x 9 block for a cell centre.
     The grid path covers the union of the blocks at its cells; for the segments kept
     from the grid path (axis-aligned, between cell centres) that union is exact. For a
     new (diagonal) segment we credit only its *robust* swept footprint: the blocks at
     its two ends plus the cells whose Chebyshev distance to the segment is
     <= footprint_radius - sample_step / 2. Every credited cell is then inside the footprint
     of some point of any sampling of the segment with spacing <= sample_step (0.25 by
     default) that includes both ends, so a denser independent check finds it too.
     A coverage count (how many polyline segments cover each cell) is kept; a candidate
     subtracts the old segments it replaces and adds its own footprint, on the bounding
     box of the replaced part only, and is refused if any target the grid path covered
     drops to 0.
   * Turning. The heading changes at i and j after the replacement may not sum to more
     than the turning of the replaced part (so total turning never grows).
   * Kept turns. No shortcut skips a waypoint on a cell the caller asks to keep (`keep`): the
     coverage rule keeps every target's one photo, not the photos an overlap implies, so the
     caller keeps the turns of lanes closer than a footprint (a side overlap) and of an overlap
     fill's detours (planning/field_plan.py).

Grid coordinates throughout: waypoint (r, c) float, row down, column right.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..grid.world import FOOTPRINT_RADIUS

MARGIN_CELLS = 0.5
SAMPLE_STEP = 0.25
PATIENCE = 8


@dataclass
class CorrectedPath:
    waypoints: np.ndarray  # (n, 2) float, grid coordinates
    before: dict = field(default_factory=dict)  # waypoints / length_cells / turning_deg
    after: dict = field(default_factory=dict)


# --- polyline helpers ------------------------------------------------------------------------

def drop_hovers(path: np.ndarray) -> np.ndarray:
    """The path without consecutive repeats of a cell."""
    path = np.asarray(path)
    if len(path) == 0:
        return path.reshape(0, 2)
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.any(path[1:] != path[:-1], axis=1)
    return path[keep]


def merge_straight(points: np.ndarray) -> np.ndarray:
    """Keep both ends and every vertex where the direction changes (points: no repeats)."""
    if len(points) <= 2:
        return points.copy()
    d = np.diff(points.astype(float), axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    turn = np.any(np.abs(d[1:] - d[:-1]) > 1e-9, axis=1)
    keep = np.concatenate([[True], turn, [True]])
    return points[keep]


def path_length(points: np.ndarray) -> float:
    """Euclidean length of a polyline (cells)."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def _heading_change(u: np.ndarray, v: np.ndarray) -> float:
    """Absolute angle (degrees) between two non-zero direction vectors."""
    cross = u[0] * v[1] - u[1] * v[0]
    dot = u[0] * v[0] + u[1] * v[1]
    return abs(float(np.degrees(np.arctan2(cross, dot))))


def total_turning(points: np.ndarray) -> float:
    """Sum of absolute heading changes (degrees) at the interior vertices of a polyline."""
    d = np.diff(drop_hovers(np.asarray(points, dtype=float)), axis=0)
    if len(d) < 2:
        return 0.0
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    dot = (d[:-1] * d[1:]).sum(axis=1)
    return float(np.abs(np.degrees(np.arctan2(cross, dot))).sum())


def _stats(n_waypoints: int, points: np.ndarray) -> dict:
    return {"waypoints": int(n_waypoints), "length_cells": path_length(points),
            "turning_deg": total_turning(points)}


# --- geometry on the grid --------------------------------------------------------------------

def chebyshev_to_segment(centres: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact Chebyshev distance from each point of `centres` (m, 2) to the segment a-b.

    f(t) = max(|u_r + t d_r|, |u_c + t d_c|) with u = a - q, d = b - a is convex and piecewise
    linear in t, so its minimum on [0, 1] is at an end or at a breakpoint: where a component is 0
    or where the two components have equal magnitude.
    """
    u = a[None, :] - centres  # (m, 2)
    d = b - a
    ts = [np.zeros(len(u)), np.ones(len(u))]
    with np.errstate(divide="ignore", invalid="ignore"):
        if d[0] != 0:
            ts.append(-u[:, 0] / d[0])
        if d[1] != 0:
            ts.append(-u[:, 1] / d[1])
        if d[0] != d[1]:
            ts.append((u[:, 1] - u[:, 0]) / (d[0] - d[1]))
        if d[0] != -d[1]:
            ts.append(-(u[:, 0] + u[:, 1]) / (d[0] + d[1]))
    t = np.clip(np.stack(ts, axis=1), 0.0, 1.0)  # (m, k)
    f = np.maximum(np.abs(u[:, 0:1] + t * d[0]), np.abs(u[:, 1:2] + t * d[1]))
    return f.min(axis=1)


def _box(a: np.ndarray, b: np.ndarray, pad: float, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Cell index box [r0, r1) x [c0, c1) of cells within `pad` of the segment's bounding box."""
    r0 = max(int(np.floor(min(a[0], b[0]) - pad)), 0)
    r1 = min(int(np.ceil(max(a[0], b[0]) + pad)) + 1, shape[0])
    c0 = max(int(np.floor(min(a[1], b[1]) - pad)), 0)
    c1 = min(int(np.ceil(max(a[1], b[1]) + pad)) + 1, shape[1])
    return r0, r1, c0, c1


def _cell_centres(r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    rr, cc = np.mgrid[r0:r1, c0:c1]
    return np.stack([rr.ravel(), cc.ravel()], axis=1).astype(float)


def segment_clear(a: np.ndarray, b: np.ndarray, obstacle: np.ndarray, margin_cells: float) -> bool:
    """True if no obstacle cell's square overlaps the segment widened by `margin_cells` (box)."""
    reach = 0.5 + margin_cells
    r0, r1, c0, c1 = _box(a, b, reach, obstacle.shape)
    window = obstacle[r0:r1, c0:c1]
    if not window.any():
        return True
    centres = _cell_centres(r0, r1, c0, c1)[window.ravel()]
    return bool((chebyshev_to_segment(centres, a, b) >= reach - 1e-9).all())


def segment_footprint(a: np.ndarray, b: np.ndarray, shape: tuple[int, int], footprint_radius: int,
                      sample_step: float = SAMPLE_STEP) -> tuple[tuple[int, int, int, int], np.ndarray]:
    """Robust swept footprint of segment a-b (integer ends): (box, bool mask over the box)."""
    r0, r1, c0, c1 = _box(a, b, footprint_radius, shape)
    centres = _cell_centres(r0, r1, c0, c1)
    dist = chebyshev_to_segment(centres, a, b)
    ends = np.minimum(np.abs(centres - a).max(axis=1), np.abs(centres - b).max(axis=1))
    mask = (dist <= footprint_radius - sample_step / 2 + 1e-9) | (ends <= footprint_radius + 1e-9)
    return (r0, r1, c0, c1), mask.reshape(r1 - r0, c1 - c0)


def _rect(a: np.ndarray, b: np.ndarray, radius: int, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Footprint of an axis-aligned segment between cell centres: a clipped rectangle."""
    return _box(a, b, radius, shape)


# --- the corrector ---------------------------------------------------------------------------

def correct_path(path: np.ndarray, obstacle: np.ndarray, targets: np.ndarray,
                 footprint_radius: int = FOOTPRINT_RADIUS, margin_cells: float = MARGIN_CELLS,
                 sample_step: float = SAMPLE_STEP, patience: int = PATIENCE,
                 keep: np.ndarray | None = None) -> CorrectedPath:
    """Correct one drone's cell path (T+1, 2) into waypoints; see the module docstring. `keep`: a bool grid
    of cells where a turn of the path stays a waypoint no shortcut skips."""
    cells = drop_hovers(np.asarray(path, dtype=np.int64))
    before = _stats(len(cells), cells)
    if len(cells) == 0:
        return CorrectedPath(np.zeros((0, 2)), before, _stats(0, cells))
    pts = merge_straight(cells).astype(float)
    shape = obstacle.shape
    # The first kept waypoint after each one: no shortcut reaches past it.
    is_anchor = np.zeros(len(pts), dtype=bool)
    if keep is not None:
        at = np.rint(pts).astype(np.int64)
        is_anchor = keep[at[:, 0], at[:, 1]]
    is_anchor[-1] = True
    next_anchor = np.minimum.accumulate(np.where(is_anchor, np.arange(len(pts)), len(pts))[::-1])[::-1]

    # Coverage count: how many polyline segments cover each cell (a lone point counts as one).
    count = np.zeros(shape, dtype=np.int32)
    if len(pts) == 1:
        r0, r1, c0, c1 = _rect(pts[0], pts[0], footprint_radius, shape)
        count[r0:r1, c0:c1] += 1
    for k in range(len(pts) - 1):
        r0, r1, c0, c1 = _rect(pts[k], pts[k + 1], footprint_radius, shape)
        count[r0:r1, c0:c1] += 1
    must_cover = targets & (count > 0)

    def turn_at(prev_dir: np.ndarray | None, u: np.ndarray, v: np.ndarray | None) -> float:
        total = 0.0
        if prev_dir is not None:
            total += _heading_change(prev_dir, u)
        if v is not None:
            total += _heading_change(u, v)
        return total

    def accept(out: list[np.ndarray], i: int, j: int) -> tuple[bool, tuple | None]:
        a, b = pts[i], pts[j]
        prev_dir = out[-1] - out[-2] if len(out) >= 2 else None
        next_dir = pts[j + 1] - pts[j] if j + 1 < len(pts) else None
        old_turn = turn_at(prev_dir, pts[i + 1] - pts[i], None) + total_turning(pts[i:j + 1])
        old_turn += 0.0 if next_dir is None else _heading_change(pts[j] - pts[j - 1], next_dir)
        if turn_at(prev_dir, b - a, next_dir) > old_turn + 1e-6:
            return False, None
        if not segment_clear(a, b, obstacle, margin_cells):
            return False, None
        # Coverage, on the box of the replaced part only.
        lo = pts[i:j + 1].min(axis=0)
        hi = pts[i:j + 1].max(axis=0)
        R0, R1, C0, C1 = _box(lo, hi, footprint_radius, shape)
        local = count[R0:R1, C0:C1].copy()
        for k in range(i, j):
            r0, r1, c0, c1 = _rect(pts[k], pts[k + 1], footprint_radius, shape)
            local[r0 - R0:r1 - R0, c0 - C0:c1 - C0] -= 1
        (r0, r1, c0, c1), mask = segment_footprint(a, b, shape, footprint_radius, sample_step)
        local[r0 - R0:r1 - R0, c0 - C0:c1 - C0] += mask
        if np.any(must_cover[R0:R1, C0:C1] & (local <= 0)):
            return False, None
        return True, ((R0, R1, C0, C1), local)

    out: list[np.ndarray] = [pts[0]]
    i = 0
    while i < len(pts) - 1:
        best_j, best_update = i + 1, None
        misses = 0
        for j in range(i + 2, int(next_anchor[i + 1]) + 1):
            ok, update = accept(out, i, j)
            if ok:
                best_j, best_update, misses = j, update, 0
            else:
                misses += 1
                if misses >= patience:
                    break
        if best_update is not None:
            (R0, R1, C0, C1), local = best_update
            count[R0:R1, C0:C1] = local
        out.append(pts[best_j])
        i = best_j

    waypoints = np.array(out)
    return CorrectedPath(waypoints, before, _stats(len(waypoints), waypoints))
