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
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.validation import explain_validity

from .errors import GeoError

Polygonal = Polygon | MultiPolygon

LEVEL_HEIGHT_M = 3.0  # metres per storey when only building:levels is known
REPAIR_AREA_TOLERANCE = 1e-6  # relative area change below which an invalid polygon is just repaired

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


def validate_polygon(geom: shapely.Geometry, where: str) -> Polygonal:
    """Check that `geom` is a valid, non-empty polygon; `where` names it in the error."""
    if geom is None or geom.is_empty:
        raise GeoError(f"{where}: the polygon is empty")
    if not isinstance(geom, (Polygon, MultiPolygon)):
        raise GeoError(f"{where}: not a polygon ({geom.geom_type})")
    coords = shapely.get_coordinates(geom)
    if not (abs(coords[:, 0]) <= 180).all() or not (abs(coords[:, 1]) <= 90).all():
        raise GeoError(f"{where}: coordinates are not lon/lat degrees (WGS84)")
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


def _read_geojson(path: Path) -> list[Feature]:
    data = _load_json(path)
    if not isinstance(data, dict) or "type" not in data:
        raise GeoError(f"{path}: not GeoJSON (no 'type' member)")
    kind = data["type"]
    if kind == "FeatureCollection":
        items = [(f.get("geometry"), f.get("properties") or {}) for f in data.get("features") or []
                 if isinstance(f, dict)]
    elif kind == "Feature":
        items = [(data.get("geometry"), data.get("properties") or {})]
    else:
        items = [(data, {})]
    out: list[Feature] = []
    for k, (geom, props) in enumerate(items):
        where = f"{path}: feature {k}"
        if geom is None:
            continue  # GeoJSON allows features without geometry; they carry no polygon
        try:
            g = shape(geom)
        except Exception as err:  # shapely raises several types for malformed geometry
            raise GeoError(f"{where}: malformed geometry ({err})") from None
        if g.geom_type == "GeometryCollection":
            parts = [p for p in g.geoms if not p.is_empty]
            if parts and all(isinstance(p, (Polygon, MultiPolygon)) for p in parts):
                g = shapely.union_all(parts)
        out.append(Feature(validate_polygon(g, where), dict(props)))
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
        pts.append((vals[0], vals[1]))
    if len(pts) < 3:
        raise GeoError(f"{where}: polygon ring has fewer than 3 points")
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


# ---- QGroundControl .plan ------------------------------------------------------------

def _latlon_ring(points: Any, where: str) -> Polygon:
    try:
        ring = [(float(p[1]), float(p[0])) for p in points]  # .plan stores [lat, lon]
    except (TypeError, ValueError, IndexError):
        raise GeoError(f"{where}: polygon points are not [lat, lon] pairs") from None
    if len(ring) < 3:
        raise GeoError(f"{where}: polygon has fewer than 3 points")
    return Polygon(ring)


def _corridor(item: dict[str, Any], where: str) -> Polygon:
    # A corridor scan has a centre line and a width: the area is that line widened,
    # buffered in metres in the local UTM zone.
    from .frame import _transformers, utm_epsg_for  # local import: frame needs pyproj only here

    line_pts = item.get("polyline") or []
    width = item.get("CorridorWidth") or (item.get("CorridorScan") or {}).get("CorridorWidth")
    try:
        pts = [(float(p[1]), float(p[0])) for p in line_pts]
        width = float(width)
    except (TypeError, ValueError, IndexError):
        raise GeoError(f"{where}: CorridorScan needs a polyline of [lat, lon] and a CorridorWidth") from None
    if len(pts) < 2 or width <= 0:
        raise GeoError(f"{where}: CorridorScan needs at least 2 polyline points and a positive width")
    line = shapely.LineString(pts)
    epsg = utm_epsg_for(line.centroid.x, line.centroid.y)
    fwd, inv = _transformers(epsg)
    buf = shapely.transform(line, lambda x, y: fwd.transform(x, y), interleaved=False).buffer(width / 2.0)
    return shapely.transform(buf, lambda x, y: inv.transform(x, y), interleaved=False)


def _read_plan(path: Path) -> tuple[list[Feature], list[Feature], list[Feature]]:
    """(survey polygons, geofence inclusion polygons, geofence exclusion polygons)."""
    data = _load_json(path)
    if not isinstance(data, dict) or data.get("fileType") not in (None, "Plan"):
        raise GeoError(f"{path}: not a QGroundControl plan (fileType is not 'Plan')")
    survey: list[Feature] = []
    items = ((data.get("mission") or {}).get("items")) or []
    for k, item in enumerate(items):
        if not isinstance(item, dict) or item.get("type") != "ComplexItem":
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
    for k, fence in enumerate(((data.get("geoFence") or {}).get("polygons")) or []):
        if not isinstance(fence, dict):
            continue
        where = f"{path}: geofence polygon {k}"
        geom = validate_polygon(_latlon_ring(fence.get("polygon") or [], where), where)
        if fence.get("inclusion", True):
            inclusion.append(Feature(geom, {"source": "geofence", "inclusion": True}))
        else:
            exclusion.append(Feature(geom, {"source": "geofence", "inclusion": False}))
    return survey, inclusion, exclusion


# ---- OpenStreetMap -----------------------------------------------------------------------

def _read_osm_buildings(path: Path) -> list[Building]:
    import osmium  # imported here so the rest of geo works without the C++ extension loaded

    wkb = osmium.geom.WKBFactory()
    out: list[Building] = []
    try:
        fp = osmium.FileProcessor(str(path)).with_areas().with_filter(osmium.filter.EntityFilter(osmium.osm.AREA))
        for area in fp:
            tags = dict(area.tags)
            if tags.get("building", "no") == "no":
                continue
            try:
                geom = shapely.from_wkb(wkb.create_multipolygon(area))
            except RuntimeError:
                continue  # broken multipolygon in the extract (missing members): skip it
            if not geom.is_valid:
                geom = _polygonal_part(shapely.make_valid(geom))
            if geom.is_empty or geom.area == 0:
                continue
            if isinstance(geom, MultiPolygon) and len(geom.geoms) == 1:
                geom = geom.geoms[0]
            tags["osm_id"] = area.orig_id()
            tags["osm_type"] = "way" if area.from_way() else "relation"
            out.append(Building(geom, building_height(tags), tags))
    except (RuntimeError, OSError) as err:
        raise GeoError(f"{path}: cannot read OSM data ({str(err).splitlines()[0] if str(err) else err})") from None
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
    area = shapely.union_all([f.geometry for f in feats])
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
