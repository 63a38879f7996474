"""What a flown fleet achieved: coverage from photo positions, closest approach, and the picture.

Pure functions over recorded tracks (no MAVLink here): fly.py records, this module judges.
- photo_positions: where photos were taken (the camera's reports, or every trigger_distance_m
  along the recorded survey track when the vehicle reports none);
- coverage: the share of the plan's reachable target cells whose centre lies within footprint_m/2
  (Chebyshev, grid-frame metres) of a photo position;
- min_separation: closest approach of any two drones, tracks interpolated onto one time base;
- draw_flight: flight.png (flown coverage over the grid, tracks, flight time per drone).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geo.frame import GridFrame


def frame_of(report: dict[str, Any]) -> GridFrame:
    grid = report["grid"]
    geo = {k: str(v) for k, v in report["georeference"].items()}
    return GridFrame.from_meta(geo, len(grid), len(grid[0]))


def target_cells(report: dict[str, Any]) -> np.ndarray:
    """(n, 2) int array of the plan's reachable target cells ('.' minus unreachable_cells)."""
    unreachable = {tuple(int(v) for v in cell) for cell in report.get("unreachable_cells") or []}
    cells = [(r, c) for r, row in enumerate(report["grid"]) for c, ch in enumerate(row)
             if ch == "." and (r, c) not in unreachable]
    return np.array(cells, dtype=np.int64).reshape(-1, 2)


def resample_polyline(points: np.ndarray, spacing: float) -> np.ndarray:
    """Points every `spacing` (same units as points) along a polyline, the first point included."""
    if len(points) == 0:
        return points.reshape(0, 2)
    if len(points) == 1 or spacing <= 0:
        return points.copy()
    seg = np.diff(points, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    if cum[-1] <= 0:
        return points[:1].copy()
    at = np.arange(0.0, cum[-1] + 1e-9, spacing)
    return np.column_stack([np.interp(at, cum, points[:, 0]), np.interp(at, cum, points[:, 1])])


def to_grid_m(frame: GridFrame, lat: Sequence[float], lon: Sequence[float]) -> np.ndarray:
    """lat/lon -> (n, 2) metres (row axis, col axis) in the grid frame (cell centres at integers * cell_m)."""
    if len(lat) == 0:
        return np.zeros((0, 2))
    r, c = frame.latlon_to_grid(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float))
    return np.column_stack([np.atleast_1d(r), np.atleast_1d(c)]) * frame.cell_m


def coverage(frame: GridFrame, targets: np.ndarray, photos_m: np.ndarray, footprint_m: float) -> np.ndarray:
    """Boolean per target cell: covered by some photo (Chebyshev distance <= footprint_m / 2)."""
    covered = np.zeros(len(targets), dtype=bool)
    if len(targets) == 0 or len(photos_m) == 0:
        return covered
    centres = targets.astype(float) * frame.cell_m
    half = footprint_m / 2.0 + 1e-9
    for start in range(0, len(photos_m), 2048):
        chunk = photos_m[start:start + 2048]
        d = np.maximum(np.abs(centres[:, None, 0] - chunk[None, :, 0]), np.abs(centres[:, None, 1] - chunk[None, :, 1]))
        covered |= (d <= half).any(axis=1)
    return covered


def min_separation(tracks: dict[int, np.ndarray], step_s: float = 0.05) -> dict[str, Any]:
    """Closest approach between any two drones. tracks[id] = (n, 4) array t, north_m, east_m, up_m
    (any common metric frame and one time base). Each pair is compared over the time both were recorded."""
    best_h = best_3d = float("inf")
    pair_h: list[int] = []
    pair_3d: list[int] = []
    ids = sorted(k for k, v in tracks.items() if len(v) >= 1)
    for i, a in enumerate(ids):
        for b in ids[i + 1:]:
            ta, tb = tracks[a], tracks[b]
            t0, t1 = max(ta[0, 0], tb[0, 0]), min(ta[-1, 0], tb[-1, 0])
            if t1 < t0:
                continue
            times = np.arange(t0, t1 + step_s, step_s)
            times = np.union1d(times, np.concatenate([ta[:, 0], tb[:, 0]]))
            times = times[(times >= t0) & (times <= t1)]
            pa = np.column_stack([np.interp(times, ta[:, 0], ta[:, k]) for k in (1, 2, 3)])
            pb = np.column_stack([np.interp(times, tb[:, 0], tb[:, k]) for k in (1, 2, 3)])
            d = pa - pb
            h = np.hypot(d[:, 0], d[:, 1])
            d3 = np.sqrt(h * h + d[:, 2] ** 2)
            if h.min() < best_h:
                best_h, pair_h = float(h.min()), [a, b]
            if d3.min() < best_3d:
                best_3d, pair_3d = float(d3.min()), [a, b]
    if not np.isfinite(best_h):
        return {"horizontal": None, "3d": None, "pair_horizontal": [], "pair_3d": []}
    return {"horizontal": round(best_h, 3), "3d": round(best_3d, 3), "pair_horizontal": pair_h, "pair_3d": pair_3d}


def draw_flight(path: Path, report: dict[str, Any], frame: GridFrame, targets: np.ndarray, covered: np.ndarray,
                tracks_m: dict[int, np.ndarray], flight_s: dict[int, float], coverage_pct: float) -> None:
    """flight.png: grid (obstacles, covered / missed targets), flown tracks, and flight time per drone."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = report["grid"]
    rows, cols = len(grid), len(grid[0])
    img = np.ones((rows, cols, 3))
    for r, row in enumerate(grid):
        for c, ch in enumerate(row):
            if ch == "#":
                img[r, c] = (0.25, 0.25, 0.25)
            elif ch == ".":
                img[r, c] = (0.85, 0.85, 0.85)  # target not in the reachable set
    for (r, c), ok in zip(targets, covered):
        img[r, c] = (0.62, 0.87, 0.62) if ok else (0.95, 0.45, 0.45)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [4, 1]})
    ax.imshow(img, interpolation="nearest", origin="upper")
    colours = plt.get_cmap("tab10")
    for k, (uid, pts) in enumerate(sorted(tracks_m.items())):
        if len(pts):
            g = pts / frame.cell_m
            ax.plot(g[:, 1], g[:, 0], "-", lw=1.2, color=colours(k % 10), label=f"uav{uid}")
            ax.plot(g[0, 1], g[0, 0], "o", ms=5, color=colours(k % 10))
    ax.set_xlim(-0.5, cols - 0.5)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_title(f"flown coverage {coverage_pct:.1f} % (green covered, red missed)")
    ax.legend(loc="upper right", fontsize=7)
    ids = sorted(flight_s)
    bx.bar([f"uav{i}" for i in ids], [flight_s[i] for i in ids], color=[colours(k % 10) for k in range(len(ids))])
    bx.set_ylabel("flight time (s)")
    bx.set_title("flight time")
    bx.tick_params(axis="x", labelrotation=45, labelsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
