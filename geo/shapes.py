"""The checks every polygon read from a file passes, whatever its format.

All geometries are shapely Polygons / MultiPolygons in (lon, lat) WGS84 order. A polygon must be
non-empty, finite, in range (longitude in [-180, 180], latitude in [-90, 90]), not spanning more
than 180 degrees of longitude (that is a shape across the antimeridian, which one UTM grid cannot
hold) and valid. A self-intersecting polygon (a bowtie) is an error, as the drawing is ambiguous;
digitising slips that make_valid fixes without changing the area (rings touching themselves,
slivers; common in GIS exports) are repaired, and the repair is reported so the caller can name it.

`check_polygons` runs the same checks over a whole array at once (vectorised in shapely), and
falls back to the one-by-one check only for the first feature that fails and for those to repair,
so a city of footprints costs little more than reading it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import shapely
from shapely.errors import GEOSException
from shapely.geometry import MultiPolygon, Polygon
from shapely.validation import explain_validity

from .errors import GeoError

Polygonal = Polygon | MultiPolygon

REPAIR_AREA_TOLERANCE = 1e-6  # relative area change below which an invalid polygon is just repaired
MAX_LON_SPAN_DEG = 180.0  # wider than this is the long way round: a shape across the antimeridian
_POLYGONAL_TYPE_IDS = (3, 6)  # shapely's type ids of Polygon and MultiPolygon


def check_lonlat(geom: shapely.Geometry, where: str) -> None:
    """Every coordinate a finite WGS84 lon/lat, and the shape not across the antimeridian.

    NaN and infinity slip through JSON (Python reads `NaN`, `Infinity`) and KML (`float('nan')`);
    a NaN compares false with everything, so it must be refused before any geometry test.
    """
    coords = shapely.get_coordinates(geom)
    if not len(coords):
        return
    finite = np.isfinite(coords).all(axis=1)
    if not finite.all():
        lon, lat = coords[~finite][0]
        raise GeoError(f"{where}: coordinate (lon {lon}, lat {lat}) is not a finite number")
    bad = (np.abs(coords[:, 0]) > 180) | (np.abs(coords[:, 1]) > 90)
    if bad.any():
        lon, lat = coords[bad][0]
        raise GeoError(f"{where}: coordinate (lon {lon}, lat {lat}) is out of range: not WGS84 lon/lat degrees "
                       f"(longitude in [-180, 180], latitude in [-90, 90], GeoJSON and KML put longitude first)")
    span = coords[:, 0].max() - coords[:, 0].min()
    if span > MAX_LON_SPAN_DEG:
        # A ring drawn across ±180° reads as going the long way round the globe; a grid laid
        # in one UTM zone cannot hold it either way.
        raise GeoError(f"{where}: the shape spans {span:.1f}° of longitude, so it crosses the antimeridian "
                       f"(±180°) or is far too large: areas across the antimeridian are not supported")


def checked_polygon(geom: shapely.Geometry | None, where: str) -> tuple[Polygonal, str | None]:
    """`geom` checked (see the module docstring), and why it was repaired (None: it was valid).

    GeoError naming `where` for an empty, non-polygonal, out-of-range, self-intersecting or
    zero-area shape.
    """
    if geom is None or geom.is_empty:
        raise GeoError(f"{where}: the polygon is empty")
    if not isinstance(geom, (Polygon, MultiPolygon)):
        raise GeoError(f"{where}: not a polygon ({geom.geom_type})")
    check_lonlat(geom, where)
    if not geom.is_valid:
        why = explain_validity(geom)
        fixed = repair_slip(geom)
        if fixed is not None:
            return fixed, why
        if polygonal_part(shapely.make_valid(geom)).area == 0:
            raise GeoError(f"{where}: the polygon has zero area (its points lie on a line)")
        if "self-intersection" in why.lower():
            raise GeoError(f"{where}: self-intersecting polygon ({why})")
        raise GeoError(f"{where}: invalid polygon ({why})")
    if geom.area == 0:
        raise GeoError(f"{where}: the polygon has zero area")
    return geom, None


def validate_polygon(geom: shapely.Geometry | None, where: str) -> Polygonal:
    """`checked_polygon` without the repair note."""
    return checked_polygon(geom, where)[0]


def check_polygons(geoms: Sequence[shapely.Geometry | None], where: Callable[[int], str]
                   ) -> tuple[list[Polygonal], dict[int, str]]:
    """Every geometry of `geoms` through `checked_polygon`, vectorised: the checked polygons and
    {index: why} of those repaired. `where(i)` names geometry i in the error of the first that fails."""
    arr = np.asarray(geoms, dtype=object)
    if not len(arr):
        return [], {}
    missing = np.array([g is None for g in arr], dtype=bool)
    present = np.where(missing, Polygon(), arr)
    problem = missing | shapely.is_empty(present) | ~np.isin(shapely.get_type_id(present), _POLYGONAL_TYPE_IDS)
    coords, owner = shapely.get_coordinates(present, return_index=True)
    if len(coords):
        bad = ~np.isfinite(coords).all(axis=1) | (np.abs(coords[:, 0]) > 180) | (np.abs(coords[:, 1]) > 90)
        problem[owner[bad]] = True
    with np.errstate(invalid="ignore"):
        bounds = shapely.bounds(present)
        problem |= (bounds[:, 2] - bounds[:, 0]) > MAX_LON_SPAN_DEG
    ok = ~problem
    valid = np.zeros(len(arr), dtype=bool)
    valid[ok] = shapely.is_valid(present[ok])
    zero = np.zeros(len(arr), dtype=bool)
    zero[ok & valid] = shapely.area(present[ok & valid]) == 0
    problem |= zero
    first_error = int(np.argmax(problem)) if problem.any() else len(arr)
    out: list[Polygonal] = list(present)
    repaired: dict[int, str] = {}
    # Invalid ones before the first plain error are repaired (or are that error themselves), in order.
    for i in np.flatnonzero(ok & ~valid):
        if i > first_error:
            break
        out[i], why = checked_polygon(arr[i], where(int(i)))
        if why is not None:
            repaired[int(i)] = why
    if first_error < len(arr):
        checked_polygon(arr[first_error], where(first_error))  # raises its own message
        raise GeoError(f"{where(first_error)}: invalid polygon")  # (not reached: every flagged case raises)
    return out, repaired


def polygonal_part(geom: shapely.Geometry) -> Polygonal:
    """The polygons of a geometry (make_valid may return lines and points beside them), as one shape."""
    parts = [g for g in getattr(geom, "geoms", [geom]) if isinstance(g, (Polygon, MultiPolygon))]
    return shapely.union_all(parts) if parts else Polygon()


def repair_slip(geom: Polygonal) -> Polygonal | None:
    """The repaired polygon when the invalidity is a digitising slip, else None.

    GIS exports often carry rings that touch themselves or tiny slivers; make_valid fixes
    those without changing the area. A real self-crossing (a bowtie) changes the area
    a lot (its signed halves cancel), so the drawing is ambiguous and stays an error.
    """
    fixed = polygonal_part(shapely.make_valid(geom))
    if fixed.is_empty or geom.area <= 0:
        return None
    if abs(fixed.area - geom.area) > REPAIR_AREA_TOLERANCE * geom.area:
        return None
    return fixed


def union(parts: list[shapely.Geometry], where: str) -> shapely.Geometry:
    """The union of polygons; GEOS refuses some invalid inputs outright (a topology error)."""
    try:
        return shapely.union_all(parts)
    except GEOSException as err:
        raise GeoError(f"{where}: invalid polygons ({str(err).splitlines()[0]})") from None
