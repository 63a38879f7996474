"""build_grid_map: rasterising areas, obstacles and buildings into a GridMap."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
import shapely

from missionplan.geo.area import build_grid_map, cells_centred_in, cells_touching
from missionplan.geo.camera import cell_size_m
from missionplan.geo.errors import GeoError
from missionplan.geo.frame import GridFrame
from missionplan.geo.readers import Building, read_buildings, read_features

MAPS = Path(__file__).resolve().parents[1].parent / "shared" / "maps"
needs_maps = pytest.mark.skipif(not MAPS.is_dir(), reason=f"shared OSM test data not found at {MAPS}")

TURIN_BOX = shapely.box(7.65189, 45.06563, 7.65861, 45.07000)
TURIN_STREET = (45.067974, 7.657154)  # open ground ~37 m from the nearest building
VIENNA_STREET = (48.1975, 16.4015)  # a street ~23 m from the nearest building
FOV = 90.0


def altitude_for_cell(cell_m, fov=FOV):
    return cell_m * 9 / (2 * math.tan(math.radians(fov) / 2))


def _square_lonlat(frame, r0, c0, r1, c1):
    """A lon/lat polygon covering grid cells r0..r1-1 x c0..c1-1 exactly (corners at half-cells)."""
    rr = np.array([r0, r0, r1, r1]) - 0.5
    cc = np.array([c0, c1, c1, c0]) - 0.5
    lat, lon = frame.grid_to_latlon(rr, cc)
    return shapely.Polygon(zip(lon, lat))


def test_rasterise_helpers_in_grid_units():
    box = shapely.box(1.5, 0.5, 3.5, 2.5)  # exactly cells rows 1-2, cols 2-3
    assert np.argwhere(cells_touching([box], 5, 6)).tolist() == [[1, 2], [1, 3], [2, 2], [2, 3]]
    assert np.argwhere(cells_centred_in([box], 5, 6)).tolist() == [[1, 2], [1, 3], [2, 2], [2, 3]]
    sliver = shapely.box(1.4, 0.5, 1.6, 0.6)  # straddles the col 1|2 border inside row 1
    assert np.argwhere(cells_touching([sliver], 5, 6)).tolist() == [[1, 1], [1, 2]]
    assert not cells_centred_in([sliver], 5, 6).any()


def test_small_synthetic_area_obstacle_building_no_fly():
    alt = altitude_for_cell(5.0)
    cell = cell_size_m(alt, FOV)
    assert cell == pytest.approx(5.0)
    frame = GridFrame.at(45.0, 7.0, cell, 40, 40)
    area = _square_lonlat(frame, 0, 0, 40, 40)  # the area's bounding box gives back this very frame
    obstacle = _square_lonlat(frame, 5, 5, 8, 8).buffer(-1e-8)
    no_fly = _square_lonlat(frame, 30, 30, 32, 35).buffer(-1e-8)
    low = Building(_square_lonlat(frame, 20, 2, 22, 6).buffer(-1e-8), 5.0)
    tall = Building(_square_lonlat(frame, 20, 10, 22, 14).buffer(-1e-8), alt)
    unknown = Building(_square_lonlat(frame, 10, 20, 12, 24).buffer(-1e-8), None)
    gmap, f2 = build_grid_map("synth", area, [obstacle], [low, tall, unknown], [no_fly],
                              [frame.cell_to_latlon(1, 1)], alt, FOV)
    assert gmap.shape == (40, 40) and (f2.rows, f2.cols) == (40, 40)
    assert gmap.obstacle[5:8, 5:8].all() and gmap.obstacle[30:32, 30:35].all()
    assert gmap.obstacle[20:22, 10:14].all() and gmap.obstacle[10:12, 20:24].all()
    # the low building is flown over: free, no target
    assert not gmap.obstacle[20:22, 2:6].any() and not gmap.target[20:22, 2:6].any()
    n_blocked = 9 + 10 + 8 + 8
    assert gmap.obstacle.sum() == n_blocked  # no spill into neighbouring cells
    assert gmap.target.sum() == 1600 - n_blocked - 8
    assert gmap.launch == [(1, 1)]
    assert gmap.georef.altitude_m == pytest.approx(alt) and gmap.georef.frame == f2
    # The georeference's .map header lines give it back.
    assert GridFrame.from_meta(gmap.georef.to_header(), *gmap.shape) == f2


def test_rotated_area_outside_cells_are_obstacles():
    area = shapely.Polygon([(7.650, 45.060), (7.652, 45.061), (7.651, 45.063), (7.649, 45.062)])
    gmap, frame = build_grid_map("rot", area, [], [], [], [], altitude_for_cell(4.0), FOV, rotation_deg=26.6)
    # Centres are tested against the area drawn in the grid frame (edges straight in UTM);
    # against straight lon/lat edges at most a few centres right on the border may differ.
    in_grid = frame.geometry_to_grid(area)
    r, c = np.nonzero(gmap.target)
    assert shapely.intersects_xy(in_grid, c, r).all()
    r, c = np.nonzero(gmap.obstacle)
    assert not shapely.intersects_xy(in_grid, c, r).any()
    lat, lon = frame.cell_to_latlon(r, c)
    assert shapely.contains_xy(area, lon, lat).sum() <= 3
    assert gmap.target.sum() > 0.3 * gmap.obstacle.size


def test_errors_launch_size_empty():
    area = shapely.box(7.650, 45.060, 7.652, 45.062)
    bld = Building(shapely.box(7.6505, 45.0605, 7.6510, 45.0610), 30.0)
    alt = altitude_for_cell(5.0)
    # The launch point is named as the `launch` setting (the CLI says --launch: tests/test_cli_errors.py).
    with pytest.raises(GeoError, match=r"^launch 45\.07,7\.651 is outside the area field\.geojson"):
        build_grid_map("e", area, [], [bld], [], [(45.07, 7.651)], alt, FOV, area_file="field.geojson")
    with pytest.raises(GeoError, match=r"^launch 45\.0607,7\.6507 is inside a building"):
        build_grid_map("e", area, [], [bld], [], [(45.0607, 7.6507)], alt, FOV)
    with pytest.raises(GeoError, match=r"^launch 45\.0607,7\.6507 is inside a no-fly zone"):
        build_grid_map("e", area, [], [], [bld.geometry], [(45.0607, 7.6507)], alt, FOV)
    with pytest.raises(GeoError, match=r"grid would be \d+x\d+ = [\d,]+ cells .*fly higher"):
        build_grid_map("e", area, [], [], [], [], alt, FOV, max_cells=100)
    with pytest.raises(GeoError, match="a.kml: the area is empty"):
        build_grid_map("e", shapely.Polygon(), [], [], [], [], alt, FOV, area_file="a.kml")
    with pytest.raises(GeoError, match="smaller than one"):
        build_grid_map("e", shapely.box(7.65, 45.06, 7.65001, 45.06001), [], [], [], [], 500, FOV)
    with pytest.raises(GeoError, match="field of view"):
        build_grid_map("e", area, [], [], [], [], alt, 0)


def test_300x300_grid_with_300_buildings():  # its speed is measured by hand, not asserted
    alt = altitude_for_cell(2.0)
    frame = GridFrame.at(45.0, 7.0, 2.0, 300, 300)
    area = _square_lonlat(frame, 0, 0, 300, 300)
    rng = np.random.default_rng(0)
    blds = []
    for _ in range(300):
        r, c = rng.integers(0, 290, 2)
        blds.append(Building(_square_lonlat(frame, r, c, r + rng.integers(2, 10), c + rng.integers(2, 10)), None))
    gmap, _ = build_grid_map("big", area, [], blds, [], [], alt, FOV)
    assert gmap.shape == (300, 300) and gmap.obstacle.any() and gmap.target.any()


@needs_maps
def test_turin_buildings_grid():
    blds = read_buildings(MAPS / "turin_cenisia_osm_buildings.geojson")
    alt = altitude_for_cell(2.0)  # 9 m
    gmap, frame = build_grid_map("turin", TURIN_BOX, [], blds, [], [TURIN_STREET], alt, FOV)
    assert gmap.shape == (248, 269)
    footprint = cells_centred_in([frame.geometry_to_grid(b.geometry) for b in blds], *gmap.shape)
    assert footprint.mean() == pytest.approx(0.20, abs=0.03)  # README: ~20 % building
    inside_obstacles = gmap.obstacle[:, :-1]  # the last column lies past the box edge
    assert 0.18 < inside_obstacles.mean() < 0.32  # touching cells add a rim around each building
    # at 9 m only the 3 m sheds (< 9 - 5 m) are overflown; everything else is blocked
    blocked = [b for b in blds if b.height_m is None or b.height_m >= 4.0]
    sheds = [b for b in blds if b.height_m is not None and b.height_m < 4.0]
    assert sheds
    assert gmap.obstacle[cells_centred_in([frame.geometry_to_grid(b.geometry) for b in blocked], *gmap.shape)].all()
    r, c = gmap.launch[0]
    assert gmap.target[r, c]

    # From 60 m up, buildings under 55 m... all known ones are overflown; unknown height stays blocked.
    high, hframe = build_grid_map("turin-high", TURIN_BOX, [], blds, [], [TURIN_STREET], 60.0, FOV)
    unknown = [b for b in blds if b.height_m is None]
    low = [b for b in blds if b.height_m is not None and b.height_m < 55.0]
    assert unknown and low
    cen = cells_centred_in([hframe.geometry_to_grid(b.geometry) for b in low], *high.shape)
    unk = cells_touching([hframe.geometry_to_grid(b.geometry) for b in unknown], *high.shape)
    free_roofs = cen & ~unk
    assert free_roofs.any() and not high.obstacle[free_roofs].any() and not high.target[free_roofs].any()
    assert high.obstacle[unk].all()
    # at 30 m, a 38.5 m building is an obstacle while a 7 m one is overflown
    mid, mframe = build_grid_map("turin-mid", TURIN_BOX, [], blds, [], [], 30.0, FOV)
    tallest = max((b for b in blds if b.height_m), key=lambda b: b.height_m)
    assert mid.obstacle[cells_touching([mframe.geometry_to_grid(tallest.geometry)], *mid.shape)].all()


@needs_maps
def test_vienna_public_space_buildings_are_obstacles():
    feats = read_features(MAPS / "vienna_rabenhof_public_space.geojson")
    area = shapely.union_all([f.geometry for f in feats])
    buildings = [f.geometry for f in feats if f.properties["space_category"] == "building"]
    gmap, frame = build_grid_map("vienna", area, buildings, [], [], [VIENNA_STREET], altitude_for_cell(2.0), FOV)
    assert abs(gmap.shape[0] - 255) <= 10 and abs(gmap.shape[1] - 255) <= 10
    centred = cells_centred_in([frame.geometry_to_grid(b) for b in buildings], *gmap.shape)
    assert 0.30 < centred.mean() < 0.42  # README: ~36 % building
    assert gmap.obstacle[centred].all()


@needs_maps
def test_vienna_osm_pbf_grid():
    blds = read_buildings(MAPS / "vienna_rabenhof.osm.pbf")
    area = shapely.box(16.39886, 48.19437, 16.40559, 48.19887)
    gmap, frame = build_grid_map("vienna-osm", area, [], blds, [], [VIENNA_STREET], altitude_for_cell(2.0), FOV)
    assert 0.30 < gmap.obstacle.mean() < 0.55
    # the area may also come as a list of polygons (e.g. from read_polygons): their union
    halves = [shapely.box(16.39886, 48.19437, 16.40300, 48.19887), shapely.box(16.40300, 48.19437, 16.40559, 48.19887)]
    same, _ = build_grid_map("vienna-osm", halves, [], blds, [], [VIENNA_STREET], altitude_for_cell(2.0), FOV)
    assert same.shape == gmap.shape and (same.obstacle == gmap.obstacle).mean() > 0.999
    assert gmap.target[gmap.launch[0]]


def test_too_many_cells_names_an_altitude_that_fits():
    area = shapely.box(7.650, 45.060, 7.652, 45.062)
    alt = altitude_for_cell(5.0)
    with pytest.raises(GeoError, match=r"fly higher, at (\d+) m or more") as error:
        build_grid_map("e", area, [], [], [], [], alt, FOV, max_cells=100)
    higher = float(re.search(r"at (\d+) m", str(error.value)).group(1))
    gmap, _ = build_grid_map("e", area, [], [], [], [], higher, FOV, max_cells=100)
    assert gmap.shape[0] * gmap.shape[1] <= 100
    with pytest.raises(GeoError, match="fly higher"):  # and not much lower than needed
        build_grid_map("e", area, [], [], [], [], 0.9 * higher, FOV, max_cells=100)
