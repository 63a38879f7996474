"""Rasterise a real-world area into an `AreaRaster` (SPEC section 7): the planner wraps it into its GridMap.

Rules (cell = camera footprint / 9, grid laid by `GridFrame.from_area`):

* A cell is inside the area when its CENTRE is inside the area polygon. Cells outside are
  obstacles: the drones stay inside the surveyed area.
* A cell that TOUCHES (its square shares interior with) an obstacle polygon, a no-fly
  polygon, or a building that is too tall or of unknown height is an obstacle - any overlap
  would put a drone's footprint centre over something it must not hit.
* A building with known height < altitude - safety margin is overflown: cells whose centre
  is on its roof are free but not targets ('o'); the roofs need no photo, the streets do.
* Every other inside cell is a target ('.').

With roof targets (`targets` roofs or all: geo/roofs.py) the overflown roofs' cells are targets too, in the
raster's `roof` layer, the street cells stay targets only with all, and the cell is the footprint at the
highest of those roofs / 9 (geo.roofs.roof_cell_m), so a photo's 9 cells hold on every roof.

Rasterising works in grid units (x = col, y = row, integers = cell centres) with shapely 2
vectorised predicates, each polygon only over the window of cells under its bounding box.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from missionplan.base.naming import Named

from .camera import Camera, cell_size_m
from .errors import GeoError
from .frame import GridFrame
from .georeference import Georeference
from .roofs import DEFAULT_TARGETS, photographs_roofs, photographs_streets, roof_cell_m
from .sources import Building

Polygonal = Polygon | MultiPolygon


@dataclass
class AreaRaster:
    """The rasterised area: boolean (rows, cols) `obstacle` and `target`, launch cells, its georeference.

    Plain arrays, so geo needs nothing from the planner; missionplan makes its GridMap from these fields.
    """

    name: str
    obstacle: np.ndarray
    target: np.ndarray
    launch: list[tuple[int, int]]
    georef: Georeference
    roof: np.ndarray | None = None  # the target cells that are roofs (None: roofs are no targets)
    highest_roof_m: float | None = None  # the highest roof target, which sized the cell (None: no roof targets)

    @property
    def shape(self) -> tuple[int, int]:
        return self.obstacle.shape  # type: ignore[return-value]


def _window(geom: shapely.Geometry, rows: int, cols: int) -> tuple[int, int, int, int] | None:
    """Row/col index range [r0, r1) x [c0, c1) of cells that may touch geom's bounding box."""
    minx, miny, maxx, maxy = geom.bounds
    r0, r1 = max(0, math.ceil(miny - 0.5)), min(rows, math.floor(maxy + 0.5) + 1)
    c0, c1 = max(0, math.ceil(minx - 0.5)), min(cols, math.floor(maxx + 0.5) + 1)
    if r0 >= r1 or c0 >= c1:
        return None
    return r0, r1, c0, c1


def _windowed(geoms_grid: Iterable[shapely.Geometry], rows: int,
              cols: int) -> Iterator[tuple[shapely.Geometry, slice, slice, np.ndarray, np.ndarray]]:
    """Each non-empty geometry (prepared) with the cell window of its bounding box: slices and cell centres."""
    for geom in geoms_grid:
        if geom is None or geom.is_empty:
            continue
        win = _window(geom, rows, cols)
        if win is None:
            continue
        r0, r1, c0, c1 = win
        rr, cc = np.mgrid[r0:r1, c0:c1]
        shapely.prepare(geom)
        yield geom, slice(r0, r1), slice(c0, c1), rr, cc


def cells_touching(geoms_grid: Iterable[shapely.Geometry], rows: int, cols: int) -> np.ndarray:
    """(rows, cols) mask of cells whose square shares interior with any of the geometries.

    Interior overlap rather than plain `intersects`: a polygon edge lying exactly on a cell
    border must not claim the neighbouring cell too.
    """
    mask = np.zeros((rows, cols), dtype=bool)
    for geom, row_slice, col_slice, rr, cc in _windowed(geoms_grid, rows, cols):
        boxes = shapely.box(cc - 0.5, rr - 0.5, cc + 0.5, rr + 0.5)
        hit = shapely.intersects(geom, boxes)
        if hit.any():
            hit[hit] &= ~shapely.touches(geom, boxes[hit])
        mask[row_slice, col_slice] |= hit
    return mask


def cells_centred_in(geoms_grid: Iterable[shapely.Geometry], rows: int, cols: int) -> np.ndarray:
    """(rows, cols) mask of cells whose centre lies inside (or on the edge of) any geometry."""
    mask = np.zeros((rows, cols), dtype=bool)
    for geom, row_slice, col_slice, rr, cc in _windowed(geoms_grid, rows, cols):
        mask[row_slice, col_slice] |= shapely.intersects_xy(geom, cc, rr)
    return mask


def _as_building(b: Building | shapely.Geometry) -> Building:
    return b if isinstance(b, Building) else Building(b, None, {})


def build_grid_map(name: str, area: Polygonal | Sequence[Polygonal], obstacles: Sequence[Polygonal],
                   buildings: Sequence[Building], no_fly: Sequence[Polygonal],
                   launch_latlon: Sequence[tuple[float, float]], altitude_m: float, fov_deg: float,
                   rotation_deg: float = 0.0, safety_margin_m: float = 5.0,
                   max_cells: int = 4_200_000, area_file: str = "area",
                   targets: str = DEFAULT_TARGETS) -> tuple[AreaRaster, GridFrame]:
    """Rasterise `area` (lon/lat) into an AreaRaster whose cell is the camera footprint / 9.

    `area` may be a list of polygons (their union). `buildings` may also hold bare polygons
    (height unknown -> obstacle). `area_file` names
    the area in error messages. `targets`: which cells are photographed (geo/roofs.py); with roofs, the
    cell is the footprint at the highest roof / 9. Returns the raster (with its georeference) and frame.
    """
    if isinstance(area, (list, tuple)):  # e.g. straight from read_polygons: one area of several parts
        area = shapely.union_all(list(area)) if area else Polygon()
    if area is None or area.is_empty or area.area == 0:
        raise GeoError(f"{area_file}: the area is empty")
    if not isinstance(area, (Polygon, MultiPolygon)):
        raise GeoError(f"{area_file}: the area is not a polygon ({area.geom_type})")
    blds = [_as_building(b) for b in buildings]
    ceiling = float(altitude_m) - float(safety_margin_m)
    # Unknown height counts as tall: better to route round a low shed than into a tower.
    tall = [b.geometry for b in blds if b.height_m is None or b.height_m >= ceiling]
    low = [b for b in blds if b.height_m is not None and b.height_m < ceiling]
    highest_roof = None
    if photographs_roofs(targets):
        in_area = [b.height_m for b in low if b.height_m is not None and b.geometry.intersects(area)]
        highest_roof = max(in_area, default=0.0)

    def cell_at(altitude: float) -> float:
        """The cell flown at `altitude`: at the highest roof target when roofs are photographed."""
        if highest_roof is None:
            return cell_size_m(altitude, fov_deg)
        return roof_cell_m(altitude, fov_deg, highest_roof)

    cell = cell_at(altitude_m)
    frame = GridFrame.from_area(area, cell, rotation_deg=rotation_deg)
    n_cells = frame.rows * frame.cols
    if n_cells > max_cells:
        # Cells grow with the altitude, so the count falls with its square; step up until it fits.
        fits = altitude_m * (n_cells / max_cells) ** 0.5
        for _ in range(50):
            bigger = GridFrame.from_area(area, cell_at(fits), rotation_deg=rotation_deg)
            if bigger.rows * bigger.cols <= max_cells:
                break
            fits *= 1.01
        raise GeoError(f"{area_file}: the grid would be {frame.rows}x{frame.cols} = {n_cells:,} cells of "
                       f"{cell:.2f} m (limit {max_cells:,}); fly higher, at {math.ceil(fits)} m or more "
                       f"(larger cells), or split the area")
    rows, cols = frame.rows, frame.cols
    to_grid = frame.geometry_to_grid

    inside = cells_centred_in([to_grid(area)], rows, cols)
    if not inside.any():
        raise GeoError(f"{area_file}: the area is smaller than one {cell:.2f} m grid cell; fly lower")

    blocked = cells_touching((to_grid(g) for g in [*obstacles, *no_fly, *tall]), rows, cols)
    roofs = cells_centred_in((to_grid(b.geometry) for b in low), rows, cols)
    obstacle = ~inside | blocked
    streets = inside & ~obstacle & ~roofs
    roof_targets = inside & ~obstacle & roofs if highest_roof is not None else None
    target = streets if photographs_streets(targets) else np.zeros_like(streets)
    if roof_targets is not None:
        target = target | roof_targets

    launch = _launch_cells(frame, area, obstacles, no_fly, blds, obstacle, launch_latlon, area_file)

    georef = Georeference(frame, float(altitude_m), Camera(fov_deg), float(safety_margin_m))
    return AreaRaster(name=name, obstacle=obstacle, target=target, launch=launch, georef=georef, roof=roof_targets,
                      highest_roof_m=highest_roof), frame


def _launch_cells(frame: GridFrame, area: Polygonal, obstacles: Sequence[Polygonal],
                  no_fly: Sequence[Polygonal], buildings: Sequence[Building], obstacle: np.ndarray,
                  launch_latlon: Sequence[tuple[float, float]], area_file: str) -> list[tuple[int, int]]:
    cells: list[tuple[int, int]] = []
    for lat, lon in launch_latlon:
        given = f"{lat},{lon}"  # the launch point as given, named with the `launch` setting
        try:
            lat, lon = float(lat), float(lon)
        except (TypeError, ValueError):
            raise GeoError(Named("{launch} {0}: not a LAT,LON position", given)) from None
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise GeoError(Named("{launch} {0}: not a valid LAT,LON position (latitude first)", given))
        if not shapely.intersects_xy(area, lon, lat):
            raise GeoError(Named("{launch} {0} is outside the area {1}", given, area_file))
        for kind, geoms in (("a no-fly zone", no_fly), ("an obstacle", obstacles),
                            ("a building", [b.geometry for b in buildings])):
            if any(shapely.intersects_xy(g, lon, lat) for g in geoms):
                raise GeoError(Named("{launch} {0} is inside {1}", given, kind))
        r, c = (int(v) for v in frame.latlon_to_cell(lat, lon))
        if not frame.contains_cell(r, c) or obstacle[r, c]:
            raise GeoError(Named("{launch} {0} falls in grid cell ({1},{2}), which is an obstacle (it touches a "
                                 "building, obstacle or no-fly zone, or lies on the area edge)", given, r, c))
        cells.append((r, c))
    return cells
