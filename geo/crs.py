"""The coordinate reference system a file is in, and its shapes brought to WGS84 lon/lat (pyproj).

A Shapefile in UTM, a GeoPackage in Web Mercator (EPSG:3857), a GeoJSON with a 2008 `crs` member:
each is reprojected with pyproj, in traditional GIS order (x = easting / longitude first:
`always_xy`), before any check of its coordinates. WGS84 lon/lat (EPSG:4326, OGC:CRS84) is taken
as it is. The report names the CRS a file was in (`crs_label`).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import pyproj
import shapely

from .errors import GeoError

_WGS84 = pyproj.CRS.from_epsg(4326)


def source_crs(user_input: str, where: str) -> pyproj.CRS | None:
    """The CRS `user_input` names (EPSG code, URN, WKT), or None when it is WGS84 lon/lat already."""
    try:
        crs = pyproj.CRS.from_user_input(user_input)
    except pyproj.exceptions.CRSError as err:
        raise GeoError(f"{where}: unknown coordinate reference system {str(user_input)[:80]!r} "
                       f"({str(err).splitlines()[0]})") from None
    if crs.equals(_WGS84, ignore_axis_order=True):
        return None
    if not (crs.is_geographic or crs.is_projected):
        raise GeoError(f"{where}: coordinate reference system {crs_label(crs)} is neither geographic nor projected")
    return crs


def crs_label(crs: pyproj.CRS) -> str:
    """'EPSG:32632 (WGS 84 / UTM zone 32N)', or the CRS's name when it has no EPSG code."""
    epsg = crs.to_epsg()
    return f"EPSG:{epsg} ({crs.name})" if epsg else crs.name


@lru_cache(maxsize=16)
def _transformer(crs_wkt: str) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs(pyproj.CRS.from_wkt(crs_wkt), _WGS84, always_xy=True)


def to_lonlat(geoms: Sequence[shapely.Geometry | None], crs: pyproj.CRS, where: str) -> list[shapely.Geometry | None]:
    """`geoms` (in `crs`, x first) in WGS84 lon/lat; GeoError when a coordinate falls outside the
    CRS's domain (pyproj gives infinity there)."""
    transformer = _transformer(crs.to_wkt())

    def transform(xy: np.ndarray) -> np.ndarray:
        lon, lat = transformer.transform(xy[:, 0], xy[:, 1], errcheck=False)
        return np.column_stack([lon, lat])

    arr = np.asarray(geoms, dtype=object)
    before = np.isfinite(shapely.get_coordinates(arr)).all(axis=1)
    out = shapely.transform(arr, transform)
    after = np.isfinite(shapely.get_coordinates(out)).all(axis=1)
    if (before & ~after).any():
        x, y = shapely.get_coordinates(arr)[before & ~after][0]
        raise GeoError(f"{where}: coordinate ({x}, {y}) has no place in WGS84 lon/lat: it lies outside where "
                       f"{crs_label(crs)} is defined (a wrong .prj or CRS?)")
    return list(out)
