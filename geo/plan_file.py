"""A QGroundControl `.plan` read as an area: its survey polygons and geofences.

The area is the polygon of a survey / StructureScan item (a CorridorScan polyline is widened by its
CorridorWidth), else the geofence inclusion polygons; geofence exclusion polygons are the no-fly
polygons. Polygons are [lat, lon] vertex lists, the first point not repeated (repeating it is accepted
too), at least 3 points. Each fault is named by mission item or geofence polygon index and cause.
(Uploading a .plan as a mission is the bridge's reader, bridge/formats/missionfile.py.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import Polygon

from .errors import GeoError
from .geojson_file import check_positions, is_number, kind, load_json
from .shapes import check_lonlat, checked_polygon
from .sources import Feature


@dataclass
class PlanPolygons:
    """The polygons of a .plan: survey items, geofence inclusions, geofence exclusions."""

    survey: list[Feature] = field(default_factory=list)
    inclusion: list[Feature] = field(default_factory=list)
    exclusion: list[Feature] = field(default_factory=list)


def _latlon_points(points: Any, where: str, what: str) -> list[tuple[float, float]]:
    """.plan [lat, lon] (or [lat, lon, alt]) number lists -> (lon, lat) tuples, all finite."""
    check_positions(points, f"{where}: {what} points are not [lat, lon] number pairs", f"{where}: {what} point")
    return [(float(p[1]), float(p[0])) for p in points]  # .plan stores [lat, lon]


def _latlon_ring(points: Any, where: str) -> Polygon:
    # QGroundControl lists a polygon's vertices without repeating the first: closed or not is fine.
    ring = _latlon_points(points, where, "polygon")
    if len(ring) > 1 and ring[0] == ring[-1]:
        ring = ring[:-1]
    if len(ring) < 3:
        raise GeoError(f"{where}: polygon has fewer than 3 points")
    return Polygon(ring)


def _corridor(item: dict[str, Any], where: str) -> Polygon:
    # A corridor scan has a centre line and a width: the area is that line widened,
    # buffered in metres in the local UTM zone.
    from .frame import _transformers, utm_epsg_for  # local import: frame needs pyproj only here

    nested = item.get("CorridorScan")
    width = item.get("CorridorWidth") or (nested.get("CorridorWidth") if isinstance(nested, dict) else None)
    pts = _latlon_points(item.get("polyline") or [], where, "CorridorScan polyline")
    if not is_number(width) or not math.isfinite(width):
        raise GeoError(f"{where}: CorridorScan needs a CorridorWidth in metres")
    if len(pts) < 2 or width <= 0:
        raise GeoError(f"{where}: CorridorScan needs at least 2 polyline points and a positive width")
    line = shapely.LineString(pts)
    check_lonlat(line, where)
    epsg = utm_epsg_for(line.centroid.x, line.centroid.y)
    fwd, inv = _transformers(epsg)
    buf = shapely.transform(line, lambda x, y: fwd.transform(x, y), interleaved=False).buffer(width / 2.0)
    return shapely.transform(buf, lambda x, y: inv.transform(x, y), interleaved=False)


def _member(data: dict[str, Any], key: str, expected: type, where: str) -> Any:
    """data[key] when it has the JSON type `expected`; absent or null reads as empty."""
    value = data.get(key)
    if value is None:
        return expected()
    if not isinstance(value, expected):
        name = "an object" if expected is dict else "a list"
        raise GeoError(f"{where}'{key}' is not {name} (it is {kind(value)})")
    return value


def _feature(geom: Polygon, where: str, ref: str, properties: dict[str, Any]) -> Feature:
    checked, repaired = checked_polygon(geom, where)
    return Feature(checked, properties, ref, repaired)


def read_plan(path: Path) -> PlanPolygons:
    """The survey and geofence polygons of a QGroundControl plan."""
    data = load_json(path)
    if not isinstance(data, dict) or data.get("fileType") not in (None, "Plan"):
        raise GeoError(f"{path}: not a QGroundControl plan (fileType is not 'Plan')")
    mission = _member(data, "mission", dict, f"{path}: ")
    out = PlanPolygons()
    for k, item in enumerate(_member(mission, "items", list, f"{path}: mission ")):
        if not isinstance(item, dict):
            raise GeoError(f"{path}: mission item {k} is not an object (it is {kind(item)})")
        if item.get("type") != "ComplexItem":
            continue
        item_kind = item.get("complexItemType", "")
        ref = f"mission item {k} ({item_kind})"
        where = f"{path}: {ref}"
        if item_kind in ("survey", "StructureScan") and item.get("polygon"):
            geom = _latlon_ring(item["polygon"], where)
        elif item_kind == "CorridorScan":
            geom = _corridor(item, where)
        else:
            continue
        out.survey.append(_feature(geom, where, ref, {"source": item_kind}))
    fence_data = _member(data, "geoFence", dict, f"{path}: ")
    for k, fence in enumerate(_member(fence_data, "polygons", list, f"{path}: geoFence ")):
        ref = f"geofence polygon {k}"
        where = f"{path}: {ref}"
        if not isinstance(fence, dict):
            raise GeoError(f"{where} is not an object (it is {kind(fence)})")
        inclusion = bool(fence.get("inclusion", True))
        feature = _feature(_latlon_ring(fence.get("polygon") or [], where), where, ref,
                           {"source": "geofence", "inclusion": inclusion})
        (out.inclusion if inclusion else out.exclusion).append(feature)
    return out
