"""Read area, obstacle, no-fly and building polygons from the files field teams have.

The format is chosen by file extension; each has one reader module:

| extension | read by | module |
|---|---|---|
| `.geojson`, `.json` | our own parser (strict RFC 7946; GDAL's driver skips bad features silently) | geojson_file.py |
| `.kml`, `.kmz` | our own parser (`<Data>` and `<SchemaData>`; LIBKML reads 'x,y' as 0,0) | kml_file.py |
| `.plan` | our own parser (QGroundControl survey / corridor / geofence) | plan_file.py |
| `.gpkg`, `.shp`, `.zip` (a Shapefile), `.fgb`, `.gml` | GDAL, through pyogrio | ogr_files.py |
| `.osm`, `.osm.pbf` | pyosmium: buildings only | osm.py |

`FILE:LAYER` names a layer of a file that has several (GeoPackage, GML, KML folders, a zip of
Shapefiles): a path that exists as given is always the file; otherwise, when the part before the
last ':' is an existing file, the part after it is the layer (`split_layer`).

Every reader gives Features in WGS84 lon/lat (a file in another CRS is reprojected, crs.py), each
checked (shapes.py), and a `SourceFile` saying how the file was read and what it left out or
repaired, by name (sources.py). Any wrong input is a GeoError: one line naming the file, the feature
(index, FID, placemark or OSM id) and the cause. Heights of buildings: heights.py.
"""

from __future__ import annotations

from pathlib import Path

from shapely.geometry import MultiPolygon, Polygon

from missionplan.base.naming import Named

from .errors import GeoError
from .geojson_file import read_geojson
from .heights import LEVEL_HEIGHT_M, HeightReader, building_height, has_field, parse_height
from .kml_file import read_kml, read_kmz
from .ogr_files import FORMATS as OGR_FORMATS
from .ogr_files import ZIP_EXT, read_ogr
from .osm import read_osm
from .plan_file import read_plan
from .shapes import check_lonlat, union, validate_polygon
from .sources import Building, Feature, Omission, SourceFile

__all__ = ["Building", "Feature", "GeoError", "LEVEL_HEIGHT_M", "Omission", "SourceFile", "building_height",
           "check_lonlat", "parse_height", "read_area", "read_area_file", "read_building_file", "read_buildings",
           "read_features", "read_obstacle_file", "read_osm_buildings", "read_polygons", "split_layer",
           "validate_polygon"]

Polygonal = Polygon | MultiPolygon

GEOJSON_EXT = (".geojson", ".json")
KML_EXT = (".kml",)
KMZ_EXT = (".kmz",)
PLAN_EXT = (".plan",)
OSM_EXT = (".osm", ".osm.pbf", ".pbf")
OGR_EXT = tuple(OGR_FORMATS) + (ZIP_EXT,)
KNOWN_EXT = GEOJSON_EXT + KML_EXT + KMZ_EXT + PLAN_EXT + OSM_EXT + OGR_EXT
LAYERED_EXT = KML_EXT + KMZ_EXT + OGR_EXT  # formats that may hold several layers


def _ext(path: Path) -> str:
    name = path.name.lower()
    for ext in sorted(KNOWN_EXT, key=len, reverse=True):  # ".osm.pbf" before ".pbf"
        if name.endswith(ext):
            return ext
    return path.suffix.lower()


def split_layer(spec: str | Path) -> tuple[Path, str | None]:
    """`FILE:LAYER` -> (FILE, LAYER); a path that exists as given is the file (layer None), and so is
    one whose part before the last ':' is not an existing file."""
    path = Path(spec)
    text = str(spec)
    if path.exists() or ":" not in path.name:
        return path, None
    head, layer = text.rsplit(":", 1)
    if layer and Path(head).is_file():
        return Path(head), layer
    return path, None


def _open(spec: str | Path) -> tuple[Path, str, str | None]:
    """(file, its extension, the layer asked for); GeoError for an unknown type, a missing file or a
    layer asked of a format that has none."""
    path, layer = split_layer(spec)
    ext = _ext(path)
    if ext not in KNOWN_EXT:
        raise GeoError(f"{path}: unknown file type {ext or '(no extension)'!r} "
                       f"(use .geojson, .json, .kml, .kmz, .gpkg, .shp, .zip (a Shapefile), .fgb, .gml, .plan, "
                       f".osm or .osm.pbf)")
    if not path.is_file():
        raise GeoError(f"{path}: file not found")
    if layer is not None and ext not in LAYERED_EXT:
        raise GeoError(f"{path}: a {ext} file has no layers (':{layer}' follows its name)")
    return path, ext, layer


def _read(path: Path, ext: str, layer: str | None) -> tuple[list[Feature], SourceFile]:
    """Every polygon of a GIS file (not .plan, not OSM), with how it was read."""
    if ext in GEOJSON_EXT:
        return read_geojson(path)
    if ext in KML_EXT:
        return read_kml(path, layer)
    if ext in KMZ_EXT:
        return read_kmz(path, layer)
    return read_ogr(path, ext, layer)


def _plan_source(path: Path, features: list[Feature], what: str) -> SourceFile:
    source = SourceFile(str(path), f"QGroundControl plan ({what})", "missionplan", features=len(features))
    source.repaired = [Omission(f.ref, f.repaired) for f in features if f.repaired]
    return source


def _osm_buildings(path: Path, height_field: str | None) -> tuple[list[Building], SourceFile]:
    footprints, source = read_osm(path)
    height = HeightReader(height_field)
    return [Building(b.geometry, height(b.tags), b.tags, b.ref, b.repaired) for b in footprints], source


# ---- public entry points -------------------------------------------------------------------

def read_area_file(spec: str | Path) -> tuple[Polygonal, SourceFile]:
    """The survey area: the union of the file's polygons (of its layer), and how the file was read.

    For a .plan: the survey (ComplexItem) polygons, else the geofence inclusion polygons.
    """
    path, ext, layer = _open(spec)
    if ext in PLAN_EXT:
        polygons = read_plan(path)
        feats = polygons.survey or polygons.inclusion
        if not feats:
            raise GeoError(f"{path}: no survey polygon and no geofence inclusion polygon found")
        source = _plan_source(path, feats, "survey" if polygons.survey else "geofence inclusion")
    elif ext in OSM_EXT:
        raise GeoError(f"{path}: OSM data holds buildings, not a survey area (give the area as GeoJSON, KML, "
                       f"GeoPackage, Shapefile or .plan)")
    else:
        feats, source = _read(path, ext, layer)
    area = union([f.geometry for f in feats], str(path))
    check_lonlat(area, str(path))  # parts each fine may still lie on both sides of ±180°
    if area.is_empty or area.area == 0:
        raise GeoError(f"{path}: the area is empty")
    if not isinstance(area, (Polygon, MultiPolygon)):
        raise GeoError(f"{path}: the area is not a polygon ({area.geom_type})")
    return area, source


def read_obstacle_file(spec: str | Path) -> tuple[list[Polygonal], SourceFile]:
    """Obstacle or no-fly polygons, and how the file was read. For a .plan: its geofence EXCLUSION
    polygons (may be none)."""
    path, ext, layer = _open(spec)
    if ext in PLAN_EXT:
        feats = read_plan(path).exclusion
        return [f.geometry for f in feats], _plan_source(path, feats, "geofence exclusion")
    if ext in OSM_EXT:
        buildings, source = _osm_buildings(path, None)
        return [b.geometry for b in buildings], source
    feats, source = _read(path, ext, layer)
    return [f.geometry for f in feats], source


def read_building_file(spec: str | Path, height_field: str | None = None) -> tuple[list[Building], SourceFile]:
    """Building footprints with heights (heights.py: `height`, `building:height`, `building:levels`, or
    the field `height_field` first), and how the file was read. GeoError when `height_field` is given
    and the file has no such field (no building carries such a tag)."""
    path, ext, layer = _open(spec)
    if ext in PLAN_EXT:
        raise GeoError(f"{path}: a .plan file holds no buildings")
    if ext in OSM_EXT:
        buildings, source = _osm_buildings(path, height_field)
    else:
        feats, source = _read(path, ext, layer)
        height = HeightReader(height_field)
        buildings = [Building(f.geometry, height(f.properties), f.properties, f.ref, f.repaired) for f in feats]
    if height_field is not None:
        names = sorted({str(key) for b in buildings for key in b.properties} - {"osm_id", "osm_type"})
        if not has_field(names, height_field):
            what = "no building carries the tag" if ext in OSM_EXT else "no field"
            shown = ", ".join(names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "")
            raise GeoError(Named("{0}: {1} {2!r} ({height_field}); {3}: {4}", source.path, what, height_field,
                                 "its tags" if ext in OSM_EXT else "its fields", shown or "none"))
    return buildings, source


def read_features(path: str | Path) -> list[Feature]:
    """Every polygon in a file with its properties.

    For a .plan: survey polygons, then geofence polygons (property `inclusion`).
    For OSM data: the building footprints (properties = OSM tags).
    """
    p, ext, layer = _open(path)
    if ext in PLAN_EXT:
        polygons = read_plan(p)
        out = polygons.survey + polygons.inclusion + polygons.exclusion
        if not out:
            raise GeoError(f"{p}: no polygon found (no survey item and no geofence polygon)")
        return out
    if ext in OSM_EXT:
        return [Feature(b.geometry, b.tags, b.ref, b.repaired) for b in read_osm(p)[0]]
    return _read(p, ext, layer)[0]


def read_area(path: str | Path) -> Polygonal:
    """`read_area_file` without the record of how the file was read."""
    return read_area_file(path)[0]


def read_polygons(path: str | Path) -> list[Polygonal]:
    """`read_obstacle_file` without the record of how the file was read."""
    return read_obstacle_file(path)[0]


def read_buildings(path: str | Path, height_field: str | None = None) -> list[Building]:
    """`read_building_file` without the record of how the file was read."""
    return read_building_file(path, height_field)[0]


def read_osm_buildings(path: str | Path) -> list[Building]:
    """Building footprints of an OSM `.osm` / `.osm.pbf` file (GeoError for any other type)."""
    p, ext, _ = _open(path)
    if ext not in OSM_EXT:
        raise GeoError(f"{p}: OSM buildings need an .osm or .osm.pbf file, not {ext!r}")
    return _osm_buildings(p, None)[0]
