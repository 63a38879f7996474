"""GeoPackage (OGC GeoPackage 1.3) of GeoJSON layers, written with the standard library's sqlite3.

One feature table per layer, in the layers' order, each in EPSG:4326 (longitude as x, latitude as
y, as GeoPackage orders them): `fid INTEGER PRIMARY KEY AUTOINCREMENT`, `geom` (declared as the
layer's geometry type, holding GeoPackageBinary: a "GP" header with the envelope, then ISO WKB,
its Z variant in a 3-D layer), then one column per property typed from its values (BOOLEAN,
INTEGER, REAL, TEXT). The metadata tables are the mandatory ones: gpkg_spatial_ref_sys (with the
-1, 0 and 4326 rows), gpkg_contents (bounding box per layer) and gpkg_geometry_columns.

A layer holding Polygons and MultiPolygons is declared MULTIPOLYGON and its Polygons are written as
one-part MultiPolygons (points and lines likewise), so that a one-type-per-file format such as ESRI
Shapefile takes it as it is. A null or empty geometry is a NULL `geom`. A layer with no geometry to
go by is declared as `geometry_types` names it, else GEOMETRY. No spatial index: the layers are a
few thousand features at most, which GDAL and QGIS read without one.

The file is written beside the target and renamed over it only when complete; a full disk or an
I/O error is an OSError naming the file, as for any other file written.
"""

from __future__ import annotations

import errno
import json
import math
import os
import sqlite3
import struct
from collections.abc import Mapping, Sequence
from typing import Any

from missionplan.base.atomic import atomic_path

from .geojson_layers import GEOMETRY_TYPES, LayerSchema, geometry_positions, layer_schema

APPLICATION_ID = 0x47504B47  # "GPKG"
USER_VERSION = 10300  # GeoPackage 1.3.0
SRS_ID = 4326
WGS84_WKT = (
    'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],'
    'AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],'
    'UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],'
    'AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]'
)
SPATIAL_REF_SYS = [  # the three rows GeoPackage requires (spec requirement 11)
    ("Undefined cartesian SRS", -1, "NONE", -1, "undefined", "undefined cartesian coordinate reference system"),
    ("Undefined geographic SRS", 0, "NONE", 0, "undefined", "undefined geographic coordinate reference system"),
    ("WGS 84 geodetic", SRS_ID, "EPSG", SRS_ID, WGS84_WKT,
     "longitude/latitude coordinates in decimal degrees on the WGS 84 spheroid"),
]
COLUMN_TYPES = {"bool": "BOOLEAN", "int": "INTEGER", "float": "REAL", "str": "TEXT"}
WKB_CODES = {"Point": 1, "LineString": 2, "Polygon": 3, "MultiPoint": 4, "MultiLineString": 5, "MultiPolygon": 6}
RESERVED = {"fid", "geom"}

METADATA_DDL = """
CREATE TABLE gpkg_spatial_ref_sys (
  srs_name TEXT NOT NULL,
  srs_id INTEGER NOT NULL PRIMARY KEY,
  organization TEXT NOT NULL,
  organization_coordsys_id INTEGER NOT NULL,
  definition TEXT NOT NULL,
  description TEXT
);
CREATE TABLE gpkg_contents (
  table_name TEXT NOT NULL PRIMARY KEY,
  data_type TEXT NOT NULL,
  identifier TEXT UNIQUE,
  description TEXT DEFAULT '',
  last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  min_x DOUBLE,
  min_y DOUBLE,
  max_x DOUBLE,
  max_y DOUBLE,
  srs_id INTEGER,
  CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id)
);
CREATE TABLE gpkg_geometry_columns (
  table_name TEXT NOT NULL,
  column_name TEXT NOT NULL,
  geometry_type_name TEXT NOT NULL,
  srs_id INTEGER NOT NULL,
  z TINYINT NOT NULL,
  m TINYINT NOT NULL,
  CONSTRAINT pk_geom_cols PRIMARY KEY (table_name, column_name),
  CONSTRAINT uk_gc_table_name UNIQUE (table_name),
  CONSTRAINT fk_gc_tn FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
  CONSTRAINT fk_gc_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id)
);
"""


def write_geopackage(path: str | os.PathLike[str], layers: Mapping[str, dict[str, Any]], *,
                     geometry_types: Mapping[str, str] | None = None) -> None:
    """Write `layers` (name -> GeoJSON FeatureCollection, EPSG:4326) to the GeoPackage `path`.

    `geometry_types` declares layers that have no geometry to infer a type from (an empty layer),
    as a GeoJSON type with " Z" for 3-D: {"missed": "MultiPolygon", "flown": "LineString Z"}.
    ValueError for a geometry type other than (Multi)Point / LineString / Polygon, a property
    named fid or geom, a non-finite coordinate or an unknown declared type.
    """
    with atomic_path(path) as tmp:
        con = sqlite3.connect(tmp, isolation_level=None)  # transactions by hand, below
        try:
            con.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            con.execute(f"PRAGMA user_version = {USER_VERSION}")
            con.execute("PRAGMA journal_mode = MEMORY")  # the temp file itself is the rollback
            con.execute("BEGIN")
            for statement in filter(str.strip, METADATA_DDL.split(";")):
                con.execute(statement)
            con.executemany("INSERT INTO gpkg_spatial_ref_sys VALUES (?, ?, ?, ?, ?, ?)", SPATIAL_REF_SYS)
            for name, collection in layers.items():
                _write_layer(con, name, collection, (geometry_types or {}).get(name))
            con.execute("COMMIT")
        except sqlite3.OperationalError as err:
            # SQLite's "database or disk is full" and I/O errors are the disk's: an OSError like any other write's
            cause = {sqlite3.SQLITE_FULL: errno.ENOSPC, sqlite3.SQLITE_IOERR: errno.EIO}.get(
                getattr(err, "sqlite_errorcode", 0) & 0xFF)
            if cause is None:
                raise
            raise OSError(cause, os.strerror(cause), os.fspath(path)) from err
        finally:
            con.close()


def _quote(identifier: str) -> str:
    return '"' + identifier.replace('"', '""') + '"'


def _declared(name: str, schema: LayerSchema, declared: str | None) -> tuple[str, bool]:
    """(GeoJSON geometry type or "Geometry", 3-D) the layer's table is declared with."""
    if declared is not None:
        kind, _, z = declared.partition(" ")
        if kind not in GEOMETRY_TYPES or z not in ("", "Z"):
            raise ValueError(f"layer {name!r}: declared geometry type {declared!r} is not one of "
                             f"{', '.join(GEOMETRY_TYPES)} (with ' Z' for 3-D)")
        if schema.geometry_type is None:
            return kind, z == "Z"
    return schema.geometry_type or "Geometry", schema.has_z


def _write_layer(con: sqlite3.Connection, name: str, collection: dict[str, Any], declared: str | None) -> None:
    schema = layer_schema(collection)
    kind, has_z = _declared(name, schema, declared)
    clash = [key for key in schema.fields if key.lower() in RESERVED]
    if clash:
        raise ValueError(f"layer {name!r}: property {clash[0]!r} clashes with the GeoPackage column of that name")
    columns = "".join(f", {_quote(key)} {COLUMN_TYPES[field]}" for key, field in schema.fields.items())
    con.execute(f"CREATE TABLE {_quote(name)} (fid INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, "
                f"geom {kind.upper()}{columns})")

    dims = 3 if has_z else 2
    bounds: list[float] = [math.inf, math.inf, -math.inf, -math.inf]  # min x, min y, max x, max y
    rows = []
    for feature in collection.get("features") or []:
        blob = _geometry_blob(feature.get("geometry"), kind, dims, bounds)
        props = feature.get("properties") or {}
        rows.append([blob] + [_value(props.get(key), field) for key, field in schema.fields.items()])
    marks = ", ".join("?" * (1 + len(schema.fields)))
    names = ", ".join(["geom"] + [_quote(key) for key in schema.fields])
    con.executemany(f"INSERT INTO {_quote(name)} ({names}) VALUES ({marks})", rows)

    extent = bounds if bounds[0] <= bounds[2] else [None] * 4
    con.execute("INSERT INTO gpkg_contents (table_name, data_type, identifier, min_x, min_y, max_x, max_y, srs_id) "
                "VALUES (?, 'features', ?, ?, ?, ?, ?, ?)", (name, name, *extent, SRS_ID))
    con.execute("INSERT INTO gpkg_geometry_columns VALUES (?, 'geom', ?, ?, ?, 0)",
                (name, kind.upper(), SRS_ID, int(has_z)))


def _value(value: Any, kind: str) -> Any:
    """A property value as its column stores it (booleans as 0 / 1, anything in a TEXT column as text)."""
    if value is None:
        return None
    if kind == "str":
        return value if isinstance(value, str) else json.dumps(value)
    return {"bool": int, "int": int, "float": float}[kind](value)


def _geometry_blob(geometry: dict[str, Any] | None, declared: str, dims: int, bounds: list[float]) -> bytes | None:
    """GeoPackageBinary of a GeoJSON geometry, promoted to the layer's Multi type if need be;
    None for a null or empty geometry. Widens `bounds` (min x, min y, max x, max y) by it."""
    positions = geometry_positions(geometry)
    if not positions:
        return None
    kind, coords = geometry["type"], geometry["coordinates"]
    if declared == "Multi" + kind:
        kind, coords = declared, [coords]
    flat = _flat(positions, dims)
    if not all(map(math.isfinite, flat)):
        raise ValueError(f"non-finite coordinate in a {kind}")
    envelope = [f(flat[axis::dims]) for axis in range(dims) for f in (min, max)]  # minx maxx miny maxy [minz maxz]
    bounds[:] = [min(bounds[0], envelope[0]), min(bounds[1], envelope[2]),
                 max(bounds[2], envelope[1]), max(bounds[3], envelope[3])]
    # flags: little-endian (bit 0), envelope [minx,maxx,miny,maxy] = 1 or with [minz,maxz] = 2 (bits 1-3)
    flags = 0x01 | ((2 if dims == 3 else 1) << 1)
    header = b"GP" + struct.pack(f"<BBi{len(envelope)}d", 0, flags, SRS_ID, *envelope)
    return header + _wkb(kind, coords, dims)


def _wkb(kind: str, coords: Any, dims: int) -> bytes:
    """ISO WKB, little-endian; the Z types are the 2-D codes + 1000."""
    head = struct.pack("<BI", 1, WKB_CODES[kind] + (1000 if dims == 3 else 0))
    if kind == "Point":
        return head + _points([coords], dims)
    if kind == "LineString":
        return head + struct.pack("<I", len(coords)) + _points(coords, dims)
    if kind == "Polygon":
        return head + struct.pack("<I", len(coords)) + b"".join(
            struct.pack("<I", len(ring)) + _points(ring, dims) for ring in coords)
    part = kind.removeprefix("Multi")
    return head + struct.pack("<I", len(coords)) + b"".join(_wkb(part, c, dims) for c in coords)


def _flat(positions: Sequence[Sequence[float]], dims: int) -> list[float]:
    """x, y[, z] of each position; a 2-D position in a 3-D layer at z 0 (as GDAL writes one)."""
    return [float(v) for p in positions for v in (list(p[:dims]) + [0.0] * (dims - len(p)))]


def _points(positions: Sequence[Sequence[float]], dims: int) -> bytes:
    flat = _flat(positions, dims)
    return struct.pack(f"<{len(flat)}d", *flat)
