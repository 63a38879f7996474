"""Property tests: every reader of user files (GeoJSON, KML, KMZ, GeoPackage, .plan as area, OSM, .map)
meets arbitrary and structurally wrong input with its own one-line error naming the file, never
another exception, and `plan` itself gives a plan or one line (exit 2), never a traceback. The
bridge's .plan / .waypoints mission readers are tested beside them (bridge/formats/missionfile.py).

Each example writes one small file; max_examples keeps the whole module to seconds. For a
longer hunt: MISSIONPLAN_FUZZ_EXAMPLES=5000 pytest tests/test_readers_fuzz.py
"""

from __future__ import annotations

import atexit
import json
import math
import os
import shutil
import struct
import tempfile
import zipfile
from pathlib import Path

import numpy as np

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from missionplan.cli import main
from missionplan.geo.errors import GeoError
from missionplan.geo.readers import read_area, read_buildings, read_features, read_osm_buildings, read_polygons
from missionplan.maps.gridmap import MapError, load_map, parse_map
from missionplan.bridge.formats.mission_items import CMD_NAV_TAKEOFF

FUZZ = settings(max_examples=int(os.environ.get("MISSIONPLAN_FUZZ_EXAMPLES", "150")), deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

_DIR = Path(tempfile.mkdtemp(prefix="mp-fuzz-"))
atexit.register(shutil.rmtree, _DIR, True)  # examples overwrite the same few files; drop them at the end

# Numbers that break readers: NaN, infinities, out-of-range degrees, huge and tiny values.
odd_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20),
                        st.sampled_from([0, 1, -1, 180.0, -180.0, 180.5, 90.0, 90.1, -90.1, 1e308, 5e-324]))
json_scalars = st.one_of(st.none(), st.booleans(), odd_numbers, st.text(max_size=8))
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=8), inner, max_size=5)), max_leaves=25)

OUTER = [[7.650, 45.060], [7.660, 45.060], [7.660, 45.070], [7.650, 45.070], [7.650, 45.060]]
VALID_GEOJSON = {"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"height": "12 m"},
     "geometry": {"type": "Polygon", "coordinates": [OUTER]}},
    {"type": "Feature", "properties": None,
     "geometry": {"type": "MultiPolygon", "coordinates": [[OUTER]]}}]}
VALID_PLAN = {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
              "mission": {"version": 2, "items": [
                  {"type": "SimpleItem", "command": CMD_NAV_TAKEOFF},
                  {"type": "ComplexItem", "complexItemType": "survey", "polygon": [[y, x] for x, y in OUTER[:-1]]},
                  {"type": "ComplexItem", "complexItemType": "CorridorScan", "CorridorWidth": 20,
                   "polyline": [[45.06, 7.65], [45.06, 7.66]]}]},
              "geoFence": {"version": 2, "circles": [], "polygons": [
                  {"inclusion": True, "polygon": [[y, x] for x, y in OUTER[:-1]], "version": 1},
                  {"inclusion": False, "polygon": [[y + 0.002, x + 0.002] for x, y in OUTER[:-1]], "version": 1}]},
              "rallyPoints": {"version": 2, "points": []}}


@st.composite
def mutated(draw: st.DrawFn, doc: object) -> object:
    """`doc` with one to three nodes (anywhere in the tree) replaced by arbitrary JSON."""
    doc = json.loads(json.dumps(doc))
    for _ in range(draw(st.integers(1, 3))):
        node, key = None, None
        cursor = doc
        for _ in range(draw(st.integers(0, 6))):  # how deep the replaced node lies
            if not isinstance(cursor, (dict, list)) or not cursor:
                break
            keys = list(cursor.keys()) if isinstance(cursor, dict) else list(range(len(cursor)))
            node, key = cursor, draw(st.sampled_from(keys))
            cursor = cursor[key]
        # A wrong scalar where a list or object belongs is the common structural fault.
        replacement = st.one_of(odd_numbers, st.booleans(), st.text(max_size=4), json_values)
        if node is None:
            return draw(replacement)
        node[key] = draw(replacement)
    return doc


def _write(name: str, content: str | bytes) -> Path:
    path = _DIR / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _dump(value: object) -> str:
    return json.dumps(value)  # NaN / Infinity written as JavaScript literals, which Python reads back


def _only_own_errors(path: Path, *readers) -> None:
    """Each reader returns or raises its own one-line error naming the file."""
    for reader in readers:
        try:
            reader(path)
        except (GeoError, MapError) as err:
            message = str(err)
            assert "\n" not in message, message
            assert path.name in message, message


def _check_polygons_finite(path: Path) -> None:
    """What a reader accepts is finite lon/lat: no NaN, no 95° latitude gets through."""
    try:
        feats = read_features(path)
    except GeoError:
        return
    for f in feats:
        minx, miny, maxx, maxy = f.geometry.bounds
        assert all(math.isfinite(v) for v in (minx, miny, maxx, maxy))
        assert -180 <= minx <= maxx <= 180 and -90 <= miny <= maxy <= 90


# ---- GeoJSON ------------------------------------------------------------------------------

@FUZZ
@given(st.one_of(json_values, mutated(VALID_GEOJSON)))
def test_geojson_reader_only_raises_geo_error(doc):
    path = _write("fuzz.geojson", _dump(doc))
    _only_own_errors(path, read_features, read_area, read_polygons, read_buildings)
    _check_polygons_finite(path)


@FUZZ
@given(st.binary(max_size=64) | st.text(max_size=64).map(str.encode))
def test_geojson_reader_on_bytes(data):
    _only_own_errors(_write("bytes.json", data), read_area, read_buildings)


# ---- QGroundControl .plan as an area -------------------------------------------------------

@FUZZ
@given(st.one_of(json_values, mutated(VALID_PLAN)))
def test_plan_area_reader_only_raises_geo_error(doc):
    path = _write("fuzz.plan", _dump(doc))
    _only_own_errors(path, read_features, read_area, read_polygons)
    _check_polygons_finite(path)


# ---- KML -----------------------------------------------------------------------------------

coordinate_token = st.one_of(
    st.tuples(odd_numbers, odd_numbers).map(lambda p: f"{p[0]},{p[1]},0"),
    st.sampled_from(["7.65,45.06", "nan,45", "inf,-inf", "7.65", ",", "1,2,3,4", "x,y", "7.65,95"]),
    st.text(alphabet="0123456789.,-e ", max_size=12))


@st.composite
def kml_documents(draw: st.DrawFn) -> str:
    ring = [f"{x},{y},0" for x, y in OUTER]
    tokens = draw(st.lists(coordinate_token, max_size=6))
    if draw(st.booleans()):
        ring = tokens  # wholly arbitrary
    else:
        ring = ring[:draw(st.integers(0, len(ring)))] + tokens  # a valid start, then anything
    inner = draw(st.sampled_from([
        "<Polygon><outerBoundaryIs><LinearRing><coordinates>{c}</coordinates></LinearRing></outerBoundaryIs></Polygon>",
        "<Polygon><outerBoundaryIs><LinearRing><coordinates>{c}</coordinates></LinearRing></outerBoundaryIs>"
        "<innerBoundaryIs><LinearRing><coordinates>{c}</coordinates></LinearRing></innerBoundaryIs></Polygon>",
        "<Polygon><innerBoundaryIs><coordinates>{c}</coordinates></innerBoundaryIs></Polygon>",
        "<MultiGeometry><Polygon><outerBoundaryIs><coordinates>{c}</coordinates></outerBoundaryIs></Polygon>"
        "<Point><coordinates>{c}</coordinates></Point></MultiGeometry>",
        "<LineString><coordinates>{c}</coordinates></LineString>",
        "<Polygon><outerBoundaryIs><LinearRing><coordinates/></LinearRing></outerBoundaryIs></Polygon>",
        "{c}",
    ])).format(c=" ".join(ring))
    name = draw(st.text(alphabet=st.characters(codec="utf-8", exclude_characters="<&\x00"), max_size=6))
    data = draw(st.sampled_from(["", '<ExtendedData><Data name="height"><value>{v}</value></Data></ExtendedData>']))
    data = data.format(v=draw(st.text(alphabet="0123456789.,m ft'-", max_size=6)))
    return (f'<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2"><Document>'
            f"<Placemark><name>{name}</name>{data}{inner}</Placemark></Document></kml>")


@FUZZ
@given(st.one_of(kml_documents(), st.text(max_size=80), st.binary(max_size=64)))
def test_kml_reader_only_raises_geo_error(doc):
    path = _write("fuzz.kml", doc)
    _only_own_errors(path, read_features, read_area, read_polygons, read_buildings)
    _check_polygons_finite(path)


# ---- OpenStreetMap -------------------------------------------------------------------------

osm_coordinate = st.one_of(odd_numbers.map(str), st.sampled_from(["45.06", "7.65", "", "nan", "1e5", "-0", "95"]),
                           st.text(alphabet="0123456789.-e+", max_size=10))


@st.composite
def osm_documents(draw: st.DrawFn) -> str:
    base = [(45.060, 7.650), (45.060, 7.651), (45.061, 7.651), (45.061, 7.650)]
    nodes = []
    for k, (lat, lon) in enumerate(base, start=1):
        if draw(st.integers(0, 4)) == 0:
            lat, lon = draw(osm_coordinate), draw(osm_coordinate)
        nodes.append(f'<node id="{k}" lat="{lat}" lon="{lon}" version="1"/>')
    refs = draw(st.one_of(st.just([1, 2, 3, 4, 1]), st.lists(st.integers(-2, 6), max_size=7)))
    tags = draw(st.dictionaries(st.sampled_from(["building", "height", "building:levels", "type", "name"]),
                                st.text(alphabet=st.characters(codec="utf-8", exclude_characters='<&"\x00'),
                                        max_size=6), max_size=4))
    tag_xml = "".join(f'<tag k="{k}" v="{v}"/>' for k, v in tags.items())
    nd_xml = "".join(f'<nd ref="{r}"/>' for r in refs)
    way = f'<way id="10" version="1">{nd_xml}{tag_xml}</way>'
    relation = draw(st.sampled_from([
        "", '<relation id="20" version="1"><member type="way" ref="10" role="outer"/>'
            '<tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation>']))
    return f'<?xml version="1.0" encoding="UTF-8"?><osm version="0.6">{"".join(nodes)}{way}{relation}</osm>'


@FUZZ
@given(st.one_of(osm_documents(), st.text(max_size=60)))
def test_osm_xml_reader_only_raises_geo_error(doc):
    path = _write("fuzz.osm", doc)
    _only_own_errors(path, read_buildings, read_osm_buildings, read_features)
    _check_polygons_finite(path)


@FUZZ
@given(st.binary(max_size=96))
def test_osm_pbf_reader_on_bytes(data):
    _only_own_errors(_write("fuzz.osm.pbf", data), read_buildings)


VIENNA_PBF = Path(__file__).resolve().parents[1].parent / "shared" / "maps" / "vienna_rabenhof.osm.pbf"


@pytest.mark.skipif(not VIENNA_PBF.is_file(), reason=f"shared OSM data not found at {VIENNA_PBF}")
@settings(FUZZ, max_examples=min(FUZZ.max_examples, 60))
@given(st.data())
def test_osm_pbf_reader_on_a_damaged_real_extract(data):
    # A real extract with a few bytes changed or its tail cut: compressed blocks, varints and
    # string tables go wrong in ways random bytes never reach.
    pbf = bytearray(VIENNA_PBF.read_bytes())
    if data.draw(st.booleans()):
        del pbf[data.draw(st.integers(1, len(pbf) - 1)):]
    for _ in range(data.draw(st.integers(1, 4))):
        pbf[data.draw(st.integers(0, len(pbf) - 1))] = data.draw(st.integers(0, 255))
    _only_own_errors(_write("damaged.osm.pbf", bytes(pbf)), read_buildings)


@FUZZ
@given(st.one_of(kml_documents().map(str.encode), st.binary(max_size=64)), st.sampled_from(["doc.kml", "a/b.kml", "x.txt"]),
       st.booleans())
def test_kmz_reader_only_raises_geo_error(doc, member, linked):
    # A KMZ is a zip holding the KML (doc.kml, else its first .kml), perhaps linked from doc.kml.
    path = _DIR / "fuzz.kmz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as kmz:
        if linked and member != "doc.kml":
            kmz.writestr("doc.kml", f'<kml><Document><NetworkLink><Link><href>{member}</href></Link></NetworkLink>'
                                    f'</Document></kml>')
        kmz.writestr(member, doc)
    _only_own_errors(path, read_features, read_area, read_polygons, read_buildings)
    _check_polygons_finite(path)


@FUZZ
@given(st.binary(max_size=96))
def test_kmz_reader_on_bytes(data):
    _only_own_errors(_write("bytes.kmz", data), read_area, read_buildings)


def _polygon_wkb(rings: list[list[tuple[float, float]]]) -> bytes:
    """A WKB polygon of any rings, open, short or NaN ones too (shapely would refuse to make them)."""
    out = struct.pack("<BII", 1, 3, len(rings))
    for ring in rings:
        out += struct.pack("<I", len(ring)) + np.asarray(ring, dtype="<f8").reshape(-1, 2).tobytes()
    return out


wkb_rings = st.lists(st.lists(st.tuples(odd_numbers.map(float), odd_numbers.map(float)), max_size=6), min_size=0,
                     max_size=2)
valid_ring = [tuple(p) for p in OUTER]


@st.composite
def gpkg_layers(draw: st.DrawFn) -> tuple[list[bytes | None], list[str | None]]:
    """Features for a GeoPackage: valid squares, arbitrary rings (open, NaN, huge), missing geometries."""
    count = draw(st.integers(1, 4))
    geoms: list[bytes | None] = []
    for _ in range(count):
        kind = draw(st.integers(0, 3))
        geoms.append(_polygon_wkb([valid_ring]) if kind == 0 else None if kind == 1 else _polygon_wkb(draw(wkb_rings))
                     if kind == 2 else _polygon_wkb([valid_ring[:draw(st.integers(0, 4))] + draw(wkb_rings)[:1][0:1]
                                                     and valid_ring]))
    heights = [draw(st.one_of(st.none(), st.text(alphabet="0123456789.,m ft'-", max_size=6))) for _ in range(count)]
    return geoms, heights


_GPKG_SEED = None


def _gpkg_bytes() -> bytes:
    """A small valid GeoPackage (two layers), written once, for the byte-flip test."""
    global _GPKG_SEED
    if _GPKG_SEED is None:
        import pyogrio.raw

        path = _DIR / "seed.gpkg"
        wkb = np.array([_polygon_wkb([valid_ring])], dtype=object)
        for layer in ("buildings", "parks"):
            pyogrio.raw.write(str(path), wkb, [np.array(["12 m"], dtype=object)], ["height"], layer=layer,
                              driver="GPKG", geometry_type="Polygon", crs="EPSG:4326", append=path.exists())
        _GPKG_SEED = path.read_bytes()
    return _GPKG_SEED


@FUZZ
@given(gpkg_layers(), st.sampled_from(["EPSG:4326", "EPSG:3857", "EPSG:32632"]))
def test_geopackage_reader_only_raises_geo_error(layer, crs):
    import pyogrio.raw

    geoms, heights = layer
    path = _DIR / "fuzz.gpkg"
    path.unlink(missing_ok=True)
    pyogrio.raw.write(str(path), np.array(geoms, dtype=object), [np.array(heights, dtype=object)], ["height"],
                      driver="GPKG", geometry_type="Polygon", crs=crs)
    _only_own_errors(path, read_features, read_area, read_polygons, read_buildings)
    _check_polygons_finite(path)


@FUZZ
@given(st.data())
def test_geopackage_reader_on_a_damaged_file(data):
    gpkg = bytearray(_gpkg_bytes())
    if data.draw(st.booleans()):
        del gpkg[data.draw(st.integers(1, len(gpkg) - 1)):]
    for _ in range(data.draw(st.integers(1, 6))):
        gpkg[data.draw(st.integers(0, len(gpkg) - 1))] = data.draw(st.integers(0, 255))
    path = _write("damaged.gpkg", bytes(gpkg))
    _only_own_errors(path, read_area, read_buildings)
    for layer in ("buildings", "parks", "nope"):  # FILE:LAYER: the message names the file
        for reader in (read_area, read_buildings):
            try:
                reader(f"{path}:{layer}")
            except GeoError as err:
                assert "\n" not in str(err) and str(err).startswith(str(path)), str(err)


signed_ids = st.one_of(st.integers(-(2**63), 2**63 - 1), st.integers(-5, 5),
                       st.sampled_from([2**62, -(2**62), 2**62 - 1, 2**63 - 2, -(2**63) + 1]))


@st.composite
def osm_documents_with_any_ids(draw: st.DrawFn) -> str:
    """A building way and perhaps a multipolygon, every id any signed 64-bit integer (JOSM: negative)."""
    node_ids = draw(st.lists(signed_ids, min_size=4, max_size=4, unique=True))
    base = [(45.060, 7.650), (45.060, 7.651), (45.061, 7.651), (45.061, 7.650)]
    nodes = "".join(f'<node id="{i}" lat="{lat}" lon="{lon}" version="1"/>' for i, (lat, lon) in zip(node_ids, base))
    way_id, rel_id = draw(signed_ids), draw(signed_ids)
    refs = draw(st.one_of(st.just(node_ids + node_ids[:1]), st.lists(st.sampled_from(node_ids) | signed_ids, max_size=6)))
    tags = draw(st.sampled_from(['<tag k="building" v="yes"/>', "", '<tag k="building" v="yes"/><tag k="height" v="9"/>']))
    way = f'<way id="{way_id}" version="1">{"".join(f"<nd ref={chr(34)}{r}{chr(34)}/>" for r in refs)}{tags}</way>'
    relation = draw(st.sampled_from([
        "", f'<relation id="{rel_id}" version="1"><member type="way" ref="{way_id}" role="outer"/>'
            '<tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation>']))
    return f'<?xml version="1.0" encoding="UTF-8"?><osm version="0.6">{nodes}{way}{relation}</osm>'


@FUZZ
@given(osm_documents_with_any_ids())
def test_osm_reader_takes_any_signed_64_bit_id(doc):
    path = _write("ids.osm", doc)
    _only_own_errors(path, read_buildings, read_features)
    try:
        blds = read_buildings(path)
    except GeoError:
        return
    for b in blds:  # a building read keeps the id the file gave it
        assert f'id="{b.properties["osm_id"]}"' in doc


# ---- plan itself: a plan or one line -------------------------------------------------------------------------

AREA_DOC = {"type": "Polygon", "coordinates": [[[7.650, 45.060], [7.652, 45.060], [7.652, 45.062], [7.650, 45.062],
                                                [7.650, 45.060]]]}


@settings(FUZZ, max_examples=min(FUZZ.max_examples, 15))  # each plan writes a whole folder
@given(st.one_of(mutated(VALID_GEOJSON).map(lambda d: ("fuzz.geojson", _dump(d))),
                 kml_documents().map(lambda d: ("fuzz.kml", d)),
                 osm_documents_with_any_ids().map(lambda d: ("fuzz.osm", d)),
                 gpkg_layers().map(lambda layer: ("fuzz-cli.gpkg", layer))),
       st.sampled_from(["--area", "--osm", "--obstacles"]))
def test_plan_gives_a_plan_or_one_line(capsys, named_doc, flag):
    name, doc = named_doc
    if name.endswith(".gpkg"):
        import pyogrio.raw

        path = _DIR / name
        path.unlink(missing_ok=True)
        pyogrio.raw.write(str(path), np.array(doc[0], dtype=object), [np.array(doc[1], dtype=object)], ["height"],
                          driver="GPKG", geometry_type="Polygon", crs="EPSG:4326")
    else:
        path = _write(name, doc)
    area = _write("area.geojson", _dump(AREA_DOC))
    out = _DIR / "plan-out"
    shutil.rmtree(out, ignore_errors=True)
    args = ["plan", "--area", str(path if flag == "--area" else area), "--launch", "45.061,7.651", "--altitude", "40",
            "--fov", "84", "--out", str(out), "--quiet"]
    if flag != "--area":
        args += [flag, str(path)]
    capsys.readouterr()
    code = main(args)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if code == 2:
        assert err.count("\n") == 1 and err.startswith("missionplan: ") and not out.exists(), err
    else:
        assert code in (0, 1) and (out / "report.json").is_file()
        assert all(line.startswith("missionplan: ") for line in err.splitlines()), err


# ---- .map ----------------------------------------------------------------------------------

@st.composite
def map_texts(draw: st.DrawFn) -> str:
    header = draw(st.lists(st.sampled_from(["name: box", "title: t", "cell_m: 2", "launch: 1,1", "launch: 1,1 2,x",
                                            "launch: -1,0", "launch: 99999999999999999999,1", "oops", "grid",
                                            ": value", "# comment", ""]), max_size=5))
    rows = draw(st.lists(st.text(alphabet="#.o x\t", min_size=0, max_size=6), max_size=5))
    grid = draw(st.sampled_from(["grid:", "grid: ", "", "GRID:"]))
    return "\n".join([*header, grid, *rows])


@FUZZ
@given(st.one_of(map_texts(), st.text(max_size=80)))
def test_map_parser_only_raises_map_error(text):
    try:
        gmap = parse_map(text, "fuzz.map")
    except MapError as err:
        assert "\n" not in str(err) and "fuzz.map" in str(err), str(err)
        return
    for cell in gmap.launch:  # what it accepts is usable: launch cells inside and free
        assert gmap.inside(cell) and not gmap.obstacle[cell]


@FUZZ
@given(st.binary(max_size=64))
def test_map_file_reader_on_bytes(data):
    _only_own_errors(_write("fuzz.map", data), load_map)


def test_readers_name_the_file_for_a_folder_or_missing_file(tmp_path):
    folder = tmp_path / "folder.geojson"
    folder.mkdir()
    for reader in (read_area, read_buildings):
        with pytest.raises(GeoError, match="folder.geojson"):
            reader(folder)
    with pytest.raises(MapError, match="folder.map"):
        (tmp_path / "folder.map").mkdir() or load_map(tmp_path / "folder.map")
