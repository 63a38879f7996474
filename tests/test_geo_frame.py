"""GridFrame: grid <-> UTM <-> lat/lon round trips, distances and rotation."""

import numpy as np
import pytest
import shapely
from pyproj import Geod

from missionplan.geo.errors import GeoError
from missionplan.geo.frame import GridFrame, utm_epsg_for

GEOD = Geod(ellps="WGS84")
TURIN = (45.07, 7.652)


def _all_cells(frame):
    rr, cc = np.mgrid[0:frame.rows, 0:frame.cols]
    return rr.ravel(), cc.ravel()


def test_utm_zone_and_hemisphere():
    assert utm_epsg_for(7.65, 45.07) == 32632
    assert utm_epsg_for(16.4, 48.2) == 32633
    assert utm_epsg_for(151.2, -33.9) == 32756  # Sydney: south
    assert utm_epsg_for(-74.0, 40.7) == 32618
    with pytest.raises(GeoError):
        utm_epsg_for(10, 89)


@pytest.mark.parametrize("rot", [0.0, 17.5, -33.0, 90.0, 135.0])
def test_cell_latlon_cell_round_trips_exactly(rot):
    frame = GridFrame.at(*TURIN, cell_m=2.0, rows=60, cols=80, rotation_deg=rot)
    r, c = _all_cells(frame)
    lat, lon = frame.cell_to_latlon(r, c)
    r2, c2 = frame.latlon_to_cell(lat, lon)
    assert np.array_equal(r, r2) and np.array_equal(c, c2)


@pytest.mark.parametrize("rot", [0.0, 23.0, -71.0])
def test_float_grid_round_trip_under_a_centimetre(rot):
    frame = GridFrame.at(-33.9, 151.2, cell_m=3.7, rows=300, cols=300, rotation_deg=rot)
    rng = np.random.default_rng(1)
    r = rng.uniform(-0.5, 299.5, 2000)
    c = rng.uniform(-0.5, 299.5, 2000)
    lat, lon = frame.grid_to_latlon(r, c)
    r2, c2 = frame.latlon_to_grid(lat, lon)
    assert np.max(np.hypot(r2 - r, c2 - c)) * frame.cell_m < 0.01
    lat2, lon2 = frame.grid_to_latlon(r2, c2)
    _, _, dist = GEOD.inv(lon, lat, lon2, lat2)
    assert np.max(dist) < 0.01


def test_integer_grid_coordinates_are_cell_centres():
    frame = GridFrame.at(*TURIN, cell_m=10.0, rows=5, cols=5)
    lat, lon = frame.grid_to_latlon(0, 0)
    _, _, d = GEOD.inv(TURIN[1], TURIN[0], float(lon), float(lat))
    assert d == pytest.approx(np.hypot(5, 5), abs=0.05)  # half a cell east and south of the corner
    assert frame.corner_latlon() == pytest.approx(TURIN, abs=1e-9)
    # a point just inside the corner cell belongs to cell (0, 0)
    assert tuple(int(v) for v in frame.latlon_to_cell(*frame.grid_to_latlon(-0.49, 0.49))) == (0, 0)


def test_100m_east_is_100m_by_geodesic():
    frame = GridFrame.at(*TURIN, cell_m=1.0, rows=200, cols=200)
    lat0, lon0 = frame.grid_to_latlon(50.0, 20.0)
    lat1, lon1 = frame.grid_to_latlon(50.0, 120.0)
    az, _, dist = GEOD.inv(float(lon0), float(lat0), float(lon1), float(lat1))
    # UTM grid distance vs true distance: the scale factor near the zone edge is within 1e-3
    # of 1, so compare to what the projection's scale says, plus 1 cm
    assert dist == pytest.approx(100.0, abs=0.1)
    assert 85 < az < 95  # east, up to grid convergence
    lat2, lon2 = frame.grid_to_latlon(150.0, 20.0)
    az2, _, dist2 = GEOD.inv(float(lon0), float(lat0), float(lon2), float(lat2))
    assert dist2 == pytest.approx(dist, abs=0.01)  # conformal: same scale north-south
    assert abs(abs(az2) - 180) < 5


@pytest.mark.parametrize("lat, lon", [(45.0, 8.9995), (45.07, 7.655), (48.196, 16.402), (41.15, -8.61),
                                      (-33.9, 18.42), (45.0, 11.9)])
def test_100m_east_is_100m_within_a_centimetre(lat, lon):
    # Cells are ground metres: the frame undoes the UTM scale factor (0.9996 on the central
    # meridian, larger towards the zone's edge: 11.9E is near zone 32's eastern edge).
    frame = GridFrame.at(lat, lon, cell_m=1.0, rows=10, cols=200)
    lat0, lon0 = frame.grid_to_latlon(5.0, 50.0)
    lat1, lon1 = frame.grid_to_latlon(5.0, 150.0)
    _, _, dist = GEOD.inv(float(lon0), float(lat0), float(lon1), float(lat1))
    assert dist == pytest.approx(100.0, abs=0.01)


@pytest.mark.parametrize("rot", [30.0, 90.0, -45.0])
def test_rotated_frame_axes_point_where_they_should(rot):
    frame = GridFrame.at(*TURIN, cell_m=1.0, rows=200, cols=200, rotation_deg=rot)
    lat0, lon0 = frame.grid_to_latlon(100.0, 100.0)
    lat1, lon1 = frame.grid_to_latlon(100.0, 150.0)  # along the column ("east") axis
    lat2, lon2 = frame.grid_to_latlon(50.0, 100.0)  # towards row 0 ("north")
    az_e, _, _ = GEOD.inv(float(lon0), float(lat0), float(lon1), float(lat1))
    az_n, _, _ = GEOD.inv(float(lon0), float(lat0), float(lon2), float(lat2))
    conv = 1.5  # grid convergence at Turin, zone 32, ~1 degree
    assert abs(((az_e - (rot + 90)) + 180) % 360 - 180) < conv
    assert abs(((az_n - rot) + 180) % 360 - 180) < conv


def test_from_area_covers_the_polygon_and_meta_round_trips():
    area = shapely.box(7.65189, 45.06563, 7.65861, 45.07000)
    for rot in (0.0, 25.0):
        frame = GridFrame.from_area(area, 2.0, rotation_deg=rot, margin_cells=1)
        lon, lat = shapely.get_coordinates(area).T
        r, c = frame.latlon_to_grid(lat, lon)
        assert (r >= 0.5 - 1e-6).all() and (c >= 0.5 - 1e-6).all()  # one margin cell on every side
        assert (r <= frame.rows - 1.5 + 1e-6).all() and (c <= frame.cols - 1.5 + 1e-6).all()
        assert GridFrame.from_meta(frame.to_meta()) == frame
    north_up = GridFrame.from_area(area, 2.0)
    assert (north_up.rows, north_up.cols) == (248, 269)  # as shared/maps/README.md says
    meta = {k: v for k, v in north_up.to_meta().items() if k in ("origin_lat", "origin_lon", "cell_m")}
    approx = GridFrame.from_meta(meta, rows=248, cols=269)
    assert approx.origin_e == pytest.approx(north_up.origin_e, abs=0.01)
    assert approx.origin_n == pytest.approx(north_up.origin_n, abs=0.01)


def test_bad_meta_and_sizes_are_geo_errors():
    with pytest.raises(GeoError, match="cell_m"):
        GridFrame.from_meta({"origin_lat": "45", "origin_lon": "7"}, rows=3, cols=3)
    with pytest.raises(GeoError, match="not a number"):
        GridFrame.from_meta({"origin_lat": "x", "origin_lon": "7", "cell_m": "1"}, rows=3, cols=3)
    with pytest.raises(GeoError):
        GridFrame.at(*TURIN, cell_m=0.0, rows=3, cols=3)
    with pytest.raises(GeoError, match="empty"):
        GridFrame.from_area(shapely.Polygon(), 2.0)
