"""How far each drone's track stays from obstacles, horizontally, in metres: report.json `clearance`.

The track is the polyline the drone flies (launch point, then its waypoints in every sortie); the
obstacles are the grid's obstacle cells as squares, so the figure is a lower bound of the distance
to the buildings themselves (a cell is an obstacle when it touches one). The corrector keeps
--clearance on every shortcut it takes; the grid planner's own moves keep half a cell (cell centres
next to an obstacle cell), so a clearance above half a cell is measured and reported, and a track
under it is named with its place (docs/field-safety.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np


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
