"""GIS files as a crew brings them: the same buildings written by ogr2ogr as KML, KMZ (LIBKML), GeoPackage,
Shapefile (and a .zip of one), FlatGeobuf and GML give the plan the same grid, the same buildings and the
same heights as the GeoJSON they were written from; layers, CRSs, heights, what is left out, and hostile
files. ogr2ogr (Debian's gdal-bin, which CI installs) writes the files, independently of the reader
(pyogrio's own GDAL); the tests that need it skip when it is absent.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapely

from missionplan.cli import main
from missionplan.cli.app import build_parser
from missionplan.cli.parsing import request_of
from missionplan.cli.plan import PlanRequest
from missionplan.geo import guards
from missionplan.geo.errors import GeoError
from missionplan.geo.readers import read_area_file, read_building_file, read_buildings
from missionplan.mission.georef import load_area_checked

OGR2OGR = shutil.which("ogr2ogr")
needs_ogr2ogr = pytest.mark.skipif(OGR2OGR is None, reason="ogr2ogr not installed (apt-get install gdal-bin)")

LON0, LAT0 = 7.6500, 45.0690
AREA = [[LON0, LAT0], [LON0 + 0.0040, LAT0], [LON0 + 0.0040, LAT0 + 0.0030], [LON0, LAT0 + 0.0030], [LON0, LAT0]]
LAUNCH = f"{LAT0 + 0.0002},{LON0 + 0.0002}"
ALTITUDE = "30"  # buildings from 25 m (30 m less the 5 m margin) are obstacles, lower ones are overflown


def _buildings(count: int = 23, heights: bool = True) -> dict:
    """`count` blocks of about 24 x 22 m on a 5-wide grid; heights 10..54 m as OSM writes them: '17',
    '18.5 m', or only building:levels (3 m a level)."""
    features = []
    for i in range(count):
        x, y = LON0 + 0.0004 + (i % 5) * 0.0007, LAT0 + 0.0004 + (i // 5) * 0.0005
        ring = [[x, y], [x + 0.0003, y], [x + 0.0003, y + 0.0002], [x, y + 0.0002], [x, y]]
        props = {"osmid": 1000 + i, "building": "yes", "height": None, "building:levels": None}
        if heights and i % 3 == 0:
            props["height"] = str(10 + 2 * i)
        elif heights and i % 3 == 1:
            props["height"] = f"{10 + 2 * i}.5 m"
        elif heights:
            props["building:levels"] = str(3 + i % 9)
        features.append({"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": [ring]}})
    return {"type": "FeatureCollection", "features": features}


def _write(path: Path, doc: object) -> Path:
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc), encoding="utf-8")
    return path


def _ogr2ogr(out: Path, src: Path, driver: str, *extra: str) -> Path:
    done = subprocess.run([OGR2OGR, "-f", driver, str(out), str(src), *extra], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    return out


def _zip(out: Path, files: list[Path]) -> Path:
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for f in files:
            z.write(f, f.name)
    return out


def _written(tmp_path: Path, src: Path, fmt: str) -> Path:
    """`src` (GeoJSON) as ogr2ogr writes `fmt`."""
    if fmt == "kml":
        return _ogr2ogr(tmp_path / "b.kml", src, "KML")
    if fmt == "kmz":
        return _ogr2ogr(tmp_path / "b.kmz", src, "LIBKML")
    if fmt == "gpkg":
        return _ogr2ogr(tmp_path / "b.gpkg", src, "GPKG")
    if fmt == "fgb":
        return _ogr2ogr(tmp_path / "b.fgb", src, "FlatGeobuf")
    if fmt == "gml":
        return _ogr2ogr(tmp_path / "b.gml", src, "GML")
    shp = _ogr2ogr(tmp_path / "b.shp", src, "ESRI Shapefile")
    if fmt == "shp":
        return shp
    return _zip(tmp_path / "b.zip", sorted(tmp_path.glob("b.*")))


def _by_osmid(path: Path) -> dict[str, tuple[float | None, shapely.Geometry]]:
    return {str(b.properties["osmid"]): (b.height_m, b.geometry) for b in read_buildings(path)}


def _args(area: Path, osm: Path | None, *extra: str) -> list[str]:
    args = ["plan", "--area", str(area), "--altitude", ALTITUDE, "--fov", "84", "--launch", LAUNCH, "--quiet", *extra]
    return args + (["--osm", str(osm)] if osm is not None else [])


def _grid(area: Path, osm: Path | None, *extra: str) -> tuple[np.ndarray, np.ndarray]:
    args = build_parser().parse_args(_args(area, osm, "--out", "unused", *extra))
    gmap = load_area_checked(request_of(PlanRequest, args).area_request())[0]
    return gmap.obstacle, gmap.target


def _plan(tmp_path: Path, area: Path, osm: Path | None, out: str, *extra: str) -> tuple[int, dict]:
    code = main(_args(area, osm, "--out", str(tmp_path / out), *extra))
    report = tmp_path / out / "report.json"
    return code, json.loads(report.read_text()) if report.exists() else {}


@pytest.fixture
def city(tmp_path: Path) -> tuple[Path, Path]:
    return (_write(tmp_path / "area.geojson", {"type": "Polygon", "coordinates": [AREA]}),
            _write(tmp_path / "buildings.geojson", _buildings()))


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, tuple[np.ndarray, np.ndarray], dict]:
    """The GeoJSON buildings planned once: area, buildings, their grid (obstacle, target) and report."""
    folder = tmp_path_factory.mktemp("reference")
    area, geojson = (_write(folder / "area.geojson", {"type": "Polygon", "coordinates": [AREA]}),
                     _write(folder / "buildings.geojson", _buildings()))
    code, report = _plan(folder, area, geojson, "run")
    assert code == 0
    return area, geojson, _grid(area, geojson), report


# ---- the same buildings through every format ------------------------------------------------------------------

@needs_ogr2ogr
@pytest.mark.parametrize("fmt", ["kml", "kmz", "gpkg", "shp", "zip", "fgb", "gml"])
def test_every_format_gives_the_geojson_grid_buildings_and_heights(tmp_path, reference, fmt, capsys):
    area, geojson, (obstacle, target), report = reference
    converted = _written(tmp_path, geojson, fmt)
    expected, got = _by_osmid(geojson), _by_osmid(converted)
    assert set(got) == set(expected) and len(got) == 23
    for osmid, (height, geom) in expected.items():
        assert got[osmid][0] == height, (osmid, got[osmid][0], height)
        assert shapely.normalize(got[osmid][1]).equals_exact(shapely.normalize(geom), 1e-9)  # (Shapefile: clockwise)
    assert all(h is not None for h, _ in got.values())  # 23 of 23 heights read
    obstacle_fmt, target_fmt = _grid(area, converted)
    assert (obstacle == obstacle_fmt).all() and (target == target_fmt).all()
    assert obstacle.any() and (~obstacle & ~target).any()  # tall blocks are obstacles, low roofs are overflown

    code_fmt, report_fmt = _plan(tmp_path, area, converted, f"from-{fmt}")
    assert code_fmt == 0
    for key in ("targets", "unreachable", "unreachable_cells", "coverage"):
        assert report[key] == report_fmt[key], key
    entry = next(e for e in report_fmt["inputs"] if e["role"] == "buildings")
    assert entry["features"] == entry["buildings_in_area"] == 23 and entry["unknown_height"] == []
    assert entry["dropped"] == [] and entry["crs"].startswith("EPSG:4326")
    assert "warning" not in capsys.readouterr().err


@needs_ogr2ogr
def test_gdal_kml_with_schemadata_keeps_every_height(tmp_path, city):
    # ogr2ogr / QGIS write attributes as <SchemaData><SimpleData name="height">: read, not "unknown".
    area, geojson = city
    kml = _written(tmp_path, geojson, "kml")
    assert "<SimpleData name=\"height\">" in kml.read_text()
    blds, source = read_building_file(kml)
    assert len(blds) == 23 and sum(b.height_m is not None for b in blds) == 23
    assert source.format == "KML" and source.reader == "missionplan"
    code, report = _plan(tmp_path, area, kml, "run")
    assert code == 0 and report["coverage"]["unknown_height_buildings"] == 0


# ---- CRS -------------------------------------------------------------------------------------------------------

@needs_ogr2ogr
def test_a_utm_shapefile_gives_the_grid_of_its_wgs84_twin_and_names_its_crs(tmp_path, city):
    area, geojson = city
    area_utm = _ogr2ogr(tmp_path / "area_utm.shp", area, "ESRI Shapefile", "-t_srs", "EPSG:32632")
    blds_utm = _ogr2ogr(tmp_path / "blds_utm.shp", geojson, "ESRI Shapefile", "-t_srs", "EPSG:32632")
    import pyogrio

    assert pyogrio.read_info(str(blds_utm))["crs"] == "EPSG:32632"  # metres: easting ~ 393 km in zone 32
    obstacle, target = _grid(area, geojson)
    obstacle_utm, target_utm = _grid(area_utm, blds_utm)
    assert (obstacle == obstacle_utm).all() and (target == target_utm).all()
    code, report = _plan(tmp_path, area_utm, blds_utm, "run")
    assert code == 0
    crs = {e["role"]: (e["crs"], e["reprojected"]) for e in report["inputs"]}
    assert crs == {"area": ("EPSG:32632 (WGS 84 / UTM zone 32N)", True),
                   "buildings": ("EPSG:32632 (WGS 84 / UTM zone 32N)", True)}


@needs_ogr2ogr
def test_a_web_mercator_geopackage_and_a_2008_geojson_crs_are_reprojected(tmp_path, city):
    area, geojson = city
    mercator = _ogr2ogr(tmp_path / "b3857.gpkg", geojson, "GPKG", "-t_srs", "EPSG:3857")
    blds, source = read_building_file(mercator)
    assert source.crs == "EPSG:3857 (WGS 84 / Pseudo-Mercator)" and source.reprojected
    expected = _by_osmid(geojson)
    for b in blds:
        assert shapely.normalize(b.geometry).equals_exact(shapely.normalize(expected[str(b.properties["osmid"])][1]),
                                                          1e-9)
    legacy = _ogr2ogr(tmp_path / "b3857.geojson", geojson, "GeoJSON", "-t_srs", "EPSG:3857")
    assert "EPSG::3857" in legacy.read_text()  # GDAL writes the 2008 'crs' member for a CRS not WGS84
    blds, source = read_building_file(legacy)
    assert source.crs.startswith("EPSG:3857") and len(blds) == 23


def test_a_file_without_crs_is_taken_as_lonlat_and_said_so(tmp_path):
    import pyogrio.raw

    poly = shapely.Polygon(AREA)
    with pytest.warns(UserWarning, match="'crs' was not provided"):  # pyogrio: as a crew's old export would be
        pyogrio.raw.write(str(tmp_path / "nocrs.shp"), np.array([shapely.to_wkb(poly)], dtype=object), [], [],
                          driver="ESRI Shapefile", geometry_type="Polygon")
    area, source = read_area_file(tmp_path / "nocrs.shp")
    assert area.equals(poly) and source.crs == "none in the file: taken as WGS84 lon/lat"


# ---- layers ----------------------------------------------------------------------------------------------------

@needs_ogr2ogr
def test_a_geopackage_of_several_layers_takes_file_colon_layer(tmp_path, city, capsys):
    area, geojson = city
    gpkg = _ogr2ogr(tmp_path / "city.gpkg", geojson, "GPKG", "-nln", "buildings")
    parks = _write(tmp_path / "parks.geojson", {"type": "Polygon", "coordinates": [[[x + 0.0001, y] for x, y in AREA]]})
    _ogr2ogr(gpkg, parks, "GPKG", "-update", "-nln", "parks")
    trees = _write(tmp_path / "trees.geojson", {"type": "Point", "coordinates": [LON0 + 0.001, LAT0 + 0.001]})
    _ogr2ogr(gpkg, trees, "GPKG", "-update", "-nln", "trees")

    code, report = _plan(tmp_path, area, Path(f"{gpkg}:buildings"), "run")
    assert code == 0
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    assert (entry["path"], entry["layer"], entry["features"]) == (str(gpkg), "buildings", 23)
    assert (_grid(area, Path(f"{gpkg}:buildings"))[0] == _grid(area, geojson)[0]).all()
    capsys.readouterr()

    assert main(_args(area, gpkg, "--out", str(tmp_path / "o"))) == 2
    err = capsys.readouterr().err
    assert err == (f"missionplan: {gpkg} holds 2 layers of polygons: buildings, parks; name one as "
                   f"{gpkg}:LAYER\n")
    assert main(_args(area, Path(f"{gpkg}:roads"), "--out", str(tmp_path / "o"))) == 2
    assert capsys.readouterr().err == f"missionplan: {gpkg}: no layer 'roads' (its layers: buildings, parks, trees)\n"
    assert main(_args(area, Path(f"{geojson}:x"), "--out", str(tmp_path / "o"))) == 2
    assert capsys.readouterr().err == f"missionplan: {geojson}: a .geojson file has no layers (':x' follows its name)\n"
    assert not (tmp_path / "o").exists()


def test_a_path_that_exists_with_a_colon_is_the_file(tmp_path):
    odd = _write(tmp_path / "a:b.geojson", {"type": "Polygon", "coordinates": [AREA]})
    assert read_area_file(odd)[1].path == str(odd) and read_area_file(odd)[1].layer is None


@needs_ogr2ogr
def test_a_multilayer_kmz_and_our_own_plan_kmz(tmp_path, city):
    area, geojson = city
    gpkg = _ogr2ogr(tmp_path / "two.gpkg", geojson, "GPKG", "-nln", "buildings")
    _ogr2ogr(gpkg, area, "GPKG", "-update", "-nln", "zone")
    kmz = _ogr2ogr(tmp_path / "two.kmz", gpkg, "LIBKML")  # one KML per layer inside, linked from doc.kml
    with pytest.raises(GeoError) as err:
        read_buildings(kmz)
    assert str(err.value) == f"{kmz} holds 2 layers of polygons: buildings, zone; name one as {kmz}:LAYER"
    blds, source = read_building_file(f"{kmz}:buildings")
    assert len(blds) == 23 and all(b.height_m is not None for b in blds) and source.layer == "buildings"
    # a plan's own plan.kmz (a Document per layer) read back: its area layer is an area
    assert main(_args(area, geojson, "--out", str(tmp_path / "run"))) == 0
    own, source = read_area_file(f"{tmp_path / 'run' / 'plan.kmz'}:area")
    assert shapely.normalize(own).equals_exact(shapely.normalize(shapely.Polygon(AREA)), 1e-9)
    assert source.format == "KMZ" and source.layer == "area"


# ---- heights and --height-field --------------------------------------------------------------------------------

@needs_ogr2ogr
def test_height_field_names_the_field_and_its_absence_is_one_line(tmp_path, city, capsys):
    area, _ = city
    doc = _buildings(heights=False)
    for i, f in enumerate(doc["features"]):
        f["properties"]["HOEHE"] = 12.0 + i  # a cadastre's own field, numbers
    gpkg = _ogr2ogr(tmp_path / "kataster.gpkg", _write(tmp_path / "k.geojson", doc), "GPKG")
    blds = read_buildings(gpkg, height_field="hoehe")  # any case
    assert sorted(b.height_m for b in blds) == [12.0 + i for i in range(23)]
    assert all(b.height_m is None for b in read_buildings(gpkg))
    assert main(_args(area, gpkg, "--height-field", "Hoehe", "--out", str(tmp_path / "run"))) == 0
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    assert entry["height_field"] == "Hoehe" and entry["unknown_height"] == []
    capsys.readouterr()
    assert main(_args(area, gpkg, "--height-field", "storeys", "--out", str(tmp_path / "o"))) == 2
    assert capsys.readouterr().err == (f"missionplan: {gpkg}: no field 'storeys' (--height-field); its fields: "
                                       f"HOEHE, building, building:levels, height, osmid\n")
    assert main(_args(area, None, "--height-field", "h", "--out", str(tmp_path / "o"))) == 2
    assert capsys.readouterr().err == "missionplan: --height-field needs --osm (the buildings whose height it holds)\n"
    assert not (tmp_path / "o").exists()


def test_unknown_repaired_and_dropped_buildings_are_named_in_the_report_and_one_warning(tmp_path, capsys):
    area = _write(tmp_path / "area.geojson", {"type": "Polygon", "coordinates": [AREA]})
    doc = _buildings(count=6)
    doc["features"][1]["properties"].update({"height": None, "building:levels": None})  # unknown height
    x, y = LON0 + 0.0011, LAT0 + 0.0004  # a ring touching itself (a zero-width spike): repaired, area unchanged
    doc["features"][2]["geometry"]["coordinates"] = [[[x, y], [x + 0.0003, y], [x + 0.0003, y + 0.0002],
                                                      [x + 0.00015, y + 0.0002], [x + 0.00015, y + 0.0003],
                                                      [x + 0.00015, y + 0.0002], [x, y + 0.0002], [x, y]]]
    doc["features"][4]["geometry"] = None  # no geometry: not read, named
    osm = _write(tmp_path / "b.geojson", doc)
    code, report = _plan(tmp_path, area, osm, "run")
    assert code == 0
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    # each named by its place in the file and the OpenStreetMap id its properties carry
    assert entry["unknown_height"] == ["feature 1 [OSM id 1001]"]
    assert [r["id"] for r in entry["repaired"]] == ["feature 2 [OSM id 1002]"]
    assert "Self-intersection" in entry["repaired"][0]["cause"]
    assert entry["dropped"] == [{"id": "feature 4 [OSM id 1004]", "cause": "no geometry (null)"}]
    err = capsys.readouterr().err.splitlines()
    assert err == [f"missionplan: warning: {report['coverage']['warnings'][0]}"]
    assert err[0] == (f"missionplan: warning: {osm}: 1 building not read: feature 4 [OSM id 1004] (no geometry "
                      f"(null)). {osm}: 1 building repaired: feature 2 [OSM id 1002] ({entry['repaired'][0]['cause']})"
                      f". {osm}: 1 of the 5 buildings in the area have no height (height, building:height or "
                      f"building:levels), so they are obstacles: feature 1 [OSM id 1001] (--unknown-building-height M "
                      f"gives them one). All are listed in report.json under inputs.")
    assert report["coverage"]["unknown_height_buildings"] == 1


def test_a_long_list_is_summarised_in_the_line_and_whole_in_the_report(tmp_path, capsys):
    area = _write(tmp_path / "area.geojson", {"type": "Polygon", "coordinates": [AREA]})
    osm = _write(tmp_path / "bare.geojson", _buildings(heights=False))
    code, report = _plan(tmp_path, area, osm, "run")
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    assert code == 0 and entry["unknown_height"] == [f"feature {i} [OSM id {1000 + i}]" for i in range(23)]
    err = capsys.readouterr().err
    assert ("23 of the 23 buildings in the area have no height (height, building:height or building:levels), so "
            "they are obstacles: feature 0 [OSM id 1000], feature 1 [OSM id 1001], feature 2 [OSM id 1002] and 20 "
            "more (") in err
    # with a height given to them, they are no longer worth a warning (the report still lists them)
    code, report = _plan(tmp_path, area, osm, "low", "--unknown-building-height", "6")
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    assert entry["unknown_height_assumed_m"] == 6.0 and len(entry["unknown_height"]) == 23
    assert "have no height" not in capsys.readouterr().err


# ---- hostile files ---------------------------------------------------------------------------------------------

LAUGHS = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol">'
          + "".join(f'<!ENTITY lol{k + 1} "{("&lol" + (str(k) if k else "") + ";") * 10}">' for k in range(9))
          + "]>\n")


@needs_ogr2ogr
def test_a_gml_with_a_dtd_is_refused_before_gdal_reads_it(tmp_path, city):
    _, geojson = city
    gml = _written(tmp_path, geojson, "gml")
    body = gml.read_text().split("?>", 1)[1]
    for name, prolog in (("laughs", LAUGHS), ("xxe", '<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY x SYSTEM '
                                                        '"file:///etc/passwd">]>\n')):
        bad = _write(tmp_path / f"{name}.gml", prolog + body)
        with pytest.raises(GeoError) as err:
            read_buildings(bad)
        assert str(err.value).startswith(f"{bad}: the XML declares a DTD (<!DOCTYPE ...>); GML needs none")
    assert not list(tmp_path.glob("*.gfs"))  # and GDAL wrote nothing beside the input
    assert len(read_buildings(gml)) == 23 and not list(tmp_path.glob("*.gfs"))


def test_kml_xxe_and_billion_laughs_are_refused(tmp_path):
    placemark = ("<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Placemark><name>&lol9;</name><Polygon><outerBoundaryIs>"
                 "<LinearRing><coordinates>7.65,45.06 7.66,45.06 7.66,45.07 7.65,45.06</coordinates></LinearRing>"
                 "</outerBoundaryIs></Polygon></Placemark></kml>")
    for name, doc in (("laughs.kml", LAUGHS + placemark),
                      ("xxe.kml", '<?xml version="1.0"?><!DOCTYPE k [<!ENTITY lol9 SYSTEM "file:///etc/passwd">]>'
                                  + placemark)):
        path = _write(tmp_path / name, doc)
        with pytest.raises(GeoError, match=r"the XML declares a DTD") as err:
            read_area_file(path)
        assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def _kmz(path: Path, doc: str, members: dict[str, str] | None = None) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("doc.kml", doc)
        for name, text in (members or {}).items():
            z.writestr(name, text)
    return path


def _forge_size(path: Path, size: int) -> None:
    """Write `size` as the declared uncompressed size of the archive's first member (local and central header)."""
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, data.find(b"PK\x03\x04") + 22, size)
    struct.pack_into("<I", data, data.find(b"PK\x01\x02") + 24, size)
    path.write_bytes(bytes(data))


KML_SQUARE = ("<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Document><Placemark><Polygon><outerBoundaryIs><LinearRing>"
              "<coordinates>" + " ".join(f"{x},{y}" for x, y in AREA) + "</coordinates></LinearRing></outerBoundaryIs>"
              "</Polygon></Placemark></Document></kml>")


def test_a_kmz_bomb_and_a_forged_kmz_are_refused_in_one_line(tmp_path):
    bomb = _kmz(tmp_path / "bomb.kmz", KML_SQUARE)
    _forge_size(bomb, 3 << 30)  # says 3 GiB: refused before a byte is inflated
    with pytest.raises(GeoError) as err:
        read_area_file(bomb)
    assert str(err.value) == (f"{bomb}: doc.kml would inflate to 3,072 MiB (limit 1,024 MiB): refused as a zip bomb "
                              f"or far too large")
    forged = _kmz(tmp_path / "forged.kmz", KML_SQUARE)
    _forge_size(forged, 100)  # says less than it holds: zipfile stops there and the CRC fails
    with pytest.raises(GeoError) as err:
        read_area_file(forged)
    assert str(err.value).startswith(f"{forged}: cannot read doc.kml from the archive (")
    assert read_area_file(_kmz(tmp_path / "fine.kmz", KML_SQUARE))[0].equals(shapely.Polygon(AREA))


def test_kmz_links_are_followed_inside_the_archive_only(tmp_path):
    outside = tmp_path / "secret.kml"
    _write(outside, KML_SQUARE)
    doc = ("<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Document>"
           + "".join(f"<NetworkLink><Link><href>{href}</href></Link></NetworkLink>"
                     for href in ("layers/a.kml", "../secret.kml", str(outside), "http://example.invalid/x.kml",
                                  "layers/a.kml"))
           + "</Document></kml>")
    kmz = _kmz(tmp_path / "links.kmz", doc, {"layers/a.kml": KML_SQUARE})
    area, source = read_area_file(kmz)
    assert area.equals(shapely.Polygon(AREA)) and source.features == 1  # a.kml once, nothing from outside


@needs_ogr2ogr
def test_a_zipped_shapefile_is_extracted_bounded(tmp_path, city, monkeypatch):
    _, geojson = city
    zipped = _written(tmp_path, geojson, "zip")
    blds, source = read_building_file(zipped)
    assert len(blds) == 23 and source.format == "Shapefile in a zip" and source.path == str(zipped)
    monkeypatch.setattr(guards, "MAX_EXTRACT_BYTES", 1000)
    with pytest.raises(GeoError) as err:
        read_buildings(zipped)
    assert str(err.value).startswith(f"{zipped}: its members would inflate to ") and "refused as a zip bomb" in str(
        err.value)
    empty = _zip(tmp_path / "none.zip", [geojson])
    with pytest.raises(GeoError, match=r"none\.zip: the zip holds no Shapefile \(\.shp\)"):
        read_buildings(empty)


@needs_ogr2ogr
def test_a_renamed_file_is_not_handed_to_another_driver(tmp_path, city):
    _, geojson = city
    gml = _written(tmp_path, geojson, "gml")
    for ext, name in ((".gpkg", "GeoPackage"), (".fgb", "FlatGeobuf"), (".shp", "Shapefile")):
        renamed = tmp_path / f"really_gml{ext}"
        shutil.copy(gml, renamed)
        with pytest.raises(GeoError) as err:
            read_buildings(renamed)
        assert str(err.value) == f"{renamed}: not a {name} (it does not start as a {name} does)"


@needs_ogr2ogr
def test_broken_gis_files_name_file_and_feature(tmp_path, city, capsys):
    area, geojson = city
    gpkg = _written(tmp_path, geojson, "gpkg")
    broken = tmp_path / "broken.gpkg"
    broken.write_bytes(gpkg.read_bytes()[:40_000])  # cut, as a copy that did not finish
    assert main(_args(area, broken, "--out", str(tmp_path / "o"))) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"missionplan: {broken}: cannot read it as GeoPackage (") and err.count("\n") == 1
    assert "database disk image is malformed" in err
    doc = _buildings(count=3)
    doc["features"][2]["geometry"]["coordinates"][0][1] = [LON0 + 0.003, LAT0 + 0.01]  # a bowtie
    bow = _ogr2ogr(tmp_path / "bow.gpkg", _write(tmp_path / "bow.geojson", doc), "GPKG")
    with pytest.raises(GeoError) as err:
        read_buildings(bow)
    assert str(err.value).startswith(f"{bow}: feature 3: self-intersecting polygon (")  # GPKG's FIDs start at 1
    assert not (tmp_path / "o").exists()


@needs_ogr2ogr
def test_an_open_ring_in_a_shapefile_names_the_feature(tmp_path, city):
    import pyogrio.raw

    _, geojson = city
    shp = _written(tmp_path, geojson, "shp")
    meta, _, wkb, fields = pyogrio.raw.read(str(shp))
    ring = shapely.get_coordinates(shapely.from_wkb(wkb[5]))[:-1]  # drop the closing point
    # shapely cannot make an open ring: write the WKB by hand (one polygon, one ring)
    wkb[5] = struct.pack("<BII", 1, 3, 1) + struct.pack("<I", len(ring)) + ring.astype("<f8").tobytes()
    pyogrio.raw.write(str(tmp_path / "open.shp"), wkb, fields, meta["fields"], driver="ESRI Shapefile",
                      geometry_type="Polygon", crs="EPSG:4326")
    with pytest.raises(GeoError) as err:
        read_buildings(tmp_path / "open.shp")
    assert str(err.value).startswith(f"{tmp_path / 'open.shp'}: feature 5: ")
