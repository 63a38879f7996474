"""GeoJSON layers on their way to GIS files: ring order, altitudes, each layer's schema, atomic output.

A layer is a GeoJSON FeatureCollection (RFC 7946: EPSG:4326, [lon, lat] or [lon, lat, alt] positions);
the plan's and the flight's layers come as a dict layer name -> collection, in drawing order. This
module is what the code building them and the writers (missionplan.geo.gpkg, missionplan.geo.kml) share:

* `rfc7946`       - a Polygon / MultiPolygon with RFC 7946's ring order (exteriors counter-clockwise,
                    holes clockwise, in the lon/lat plane), the order GeoJSON readers, GDAL and QGIS
                    agree on for inside and outside;
* `layer_schema`  - the geometry type a layer is written as, whether it is 3-D, one type per property.
The writers write atomically with missionplan.base.atomic (base imports nothing from geo, so no circle).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

SIMPLE_TYPES = ("Point", "LineString", "Polygon")
GEOMETRY_TYPES = SIMPLE_TYPES + tuple("Multi" + kind for kind in SIMPLE_TYPES)
# Property types, narrowest first: a property whose values mix kinds takes the widest one seen.
FIELD_TYPES = ("bool", "int", "float", "str")


def _twice_area(ring: list[list[float]]) -> float:
    """Shoelace sum in the lon/lat plane: > 0 counter-clockwise, < 0 clockwise, 0 degenerate."""
    x0, y0 = ring[0][0], ring[0][1]  # measured from the first vertex, for precision far from 0, 0
    pts = [(p[0] - x0, p[1] - y0) for p in ring]
    return sum(xa * yb - xb * ya for (xa, ya), (xb, yb) in zip(pts, pts[1:] + pts[:1]))


def _oriented(ring: Sequence[Sequence[float]], counter_clockwise: bool) -> list[list[float]]:
    out = [list(p) for p in ring]
    area = _twice_area(out) if out else 0.0
    wrong = area < 0 if counter_clockwise else area > 0
    return out[::-1] if wrong else out


def _polygon(rings: Sequence[Sequence[Sequence[float]]]) -> list[list[list[float]]]:
    return [_oriented(ring, counter_clockwise=(i == 0)) for i, ring in enumerate(rings)]


def rfc7946(geometry: dict[str, Any] | None) -> dict[str, Any] | None:
    """The geometry with exterior rings counter-clockwise and holes clockwise (a new dict).

    Polygon and MultiPolygon only; any other geometry (or None) is returned as it is. Altitudes
    and other members of the geometry are kept; a degenerate (zero-area) ring is left as given.
    """
    kind = geometry.get("type") if geometry else None
    if kind == "Polygon":
        return {**geometry, "coordinates": _polygon(geometry["coordinates"])}
    if kind == "MultiPolygon":
        return {**geometry, "coordinates": [_polygon(p) for p in geometry["coordinates"]]}
    return geometry


@dataclass(frozen=True)
class LayerSchema:
    """How a layer's features are written: one geometry type, 2-D or 3-D, typed properties."""

    geometry_type: str | None  # GeoJSON type; "Geometry" when kinds mix, None when no feature has one
    has_z: bool  # any position has an altitude
    fields: dict[str, str]  # property name -> one of FIELD_TYPES, in first-seen order


def _positions(coords: Any) -> Iterator[Sequence[float]]:
    """Every position of a GeoJSON coordinates array, at any nesting depth."""
    if coords and isinstance(coords[0], numbers.Real):
        yield coords
    else:
        for part in coords:
            yield from _positions(part)


def geometry_positions(geometry: dict[str, Any] | None) -> list[Sequence[float]]:
    """The positions of a geometry ([] for None or an empty one); ValueError for an unknown type."""
    if not geometry:
        return []
    if geometry.get("type") not in GEOMETRY_TYPES:
        raise ValueError(f"unsupported geometry type {geometry.get('type')!r} (one of {', '.join(GEOMETRY_TYPES)})")
    return list(_positions(geometry.get("coordinates") or []))


def field_type(value: Any) -> str:
    """The FIELD_TYPES name of a property value (lists, dicts and anything else are written as text)."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, numbers.Integral):
        return "int"
    if isinstance(value, numbers.Real):
        return "float"
    return "str"


def layer_schema(collection: dict[str, Any]) -> LayerSchema:
    """The schema of a FeatureCollection: Polygon and MultiPolygon in one layer give MultiPolygon
    (and so for points and lines), so that every feature fits one declared type."""
    kinds: set[str] = set()
    has_z = False
    fields: dict[str, str | None] = {}  # None until a value other than null is seen
    for feature in collection.get("features") or []:
        geometry = feature.get("geometry")
        positions = geometry_positions(geometry)
        if positions:
            kinds.add(geometry["type"])
            has_z = has_z or any(len(p) >= 3 for p in positions)
        for key, value in (feature.get("properties") or {}).items():
            seen = fields.setdefault(key, None)
            if value is not None:
                kind = field_type(value)
                fields[key] = kind if seen is None else max(seen, kind, key=FIELD_TYPES.index)
    families = {kind.removeprefix("Multi") for kind in kinds}
    if not kinds:
        geometry_type = None
    elif len(kinds) == 1:
        geometry_type = kinds.pop()
    elif len(families) == 1:
        geometry_type = "Multi" + families.pop()
    else:
        geometry_type = "Geometry"
    return LayerSchema(geometry_type, has_z, {key: kind or "str" for key, kind in fields.items()})
