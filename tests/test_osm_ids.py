"""OpenStreetMap ids are any signed 64-bit integer, and no OSM building is dropped without a name.

JOSM gives the objects a user draws negative ids, and libosmium keeps node locations for ids from 0 up
only: a building drawn in JOSM used to vanish from the plan (exit 0, the track flew through it). Way and
relation ids of 2^62 or more overflow libosmium's area ids. The reader renumbers such ids in a temporary
copy and names the originals. Every building it cannot take (a missing node, a broken multipolygon, an
unclosed way, zero area) is named in report.json and in one warning line.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import shapely
from shapely.geometry import LineString, Polygon

from missionplan.cli import main
from missionplan.geo.errors import GeoError
from missionplan.geo.readers import read_building_file, read_buildings

STREET = [[7.6490, 45.0690], [7.6520, 45.0690], [7.6520, 45.0720], [7.6490, 45.0720], [7.6490, 45.0690]]
LAUNCH = "45.0692,7.6492"
# A 60 m block of about 80 x 110 m in the middle of the street area.
BLOCK = [(45.0700, 7.6500), (45.0700, 7.6510), (45.0710, 7.6510), (45.0710, 7.6500)]


def _osm(nodes: list[tuple[int, float, float]], ways: list[tuple[int, list[int], dict[str, str]]],
         relations: list[tuple[int, list[tuple[str, int, str]], dict[str, str]]] = ()) -> str:
    out = ["<?xml version='1.0' encoding='UTF-8'?>", "<osm version='0.6' generator='JOSM'>"]
    out += [f"  <node id='{i}' action='modify' lat='{lat}' lon='{lon}' />" for i, lat, lon in nodes]
    for i, refs, tags in ways:
        out.append(f"  <way id='{i}' action='modify'>" + "".join(f"<nd ref='{r}' />" for r in refs)
                   + "".join(f"<tag k='{k}' v='{v}' />" for k, v in tags.items()) + "</way>")
    for i, members, tags in relations:
        out.append(f"  <relation id='{i}'>" + "".join(f"<member type='{t}' ref='{r}' role='{role}'/>"
                                                     for t, r, role in members)
                   + "".join(f"<tag k='{k}' v='{v}' />" for k, v in tags.items()) + "</relation>")
    return "\n".join(out + ["</osm>", ""])


def _block(node_ids: list[int], way_id: int, height: str = "60") -> str:
    nodes = [(i, lat, lon) for i, (lat, lon) in zip(node_ids, BLOCK)]
    return _osm(nodes, [(way_id, node_ids + node_ids[:1], {"building": "yes", "height": height})])


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _plan(tmp_path: Path, osm: Path, out: str = "run", *extra: str) -> int:
    area = _write(tmp_path / "street.geojson", json.dumps({"type": "Polygon", "coordinates": [STREET]}))
    return main(["plan", "--area", str(area), "--osm", str(osm), "--altitude", "30", "--fov", "84",
                 "--launch", LAUNCH, "--out", str(tmp_path / out), "--quiet", *extra])


def _track(folder: Path) -> LineString:
    plan = json.loads((folder / "uav1.plan").read_text())
    points = [(item["params"][5], item["params"][4]) for item in plan["mission"]["items"]
              if item.get("type") == "SimpleItem" and item["params"][4] not in (0, None)]
    return LineString(points)


def _with_a_josm_block(negative_first: bool = True) -> str:
    """An extract (positive ids: a 12 m shed in a corner of the area) with a 60 m block drawn in JOSM
    (negative ids) in the middle; by default in libosmium's order (negative ids first)."""
    shed = [(45.0714, 7.6513), (45.0714, 7.6516), (45.0716, 7.6516), (45.0716, 7.6513)]
    josm = [(i, lat, lon) for i, (lat, lon) in zip([-101, -102, -103, -104], BLOCK)]
    extract = [(i, lat, lon) for i, (lat, lon) in zip([1, 2, 3, 4], shed)]
    block = (-201, [-101, -102, -103, -104, -101], {"building": "yes", "height": "60"})
    shed_way = (7, [1, 2, 3, 4, 1], {"building": "yes", "height": "12"})
    if negative_first:
        return _osm(josm + extract, [block, shed_way])
    return _osm(extract + josm, [shed_way, block])


def test_a_josm_building_with_negative_ids_is_an_obstacle_the_track_avoids(tmp_path, capsys):
    # It was dropped without a word (exit 0) and the 30 m track flew through the 60 m block.
    osm = _write(tmp_path / "josm.osm", _with_a_josm_block())
    assert _plan(tmp_path, osm) == 0
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    buildings = [entry for entry in report["inputs"] if entry["role"] == "buildings"]
    assert buildings[0]["features"] == 2 and buildings[0]["buildings_in_area"] == 2 and buildings[0]["dropped"] == []
    assert "renumbered" in buildings[0]["notes"][0]
    block = Polygon([(lon, lat) for lat, lon in BLOCK])
    track = _track(tmp_path / "run")
    assert len(track.coords) > 10 and not track.intersects(block)  # 60 m tall, flown at 30 m: round it
    assert "warning" not in capsys.readouterr().err


def test_ways_out_of_libosmium_order_are_read(tmp_path):
    # libosmium wants negative ids first: the other order stopped the read ("Way IDs out of order").
    blds = read_buildings(_write(tmp_path / "order.osm", _with_a_josm_block(negative_first=False)))
    assert sorted((b.ref, b.height_m) for b in blds) == [("way -201", 60.0), ("way 7", 12.0)]


def test_a_file_whose_ids_are_all_negative_reads(tmp_path):
    blds, source = read_building_file(_write(tmp_path / "neg.osm", _block([-1, -2, -3, -4], -1, "12 m")))
    assert [(b.ref, b.height_m, b.properties["osm_id"]) for b in blds] == [("way -1", 12.0, -1)]
    assert source.dropped == [] and source.reader == "pyosmium"


def test_negative_ids_beside_positive_ones_and_a_negative_multipolygon(tmp_path):
    # An extract (positive ids) with a new courtyard building drawn in JOSM: relation, ways and nodes negative.
    hole = [(45.0703, 7.6503), (45.0703, 7.6506), (45.0706, 7.6506), (45.0706, 7.6503)]
    nodes = ([(10 + k, lat, lon + 0.002) for k, (lat, lon) in enumerate(BLOCK)]
             + [(-1 - k, lat, lon) for k, (lat, lon) in enumerate(BLOCK)]
             + [(-11 - k, lat, lon) for k, (lat, lon) in enumerate(hole)])
    ways = [(5, [10, 11, 12, 13, 10], {"building": "yes", "building:levels": "4"}),
            (-7, [-1, -2, -3, -4, -1], {}), (-8, [-11, -12, -13, -14, -11], {})]
    relations = [(-9, [("w", -7, "outer"), ("w", -8, "inner")], {"type": "multipolygon", "building": "yes",
                                                                   "building:height": "20"})]
    blds = {b.ref: b for b in read_buildings(_write(tmp_path / "mixed.osm", _osm(nodes, ways, relations)))}
    assert set(blds) == {"way 5", "relation -9"}
    assert blds["way 5"].height_m == 12.0 and blds["relation -9"].height_m == 20.0  # building:height
    assert len(blds["relation -9"].geometry.interiors) == 1  # the courtyard kept


@pytest.mark.parametrize("way_id", [2**62, -(2**62), 2**63 - 2, -(2**63 - 2)])
def test_way_ids_past_2_to_the_62_keep_their_id(tmp_path, way_id):
    # libosmium's area id is 2|id| (+1 for a relation): from 2^62 on it overflows and named another way.
    blds = read_buildings(_write(tmp_path / "big.osm", _block([1, 2, 3, 4], way_id)))
    assert [(b.ref, b.properties["osm_id"]) for b in blds] == [(f"way {way_id}", way_id)]


@pytest.mark.parametrize("way_id", [2**63 - 1, -(2**63)])
def test_the_two_ids_libosmium_refuses_are_one_line(tmp_path, way_id):
    path = _write(tmp_path / "edge.osm", _block([1, 2, 3, 4], way_id))
    with pytest.raises(GeoError) as err:
        read_buildings(path)
    assert str(err.value) == f"{path}: cannot read OSM data (illegal id: '{way_id}')"


def test_every_building_left_out_is_named(tmp_path):
    square = [(1, 45.0700, 7.6500), (2, 45.0700, 7.6510), (3, 45.0710, 7.6510), (4, 45.0710, 7.6500)]
    line = [(5, 45.0712, 7.6500), (6, 45.0712, 7.6505), (7, 45.0712, 7.6510)]
    ways = [(10, [1, 2, 3, 4, 1], {"building": "yes", "height": "9"}),
            (11, [1, 2, 99, 4, 1], {"building": "yes"}),  # node 99 is not in the file
            (12, [5, 6, 7, 5], {"building": "yes"}),  # all on one line: zero area
            (13, [1, 2, 3], {"building": "yes"}),  # not closed, in no multipolygon
            (20, [1, 2, 3, 4, 1], {})]
    relations = [(30, [("w", 20, "outer"), ("w", 21, "inner")], {"type": "multipolygon", "building": "yes"})]
    blds, source = read_building_file(_write(tmp_path / "gaps.osm", _osm(square + line, ways, relations)))
    assert [b.ref for b in blds] == ["way 10"]
    assert {o.ref: o.cause for o in source.dropped} == {
        "way 11": "node 99 missing from the file",
        "way 12": "zero area (its nodes lie on a line)",
        "way 13": "not closed (its first and last nodes differ) and in no building multipolygon",
        "relation 30": "broken multipolygon: inner member way 21 missing from the file",
    }


def test_a_missing_node_and_a_broken_multipolygon_in_the_report_and_one_warning(tmp_path, capsys):
    nodes = [(i, lat, lon) for i, (lat, lon) in zip([1, 2, 3, 4], BLOCK)]
    ways = [(10, [1, 2, 3, 4, 1], {"building": "yes", "height": "60"}),
            (11, [1, 2, 98, 4, 1], {"building": "yes"}),
            (20, [1, 2, 3, 4, 1], {})]
    relations = [(30, [("w", 20, "outer"), ("w", 22, "inner")], {"type": "multipolygon", "building": "yes"})]
    osm = _write(tmp_path / "clipped.osm", _osm(nodes, ways, relations))
    assert _plan(tmp_path, osm) == 0
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    entry = next(e for e in report["inputs"] if e["role"] == "buildings")
    assert entry["dropped"] == [{"id": "way 11", "cause": "node 98 missing from the file"},
                                {"id": "relation 30", "cause": "broken multipolygon: inner member way 22 missing "
                                                               "from the file"}]
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0] == f"missionplan: warning: {report['coverage']['warnings'][0]}"
    assert err[0].startswith(f"missionplan: warning: {osm}: 2 buildings not read: way 11 (node 98 missing from the "
                             f"file), relation 30 (broken multipolygon: inner member way 22 missing from the file)")
    assert err[0].endswith("All are listed in report.json under inputs.")


def test_no_building_at_all_names_what_was_dropped(tmp_path):
    path = _write(tmp_path / "one.osm", _osm([(1, 45.07, 7.65)], [(10, [1, 2, 3, 1], {"building": "yes"})]))
    with pytest.raises(GeoError) as err:
        read_buildings(path)
    assert str(err.value) == (f"{path}: no building polygon found (1 dropped: way 10: nodes 2, 3 missing from "
                              f"the file)")


def test_an_out_of_range_node_in_a_renumbered_file_names_the_original_ids(tmp_path):
    text = _block([-1, -2, -3, -4], -5).replace("lat='45.07' lon='7.65'", "lat='95' lon='7.65'")
    path = _write(tmp_path / "far.osm", text)
    with pytest.raises(GeoError) as err:
        read_buildings(path)
    assert str(err.value).startswith(f"{path}: way -5, node -1: location (lat 95.0, lon 7.65) is out of range")


def test_a_self_crossing_footprint_is_repaired_and_named(tmp_path):
    # A bowtie: libosmium assembles no area of it; make_valid makes its two triangles, and it is listed.
    nodes = [(1, 45.0700, 7.6500), (2, 45.0710, 7.6510), (3, 45.0700, 7.6510), (4, 45.0710, 7.6500)]
    blds, source = read_building_file(_write(tmp_path / "bowtie.osm", _osm(nodes, [
        (10, [1, 2, 3, 4, 1], {"building": "yes", "height": "8"})])))
    assert [(b.ref, b.height_m) for b in blds] == [("way 10", 8.0)] and shapely.is_valid(blds[0].geometry)
    assert blds[0].geometry.geom_type == "MultiPolygon" and len(blds[0].geometry.geoms) == 2
    assert [(o.ref, o.cause.split(":")[0]) for o in source.repaired] == [("way 10", "libosmium could not assemble "
                                                                                   "its ring")]
    assert "Self-intersection" in source.repaired[0].cause and source.dropped == []
