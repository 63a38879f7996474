"""`GridFrame`: where a planning grid lies on the Earth.

The grid is laid in the UTM zone of the area (a metric, conformal projection, via pyproj),
north-up or rotated. Conventions, used everywhere in `geo`:

* Row 0 is the top row; before rotation rows grow southwards and columns eastwards.
* The origin (`origin_e`, `origin_n`, UTM metres) is the top-left CORNER of cell (0, 0).
* Grid coordinates are floats (row, col) whose INTEGER values are cell CENTRES: cell (i, j)
  is the square row in [i-0.5, i+0.5), col in [j-0.5, j+0.5). `latlon_to_cell` rounds.
* `rotation_deg` turns the grid clockwise (seen from above) about the origin corner: the
  grid's "up" (towards row -1) points at compass bearing `rotation_deg`, the column axis
  (towards increasing col) at bearing `rotation_deg + 90`.
* The UTM zone is the standard 6-degree zone of the area centroid (no Norway/Svalbard
  exceptions); EPSG 326zz north of the equator, 327zz south.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import shapely
from pyproj import Proj, Transformer

from .errors import GeoError

ArrayLike = float | np.ndarray  # scalars or arrays of grid / lat-lon coordinates

def utm_epsg_for(lon: float, lat: float) -> int:
    """EPSG code of the standard UTM zone holding (lon, lat)."""
    if not (math.isfinite(lon) and math.isfinite(lat)) or not -180 <= lon <= 180 or not -90 <= lat <= 90:
        raise GeoError(f"position lat {lat!r}, lon {lon!r} is not a valid WGS84 position")
    if abs(lat) > 84:
        raise GeoError(f"position lat {lat!r} is outside the UTM range (80S..84N)")
    zone = min(int((lon + 180.0) // 6.0) + 1, 60)
    return (32600 if lat >= 0 else 32700) + zone


@lru_cache(maxsize=16)
def _transformers(epsg: int) -> tuple[Transformer, Transformer]:
    # always_xy: (lon, lat) and (easting, northing) order, whatever the CRS axis order says.
    fwd = Transformer.from_crs(4326, epsg, always_xy=True)
    inv = Transformer.from_crs(epsg, 4326, always_xy=True)
    return fwd, inv


def header_float(meta: Mapping[str, str], key: str) -> float:
    """The number under `key` of a map header (GeoError naming the key when it is missing, not a number or
    not finite)."""
    try:
        v = float(meta[key])
    except KeyError:
        raise GeoError(f"map georeference: key {key!r} is missing") from None
    except ValueError:
        raise GeoError(f"map georeference: {key} {meta[key]!r} is not a number") from None
    if not math.isfinite(v):
        raise GeoError(f"map georeference: {key} {meta[key]!r} is not finite")
    return v


@dataclass(frozen=True)
class GridFrame:
    """A rows x cols grid of square `cell_m` cells laid in UTM zone `utm_epsg`."""

    utm_epsg: int
    origin_e: float
    origin_n: float
    cell_m: float
    rows: int
    cols: int
    rotation_deg: float = 0.0
    # UTM metres per metre on the ground at the grid origin (the projection's point scale
    # factor, 0.9996 on the zone's central meridian, up to ~1.001 at its edges). Cells are
    # ground metres, so without it a 100 m offset would be off by up to 10 cm. Over the few
    # kilometres of an area the factor varies by less than 1e-5: one value per frame is enough.
    scale: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise GeoError(f"grid cell size {self.cell_m!r} m must be positive")
        if self.rows < 1 or self.cols < 1:
            raise GeoError(f"grid size {self.rows}x{self.cols} must be at least 1x1")
        if not self.scale:
            lon, lat = _transformers(self.utm_epsg)[1].transform(self.origin_e, self.origin_n)
            factors = Proj(f"EPSG:{self.utm_epsg}").get_factors(lon, lat)
            object.__setattr__(self, "scale", float(factors.meridional_scale))

    # ---- constructors -------------------------------------------------------------
    @classmethod
    def at(cls, origin_lat: float, origin_lon: float, cell_m: float, rows: int, cols: int,
           rotation_deg: float = 0.0) -> "GridFrame":
        """A frame whose top-left grid corner is at (origin_lat, origin_lon); UTM zone of that corner."""
        epsg = utm_epsg_for(float(origin_lon), float(origin_lat))
        e, n = _transformers(epsg)[0].transform(float(origin_lon), float(origin_lat))
        return cls(epsg, float(e), float(n), float(cell_m), int(rows), int(cols), float(rotation_deg))

    @classmethod
    def from_area(cls, polygon_lonlat: shapely.Geometry, cell_m: float, rotation_deg: float = 0.0,
                  margin_cells: int = 0) -> "GridFrame":
        """The smallest grid (plus `margin_cells` on every side) covering the polygon's bounding
        box in the rotated frame; UTM zone of the polygon centroid."""
        if polygon_lonlat is None or polygon_lonlat.is_empty:
            raise GeoError("the area is empty")
        cell_m = float(cell_m)
        if not (math.isfinite(cell_m) and cell_m > 0):
            raise GeoError(f"grid cell size {cell_m!r} m must be positive")
        c = polygon_lonlat.centroid
        epsg = utm_epsg_for(c.x, c.y)
        projected = shapely.transform(polygon_lonlat, _lonlat_to_en(epsg), interleaved=False)
        # Local axes through the area's centroid: x along the columns, y along the rows (down).
        ce, cn = _transformers(epsg)[0].transform(c.x, c.y)
        probe = cls(epsg, float(ce), float(cn), cell_m, 1, 1, float(rotation_deg))
        xy = shapely.get_coordinates(projected)
        x, y = probe._en_to_xy(xy[:, 0], xy[:, 1])
        m = margin_cells * cell_m
        x0, y0 = float(x.min()) - m, float(y.min()) - m
        # 1e-3 cell: the scale factor drifts by ~1e-6 across an area, which must not add a row.
        cols = max(1, math.ceil((float(x.max()) + m - x0) / cell_m - 1e-3))
        rows = max(1, math.ceil((float(y.max()) + m - y0) / cell_m - 1e-3))
        e0, n0 = probe._xy_to_en(np.float64(x0), np.float64(y0))
        return cls(epsg, float(e0), float(n0), cell_m, rows, cols, float(rotation_deg), scale=probe.scale)

    # ---- metadata -----------------------------------------------------------------
    def to_meta(self) -> dict[str, str]:
        """String keys for `GridMap.meta` (repr keeps floats exact through a .map file)."""
        lat, lon = self.corner_latlon()
        return {
            "utm_epsg": str(self.utm_epsg),
            "origin_e": repr(float(self.origin_e)),
            "origin_n": repr(float(self.origin_n)),
            "cell_m": repr(float(self.cell_m)),
            "rotation_deg": repr(float(self.rotation_deg)),
            "grid_rows": str(self.rows),
            "grid_cols": str(self.cols),
            "origin_lat": f"{lat:.9f}",
            "origin_lon": f"{lon:.9f}",
        }

    @classmethod
    def from_meta(cls, meta: Mapping[str, str], rows: int | None = None, cols: int | None = None) -> "GridFrame":
        """Inverse of `to_meta`. `rows`/`cols` (e.g. the GridMap shape) override grid_rows/grid_cols.
        A hand-written map may give only origin_lat/origin_lon (+ cell_m, rotation_deg)."""
        try:
            r = int(rows if rows is not None else meta["grid_rows"])
            c = int(cols if cols is not None else meta["grid_cols"])
        except KeyError as err:
            raise GeoError(f"map georeference: key {err.args[0]!r} is missing (or pass the grid shape)") from None
        except ValueError:
            raise GeoError("map georeference: grid_rows/grid_cols are not integers") from None
        cell = header_float(meta, "cell_m")
        rot = header_float(meta, "rotation_deg") if "rotation_deg" in meta else 0.0
        if "utm_epsg" in meta:
            try:
                epsg = int(meta["utm_epsg"])
            except ValueError:
                raise GeoError(f"map georeference: utm_epsg {meta['utm_epsg']!r} is not an EPSG code") from None
            return cls(epsg, header_float(meta, "origin_e"), header_float(meta, "origin_n"), cell, r, c, rot)
        return cls.at(header_float(meta, "origin_lat"), header_float(meta, "origin_lon"), cell, r, c, rot)

    # ---- local metric <-> UTM -------------------------------------------------------
    def _axes(self) -> tuple[float, float]:
        t = math.radians(self.rotation_deg)
        return math.cos(t), math.sin(t)

    def _xy_to_en(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # x: metres along the column axis (bearing rot+90); y: metres down the rows (bearing rot+180).
        cos_t, sin_t = self._axes()
        x, y = x * self.scale, y * self.scale
        return self.origin_e + x * cos_t - y * sin_t, self.origin_n - x * sin_t - y * cos_t

    def _en_to_xy(self, e: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cos_t, sin_t = self._axes()
        de, dn = (e - self.origin_e) / self.scale, (n - self.origin_n) / self.scale
        return de * cos_t - dn * sin_t, -de * sin_t - dn * cos_t

    # ---- grid <-> UTM / lat-lon -------------------------------------------------------
    def grid_to_en(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Float grid coordinates (integers = cell centres) -> UTM easting, northing."""
        r = np.asarray(rows, dtype=float)
        c = np.asarray(cols, dtype=float)
        return self._xy_to_en((c + 0.5) * self.cell_m, (r + 0.5) * self.cell_m)

    def en_to_grid(self, e: ArrayLike, n: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """UTM easting, northing -> float grid (row, col)."""
        x, y = self._en_to_xy(np.asarray(e, dtype=float), np.asarray(n, dtype=float))
        return y / self.cell_m - 0.5, x / self.cell_m - 0.5

    def grid_to_latlon(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Float grid (row, col), integer values = cell centres -> (lat, lon) degrees. Vectorised."""
        e, n = self.grid_to_en(rows, cols)
        lon, lat = _transformers(self.utm_epsg)[1].transform(e, n)
        return np.asarray(lat), np.asarray(lon)

    def latlon_to_grid(self, lat: ArrayLike, lon: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(lat, lon) degrees -> float grid (row, col); inverse of `grid_to_latlon`."""
        e, n = _transformers(self.utm_epsg)[0].transform(np.asarray(lon, dtype=float), np.asarray(lat, dtype=float))
        return self.en_to_grid(e, n)

    def cell_to_latlon(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Integer cell (row, col) -> (lat, lon) of the cell CENTRE."""
        return self.grid_to_latlon(rows, cols)

    def latlon_to_cell(self, lat: ArrayLike, lon: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(lat, lon) -> integer (row, col) of the cell containing the point (may be outside the grid)."""
        r, c = self.latlon_to_grid(lat, lon)
        # floor(x + 0.5): cell (i, j) spans [i-0.5, i+0.5).
        return np.floor(r + 0.5).astype(np.int64), np.floor(c + 0.5).astype(np.int64)

    def corner_latlon(self) -> tuple[float, float]:
        """(lat, lon) of the grid origin, the top-left corner of cell (0, 0)."""
        lat, lon = self.grid_to_latlon(-0.5, -0.5)
        return float(lat), float(lon)

    def latlon_box(self) -> tuple[float, float, float, float]:
        """(min_lat, min_lon, max_lat, max_lon) of the grid's four outer corners (it may be rotated)."""
        lat, lon = self.grid_to_latlon(np.array([-0.5, -0.5, self.rows - 0.5, self.rows - 0.5]),
                                       np.array([-0.5, self.cols - 0.5, -0.5, self.cols - 0.5]))
        return float(lat.min()), float(lon.min()), float(lat.max()), float(lon.max())

    def contains_cell(self, row: int, col: int) -> bool:
        return 0 <= row < self.rows and 0 <= col < self.cols

    def geometry_to_grid(self, geom_lonlat: shapely.Geometry) -> shapely.Geometry:
        """A lon/lat geometry in grid coordinates: x = col, y = row (integers = cell centres).

        Rasterising in these units makes cell (i, j) the box [j-0.5, j+0.5] x [i-0.5, i+0.5].
        """
        fwd = _transformers(self.utm_epsg)[0]

        def to_grid(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            e, n = fwd.transform(lon, lat)
            r, c = self.en_to_grid(e, n)
            return c, r

        return shapely.transform(geom_lonlat, to_grid, interleaved=False)


def _lonlat_to_en(epsg: int):  # a shapely.transform callback into UTM metres
    fwd = _transformers(epsg)[0]

    def f(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return fwd.transform(lon, lat)

    return f
