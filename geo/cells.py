"""Grid cells back on the Earth: a set of cells as polygons in longitude / latitude.

What a crew carries away is an area, not grid indices: the cells no photo covered become one or more
polygons (neighbouring cells merged, holes kept), each vertex a cell corner put through the grid's
frame (GridFrame.grid_to_latlon), with RFC 7946's ring order (exteriors counter-clockwise, holes
clockwise) so that GeoJSON readers and QGIS agree on inside and outside.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from .frame import GridFrame


def cells_polygons(frame: GridFrame, cells: np.ndarray) -> list[Polygon]:
    """The (n, 2) [row, col] cells as merged polygons in (lon, lat) degrees."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if not len(cells):
        return []
    rows, cols = cells[:, 0], cells[:, 1]
    squares = shapely.box(cols - 0.5, rows - 0.5, cols + 0.5, rows + 0.5)  # x: column, y: row; all at once
    merged = shapely.unary_union(squares)
    parts = list(merged.geoms) if isinstance(merged, MultiPolygon) else [merged]

    def to_lonlat(xy: np.ndarray) -> np.ndarray:
        lat, lon = frame.grid_to_latlon(xy[:, 1], xy[:, 0])
        return np.column_stack([lon, lat])

    return [orient(shapely.transform(part, to_lonlat), sign=1.0) for part in parts]


def cells_feature(frame: GridFrame, cells: np.ndarray, properties: dict[str, Any]) -> dict[str, Any]:
    """A GeoJSON Feature: the cells as one MultiPolygon (None geometry when there are none)."""
    polygons = cells_polygons(frame, cells)
    geometry = shapely.geometry.mapping(MultiPolygon(polygons)) if polygons else None
    return {"type": "Feature", "properties": properties, "geometry": geometry}
