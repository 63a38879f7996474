"""The GIS files a crew carries away (missionplan.geo.gpkg's GeoPackage, missionplan.geo.kml's KMZ), read back by GDAL.

The reader is independent of the writers: GDAL through pyogrio (its GPKG, LIBKML, KML and ESRI
Shapefile drivers), plus GDAL's command-line tools where they are on PATH. GDAL's warnings (an
inconsistent GeoPackage, an unknown version) come out of pyogrio as RuntimeWarnings, which the
readers here turn into failures. The layers are a small plan and flight over Turin, built here.
"""

from __future__ import annotations

import copy
import math
import re
import shutil
import sqlite3
import struct
import subprocess
import warnings
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely

from missionplan.geo.geojson_layers import LayerSchema, layer_schema, rfc7946
from missionplan.geo.gpkg import write_geopackage
from missionplan.geo.kml import write_kmz

KML = "{http://www.opengis.net/kml/2.2}"
LON, LAT = 7.65, 45.07


def gdal() -> Any:
    return pytest.importorskip("pyogrio", reason="pyogrio (GDAL) is the independent reader: pip install pyogrio")


# ---- the layers: a small plan and flight near Turin ---------------------------------------------

def rect(w: float, s: float, e: float, n: float, ccw: bool = True) -> list[list[float]]:
    ring = [[w, s], [e, s], [e, n], [w, n], [w, s]]
    return ring if ccw else ring[::-1]


def feature(kind: str, coordinates: Any, **props: Any) -> dict[str, Any]:
    return {"type": "Feature", "geometry": {"type": kind, "coordinates": coordinates}, "properties": props}


def collection(*features: dict[str, Any]) -> dict[str, Any]:
    return {"type": "FeatureCollection", "features": list(features)}


AREA = [rect(LON - 0.002, LAT - 0.0015, LON + 0.002, LAT + 0.0015),
        rect(LON - 0.0004, LAT - 0.0003, LON + 0.0004, LAT + 0.0003, ccw=False)]  # a courtyard: a hole
PATH_1 = [[LON, LAT, 0.0], [LON - 0.0018, LAT - 0.0012, 60.0], [LON + 0.0018, LAT - 0.0012, 60.0],
          [LON + 0.0018, LAT + 0.0012, 62.5], [LON, LAT, 0.0]]
PATH_2 = [[LON + 0.0001, LAT, 0.0], [LON - 0.0018, LAT + 0.0012, 70.0], [LON + 0.0001, LAT, 0.0]]


def plan_layers() -> dict[str, dict[str, Any]]:
    return copy.deepcopy({  # AREA and the paths are shared: a test may spoil its copy
        "area": collection(feature("Polygon", AREA, name="Borgo San Paolo")),
        "buildings": collection(  # Polygon and MultiPolygon mixed: written as MULTIPOLYGON
            feature("Polygon", [rect(LON + 0.001, LAT + 0.0005, LON + 0.0013, LAT + 0.0008)],
                    height_m=18.5, known_height=True),
            feature("Polygon", [rect(LON - 0.0013, LAT + 0.0005, LON - 0.001, LAT + 0.0008)],
                    height_m=None, known_height=False),
            feature("MultiPolygon", [[rect(LON + 0.001, LAT - 0.0008, LON + 0.0012, LAT - 0.0006)],
                                     [rect(LON + 0.0013, LAT - 0.0008, LON + 0.0015, LAT - 0.0006)]],
                    height_m=9.0, known_height=True)),
        "clearance": collection(feature("MultiPolygon", [[rect(LON + 0.00095, LAT + 0.00045, LON + 0.00135,
                                                               LAT + 0.00085)]], clearance_m=5.0)),
        "zones": collection(feature("Polygon", [rect(LON - 0.002, LAT - 0.0015, LON, LAT + 0.0015)], uav=1, cells=40),
                            feature("Polygon", [rect(LON, LAT - 0.0015, LON + 0.002, LAT + 0.0015)], uav=2, cells=38)),
        "unreachable": collection(feature("MultiPolygon", [[rect(LON + 0.001, LAT + 0.0005, LON + 0.0013,
                                                                 LAT + 0.0008)]],
                                          cause="building", cells=3, reason="inside a building footprint")),
        "fences": collection(feature("Polygon", [rect(LON - 0.0025, LAT - 0.002, LON + 0.0005, LAT + 0.002)],
                                     uav=1, max_altitude_m=80.0),
                             feature("Polygon", [rect(LON - 0.0005, LAT - 0.002, LON + 0.0025, LAT + 0.002)],
                                     uav=2, max_altitude_m=90.0)),
        "paths": collection(
            feature("LineString", PATH_1, uav=1, sortie=1, altitude_m=60.0, waypoints=5, length_m=1067.2,
                    flight_s=212.5, photos=3),
            feature("LineString", PATH_2, uav=2, sortie=1, altitude_m=70.0, waypoints=3, length_m=452.0,
                    flight_s=95.0, photos=1)),
        "photos": collection(*[feature("Point", p, uav=1, index=i) for i, p in enumerate(PATH_1[1:4])],
                             feature("Point", PATH_2[1], uav=2, index=0)),
        "launch": collection(feature("Point", PATH_1[0], uav=1, label="UAV 1"),
                             feature("Point", PATH_2[0], uav=2, label="UAV 2")),
        "flown": collection(feature("LineString", [p[:2] + [p[2] + 0.4] for p in PATH_1], uav=1, flight_s=219.0)),
        "photos_taken": collection(feature("Point", [LON - 0.0018, LAT - 0.0012, 60.3], uav=1, image="IMG_0001.JPG",
                                           source="camera"),
                                   feature("Point", [LON + 0.0018, LAT - 0.0012, 59.8], uav=1, image="IMG_0002.JPG",
                                           source="log")),
        "missed": collection(),  # full coverage: an empty layer
        "covered": collection(feature("MultiPolygon", [AREA], cells=78)),
    })


GEOMETRY_TYPES = {"missed": "MultiPolygon"}  # declared, as it has no geometry to go by
EXPECTED_TYPES = {  # GDAL's names
    "area": "Polygon", "buildings": "MultiPolygon", "clearance": "MultiPolygon", "zones": "Polygon",
    "unreachable": "MultiPolygon", "fences": "Polygon", "paths": "LineString Z", "photos": "Point Z",
    "launch": "Point Z", "flown": "LineString Z", "photos_taken": "Point Z", "missed": "MultiPolygon",
    "covered": "MultiPolygon",
}


@pytest.fixture
def layers() -> dict[str, dict[str, Any]]:
    return plan_layers()


@pytest.fixture
def gpkg(tmp_path: Path, layers: dict[str, dict[str, Any]]) -> Path:
    path = tmp_path / "plan.gpkg"
    write_geopackage(path, layers, geometry_types=GEOMETRY_TYPES)
    return path


@pytest.fixture
def kmz(tmp_path: Path, layers: dict[str, dict[str, Any]]) -> Path:
    path = tmp_path / "plan.kmz"
    write_kmz(path, layers, "Borgo San Paolo survey")
    return path


def read(path: Path | str, layer: str) -> tuple[dict[str, Any], list[Any], dict[str, Any]]:
    """(meta, shapely geometries, field name -> values) of one layer, GDAL warnings as errors."""
    pyogrio = gdal()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        meta, _, geometries, values = pyogrio.raw.read(str(path), layer=layer)
    return meta, [shapely.from_wkb(g) for g in geometries], dict(zip(meta["fields"], values))


def info(path: Path | str, layer: str) -> dict[str, Any]:
    pyogrio = gdal()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        return pyogrio.read_info(str(path), layer=layer)


def listed(path: Path | str) -> list[tuple[str, str]]:
    pyogrio = gdal()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        return [(str(name), str(kind)) for name, kind in pyogrio.list_layers(str(path))]


def coords(geometry: Any) -> np.ndarray:
    return shapely.get_coordinates(geometry, include_z=shapely.has_z(geometry))


# ---- ring order and altitudes -------------------------------------------------------------------

def test_rfc7946_turns_exteriors_counter_clockwise_and_holes_clockwise() -> None:
    outer_cw = rect(LON - 0.002, LAT - 0.001, LON + 0.002, LAT + 0.001, ccw=False)
    hole_ccw = [p + [3.0] for p in rect(LON - 0.0005, LAT - 0.0002, LON + 0.0005, LAT + 0.0002)]  # with altitudes
    polygon = {"type": "Polygon", "coordinates": [outer_cw, hole_ccw], "bbox": [0, 0, 1, 1]}
    fixed = rfc7946(polygon)
    shape = shapely.geometry.shape(fixed)
    assert shapely.is_ccw(shape.exterior) and not shapely.is_ccw(shape.interiors[0])
    assert fixed["coordinates"][0] == outer_cw[::-1] and fixed["coordinates"][1] == hole_ccw[::-1]
    assert fixed["bbox"] == [0, 0, 1, 1] and polygon["coordinates"][0] == outer_cw  # a new dict; input kept
    assert shape.area == pytest.approx(shapely.geometry.shape(polygon).area)

    multi = rfc7946({"type": "MultiPolygon", "coordinates": [[outer_cw, hole_ccw], [rect(8.0, 45.0, 8.001, 45.001)]]})
    parts = shapely.geometry.shape(multi).geoms
    assert [shapely.is_ccw(p.exterior) for p in parts] == [True, True]
    assert not shapely.is_ccw(parts[0].interiors[0])
    assert multi["coordinates"][1][0] == rect(8.0, 45.0, 8.001, 45.001)  # already right: unchanged

    line = {"type": "LineString", "coordinates": outer_cw}
    assert rfc7946(line) is line


def test_rfc7946_keeps_right_rings_as_they_are() -> None:
    polygon = {"type": "Polygon", "coordinates": AREA}
    assert rfc7946(polygon)["coordinates"] == AREA


def test_layer_schema_types_and_promotion(layers: dict[str, dict[str, Any]]) -> None:
    buildings = layer_schema(layers["buildings"])
    assert buildings.geometry_type == "MultiPolygon" and not buildings.has_z
    assert buildings.fields == {"height_m": "float", "known_height": "bool"}
    paths = layer_schema(layers["paths"])
    assert paths.geometry_type == "LineString" and paths.has_z
    assert paths.fields["uav"] == "int" and paths.fields["length_m"] == "float"
    assert layer_schema(layers["missed"]).geometry_type is None
    mixed = collection(feature("Point", [LON, LAT], v=1), feature("LineString", [[LON, LAT], [LON, 45.0]], v=2.5),
                       feature("Point", [LON, LAT], v=None, note=None))
    assert layer_schema(mixed) == LayerSchema("Geometry", False, {"v": "float", "note": "str"})


# ---- GeoPackage ---------------------------------------------------------------------------------

def test_geopackage_layers_types_counts_and_crs(gpkg: Path, layers: dict[str, dict[str, Any]]) -> None:
    assert listed(gpkg) == list(EXPECTED_TYPES.items())  # names, drawing order, geometry types with Z
    for name, fc in layers.items():
        about = info(gpkg, name)
        assert about["features"] == len(fc["features"]), name
        assert about["crs"] == "EPSG:4326", name
        assert about["driver"] == "GPKG"


def test_geopackage_properties_keep_values_and_types(gpkg: Path) -> None:
    meta, _, values = read(gpkg, "paths")
    assert list(meta["fields"]) == ["uav", "sortie", "altitude_m", "waypoints", "length_m", "flight_s", "photos"]
    assert list(meta["dtypes"]) == ["int64", "int64", "float64", "int64", "float64", "float64", "int64"]
    assert values["uav"].tolist() == [1, 2] and values["length_m"].tolist() == [1067.2, 452.0]

    meta, _, values = read(gpkg, "buildings")
    assert dict(zip(meta["fields"], meta["dtypes"])) == {"height_m": "float64", "known_height": "bool"}
    assert values["known_height"].tolist() == [True, False, True]
    assert values["height_m"][0] == 18.5 and math.isnan(values["height_m"][1])  # None read back as null

    meta, _, values = read(gpkg, "unreachable")
    assert values["reason"].tolist() == ["inside a building footprint"] and values["cells"].tolist() == [3]
    _, _, values = read(gpkg, "photos_taken")
    assert values["image"].tolist() == ["IMG_0001.JPG", "IMG_0002.JPG"]
    assert values["source"].tolist() == ["camera", "log"]


def test_geopackage_coordinates_round_trip(gpkg: Path, layers: dict[str, dict[str, Any]]) -> None:
    _, paths, _ = read(gpkg, "paths")
    assert coords(paths[0]).tolist() == PATH_1 and coords(paths[1]).tolist() == PATH_2  # altitudes too
    _, photos, _ = read(gpkg, "photos")
    assert [coords(p).tolist()[0] for p in photos] == PATH_1[1:4] + [PATH_2[1]]

    _, (area,), _ = read(gpkg, "area")
    assert area.geom_type == "Polygon" and len(area.interiors) == 1
    assert [list(c) for c in area.exterior.coords] == AREA[0]
    assert [list(c) for c in area.interiors[0].coords] == AREA[1]
    assert not area.contains(shapely.Point(LON, LAT))  # in the courtyard
    assert shapely.is_ccw(area.exterior) and not shapely.is_ccw(area.interiors[0])

    _, buildings, _ = read(gpkg, "buildings")
    assert [b.geom_type for b in buildings] == ["MultiPolygon"] * 3  # the Polygons promoted
    expected = [shapely.geometry.shape(f["geometry"]) for f in layers["buildings"]["features"]]
    assert all(shapely.equals_exact(b, shapely.MultiPolygon([e]) if e.geom_type == "Polygon" else e, 0)
               for b, e in zip(buildings, expected))


def test_geopackage_envelopes_serve_a_bounding_box_query(gpkg: Path) -> None:
    # GDAL skips a feature whose GeoPackageBinary header envelope misses the box, before parsing it
    pyogrio = gdal()
    lon, lat, _ = PATH_1[2]
    _, _, _, values = pyogrio.raw.read(str(gpkg), layer="photos", bbox=(lon - 1e-5, lat - 1e-5, lon + 1e-5, lat + 1e-5))
    assert values[1].tolist() == [1]  # photo index 1 alone
    _, _, _, values = pyogrio.raw.read(str(gpkg), layer="buildings",
                                       bbox=(LON + 0.00141, LAT - 0.0007, LON + 0.00142, LAT - 0.00069))
    assert values[0].tolist() == [9.0]  # in the third building's second part
    _, _, _, values = pyogrio.raw.read(str(gpkg), layer="paths",
                                       bbox=(LON - 0.0019, LAT + 0.0011, LON - 0.0017, LAT + 0.0013))
    assert values[0].tolist() == [2]  # uav 2's turn point


def test_geopackage_binary_headers(gpkg: Path) -> None:
    """Every geometry blob: "GP", version 0, little-endian, SRS 4326, the envelope of its WKB (GEOS's
    reading): [minx, maxx, miny, maxy] in 2-D layers, + [minz, maxz] in 3-D ones."""
    with sqlite3.connect(gpkg) as con:
        layers = con.execute("SELECT table_name, z FROM gpkg_geometry_columns").fetchall()
        blobs = [(z, blob) for name, z in layers for (blob,) in con.execute(f'SELECT geom FROM "{name}"')]
    assert len(blobs) == sum(len(fc["features"]) for fc in plan_layers().values())
    for z, blob in blobs:
        magic, version, flags, srs_id = struct.unpack_from("<2sBBi", blob)
        assert (magic, version, srs_id, flags & 1, flags & 0b10000) == (b"GP", 0, 4326, 1, 0)
        envelope_kind = (flags >> 1) & 0b111
        assert envelope_kind == (2 if z else 1)
        envelope = struct.unpack_from(f"<{2 * (envelope_kind + 1)}d", blob, 8)
        geometry = shapely.from_wkb(blob[8 + 8 * len(envelope):])
        assert shapely.has_z(geometry) == bool(z)
        xyz = coords(geometry)
        assert list(envelope) == [float(f(xyz[:, axis])) for axis in range(xyz.shape[1]) for f in (np.min, np.max)]


def test_geopackage_metadata_tables(gpkg: Path, layers: dict[str, dict[str, Any]]) -> None:
    with sqlite3.connect(gpkg) as con:
        assert con.execute("PRAGMA application_id").fetchone()[0] == 0x47504B47  # 'GPKG'
        assert con.execute("PRAGMA user_version").fetchone()[0] == 10300
        srs = con.execute("SELECT srs_id, organization, organization_coordsys_id FROM gpkg_spatial_ref_sys "
                          "ORDER BY srs_id").fetchall()
        assert srs == [(-1, "NONE", -1), (0, "NONE", 0), (4326, "EPSG", 4326)]
        contents = {row[0]: row[1:] for row in con.execute(
            "SELECT table_name, data_type, min_x, min_y, max_x, max_y, srs_id FROM gpkg_contents")}
        columns = {row[0]: row[1:] for row in con.execute(
            "SELECT table_name, column_name, geometry_type_name, srs_id, z, m FROM gpkg_geometry_columns")}
        declared = {row[1]: row[2] for row in con.execute("PRAGMA table_info(buildings)")}
    assert set(contents) == set(layers) == set(columns)
    union = shapely.union_all([shapely.geometry.shape(f["geometry"]) for f in layers["paths"]["features"]])
    assert contents["paths"] == ("features", *union.bounds, 4326)
    assert contents["missed"] == ("features", None, None, None, None, 4326)
    assert columns["paths"] == ("geom", "LINESTRING", 4326, 1, 0)
    assert columns["buildings"] == ("geom", "MULTIPOLYGON", 4326, 0, 0)
    assert declared == {"fid": "INTEGER", "geom": "MULTIPOLYGON", "height_m": "REAL", "known_height": "BOOLEAN"}


def test_geopackage_empty_layer_without_a_declared_type(tmp_path: Path) -> None:
    path = tmp_path / "empty.gpkg"
    write_geopackage(path, {"missed": collection(), "flown": collection()}, geometry_types={"flown": "LineString Z"})
    assert listed(path) == [("missed", "Unknown"), ("flown", "LineString Z")]
    assert info(path, "missed")["features"] == 0
    with pytest.raises(ValueError, match="'Curve' is not one of"):
        write_geopackage(tmp_path / "bad.gpkg", {"missed": collection()}, geometry_types={"missed": "Curve"})


def test_geopackage_refuses_what_it_cannot_write(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="'fid' clashes"):
        write_geopackage(tmp_path / "a.gpkg", {"x": collection(feature("Point", [LON, LAT], fid=3))})
    with pytest.raises(ValueError, match="unsupported geometry type 'GeometryCollection'"):
        write_geopackage(tmp_path / "b.gpkg", {"x": collection(feature("GeometryCollection", []))})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.filterwarnings("ignore:Normalized/laundered field name:RuntimeWarning")  # shapefile's 10 characters
def test_geopackage_converts_to_shapefile_and_kml(gpkg: Path, tmp_path: Path,
                                                  layers: dict[str, dict[str, Any]]) -> None:
    pyogrio = gdal()
    shp_dir, kml_path = tmp_path / "shp", tmp_path / "plan.kml"
    shp_dir.mkdir()
    for name, fc in layers.items():
        meta, _, geometries, values = pyogrio.raw.read(str(gpkg), layer=name)
        written = dict(fields=meta["fields"], crs=meta["crs"], geometry_type=meta["geometry_type"])
        pyogrio.raw.write(str(shp_dir / f"{name}.shp"), geometries, values, driver="ESRI Shapefile",
                          encoding="UTF-8", **written)
        pyogrio.raw.write(str(kml_path), geometries, values, driver="KML", layer=name, append=kml_path.exists(),
                          **written)
        shp = info(shp_dir / f"{name}.shp", None)
        assert shp["features"] == len(fc["features"]) and shp["crs"] == "EPSG:4326", name
        # Shapefile has no single-part polygon type: a polygon shapefile holds both
        assert shp["geometry_type"] == EXPECTED_TYPES[name].replace("MultiPolygon", "Polygon"), name
    _, paths, values = read(shp_dir / "paths.shp", None)
    assert coords(paths[0]).tolist() == PATH_1 and values["flight_s"].tolist() == [212.5, 95.0]
    _, (area,), _ = read(shp_dir / "area.shp", None)
    assert len(area.interiors) == 1
    assert [name for name, _ in listed(kml_path)] == list(layers)
    assert [info(kml_path, name)["features"] for name in layers] == [len(fc["features"]) for fc in layers.values()]


@pytest.mark.skipif(shutil.which("ogrinfo") is None or shutil.which("ogr2ogr") is None,
                    reason="GDAL's command-line tools (ogrinfo, ogr2ogr) are not on PATH")
def test_gdal_command_line_tools_read_and_convert_the_geopackage(gpkg: Path, tmp_path: Path,
                                                                 layers: dict[str, dict[str, Any]]) -> None:
    run = dict(capture_output=True, text=True, check=True, timeout=120)
    summary = subprocess.run(["ogrinfo", "-ro", "-so", "-al", str(gpkg)], **run).stdout
    counts = dict(re.findall(r"Layer name: (\w+)\n(?:.*\n)*?Feature Count: (\d+)", summary))
    assert counts == {name: str(len(fc["features"])) for name, fc in layers.items()}
    subprocess.run(["ogr2ogr", "-f", "ESRI Shapefile", str(tmp_path / "shp"), str(gpkg)], **run)
    assert sorted(p.stem for p in (tmp_path / "shp").glob("*.shp")) == sorted(layers)
    subprocess.run(["ogr2ogr", "-f", "KML", str(tmp_path / "plan.kml"), str(gpkg)], **run)
    summary = subprocess.run(["ogrinfo", "-ro", "-so", "-al", str(tmp_path / "plan.kml")], **run).stdout
    assert re.findall(r"Layer name: (\w+)", summary) == list(layers)


# ---- KMZ ----------------------------------------------------------------------------------------

def kml_root(path: Path) -> ET.Element:
    with zipfile.ZipFile(path) as archive:
        assert archive.namelist() == ["doc.kml"]
        return ET.fromstring(archive.read("doc.kml"))  # well-formed XML, or this raises


@pytest.mark.parametrize("inside", [False, True], ids=["kmz", "vsizip-doc.kml"])
def test_kmz_opens_with_libkml(kmz: Path, layers: dict[str, dict[str, Any]], inside: bool) -> None:
    pyogrio = gdal()
    if "LIBKML" not in pyogrio.list_drivers():
        pytest.skip("this GDAL has no LIBKML driver")
    source = f"/vsizip/{kmz}/doc.kml" if inside else kmz
    assert [name for name, _ in listed(source)] == list(layers)
    assert [info(source, name)["features"] for name in layers] == [len(fc["features"]) for fc in layers.values()]
    assert info(source, "area")["crs"] == "EPSG:4326"

    meta, paths, values = read(source, "paths")
    assert coords(paths[0]).tolist() == PATH_1 and coords(paths[1]).tolist() == PATH_2  # altitudes kept
    assert values["altitudeMode"].tolist() == ["relativeToGround"] * 2
    assert values["uav"].tolist() == [1, 2] and values["flight_s"].tolist() == [212.5, 95.0]  # typed columns
    _, photos, values = read(source, "photos_taken")
    assert [coords(p).tolist()[0][2] for p in photos] == [60.3, 59.8]
    assert values["Name"].tolist() == ["IMG_0001.JPG", "IMG_0002.JPG"]
    _, (area,), _ = read(source, "area")
    assert len(area.interiors) == 1 and [list(c) for c in area.interiors[0].coords] == AREA[1]
    _, buildings, values = read(source, "buildings")
    assert values["extrude"].tolist() == [1, 0, 1] and values["known_height"].tolist() == [True, False, True]
    assert set(coords(buildings[0])[:, 2]) == {18.5}  # the roof, extruded down to the ground


def test_kml_document_structure(kmz: Path) -> None:
    root = kml_root(kmz)
    assert root.tag == KML + "kml"
    doc = root.find(KML + "Document")
    assert doc.findtext(KML + "name") == "Borgo San Paolo survey"
    folders = {f.findtext(KML + "name"): f for f in doc.findall(KML + "Document")}
    assert list(folders) == list(plan_layers())
    lines = folders["paths"].findall(f".//{KML}LineString")
    assert len(lines) == 2 and {line.findtext(KML + "altitudeMode") for line in lines} == {"relativeToGround"}
    first = [[float(v) for v in xyz.split(",")] for xyz in lines[0].findtext(KML + "coordinates").split()]
    assert first == PATH_1
    points = folders["launch"].findall(f".//{KML}Point")
    assert [p.findtext(KML + "coordinates") for p in points] == [f"{LON!r},{LAT!r},0.0",
                                                                 f"{LON + 0.0001!r},{LAT!r},0.0"]
    for name in ("area", "zones", "clearance", "covered"):
        polygons = folders[name].findall(f".//{KML}Polygon")
        assert polygons and {p.findtext(KML + "altitudeMode") for p in polygons} == {"clampToGround"}, name
    known, unknown, _ = folders["buildings"].findall(KML + "Placemark")
    assert known.find(f".//{KML}Polygon").findtext(KML + "extrude") == "1"
    assert unknown.find(f".//{KML}Polygon").findtext(KML + "extrude") is None
    data = {d.get("name"): d.text for d in folders["paths"].find(KML + "Placemark").iter(KML + "SimpleData")}
    assert data == {"uav": "1", "sortie": "1", "altitude_m": "60.0", "waypoints": "5", "length_m": "1067.2",
                    "flight_s": "212.5", "photos": "3"}
    assert "missed" in folders and folders["missed"].find(KML + "Placemark") is None


def test_kml_colours_per_uav(tmp_path: Path, layers: dict[str, dict[str, Any]]) -> None:
    def styles(path: Path) -> dict[str, str]:
        doc = kml_root(path).find(KML + "Document")
        return {s.get("id"): s.find(KML + "LineStyle").findtext(KML + "color") for s in doc.findall(KML + "Style")}

    write_kmz(tmp_path / "default.kmz", layers, "t")
    assert styles(tmp_path / "default.kmz")["uav1"] == "ffb4771f"  # tab10 blue #1f77b4 as aabbggrr
    assert styles(tmp_path / "default.kmz")["uav2"] == "ff0e7fff"  # tab10 orange #ff7f0e
    write_kmz(tmp_path / "own.kmz", layers, "t", colours={2: "#00FF80"})
    assert styles(tmp_path / "own.kmz")["uav2"] == "ff80ff00"
    placemark = kml_root(tmp_path / "own.kmz").find(f".//{KML}Placemark[{KML}name='paths uav 2 sortie 1']")
    assert placemark.findtext(KML + "styleUrl") == "#uav2"
    with pytest.raises(ValueError, match="'red' is not #rrggbb"):
        write_kmz(tmp_path / "bad.kmz", layers, "t", colours={1: "red"})


def test_kmz_same_layers_same_bytes(tmp_path: Path, layers: dict[str, dict[str, Any]]) -> None:
    write_kmz(tmp_path / "a.kmz", layers, "t")
    write_kmz(tmp_path / "b.kmz", plan_layers(), "t")
    assert (tmp_path / "a.kmz").read_bytes() == (tmp_path / "b.kmz").read_bytes()
    with zipfile.ZipFile(tmp_path / "a.kmz") as archive:
        assert archive.getinfo("doc.kml").date_time == (1980, 1, 1, 0, 0, 0)


# ---- atomic writes ------------------------------------------------------------------------------

def test_a_failed_geopackage_write_leaves_no_file(tmp_path: Path, layers: dict[str, dict[str, Any]]) -> None:
    layers["covered"]["features"][0]["geometry"]["coordinates"][0][0][1] = [LON, math.nan]  # the last layer
    with pytest.raises(ValueError, match="non-finite"):
        write_geopackage(tmp_path / "plan.gpkg", layers)
    assert list(tmp_path.iterdir()) == []  # neither the file nor its temp

    (tmp_path / "plan.gpkg").write_bytes(b"the previous plan")
    with pytest.raises(ValueError, match="non-finite"):
        write_geopackage(tmp_path / "plan.gpkg", layers)
    assert [p.name for p in tmp_path.iterdir()] == ["plan.gpkg"]
    assert (tmp_path / "plan.gpkg").read_bytes() == b"the previous plan"  # untouched


def test_a_failed_kmz_write_leaves_no_file(tmp_path: Path, layers: dict[str, dict[str, Any]],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    def disk_full(*args: Any, **kwargs: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(zipfile.ZipFile, "writestr", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_kmz(tmp_path / "plan.kmz", layers, "t")
    assert list(tmp_path.iterdir()) == []
