"""Area / obstacle / building readers on small hand-written files and the shared OSM data."""

import json
from pathlib import Path

import pytest
import shapely
from shapely.geometry import MultiPolygon, Polygon

from missionplan.geo.errors import GeoError
from missionplan.geo.readers import (building_height, parse_height, read_area, read_buildings, read_features,
                         read_osm_buildings, read_polygons)
from missionplan.bridge.formats.mission_items import CMD_NAV_TAKEOFF

MAPS = Path(__file__).resolve().parents[1].parent / "shared" / "maps"
needs_maps = pytest.mark.skipif(not MAPS.is_dir(), reason=f"shared OSM test data not found at {MAPS}")

OUTER = [[7.650, 45.060], [7.660, 45.060], [7.660, 45.070], [7.650, 45.070], [7.650, 45.060]]
HOLE = [[7.654, 45.064], [7.656, 45.064], [7.656, 45.066], [7.654, 45.066], [7.654, 45.064]]
BOWTIE = [[7.650, 45.060], [7.660, 45.070], [7.660, 45.060], [7.650, 45.070], [7.650, 45.060]]


def _write(tmp_path, name, data):
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else json.dumps(data), encoding="utf-8")
    return p


# ---- GeoJSON ---------------------------------------------------------------------------

def test_geojson_feature_collection_with_hole_and_properties(tmp_path):
    fc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"kind": "area"},
         "geometry": {"type": "Polygon", "coordinates": [OUTER, HOLE]}}]}
    feats = read_features(_write(tmp_path, "a.geojson", fc))
    assert len(feats) == 1 and feats[0].properties == {"kind": "area"}
    g = feats[0].geometry
    assert isinstance(g, Polygon) and len(g.interiors) == 1
    assert not g.contains(shapely.Point(7.655, 45.065))  # inside the hole
    assert g.contains(shapely.Point(7.651, 45.061))


def test_geojson_bare_geometry_and_multipolygon(tmp_path):
    second = [[x + 0.02, y] for x, y in OUTER]
    mp = {"type": "MultiPolygon", "coordinates": [[OUTER, HOLE], [second]]}
    area = read_area(_write(tmp_path, "a.json", mp))
    assert isinstance(area, MultiPolygon) and len(area.geoms) == 2
    feat = {"type": "Feature", "properties": None, "geometry": {"type": "Polygon", "coordinates": [OUTER]}}
    assert read_area(_write(tmp_path, "b.geojson", feat)).area == pytest.approx(1e-4)


def test_geojson_linestring_is_not_a_polygon(tmp_path):
    p = _write(tmp_path, "line.geojson", {"type": "LineString", "coordinates": OUTER[:3]})
    with pytest.raises(GeoError, match=r"line\.geojson.*not a polygon \(LineString\)"):
        read_area(p)


def test_bowtie_is_self_intersecting(tmp_path):
    p = _write(tmp_path, "bow.geojson", {"type": "Polygon", "coordinates": [BOWTIE]})
    with pytest.raises(GeoError, match=r"bow\.geojson.*self-intersecting"):
        read_area(p)


def test_unparsable_and_empty_and_unknown_extension(tmp_path):
    with pytest.raises(GeoError, match=r"bad\.geojson: cannot read JSON"):
        read_area(_write(tmp_path, "bad.geojson", "{not json"))
    with pytest.raises(GeoError, match=r"empty\.geojson: no polygon found"):
        read_area(_write(tmp_path, "empty.geojson", {"type": "FeatureCollection", "features": []}))
    flat = [[7.65, 45.06], [7.66, 45.06], [7.67, 45.06], [7.65, 45.06]]
    with pytest.raises(GeoError, match=r"flat\.geojson.*(zero area|invalid)"):
        read_area(_write(tmp_path, "flat.geojson", {"type": "Polygon", "coordinates": [flat]}))
    with pytest.raises(GeoError, match=r"area\.dxf: unknown file type '\.dxf'"):
        read_area(_write(tmp_path, "area.dxf", "x"))
    with pytest.raises(GeoError, match=r"area\.shp: not a Shapefile \(it does not start as a Shapefile does\)"):
        read_area(_write(tmp_path, "area.shp", "x"))
    with pytest.raises(GeoError, match="file not found"):
        read_area(tmp_path / "missing.geojson")


# ---- KML -----------------------------------------------------------------------------------

def _coords(ring):
    return " ".join(f"{x},{y},0" for x, y in ring)


KML = f"""<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2"><Document>
 <Placemark><name>yard</name>
  <ExtendedData><Data name="height"><value>4 m</value></Data></ExtendedData>
  <Polygon><outerBoundaryIs><LinearRing><coordinates>{_coords(OUTER)}</coordinates></LinearRing></outerBoundaryIs>
   <innerBoundaryIs><LinearRing><coordinates>{_coords(HOLE)}</coordinates></LinearRing></innerBoundaryIs></Polygon>
 </Placemark>
 <Placemark><name>two</name><MultiGeometry>
  <Polygon><outerBoundaryIs><LinearRing><coordinates>{_coords([[x + 0.02, y] for x, y in OUTER])}</coordinates></LinearRing></outerBoundaryIs></Polygon>
  <Polygon><outerBoundaryIs><LinearRing><coordinates>{_coords([[x + 0.04, y] for x, y in OUTER])}</coordinates></LinearRing></outerBoundaryIs></Polygon>
 </MultiGeometry></Placemark>
</Document></kml>
"""


def test_kml_polygon_with_hole_and_multigeometry(tmp_path):
    feats = read_features(_write(tmp_path, "a.kml", KML))
    assert [f.properties["name"] for f in feats] == ["yard", "two"]
    assert len(feats[0].geometry.interiors) == 1
    assert isinstance(feats[1].geometry, MultiPolygon) and len(feats[1].geometry.geoms) == 2
    assert read_buildings(tmp_path / "a.kml")[0].height_m == 4.0
    assert read_area(tmp_path / "a.kml").area == pytest.approx(3e-4 - 4e-6)


def test_kml_linestring_and_bowtie_and_garbage(tmp_path):
    line = KML.replace("<Polygon><outerBoundaryIs><LinearRing>", "<LineString>", 1)
    line = line.split("</coordinates>", 1)[0] + "</coordinates></LineString></Placemark></Document></kml>"
    with pytest.raises(GeoError, match=r"line\.kml: placemark 'yard': not a polygon \(LineString\)"):
        read_area(_write(tmp_path, "line.kml", line))
    bow = KML.replace(_coords(OUTER), _coords(BOWTIE), 1)
    with pytest.raises(GeoError, match=r"bow\.kml: placemark 'yard': self-intersecting"):
        read_area(_write(tmp_path, "bow.kml", bow))
    with pytest.raises(GeoError, match=r"junk\.kml: cannot read KML"):
        read_area(_write(tmp_path, "junk.kml", "<kml><Placemark>"))


# ---- QGroundControl .plan ------------------------------------------------------------------

def _latlon(ring):
    return [[y, x] for x, y in ring[:-1]]


def _plan(items=(), fences=()):
    return {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
            "mission": {"version": 2, "items": list(items)},
            "geoFence": {"version": 2, "circles": [], "polygons": list(fences)},
            "rallyPoints": {"version": 2, "points": []}}


def test_plan_survey_polygon_wins_over_geofence(tmp_path):
    survey = {"type": "ComplexItem", "complexItemType": "survey", "polygon": _latlon(OUTER)}
    fence_in = {"inclusion": True, "polygon": _latlon([[x + 1, y] for x, y in OUTER]), "version": 1}
    fence_out = {"inclusion": False, "polygon": _latlon(HOLE), "version": 1}
    p = _write(tmp_path, "m.plan", _plan([{"type": "SimpleItem", "command": CMD_NAV_TAKEOFF}, survey],
                                         [fence_in, fence_out]))
    area = read_area(p)
    assert area.equals(Polygon(OUTER))
    no_fly = read_polygons(p)
    assert len(no_fly) == 1 and no_fly[0].equals(Polygon(HOLE))


def test_plan_geofence_inclusion_when_no_survey(tmp_path):
    fence = {"inclusion": True, "polygon": _latlon(OUTER), "version": 1}
    assert read_area(_write(tmp_path, "g.plan", _plan([], [fence]))).equals(Polygon(OUTER))


def test_plan_structure_scan_and_corridor(tmp_path):
    s = {"type": "ComplexItem", "complexItemType": "StructureScan", "polygon": _latlon(HOLE)}
    assert read_area(_write(tmp_path, "s.plan", _plan([s]))).equals(Polygon(HOLE))
    c = {"type": "ComplexItem", "complexItemType": "CorridorScan", "CorridorWidth": 20,
         "polyline": [[45.06, 7.65], [45.06, 7.66]]}
    corridor = read_area(_write(tmp_path, "c.plan", _plan([c])))
    assert corridor.contains(shapely.Point(7.655, 45.06005))
    assert not corridor.contains(shapely.Point(7.655, 45.0602))  # ~22 m north: outside the 10 m half-width


def test_plan_without_polygon_is_an_error(tmp_path):
    with pytest.raises(GeoError, match=r"none\.plan: no survey polygon"):
        read_area(_write(tmp_path, "none.plan", _plan([{"type": "SimpleItem"}])))
    bow = {"type": "ComplexItem", "complexItemType": "survey", "polygon": _latlon(BOWTIE)}
    with pytest.raises(GeoError, match=r"bow\.plan: mission item 0 \(survey\): self-intersecting"):
        read_area(_write(tmp_path, "bow.plan", _plan([bow])))


# ---- heights -------------------------------------------------------------------------------

@pytest.mark.parametrize("text,metres", [("12", 12.0), ("12 m", 12.0), ("12.5m", 12.5), ("12,5", 12.5),
                                         ("33 ft", 33 * 0.3048), ("tall", None), (None, None), (7, 7.0)])
def test_parse_height(text, metres):
    assert parse_height(text) == (pytest.approx(metres) if metres is not None else None)


def test_building_height_from_levels():
    assert building_height({"height": "9 m", "building:levels": "5"}) == 9.0
    assert building_height({"building:levels": "5"}) == 15.0
    assert building_height({"building": "yes"}) is None


# ---- real OSM data -------------------------------------------------------------------------

@needs_maps
def test_turin_buildings_geojson():
    blds = read_buildings(MAPS / "turin_cenisia_osm_buildings.geojson")
    assert len(blds) == 134
    known = [b.height_m for b in blds if b.height_m is not None]
    assert len(known) > 100 and max(known) > 30 and min(known) >= 3


@needs_maps
def test_vienna_public_space_geojson():
    feats = read_features(MAPS / "vienna_rabenhof_public_space.geojson")
    assert len(feats) == 10
    cats = {f.properties["space_category"] for f in feats}
    assert {"building", "traffic area", "open space"} <= cats
    assert all(f.geometry.is_valid for f in feats)  # the one GIS sliver is repaired, not rejected


@needs_maps
def test_vienna_osm_pbf_buildings_through_osmium():
    blds = read_buildings(MAPS / "vienna_rabenhof.osm.pbf")
    assert 170 <= len(blds) <= 210
    assert all(b.geometry.is_valid and b.geometry.area > 0 for b in blds)
    rabenhof = [b for b in blds if b.properties.get("name") == "Rabenhof"]
    assert rabenhof and rabenhof[0].height_m == 21.0  # 7 levels x 3 m
    assert any(b.properties["osm_type"] == "relation" for b in blds)
    with pytest.raises(GeoError, match="OSM data holds buildings"):
        read_area(MAPS / "vienna_rabenhof.osm.pbf")
    assert len(read_osm_buildings(MAPS / "vienna_rabenhof.osm.pbf")) == len(blds)
    with pytest.raises(GeoError, match="need an .osm or .osm.pbf file"):
        read_osm_buildings(MAPS / "turin_cenisia_osm_buildings.geojson")


def test_osm_xml_buildings(tmp_path):
    osm = """<?xml version='1.0' encoding='UTF-8'?>
<osm version="0.6" generator="test">
 <node id="1" lat="45.0600" lon="7.6500" version="1"/>
 <node id="2" lat="45.0600" lon="7.6510" version="1"/>
 <node id="3" lat="45.0610" lon="7.6510" version="1"/>
 <node id="4" lat="45.0610" lon="7.6500" version="1"/>
 <node id="5" lat="45.0620" lon="7.6500" version="1"/>
 <way id="10" version="1"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
  <tag k="building" v="yes"/><tag k="height" v="12.5m"/></way>
 <way id="11" version="1"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
  <tag k="building" v="no"/></way>
 <way id="12" version="1"><nd ref="4"/><nd ref="5"/><tag k="highway" v="footway"/></way>
</osm>
"""
    blds = read_buildings(_write(tmp_path, "b.osm", osm))
    assert len(blds) == 1 and blds[0].height_m == 12.5 and blds[0].properties["osm_id"] == 10
    with pytest.raises(GeoError, match=r"none\.osm: no building polygon found"):
        read_buildings(_write(tmp_path, "none.osm", osm.replace('v="yes"', 'v="no"')))
    with pytest.raises(GeoError, match=r"junk\.osm\.pbf: cannot read OSM data"):
        read_buildings(_write(tmp_path, "junk.osm.pbf", "not a pbf"))
