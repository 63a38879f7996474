"""Camera footprint and cell size (SPEC section 7) checked by hand."""

import math

import pytest

from missionplan.geo.camera import Camera, cell_size_m, footprint_side_m
from missionplan.geo.errors import GeoError


def test_fov_90_at_50m_gives_100m_footprint_and_11_11m_cell():
    assert footprint_side_m(50, 90) == pytest.approx(100.0)
    assert cell_size_m(50, 90) == pytest.approx(100.0 / 9)
    assert round(cell_size_m(50, 90), 2) == 11.11


def test_fov_60_by_hand():
    assert footprint_side_m(30, 60) == pytest.approx(2 * 30 * math.tan(math.radians(30)))


def test_sensor_uses_the_narrower_side():
    cam = Camera.from_sensor(13.2, 8.8, 8.8)
    # narrower side 8.8 mm, f 8.8 mm -> 2*atan(0.5)
    assert cam.fov_deg == pytest.approx(math.degrees(2 * math.atan(0.5)))
    assert Camera.from_sensor(8.8, 13.2, 8.8).fov_deg == pytest.approx(cam.fov_deg)
    assert cam.footprint_side_m(50) == pytest.approx(50.0)  # 2*50*tan(atan(0.5))
    assert cam.cell_size_m(50) == pytest.approx(50.0 / 9)


@pytest.mark.parametrize("fov", [0, 180, -10, 200, float("nan"), "wide"])
def test_bad_fov_is_a_geo_error(fov):
    with pytest.raises(GeoError, match="field of view"):
        cell_size_m(50, fov)
    with pytest.raises(GeoError, match="field of view"):
        Camera(fov)


@pytest.mark.parametrize("alt", [0, -5, float("inf")])
def test_bad_altitude_is_a_geo_error(alt):
    with pytest.raises(GeoError, match="altitude"):
        footprint_side_m(alt, 90)


@pytest.mark.parametrize("w,h,f,what", [(0, 8.8, 8.8, "sensor width"), (13.2, -1, 8.8, "sensor height"),
                                        (13.2, 8.8, 0, "focal length")])
def test_bad_sensor_numbers_are_geo_errors(w, h, f, what):
    with pytest.raises(GeoError, match=what):
        Camera.from_sensor(w, h, f)
