"""Property tests: every reader of user files (GeoJSON, KML, .plan as area, OSM, .map) meets
arbitrary and structurally wrong input with its own one-line error naming the file, never
another exception. The bridge's .plan / .waypoints mission readers are tested beside them
(bridge/formats/missionfile.py).

Each example writes one small file; max_examples keeps the whole module to seconds. For a
longer hunt: MISSIONPLAN_FUZZ_EXAMPLES=5000 pytest tests/test_readers_fuzz.py
"""

from __future__ import annotations

import atexit
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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
