"""The ground under a track's legs (missionplan.mission.terrain_legs): samples every few metres along each
leg, the sea-level track a PX4 mission flies (legs split where the ground leaves the straight line), and the
height above the ground such a track keeps. Grounds are analytic hills, so every expected height is exact.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyproj import Geod

from missionplan.geo.errors import GeoError
from missionplan.mission.terrain_legs import amsl_track, flown_heights, sample_legs

SETTINGS = settings(max_examples=150, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
GEOD = Geod(ellps="WGS84")
LAT0, LON0 = 44.41, 8.93  # Genoa: a city on a hill
# metres per degree about LAT0, LON0 on the WGS84 ellipsoid (geodesics over 0.01 degree)
M_PER_DEG_LAT = GEOD.inv(LON0, LAT0 - 0.005, LON0, LAT0 + 0.005)[2] / 0.01
M_PER_DEG_LON = GEOD.inv(LON0 - 0.005, LAT0, LON0 + 0.005, LAT0)[2] / 0.01


def _to_deg(east_m: np.ndarray, north_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return LAT0 + np.asarray(north_m) / M_PER_DEG_LAT, LON0 + np.asarray(east_m) / M_PER_DEG_LON


class Hills:
    """A ground of Gaussian hills on a base height, with a bound on its curvature along any line."""

    def __init__(self, base: float, hills: list[tuple[float, float, float, float]]) -> None:
        self.base = base
        self.hills = hills  # (east m, north m, height m, sigma m)

    def __call__(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        east = (np.asarray(lon) - LON0) * M_PER_DEG_LON
        north = (np.asarray(lat) - LAT0) * M_PER_DEG_LAT
        height = np.full(east.shape, self.base)
        for x, y, top, sigma in self.hills:
            height = height + top * np.exp(-((east - x) ** 2 + (north - y) ** 2) / (2 * sigma**2))
        return height

    def max_curvature(self) -> float:
        """An upper bound of |d2 ground / ds2| along any straight line: a hill's is at most top / sigma^2."""
        return sum(abs(top) / sigma**2 for _, _, top, sigma in self.hills)


def _flat(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return np.full(np.shape(lat), 120.0)


def _slope(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """A plane rising 15 m per 100 m east and 5 m per 100 m north."""
    return 50.0 + 0.15 * (np.asarray(lon) - LON0) * M_PER_DEG_LON + 0.05 * (np.asarray(lat) - LAT0) * M_PER_DEG_LAT


# ------------------------------------------------------------------------------------------ sample_legs

def test_samples_cover_every_leg_end_to_end_no_further_apart_than_the_step() -> None:
    lat, lon = _to_deg(np.array([0.0, 1000.0, 1000.0, 1000.0, 0.0]), np.array([0.0, 0.0, 37.0, 37.0, 600.0]))
    s_lat, s_lon, leg = sample_legs(lat, lon, 5.0)
    assert list(np.unique(leg)) == [0, 1, 2, 3]
    for number in range(4):
        on = leg == number
        # both ends of every leg, exactly
        assert (s_lat[on][0], s_lon[on][0]) == pytest.approx((lat[number], lon[number]), abs=1e-12)
        assert (s_lat[on][-1], s_lon[on][-1]) == pytest.approx((lat[number + 1], lon[number + 1]), abs=1e-12)
        # geodesic spacing (an independent metric): evenly spaced, never more than the step
        _, _, gaps = GEOD.inv(s_lon[on][:-1], s_lat[on][:-1], s_lon[on][1:], s_lat[on][1:])
        assert np.all(gaps <= 5.0 + 0.01)
        assert np.ptp(gaps) < 0.01
    assert np.sum(leg == 0) == 201  # 1000 m in 200 steps of 5 m
    assert np.sum(leg == 1) == 9  # 37 m in 8 steps of 4.6 m
    assert np.sum(leg == 2) == 2  # a leg of no length: its two ends
    assert sample_legs(lat[:1], lon[:1], 5.0)[0].size == 0  # one point: no legs


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_a_step_that_is_not_a_positive_length_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="step_m must be a positive number of metres"):
        sample_legs([LAT0, LAT0], [LON0, LON0 + 0.01], bad)


# ------------------------------------------------------------------------------------------- amsl_track

def _lawnmower(width_m: float = 800.0, lanes: int = 5, spacing_m: float = 150.0) -> tuple[np.ndarray, np.ndarray]:
    east = np.repeat(np.where(np.arange(lanes) % 2 == 0, 0.0, width_m), 2)
    east[1::2] = width_m - east[::2]
    north = np.repeat(np.arange(lanes) * spacing_m, 2)
    return _to_deg(east, north)


@pytest.mark.parametrize("ground", [_flat, _slope], ids=["flat", "planar slope"])
def test_ground_a_straight_line_follows_adds_no_point(ground) -> None:
    lat, lon = _lawnmower()
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, 40.0, ground)
    assert list(source) == list(range(lat.size))
    assert np.array_equal(out_lat, lat) and np.array_equal(out_lon, lon)
    assert amsl == pytest.approx(ground(lat, lon) + 40.0)
    assert np.abs(flown_heights(out_lat, out_lon, amsl, ground, 5.0) - 40.0).max() < 1e-6


def test_a_bump_within_the_tolerance_adds_none_and_one_above_it_adds_points_on_its_leg_only() -> None:
    lat, lon = _to_deg(np.array([0.0, 600.0, 600.0, 0.0]), np.array([0.0, 0.0, 300.0, 300.0]))
    low = Hills(80.0, [(300.0, 0.0, 1.9, 60.0)])  # under the first leg, 1.9 m high
    assert list(amsl_track(lat, lon, 30.0, low, tolerance_m=2.0)[3]) == [0, 1, 2, 3]
    high = Hills(80.0, [(300.0, 0.0, 25.0, 60.0)])
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, 30.0, high, tolerance_m=2.0)
    added = np.flatnonzero(source == -1)
    assert added.size >= 3
    assert list(source[source >= 0]) == [0, 1, 2, 3]
    assert np.all((added > 0) & (added < list(source).index(1)))  # all between points 0 and 1
    # an added point lies on the first leg, at ground + the height asked for
    assert out_lat[added] == pytest.approx(np.full(added.size, LAT0), abs=1e-9)
    assert amsl[added] == pytest.approx(high(out_lat[added], out_lon[added]) + 30.0)
    assert np.abs(flown_heights(out_lat, out_lon, amsl, high, 5.0) - 30.0).max() <= 2.0


def test_a_ridge_between_two_points_at_one_altitude_is_split() -> None:
    """The check is on the straight line flown, not on neighbouring altitudes: both ends of this leg are at
    the same altitude above sea level and a 40 m ridge runs across its middle."""
    lat, lon = _to_deg(np.array([0.0, 800.0]), np.array([0.0, 0.0]))
    ridge = Hills(100.0, [(400.0, 0.0, 40.0, 50.0)])
    _, _, amsl, source = amsl_track(lat, lon, 30.0, ridge)
    assert (source == -1).sum() >= 3
    assert amsl.max() == pytest.approx(170.0, abs=0.5)  # the ridge's top is flown over at 30 m


def test_heights_per_point_are_kept_at_the_points_and_taken_linearly_along_a_leg() -> None:
    lat, lon = _to_deg(np.array([0.0, 500.0, 500.0]), np.array([0.0, 0.0, 400.0]))
    hills = Hills(10.0, [(250.0, 0.0, 30.0, 40.0), (500.0, 200.0, 30.0, 40.0)])
    height = np.array([20.0, 60.0, 40.0])
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, height, hills, tolerance_m=1.0)
    kept = source >= 0
    assert amsl[kept] == pytest.approx(hills(lat, lon) + height)
    # along the first leg the height asked for goes from 20 to 60 m
    first = np.flatnonzero(out_lat[: list(source).index(1) + 1] == pytest.approx(LAT0))
    share = (out_lon[first] - LON0) / (lon[1] - LON0)
    assert amsl[first] - hills(out_lat[first], out_lon[first]) == pytest.approx(20.0 + 40.0 * share)


def test_a_hole_under_a_leg_is_refused_naming_where() -> None:
    lat, lon = _to_deg(np.array([0.0, 500.0]), np.array([0.0, 0.0]))

    def holed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        heights = _flat(a, b)
        heights[(b - LON0) * M_PER_DEG_LON > 300.0] = np.nan
        return heights

    with pytest.raises(GeoError, match=r"no ground height at 44\.410000, 8\.93[0-9]+ under the track \([0-9]+ such"):
        amsl_track(lat, lon, 30.0, holed)


@st.composite
def _hills_and_tracks(draw: st.DrawFn) -> tuple[Hills, np.ndarray, np.ndarray, object, float, float]:
    hills = Hills(draw(st.floats(-50.0, 2000.0)), [
        (draw(st.floats(-200.0, 1200.0)), draw(st.floats(-200.0, 1200.0)), draw(st.floats(-80.0, 120.0)),
         draw(st.floats(25.0, 400.0))) for _ in range(draw(st.integers(1, 4)))])
    points = draw(st.integers(2, 8))
    east = np.array(draw(st.lists(st.floats(0.0, 1000.0), min_size=points, max_size=points)))
    north = np.array(draw(st.lists(st.floats(0.0, 1000.0), min_size=points, max_size=points)))
    lat, lon = _to_deg(east, north)
    height = draw(st.one_of(st.floats(5.0, 120.0),
                            st.lists(st.floats(5.0, 120.0), min_size=points, max_size=points).map(np.array)))
    return hills, lat, lon, height, draw(st.sampled_from([1.0, 2.0, 5.0])), draw(st.sampled_from([2.0, 5.0, 10.0]))


@SETTINGS
@given(_hills_and_tracks())
def test_every_sample_of_every_split_leg_is_within_the_tolerance(case) -> None:
    hills, lat, lon, height, tolerance, step = case
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, height, hills, tolerance_m=tolerance, step_m=step)
    heights = np.broadcast_to(height, lat.shape)
    # every input point is there, in order, at ground + its height
    assert list(source[source >= 0]) == list(range(lat.size))
    assert np.array_equal(out_lat[source >= 0], lat) and np.array_equal(out_lon[source >= 0], lon)
    assert amsl[source >= 0] == pytest.approx(hills(lat, lon) + heights)
    positions = np.flatnonzero(source >= 0)
    s_lat, s_lon, s_leg = sample_legs(lat, lon, step)
    fine_lat, fine_lon, fine_leg = sample_legs(lat, lon, step / 4)
    slack = hills.max_curvature() * step**2 / 8  # how far the ground can bend between two samples
    for leg in range(lat.size - 1):
        if _share_along(lat, lon, (lat[leg + 1:leg + 2], lon[leg + 1:leg + 2]), np.array([leg]))[0] == 0.0:
            continue  # a leg of no length: nothing is flown along it
        on_leg = slice(positions[leg], positions[leg + 1] + 1)
        legs_of = np.full(out_lat[on_leg].size, leg)
        out_share = _share_along(lat, lon, (out_lat[on_leg], out_lon[on_leg]), legs_of)
        assert np.all(np.diff(out_share) > 0)  # added points lie along the leg, in order
        for points, legs in (((s_lat, s_lon), s_leg), ((fine_lat, fine_lon), fine_leg)):
            p_lat, p_lon = points[0][legs == leg], points[1][legs == leg]
            share = _share_along(lat, lon, (p_lat, p_lon), np.full(p_lat.size, leg))
            flown = np.interp(share, out_share, amsl[on_leg])  # the straight lines between kept points
            asked = hills(p_lat, p_lon) + heights[leg] + share * (heights[leg + 1] - heights[leg])
            # exactly within at the samples the split was decided on; between them, within the bend's slack
            allowed = tolerance + 1e-6 if points[0] is s_lat else tolerance + slack + 1e-6
            assert np.abs(flown - asked).max() <= allowed
    if np.ndim(height) == 0:  # flown_heights agrees: straight legs in sea-level altitude over the hills
        assert np.abs(flown_heights(out_lat, out_lon, amsl, hills, step) - height).max() <= tolerance + slack + 1e-6


def test_lead_in_turns_cuts_each_legs_first_stretch_where_the_ground_spans_the_tolerance() -> None:
    """A multicopter that reaches a leg's next altitude early (PX4, turning onto the leg) must be within the
    tolerance at any altitude between the ends of the leg's first stretch: over a planar slope, whose straight
    legs need no split, each leg gets one point where the ground has risen or fallen by the tolerance."""
    lat, lon = _lawnmower(width_m=400.0, lanes=3, spacing_m=60.0)
    assert list(amsl_track(lat, lon, 30.0, _slope, tolerance_m=2.0)[3]) == list(range(lat.size))
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, 30.0, _slope, tolerance_m=2.0, lead_in_turns=True)
    assert list(source[source >= 0]) == list(range(lat.size))
    added = np.flatnonzero(source == -1)
    assert list(added) == [int(np.flatnonzero(source == k)[0]) + 1 for k in range(lat.size - 1)]  # one per leg
    # 15 m per 100 m east: 2 m of ground within 13.3 m, so the stretch ends at the last 5 m sample before it
    start = added - 1
    run = np.hypot((out_lat[added] - out_lat[start]) * M_PER_DEG_LAT, (out_lon[added] - out_lon[start]) * M_PER_DEG_LON)
    east_west = np.abs(out_lat[added] - out_lat[start]) < 1e-9
    assert run[east_west] == pytest.approx(np.full(east_west.sum(), 400.0 / 80 * 2), abs=0.01)
    assert np.abs(amsl[added] - amsl[start]).max() <= 2.0


@SETTINGS
@given(_hills_and_tracks())
def test_with_lead_in_turns_any_altitude_between_a_legs_first_two_points_is_within_the_tolerance(case) -> None:
    hills, lat, lon, height, tolerance, step = case
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, height, hills, tolerance_m=tolerance, step_m=step,
                                                lead_in_turns=True)
    assert list(source[source >= 0]) == list(range(lat.size))
    heights = np.broadcast_to(height, lat.shape)
    positions = np.flatnonzero(source >= 0)
    s_lat, s_lon, s_leg = sample_legs(lat, lon, step)
    for leg in range(lat.size - 1):
        start, end = positions[leg], positions[leg] + 1  # the leg's first stretch: its point and the next
        on = s_leg == leg
        p_lat, p_lon = s_lat[on], s_lon[on]
        share = _share_along(lat, lon, (p_lat, p_lon), np.full(p_lat.size, leg))
        end_share = _share_along(lat, lon, (out_lat[end:end + 1], out_lon[end:end + 1]), np.array([leg]))[0]
        if end_share == 0.0:
            continue  # a leg of no length
        asked = hills(p_lat, p_lon) + heights[leg] + share * (heights[leg + 1] - heights[leg])
        first = share <= end_share + 1e-9
        if first.sum() <= 2:
            continue  # the stretch is one sample step: as short as the samples can cut it
        # both ends' altitudes, and so any between them, within the tolerance of every sample of the stretch
        for altitude in (amsl[start], amsl[end]):
            assert np.abs(asked[first] - altitude).max() <= tolerance + 1e-6


def _share_along(lat: np.ndarray, lon: np.ndarray, points: tuple[np.ndarray, np.ndarray],
                 leg: np.ndarray) -> np.ndarray:
    """How far along its input leg (0 to 1) each point is (0 on a leg of no length)."""
    p_lat, p_lon = points
    d_lat, d_lon = lat[leg + 1] - lat[leg], lon[leg + 1] - lon[leg]
    length2 = (d_lat * M_PER_DEG_LAT) ** 2 + (d_lon * M_PER_DEG_LON) ** 2
    dot = (p_lat - lat[leg]) * d_lat * M_PER_DEG_LAT**2 + (p_lon - lon[leg]) * d_lon * M_PER_DEG_LON**2
    return np.divide(dot, length2, out=np.zeros_like(dot), where=length2 > 1e-6)


def test_flown_heights_of_a_straight_climb_over_a_slope() -> None:
    lat, lon = _to_deg(np.array([0.0, 195.0]), np.array([0.0, 0.0]))
    assert _slope(lat, lon) == pytest.approx([50.0, 79.25])
    heights = flown_heights(lat, lon, np.array([100.0, 100.0]), _slope, 10.0)
    assert heights == pytest.approx(np.linspace(50.0, 20.75, 21))  # 20 steps of 9.75 m
    climbing = flown_heights(lat, lon, np.array([90.0, 119.25]), _slope, 10.0)
    assert climbing == pytest.approx(np.full(21, 40.0))
