"""Read area, obstacle, no-fly and building polygons from the files field teams have.

Formats (chosen by file extension):

* GeoJSON (`.geojson`, `.json`): FeatureCollection, Feature or bare geometry; Polygon and
  MultiPolygon (holes kept); feature properties are returned with each shape.
* KML (`.kml`): Placemark Polygons (outerBoundaryIs / innerBoundaryIs), MultiGeometry.
* QGroundControl plan (`.plan`): the area is the polygon of a survey / StructureScan item
  (a CorridorScan polyline is widened by its CorridorWidth), else the geofence inclusion
  polygons; geofence exclusion polygons are the no-fly polygons.
* OpenStreetMap (`.osm`, `.osm.pbf`, via pyosmium): buildings only - closed ways and
  multipolygon relations tagged building=* (not building=no).

All geometries are shapely Polygons / MultiPolygons in (lon, lat) WGS84 order. User-drawn
polygons must be valid: a self-intersecting one (a bowtie) is an error, as the drawing is
ambiguous - except digitising slips that make_valid fixes without changing the area (rings
touching themselves, slivers; common in GIS exports), which are repaired silently. OSM
building footprints, thousands of them drawn by others, are always repaired with make_valid
instead of rejecting the whole extract for one broken roof.

Any other wrong input is a GeoError naming the file: a structure that is not what the format
says (`features` not a list, a `.plan` mission that is not an object, points that are not
number pairs), GeoJSON / KML rings that are not closed, NaN, infinite or out-of-range
coordinates, and shapes spanning more than 180 degrees of longitude (across the antimeridian).
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.errors import GEOSException
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.validation import explain_validity

from .errors import GeoError

Polygonal = Polygon | MultiPolygon

LEVEL_HEIGHT_M = 3.0  # metres per storey when only building:levels is known
REPAIR_AREA_TOLERANCE = 1e-6  # relative area change below which an invalid polygon is just repaired
MAX_LON_SPAN_DEG = 180.0  # wider than this is the long way round: a shape across the antimeridian

GEOJSON_EXT = (".geojson", ".json")
KML_EXT = (".kml",)
PLAN_EXT = (".plan",)
OSM_EXT = (".osm", ".osm.pbf", ".pbf")
KNOWN_EXT = GEOJSON_EXT + KML_EXT + PLAN_EXT + OSM_EXT


@dataclass
class Feature:
    """One polygonal shape and the properties that came with it (may be empty)."""

    geometry: Polygonal
    properties: dict[str, Any] = field(default_factory=dict)


@dataclass
class Building:
    """A building footprint; `height_m` None when the data does not say."""

    geometry: Polygonal
    height_m: float | None
    properties: dict[str, Any] = field(default_factory=dict)


# ---- helpers -------------------------------------------------------------------------

def _ext(path: Path) -> str:
    name = path.name.lower()
    for ext in sorted(KNOWN_EXT, key=len, reverse=True):  # ".osm.pbf" before ".pbf"
        if name.endswith(ext):
            return ext
    return path.suffix.lower()


def _check_ext(path: Path) -> str:
    ext = _ext(path)
    if ext not in KNOWN_EXT:
        raise GeoError(f"{path}: unknown file type {ext or '(no extension)'!r} "
                       f"(use .geojson, .json, .kml, .plan, .osm or .osm.pbf)")
    if not path.is_file():
        raise GeoError(f"{path}: file not found")
    return ext


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


def validate_polygon(geom: shapely.Geometry, where: str) -> Polygonal:
    """Check that `geom` is a valid, non-empty polygon; `where` names it in the error."""
    if geom is None or geom.is_empty:
        raise GeoError(f"{where}: the polygon is empty")
    if not isinstance(geom, (Polygon, MultiPolygon)):
        raise GeoError(f"{where}: not a polygon ({geom.geom_type})")
    check_lonlat(geom, where)
    if not geom.is_valid:
        fixed = _repair_slip(geom)
        if fixed is not None:
            return fixed
        if _polygonal_part(shapely.make_valid(geom)).area == 0:
            raise GeoError(f"{where}: the polygon has zero area (its points lie on a line)")
        why = explain_validity(geom)
        if "self-intersection" in why.lower():
            raise GeoError(f"{where}: self-intersecting polygon ({why})")
        raise GeoError(f"{where}: invalid polygon ({why})")
    if geom.area == 0:
        raise GeoError(f"{where}: the polygon has zero area")
    return geom


def _union(parts: list[shapely.Geometry], where: str) -> shapely.Geometry:
    """The union of polygons; GEOS refuses some invalid inputs outright (a topology error)."""
    try:
        return shapely.union_all(parts)
    except GEOSException as err:
        raise GeoError(f"{where}: invalid polygons ({str(err).splitlines()[0]})") from None


def _polygonal_part(geom: shapely.Geometry) -> Polygonal:
    parts = [g for g in getattr(geom, "geoms", [geom]) if isinstance(g, (Polygon, MultiPolygon))]
    return shapely.union_all(parts) if parts else Polygon()


def _repair_slip(geom: Polygonal) -> Polygonal | None:
    """The repaired polygon when the invalidity is a digitising slip, else None.

    GIS exports often carry rings that touch themselves or tiny slivers; make_valid fixes
    those without changing the area. A real self-crossing (a bowtie) changes the area
    a lot (its signed halves cancel), so the drawing is ambiguous and stays an error.
    """
    fixed = _polygonal_part(shapely.make_valid(geom))
    if fixed.is_empty or geom.area <= 0:
        return None
    if abs(fixed.area - geom.area) > REPAIR_AREA_TOLERANCE * geom.area:
        return None
    return fixed


def parse_height(value: Any) -> float | None:
    """OSM-style height: '12', '12 m', '12.5m', '12,5', "40'" / '40 ft' -> metres; else None."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        v = float(value)
        return v if math.isfinite(v) and v >= 0 else None
    m = re.fullmatch(r"\s*(\d+(?:[.,]\d+)?)\s*(m|meters?|metres?|ft|feet|')?\s*", str(value), re.IGNORECASE)
    if not m:
        return None
    v = float(m.group(1).replace(",", "."))
    if m.group(2) and m.group(2).lower() in ("ft", "feet", "'"):
        v *= 0.3048
    return v


def building_height(tags: dict[str, Any]) -> float | None:
    """`height` tag, else `building:levels` x 3 m, else None (unknown)."""
    h = parse_height(tags.get("height"))
    if h is not None:
        return h
    levels = parse_height(tags.get("building:levels"))
    return levels * LEVEL_HEIGHT_M if levels is not None else None


# ---- GeoJSON -------------------------------------------------------------------------

def _load_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise GeoError(f"{path}: cannot read JSON ({str(err).splitlines()[0]})") from None


def _kind(value: Any) -> str:
    """A JSON value's type as a user reads it, for 'is not a list (it is a string)'-style messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "an object"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_geojson_rings(geom: dict[str, Any], where: str) -> None:
    """RFC 7946 polygon rings: lists of [lon, lat(, alt)] numbers, closed, at least 4 positions.

    shapely closes an open ring silently, so a 3-point sketch would pass as a triangle; the
    format says a ring is closed, and an open one usually means a vertex was lost.
    """
    kind = geom.get("type")
    if kind == "GeometryCollection":
        parts = geom.get("geometries")
        if not isinstance(parts, list):
            raise GeoError(f"{where}: GeometryCollection 'geometries' is not a list (it is {_kind(parts)})")
        for part in parts:
            if not isinstance(part, dict):
                raise GeoError(f"{where}: a GeometryCollection member is not an object (it is {_kind(part)})")
            _check_geojson_rings(part, where)
        return
    if kind not in ("Polygon", "MultiPolygon"):
        return  # refused (or accepted) later by what shapely makes of it
    coords = geom.get("coordinates")
    polygons = [coords] if kind == "Polygon" else coords
    if not isinstance(polygons, list) or not all(isinstance(rings, list) for rings in polygons):
        raise GeoError(f"{where}: {kind} coordinates are not nested lists of [lon, lat] positions")
    for rings in polygons:
        for k, ring in enumerate(rings):
            label = "outer ring" if k == 0 else f"hole {k}"
            _check_positions(ring, f"{where}: {kind} {label}: positions are not [lon, lat] number pairs",
                             f"{where}: {kind} {label}: position")
            if ring and ring[0] != ring[-1]:
                raise GeoError(f"{where}: {kind} {label} is not closed (its first and last positions differ); "
                               f"GeoJSON rings repeat the first position at the end")
            if len(ring) < 4:
                raise GeoError(f"{where}: {kind} {label} has {len(ring)} positions; a closed ring needs at least 4")


def _read_geojson(path: Path) -> list[Feature]:
    data = _load_json(path)
    if not isinstance(data, dict) or "type" not in data:
        raise GeoError(f"{path}: not GeoJSON (no 'type' member)")
    kind = data["type"]
    if kind == "FeatureCollection":
        features = data.get("features")
        if not isinstance(features, list):
            raise GeoError(f"{path}: 'features' is not a list (it is {_kind(features)})")
        for k, f in enumerate(features):
            if not isinstance(f, dict):
                raise GeoError(f"{path}: feature {k} is not an object (it is {_kind(f)})")
        items = [(f.get("geometry"), f.get("properties")) for f in features]
    elif kind == "Feature":
        items = [(data.get("geometry"), data.get("properties"))]
    else:
        items = [(data, {})]
    out: list[Feature] = []
    for k, (geom, props) in enumerate(items):
        where = f"{path}: feature {k}"
        if props is not None and not isinstance(props, dict):
            raise GeoError(f"{where}: 'properties' is not an object (it is {_kind(props)})")
        if geom is None:
            continue  # GeoJSON allows features without geometry; they carry no polygon
        if not isinstance(geom, dict):
            raise GeoError(f"{where}: 'geometry' is not an object (it is {_kind(geom)})")
        _check_geojson_rings(geom, where)
        try:
            g = shape(geom)
        except Exception as err:  # shapely raises several types for malformed geometry
            raise GeoError(f"{where}: malformed geometry ({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None
        if g.geom_type == "GeometryCollection":
            check_lonlat(g, where)
            parts = [p for p in g.geoms if not p.is_empty]
            if parts and all(isinstance(p, (Polygon, MultiPolygon)) for p in parts):
                g = _union(parts, where)
        out.append(Feature(validate_polygon(g, where), dict(props or {})))
    if not out:
        raise GeoError(f"{path}: no polygon found")
    return out


# ---- KML -----------------------------------------------------------------------------

def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]  # drop the XML namespace


def _children(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el if _local(c.tag) == name]


def _descendants(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el.iter() if _local(c.tag) == name]


def _kml_ring(boundary: ET.Element, where: str) -> list[tuple[float, float]]:
    coords = [c for c in _descendants(boundary, "coordinates")]
    if not coords or not (coords[0].text or "").strip():
        raise GeoError(f"{where}: polygon boundary without coordinates")
    pts = []
    for token in coords[0].text.split():
        try:
            vals = [float(v) for v in token.split(",")]
        except ValueError:
            raise GeoError(f"{where}: bad coordinate {token[:40]!r}") from None
        if len(vals) < 2:
            raise GeoError(f"{where}: bad coordinate {token[:40]!r}")
        if not all(math.isfinite(v) for v in vals):
            raise GeoError(f"{where}: coordinate {token[:40]!r} is not finite numbers")
        pts.append((vals[0], vals[1]))
    if pts[0] != pts[-1]:
        # KML's LinearRing repeats its first point at the end; an open ring usually lost a vertex.
        raise GeoError(f"{where}: polygon ring is not closed (its first and last points differ)")
    if len(pts) < 4:
        raise GeoError(f"{where}: polygon ring has {len(pts)} points; a closed ring needs at least 4")
    return pts


def _read_kml(path: Path) -> list[Feature]:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise GeoError(f"{path}: cannot read KML ({err})") from None
    out: list[Feature] = []
    for k, pm in enumerate(_descendants(root, "Placemark")):
        props: dict[str, Any] = {}
        for key in ("name", "description"):
            found = _children(pm, key)
            if found and found[0].text:
                props[key] = found[0].text.strip()
        for data in _descendants(pm, "Data"):
            val = _children(data, "value")
            props[data.get("name", "")] = val[0].text if val else None
        label = f"placemark {props['name']!r}" if "name" in props else f"placemark {k}"
        where = f"{path}: {label}"
        polys = []
        for pg in _descendants(pm, "Polygon"):
            outer = _children(pg, "outerBoundaryIs")
            if not outer:
                raise GeoError(f"{where}: Polygon without outerBoundaryIs")
            holes = [_kml_ring(b, where) for b in _children(pg, "innerBoundaryIs")]
            polys.append(Polygon(_kml_ring(outer[0], where), holes))
        if not polys:
            others = {_local(c.tag) for c in pm.iter()} & {"Point", "LineString", "LinearRing", "Model", "Track"}
            if others:
                raise GeoError(f"{where}: not a polygon ({sorted(others)[0]})")
            continue
        geom = polys[0] if len(polys) == 1 else MultiPolygon(polys)
        out.append(Feature(validate_polygon(geom, where), props))
    if not out:
        raise GeoError(f"{path}: no polygon found")
    return out


def _check_positions(points: Any, not_numbers: str, position: str) -> None:
    """GeoError unless `points` is a list of 2- or 3-number lists, all finite (GeoJSON rings and
    .plan polygons alike): `not_numbers` is the message for the shape, `position` prefixes a bad one."""
    if not isinstance(points, list) or not all(
            isinstance(p, list) and 2 <= len(p) <= 3 and all(_is_number(v) for v in p) for p in points):
        raise GeoError(not_numbers)
    for p in points:
        if not all(math.isfinite(v) for v in p):
            raise GeoError(f"{position} {p} is not finite numbers")


# ---- QGroundControl .plan ------------------------------------------------------------

def _latlon_points(points: Any, where: str, what: str) -> list[tuple[float, float]]:
    """.plan [lat, lon] (or [lat, lon, alt]) number lists -> (lon, lat) tuples, all finite."""
    _check_positions(points, f"{where}: {what} points are not [lat, lon] number pairs", f"{where}: {what} point")
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
    if not _is_number(width) or not math.isfinite(width):
        raise GeoError(f"{where}: CorridorScan needs a CorridorWidth in metres")
    if len(pts) < 2 or width <= 0:
        raise GeoError(f"{where}: CorridorScan needs at least 2 polyline points and a positive width")
    line = shapely.LineString(pts)
    check_lonlat(line, where)
    epsg = utm_epsg_for(line.centroid.x, line.centroid.y)
    fwd, inv = _transformers(epsg)
    buf = shapely.transform(line, lambda x, y: fwd.transform(x, y), interleaved=False).buffer(width / 2.0)
    return shapely.transform(buf, lambda x, y: inv.transform(x, y), interleaved=False)


def _member(data: dict[str, Any], key: str, kind: type, where: str) -> Any:
    """data[key] when it has the JSON type `kind`; absent or null reads as empty."""
    value = data.get(key)
    if value is None:
        return kind()
    if not isinstance(value, kind):
        expected = "an object" if kind is dict else "a list"
        raise GeoError(f"{where}'{key}' is not {expected} (it is {_kind(value)})")
    return value


def _read_plan(path: Path) -> tuple[list[Feature], list[Feature], list[Feature]]:
    """(survey polygons, geofence inclusion polygons, geofence exclusion polygons)."""
    data = _load_json(path)
    if not isinstance(data, dict) or data.get("fileType") not in (None, "Plan"):
        raise GeoError(f"{path}: not a QGroundControl plan (fileType is not 'Plan')")
    mission = _member(data, "mission", dict, f"{path}: ")
    survey: list[Feature] = []
    for k, item in enumerate(_member(mission, "items", list, f"{path}: mission ")):
        if not isinstance(item, dict):
            raise GeoError(f"{path}: mission item {k} is not an object (it is {_kind(item)})")
        if item.get("type") != "ComplexItem":
            continue
        kind = item.get("complexItemType", "")
        where = f"{path}: mission item {k} ({kind})"
        if kind in ("survey", "StructureScan") and item.get("polygon"):
            geom = _latlon_ring(item["polygon"], where)
        elif kind == "CorridorScan":
            geom = _corridor(item, where)
        else:
            continue
        survey.append(Feature(validate_polygon(geom, where), {"source": kind}))
    inclusion: list[Feature] = []
    exclusion: list[Feature] = []
    fence_data = _member(data, "geoFence", dict, f"{path}: ")
    for k, fence in enumerate(_member(fence_data, "polygons", list, f"{path}: geoFence ")):
        where = f"{path}: geofence polygon {k}"
        if not isinstance(fence, dict):
            raise GeoError(f"{where} is not an object (it is {_kind(fence)})")
        geom = validate_polygon(_latlon_ring(fence.get("polygon") or [], where), where)
        if fence.get("inclusion", True):
            inclusion.append(Feature(geom, {"source": "geofence", "inclusion": True}))
        else:
            exclusion.append(Feature(geom, {"source": "geofence", "inclusion": False}))
    return survey, inclusion, exclusion


# ---- OpenStreetMap -----------------------------------------------------------------------

_OSM_UNDEFINED_COORDINATE = 2**31 - 1  # osmium's x / y of a node the extract does not hold


def _check_osm_way_nodes(path: Path, way: Any) -> None:
    """A building way whose node has a location out of WGS84 range is bad data, not a skip.

    osmium marks such a location invalid and would drop the building silently; a node the
    extract simply lacks (clipped at its edge) is undefined instead, and stays a skip.
    """
    for node in way.nodes:
        loc = node.location
        if not loc.valid() and loc.x != _OSM_UNDEFINED_COORDINATE and loc.y != _OSM_UNDEFINED_COORDINATE:
            raise GeoError(f"{path}: way {way.id}, node {node.ref}: location (lat {loc.y / 1e7}, lon {loc.x / 1e7}) "
                           f"is out of range (latitude in [-90, 90], longitude in [-180, 180])")


def _read_osm_buildings(path: Path) -> list[Building]:
    import osmium  # imported here so the rest of geo works without the C++ extension loaded

    wkb = osmium.geom.WKBFactory()
    out: list[Building] = []
    try:
        fp = (osmium.FileProcessor(str(path)).with_areas()
              .with_filter(osmium.filter.EntityFilter(osmium.osm.AREA | osmium.osm.WAY))
              .with_filter(osmium.filter.KeyFilter("building")))  # in C++: Python sees buildings only
        for obj in fp:
            if obj.is_way():
                if obj.tags.get("building", "no") != "no":
                    try:
                        wkb.create_linestring(obj)  # C++: fails only when a node location is not valid
                    except (RuntimeError, osmium.InvalidLocationError):
                        _check_osm_way_nodes(path, obj)  # the slow look, only then: missing or out of range
                continue
            area = obj
            tags = dict(area.tags)
            if tags.get("building", "no") == "no":
                continue
            try:
                geom = shapely.from_wkb(wkb.create_multipolygon(area))
            except (RuntimeError, osmium.InvalidLocationError):
                continue  # broken multipolygon in the extract (missing members): skip it
            check_lonlat(geom, f"{path}: {'way' if area.from_way() else 'relation'} {area.orig_id()}")
            if not geom.is_valid:
                geom = _polygonal_part(shapely.make_valid(geom))
            if geom.is_empty or geom.area == 0:
                continue
            if isinstance(geom, MultiPolygon) and len(geom.geoms) == 1:
                geom = geom.geoms[0]
            tags["osm_id"] = area.orig_id()
            tags["osm_type"] = "way" if area.from_way() else "relation"
            out.append(Building(geom, building_height(tags), tags))
    except GeoError:
        raise
    except (RuntimeError, OSError, ValueError, osmium.InvalidLocationError) as err:
        # libosmium reports a malformed file as RuntimeError (XML / PBF errors), a bad
        # coordinate text as InvalidLocationError, undecodable tag text as ValueError.
        raise GeoError(f"{path}: cannot read OSM data ({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None
    if not out:
        raise GeoError(f"{path}: no building polygon found")
    return out


# ---- public entry points -------------------------------------------------------------------

def read_features(path: str | Path) -> list[Feature]:
    """Every polygon in a GeoJSON / KML / .plan file with its properties.

    For a .plan: survey polygons, then geofence polygons (property `inclusion`).
    For OSM data: the building footprints (properties = OSM tags).
    """
    p = Path(path)
    ext = _check_ext(p)
    if ext in GEOJSON_EXT:
        return _read_geojson(p)
    if ext in KML_EXT:
        return _read_kml(p)
    if ext in PLAN_EXT:
        survey, inclusion, exclusion = _read_plan(p)
        out = survey + inclusion + exclusion
        if not out:
            raise GeoError(f"{p}: no polygon found (no survey item and no geofence polygon)")
        return out
    return [Feature(b.geometry, b.properties) for b in _read_osm_buildings(p)]


def read_area(path: str | Path) -> Polygonal:
    """The survey area: the union of the file's polygons.

    For a .plan: the survey (ComplexItem) polygons, else the geofence inclusion polygons.
    """
    p = Path(path)
    ext = _check_ext(p)
    if ext in PLAN_EXT:
        survey, inclusion, _ = _read_plan(p)
        feats = survey or inclusion
        if not feats:
            raise GeoError(f"{p}: no survey polygon and no geofence inclusion polygon found")
    elif ext in OSM_EXT:
        raise GeoError(f"{p}: OSM data holds buildings, not a survey area (give the area as GeoJSON, KML or .plan)")
    else:
        feats = read_features(p)
    area = _union([f.geometry for f in feats], str(p))
    check_lonlat(area, str(p))  # parts each fine may still lie on both sides of ±180°
    if area.is_empty or area.area == 0:
        raise GeoError(f"{p}: the area is empty")
    if not isinstance(area, (Polygon, MultiPolygon)):
        raise GeoError(f"{p}: the area is not a polygon ({area.geom_type})")
    return area


def read_polygons(path: str | Path) -> list[Polygonal]:
    """Obstacle or no-fly polygons. For a .plan: its geofence EXCLUSION polygons (may be empty)."""
    p = Path(path)
    ext = _check_ext(p)
    if ext in PLAN_EXT:
        return [f.geometry for f in _read_plan(p)[2]]
    return [f.geometry for f in read_features(p)]


def read_buildings(path: str | Path) -> list[Building]:
    """Building footprints with heights: OSM `.osm` / `.osm.pbf`, or GeoJSON / KML whose
    properties may carry `height` / `building:levels` (OSM tag names)."""
    p = Path(path)
    ext = _check_ext(p)
    if ext in OSM_EXT:
        return _read_osm_buildings(p)
    if ext in PLAN_EXT:
        raise GeoError(f"{p}: a .plan file holds no buildings")
    return [Building(f.geometry, building_height(f.properties), f.properties) for f in read_features(p)]


def read_osm_buildings(path: str | Path) -> list[Building]:
    """Building footprints of an OSM `.osm` / `.osm.pbf` file (GeoError for any other type)."""
    p = Path(path)
    ext = _check_ext(p)
    if ext not in OSM_EXT:
        raise GeoError(f"{p}: OSM buildings need an .osm or .osm.pbf file, not {ext!r}")
    return _read_osm_buildings(p)
