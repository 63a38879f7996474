"""Structurally wrong and out-of-range input in every geo reader: one GeoError line naming the file.

The cases a property-based fuzzer hit against earlier versions of the readers, each pinned here
so it cannot come back even when the fuzzer's random draw misses it.
"""

import json

import pytest
from shapely.geometry import Polygon

from missionplan.geo.errors import GeoError
from missionplan.geo.readers import read_area, read_buildings, read_features, read_polygons
from missionplan.maps.gridmap import MapError, load_map

OUTER = [[7.650, 45.060], [7.660, 45.060], [7.660, 45.070], [7.650, 45.070], [7.650, 45.060]]


def _write(tmp_path, name, data):
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else json.dumps(data), encoding="utf-8")
    return p


def _poly(ring):
    return {"type": "Polygon", "coordinates": [ring]}


def _plan(mission=None, fence=None):
    doc = {"fileType": "Plan", "version": 1}
    doc["mission"] = mission if mission is not None else {"version": 2, "items": []}
    doc["geoFence"] = fence if fence is not None else {"version": 2, "polygons": []}
    return doc


def _fence(points, inclusion=True):
    return {"version": 2, "polygons": [{"inclusion": inclusion, "polygon": points, "version": 1}]}


LATLON = [[y, x] for x, y in OUTER[:-1]]


@pytest.mark.parametrize("doc, message", [
    ({"type": "FeatureCollection", "features": 5}, "'features' is not a list (it is a number)"),
    ({"type": "FeatureCollection", "features": {"a": 1}}, "'features' is not a list (it is an object)"),
    ({"type": "FeatureCollection", "features": [7]}, "feature 0 is not an object (it is a number)"),
    ({"type": "Feature", "geometry": [1, 2], "properties": {}}, "'geometry' is not an object (it is a list)"),
    ({"type": "Feature", "geometry": _poly(OUTER), "properties": "x"}, "'properties' is not an object"),
    ({"type": "Polygon", "coordinates": 5}, "coordinates are not nested lists"),
    ({"type": "Polygon", "coordinates": [[[7.65, "45"], [7.66, 45.0], [7.66, 45.1], [7.65, "45"]]]},
     "positions are not [lon, lat] number pairs"),
    (_poly(OUTER[:3]), "outer ring is not closed"),
    (_poly(OUTER[:-1]), "outer ring is not closed"),
    (_poly([OUTER[0], OUTER[1], OUTER[0]]), "has 3 positions; a closed ring needs at least 4"),
    (_poly([[float("nan"), 45.06]] + OUTER[1:-1] + [[float("nan"), 45.06]]), "is not finite numbers"),
    (_poly([[7.65, 95.0], [7.66, 95.0], [7.66, 45.07], [7.65, 95.0]]), "(lon 7.65, lat 95.0) is out of range"),
    (_poly([[45.06, 7.65], [45.06, 7.66], [45.07, 7.66], [45.06, 7.65]]), None),  # lat/lon swapped: valid lon/lat
    (_poly([[179.9, 10.0], [-179.9, 10.0], [-179.9, 10.1], [179.9, 10.1], [179.9, 10.0]]), "crosses the antimeridian"),
    ({"type": "MultiPolygon", "coordinates": [[[[179.9, 10.0], [180.0, 10.0], [180.0, 10.1], [179.9, 10.0]]],
                                               [[[-180.0, 10.0], [-179.9, 10.0], [-180.0, 10.1], [-180.0, 10.0]]]]},
     "crosses the antimeridian"),
])
def test_geojson_structure_and_coordinates(tmp_path, doc, message):
    path = _write(tmp_path, "a.geojson", doc)
    if message is None:
        read_area(path)  # swapped order stays a (wrong but legal) place; the launch check catches it
        return
    with pytest.raises(GeoError) as err:
        read_area(path)
    text = str(err.value)
    assert message in text and text.startswith(str(path)) and "\n" not in text


def test_geojson_multipolygon_across_antimeridian_parts_each_fine(tmp_path):
    # RFC 7946 splits such an area at ±180°; each part is valid, the whole cannot be one grid.
    east = [[179.9, 10.0], [180.0, 10.0], [180.0, 10.1], [179.9, 10.1], [179.9, 10.0]]
    west = [[-180.0, 10.0], [-179.9, 10.0], [-179.9, 10.1], [-180.0, 10.1], [-180.0, 10.0]]
    fc = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": _poly(east)},
                                                    {"type": "Feature", "properties": {}, "geometry": _poly(west)}]}
    path = _write(tmp_path, "split.geojson", fc)
    assert len(read_features(path)) == 2
    with pytest.raises(GeoError, match=r"split\.geojson: the shape spans 360\.0° of longitude"):
        read_area(path)


@pytest.mark.parametrize("doc, message", [
    ({"fileType": "Plan", "mission": [1, 2]}, "'mission' is not an object (it is a list)"),
    ({"fileType": "Plan", "mission": 3.5}, "'mission' is not an object (it is a number)"),
    ({"fileType": "Plan", "mission": {"items": 4}}, "mission 'items' is not a list"),
    ({"fileType": "Plan", "mission": {"items": [5]}}, "mission item 0 is not an object"),
    ({"fileType": "Plan", "geoFence": "fence"}, "'geoFence' is not an object (it is a string)"),
    ({"fileType": "Plan", "geoFence": {"polygons": 9}}, "geoFence 'polygons' is not a list"),
    ({"fileType": "Plan", "geoFence": {"polygons": [1.5]}}, "geofence polygon 0 is not an object"),
    (_plan(fence=_fence([1, 2, 3])), "geofence polygon 0: polygon points are not [lat, lon] number pairs"),
    (_plan(fence=_fence(5)), "polygon points are not [lat, lon] number pairs"),
    (_plan(fence=_fence([{"lat": 1}, {"lat": 2}, {"lat": 3}])), "not [lat, lon] number pairs"),
    (_plan(fence=_fence([[float("nan"), 7.65]] + LATLON[1:])), "is not finite numbers"),
    (_plan(fence=_fence([[95.0, 7.65]] + LATLON[1:])), "(lon 7.65, lat 95.0) is out of range"),
    (_plan(mission={"items": [{"type": "ComplexItem", "complexItemType": "CorridorScan", "CorridorWidth": 20,
                               "polyline": [[45.06, float("inf")], [45.06, 7.66]]}]}), "is not finite numbers"),
    (_plan(mission={"items": [{"type": "ComplexItem", "complexItemType": "CorridorScan", "CorridorScan": 7,
                               "polyline": [[45.06, 7.65], [45.06, 7.66]]}]}), "needs a CorridorWidth"),
    (_plan(mission={"items": [{"type": "ComplexItem", "complexItemType": "survey",
                               "polygon": [[10.0, 179.9], [10.0, -179.9], [10.1, -179.9]]}]}),
     "crosses the antimeridian"),
])
def test_plan_area_structure_and_coordinates(tmp_path, doc, message):
    path = _write(tmp_path, "m.plan", doc)
    with pytest.raises(GeoError) as err:
        read_features(path)
    text = str(err.value)
    assert message in text and text.startswith(str(path)) and "\n" not in text, text


def test_plan_polygon_of_three_points_open_or_closed_is_a_triangle(tmp_path):
    # QGroundControl lists vertices without repeating the first: 3 points is a closed triangle.
    tri = LATLON[:3]
    for name, points in (("open.plan", tri), ("closed.plan", tri + [tri[0]])):
        area = read_area(_write(tmp_path, name, _plan(fence=_fence(points))))
        assert area.equals(Polygon([(x, y) for y, x in tri]))


def _kml(coords):
    return (f'<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><name>p</name><Polygon><outerBoundaryIs>'
            f"<LinearRing><coordinates>{coords}</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark></kml>")


@pytest.mark.parametrize("coords, message", [
    ("7.65,45.06 7.66,45.06 7.66,45.07", "polygon ring is not closed"),
    ("7.65,45.06 7.66,45.06 7.65,45.06", "has 3 points; a closed ring needs at least 4"),
    ("7.65,45.06 inf,45.06 7.66,45.07 7.65,45.06", "is not finite numbers"),
    ("7.65,nan 7.66,45.06 7.66,45.07 7.65,nan", "is not finite numbers"),
    ("7.65,-95 7.66,45.06 7.66,45.07 7.65,-95", "is out of range"),
    ("179.9,1 -179.9,1 -179.9,1.1 179.9,1", "crosses the antimeridian"),
])
def test_kml_rings_and_coordinates(tmp_path, coords, message):
    path = _write(tmp_path, "a.kml", _kml(coords))
    with pytest.raises(GeoError) as err:
        read_polygons(path)
    text = str(err.value)
    assert message in text and text.startswith(str(path)) and "\n" not in text, text


OSM = """<?xml version='1.0' encoding='UTF-8'?>
<osm version="0.6" generator="test">
 <node id="1" lat="LAT" lon="7.6500" version="1"/>
 <node id="2" lat="45.0600" lon="7.6510" version="1"/>
 <node id="3" lat="45.0610" lon="7.6510" version="1"/>
 <node id="4" lat="45.0610" lon="7.6500" version="1"/>
 <way id="10" version="1"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
  <tag k="building" v="yes"/></way>
 <way id="11" version="1"><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="2"/><tag k="building" v="yes"/></way>
</osm>
"""


@pytest.mark.parametrize("lat, message", [
    ("95", "way 10, node 1: location (lat 95.0, lon 7.65) is out of range"),
    ("-90.5", "way 10, node 1: location (lat -90.5, lon 7.65) is out of range"),
    ("nan", "cannot read OSM data (wrong format for coordinate: 'nan')"),
    ("inf", "cannot read OSM data (wrong format for coordinate: 'inf')"),
])
def test_osm_node_out_of_range_or_not_a_number(tmp_path, lat, message):
    path = _write(tmp_path, "b.osm", OSM.replace('"LAT"', f'"{lat}"'))
    with pytest.raises(GeoError) as err:
        read_buildings(path)
    assert str(err.value).startswith(f"{path}: ") and message in str(err.value)


def test_osm_node_missing_from_the_extract_is_still_a_skip(tmp_path):
    # A clipped extract lacks nodes outside its box: that building is skipped, the rest read.
    path = _write(tmp_path, "c.osm", OSM.replace(' <node id="1" lat="LAT" lon="7.6500" version="1"/>\n', ""))
    blds = read_buildings(path)
    assert [b.properties["osm_id"] for b in blds] == [11]


def test_map_file_that_is_not_utf8(tmp_path):
    path = tmp_path / "bin.map"
    path.write_bytes(b"name: x\ngrid:\n\xff\xfe")
    with pytest.raises(MapError, match=r"bin\.map: not a map file \(not UTF-8 text"):
        load_map(path)
