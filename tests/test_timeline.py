"""missionplan.mission.timeline: planned missions as timed 3-D tracks, and the closest approach of timed tracks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missionplan.bridge.flight_models import copter_model as cm
from missionplan.bridge.flight_models.copter_model import CopterParams, Motion
from missionplan.mission.timeline import (FlightModel, closest_approach, closest_approach_out_of_step, planned_seconds,
                                         planned_track)

LAUNCH = np.array([10.0, 20.0])
# Two waypoints due "south" of the launch point along the row axis: a straight survey line.
WAYPOINTS = np.array([[40.0, 20.0], [90.0, 20.0]])
ALT = 15.0
MODEL = FlightModel(speed_m_s=5.0, acceptance_m=1.0)
# ArduCopter's defaults: WPNAV_SPEED_UP 2.5 m/s, WPNAV_ACCEL_Z 1 m/s/s, WPNAV_ACCEL 2.5 m/s/s,
# WPNAV_SPEED 10 m/s (RTL's way home), WPNAV_SPEED_DN 1.5 m/s to LAND_ALT_LOW 10 m, then LAND_SPEED 0.5 m/s.
TAKEOFF = cm.TAKEOFF_SPOOL_S + 15.0 / 2.5 + 2.5 / 1.0       # spool-up, then 15 m up: 6 s cruising + 2.5 s of ramps
LEG1, LEG2 = 30.0 / 5.0 + 5.0 / 2.5, 50.0 / 5.0 + 5.0 / 2.5  # rest to rest: distance / speed + speed / accel
HOME = cm.RTL_START_S + 80.0 / 10.0 + 10.0 / 2.5             # at WPNAV_SPEED, not the mission's 5 m/s
LOITER = 5.0 + cm.RTL_SETTLE_S                                # RTL_LOIT_TIME
# 15 -> 10 m: up to 1.5 m/s at 1 m/s/s (1.5 s, 1.125 m), down to 0.5 m/s (1 s, 1 m), 2.875 m at 1.5 m/s.
DESCENT = 1.5 + 1.0 + 2.875 / 1.5
LAND = 10.0 / 0.5 + cm.TOUCHDOWN_S                            # the last 10 m at 0.5 m/s, then disarm


def _at(track: np.ndarray, t: float) -> np.ndarray:
    return np.array([np.interp(t, track[:, 0], track[:, k]) for k in (1, 2, 3)])


def test_rtl_flight_spelled_out() -> None:
    track = planned_track(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL)
    marks = np.cumsum([TAKEOFF, LEG1, LEG2, HOME, LOITER, DESCENT, LAND])
    assert track[-1, 0] == pytest.approx(marks[-1], abs=1e-9)
    assert planned_seconds(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL) == pytest.approx(marks[-1], abs=1e-9)
    np.testing.assert_allclose(_at(track, cm.TAKEOFF_SPOOL_S), [10.0, 20.0, 0.0], atol=1e-9)  # still on the ground
    np.testing.assert_allclose(_at(track, marks[0]), [10.0, 20.0, ALT], atol=1e-9)
    np.testing.assert_allclose(_at(track, marks[1]), [40.0, 20.0, ALT], atol=1e-9)  # the waypoint itself
    np.testing.assert_allclose(_at(track, marks[2]), [90.0, 20.0, ALT], atol=1e-9)
    np.testing.assert_allclose(_at(track, marks[3]), [10.0, 20.0, ALT], atol=1e-9)  # above home, at 15 m >= RTL_ALT
    np.testing.assert_allclose(_at(track, marks[4]), [10.0, 20.0, ALT], atol=1e-9)  # after the loiter
    np.testing.assert_allclose(_at(track, marks[5]), [10.0, 20.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(track[-1, 1:], [10.0, 20.0, 0.0], atol=1e-9)
    # The last 10 m take 20 s: at 0.5 m/s, one metre every 2 s.
    np.testing.assert_allclose(_at(track, marks[5] + 2.0)[2], 9.0, atol=1e-9)
    # Half way along the 30 m leg (rest to rest, symmetric): at 15 m.
    np.testing.assert_allclose(_at(track, marks[0] + LEG1 / 2)[0], 25.0, atol=0.05)


def test_land_flight_has_no_return_leg_and_lands_on_the_last_waypoint() -> None:
    track = planned_track(LAUNCH, WAYPOINTS, ALT, "land", MODEL)
    assert track[-1, 0] == pytest.approx(TAKEOFF + LEG1 + LEG2 + DESCENT + LAND, abs=1e-9)
    np.testing.assert_allclose(track[-1, 1:], [90.0, 20.0, 0.0], atol=1e-9)
    rtl = planned_track(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL)
    cut = TAKEOFF + LEG1 + LEG2
    np.testing.assert_allclose(track[track[:, 0] <= cut], rtl[rtl[:, 0] <= cut], atol=1e-12)  # the same until then


def test_rtl_climbs_to_rtl_alt_first_and_less_near_home() -> None:
    low = planned_track(LAUNCH, WAYPOINTS, 8.0, "rtl", MODEL)
    t_last = cm.TAKEOFF_SPOOL_S + Motion((0, 0, 0), (0, 0, 8.0), 2.5, 1.0).duration + LEG1 + LEG2
    climb = Motion((0, 0, 8.0), (0, 0, 15.0), 2.5, 1.0).duration
    np.testing.assert_allclose(_at(low, t_last + cm.RTL_START_S + climb), [90.0, 20.0, 15.0], atol=1e-9)  # straight up
    assert low[:, 3].max() == pytest.approx(15.0)
    # 2 m from home the cone (RTL_CONE_SLOPE 3) allows 6 m, but ArduCopter climbs at least 2.5 m: 10.5 m.
    near = planned_track(np.array([0.0, 0.0]), np.array([[2.0, 0.0]]), 8.0, "rtl", MODEL)
    assert near[:, 3].max() == pytest.approx(8.0 + cm.RTL_ABS_MIN_CLIMB_M)
    # Above RTL_ALT it returns at its own altitude: never a descent before the landing.
    high = planned_track(LAUNCH, WAYPOINTS, 30.0, "rtl", MODEL)
    assert high[:, 3].max() == pytest.approx(30.0)


def test_the_vehicles_parameters_change_the_timeline() -> None:
    params = CopterParams.from_params({"WPNAV_SPEED_UP": 500.0, "WPNAV_ACCEL": 500.0, "RTL_SPEED": 500.0,
                                       "RTL_LOIT_TIME": 0.0, "LAND_SPEED": 100.0, "LAND_ALT_LOW": 500.0,
                                       "WPNAV_SPEED_DN": 250.0, "WPNAV_ACCEL_Z": 250.0})
    assert (params.speed_up, params.wp_accel, params.return_speed, params.rtl_loiter_s) == (5.0, 5.0, 5.0, 0.0)
    assert (params.land_speed, params.land_alt_low, params.descent_speed) == (1.0, 5.0, 2.5)
    assert params.wp_speed == 10.0  # not given: the default
    assert CopterParams.from_params(params.as_params()) == params
    model = FlightModel(5.0, 1.0, params)
    expected = (cm.TAKEOFF_SPOOL_S + 15.0 / 5.0 + 5.0 / 2.5 + 30.0 / 5.0 + 5.0 / 5.0 + 50.0 / 5.0 + 5.0 / 5.0
                + cm.RTL_START_S + 80.0 / 5.0 + 5.0 / 5.0 + cm.RTL_SETTLE_S
                + Motion((0, 0, 15.0), (0, 0, 5.0), 2.5, 2.5, v1=1.0).duration + 5.0 / 1.0 + cm.TOUCHDOWN_S)
    assert planned_seconds(LAUNCH, WAYPOINTS, ALT, "rtl", model) == pytest.approx(expected, abs=1e-9)
    assert planned_seconds(LAUNCH, WAYPOINTS, ALT, "rtl", model) < planned_seconds(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL)


def test_many_short_legs_take_far_longer_than_distance_over_speed() -> None:
    # A 20 x 10 m zigzag of 2 m legs: each leg is 2 * sqrt(2 / 2.5) s from rest to rest, not 0.4 s.
    zigzag = np.array([[2.0 * (k // 2 + k % 2), 2.0 * (k // 2)] for k in range(1, 21)])
    legs = np.hypot(*np.diff(np.vstack([[0.0, 0.0], zigzag]), axis=0).T)
    survey = sum(Motion((0, 0, 0), (d, 0, 0), 5.0, 2.5).duration for d in legs)
    assert survey == pytest.approx(20 * 2.0 * math.sqrt(2.0 / 2.5))
    assert survey > 4 * legs.sum() / 5.0


def test_motion_profile_respects_speed_and_acceleration() -> None:
    for distance, speed in ((0.5, 5.0), (4.0, 5.0), (30.0, 5.0), (200.0, 10.0)):
        m = Motion((0.0, 0.0, 0.0), (distance, 0.0, 0.0), speed, 2.5)
        t = np.linspace(0.0, m.duration, 2001)
        s = m.travelled(t)
        v = np.diff(s) / np.diff(t)
        assert s[0] == 0.0 and s[-1] == pytest.approx(distance)
        assert np.all(np.diff(s) >= -1e-12) and v.max() <= speed + 1e-6
        assert np.abs(np.diff(v) / np.diff(t)[1:]).max() <= 2.5 + 1e-3
        assert v[0] < 0.1 and v[-1] < 0.1  # from rest to rest
    # With an entry and an exit speed (the landing's switch to LAND_SPEED), and a wait.
    m = Motion((0.0, 0.0, 15.0), (0.0, 0.0, 10.0), 1.5, 1.0, v1=0.5)
    assert m.duration == pytest.approx(DESCENT)
    assert cm.wait((1.0, 2.0, 3.0), 4.0).duration == 4.0
    np.testing.assert_allclose(cm.wait((1.0, 2.0, 3.0), 4.0).position(2.0), [[1.0, 2.0, 3.0]])


# ------------------------------------------------------------------------------------------- closest approach
def _line(t0: float, t1: float, start: tuple[float, float, float], end: tuple[float, float, float]) -> np.ndarray:
    return np.array([(t0, *start), (t1, *end)], dtype=float)


def _crossing_tracks(t0: float = 100.0) -> dict[int, np.ndarray]:
    # A flies down the row axis through column 0; B flies along the columns on row 4. Both at 10 m/s.
    # A - B = (u - 54, 50 - u) with u = 10 (t - t0): minimum at u = 52, i.e. t0 + 5.2 s, 2*sqrt(2) m.
    return {
        1: _line(t0, t0 + 10.0, (-50.0, 0.0, 10.0), (50.0, 0.0, 10.0)),
        2: _line(t0, t0 + 10.0, (4.0, -50.0, 10.0), (4.0, 50.0, 10.0)),
    }


def test_closest_approach_of_crossing_tracks() -> None:
    tracks = _crossing_tracks()
    tracks[3] = _line(98.0, 112.0, (500.0, 500.0, 10.0), (500.0, 500.0, 10.0))  # far away, starts 2 s earlier
    got = closest_approach(tracks)
    assert got["horizontal"] == pytest.approx(2 * math.sqrt(2), abs=1e-3)
    assert got["3d"] == pytest.approx(2 * math.sqrt(2), abs=1e-3)
    assert got["pair_horizontal"] == [1, 2] and got["pair_3d"] == [1, 2]
    assert got["at_s"] == pytest.approx(7.2, abs=0.011)  # from the earliest start of any track (98 s)


def test_closest_approach_minimum_between_recorded_times_is_found_by_the_step() -> None:
    # Only the end points are recorded: the minimum at t = 5.2 s lies between them.
    got = closest_approach(_crossing_tracks(t0=0.0), step_s=0.01)
    assert got["horizontal"] == pytest.approx(2 * math.sqrt(2), abs=1e-3)
    assert got["at_s"] == pytest.approx(5.2, abs=0.011)


def test_vertical_offset_makes_3d_larger_than_horizontal() -> None:
    tracks = _crossing_tracks(t0=0.0)
    tracks[2][:, 3] = 13.0  # 3 m above A
    got = closest_approach(tracks)
    assert got["horizontal"] == pytest.approx(2 * math.sqrt(2), abs=1e-3)
    assert got["3d"] == pytest.approx(math.sqrt(8.0 + 9.0), abs=1e-3)
    assert got["3d"] > got["horizontal"]
    assert got["at_s"] == pytest.approx(5.2, abs=0.011)


def test_horizontal_and_3d_pairs_can_differ() -> None:
    tracks = _crossing_tracks(t0=0.0)
    # C hovers 1 m (horizontally) beside A's path at t = 2 s but 40 m above it.
    tracks[3] = _line(0.0, 10.0, (-30.0, 1.0, 50.0), (-30.0, 1.0, 50.0))
    got = closest_approach(tracks)
    assert got["pair_horizontal"] == [1, 3] and got["horizontal"] == pytest.approx(1.0, abs=1e-3)
    assert got["pair_3d"] == [1, 2] and got["3d"] == pytest.approx(2 * math.sqrt(2), abs=1e-3)


def test_tracks_that_do_not_overlap_in_time() -> None:
    tracks = {1: _line(0.0, 10.0, (0.0, 0.0, 10.0), (10.0, 0.0, 10.0)),
              2: _line(20.0, 30.0, (0.0, 0.0, 10.0), (10.0, 0.0, 10.0))}  # same path, later
    got = closest_approach(tracks)
    assert got == {"horizontal": None, "3d": None, "pair_horizontal": [], "pair_3d": [], "at_s": None}
    assert closest_approach({1: tracks[1]})["3d"] is None
    assert closest_approach({})["horizontal"] is None


def _follower(lag_s: float) -> dict[int, np.ndarray]:
    """Drone 2 flies drone 1's straight 5 m/s line lag_s seconds behind it (5 * lag_s metres back)."""
    return {1: _line(0.0, 20.0, (0.0, 0.0, 10.0), (100.0, 0.0, 10.0)),
            2: _line(0.0, 20.0, (-5.0 * lag_s, 0.0, 10.0), (100.0 - 5.0 * lag_s, 0.0, 10.0))}


def test_out_of_step_a_follower_may_catch_up_by_the_slack() -> None:
    tracks = _follower(2.0)
    assert closest_approach(tracks)["3d"] == pytest.approx(10.0, abs=1e-3)  # in step: 2 s = 10 m apart
    # Up to 1 s out of step: half the gap; 2 s: the follower may be where the leader is.
    assert closest_approach_out_of_step(tracks, 1.0, 0.0)["3d"] == pytest.approx(5.0, abs=1e-3)
    assert closest_approach_out_of_step(tracks, 2.0, 0.0)["3d"] == pytest.approx(0.0, abs=1e-3)
    # The slack grows with time: 0.1 s per second reaches 2 s only at 20 s, where the lines end: the
    # follower's end is where the leader was at 18 s (at_s: the first-named drone's time).
    grown = closest_approach_out_of_step(tracks, 0.0, 0.1)
    assert grown["3d"] == pytest.approx(0.0, abs=1e-3) and grown["at_s"] == pytest.approx(18.0)
    assert closest_approach_out_of_step(tracks, 0.0, 0.09)["3d"] > 0.5  # 1.8 s: not caught up


def test_out_of_step_without_slack_is_the_closest_approach() -> None:
    for tracks in (_crossing_tracks(t0=0.0), _follower(2.0)):
        exact, stepped = closest_approach(tracks), closest_approach_out_of_step(tracks, 0.0, 0.0, step_s=0.1)
        assert stepped["3d"] == pytest.approx(exact["3d"], abs=0.1) and stepped["pair_3d"] == exact["pair_3d"]


def test_out_of_step_is_the_same_whichever_drone_is_named_first() -> None:
    tracks = _follower(3.0)
    swapped = {1: tracks[2], 2: tracks[1]}
    for floor_s, rate in ((1.0, 0.0), (0.0, 0.1), (0.5, 0.05)):
        assert (closest_approach_out_of_step(tracks, floor_s, rate)["3d"]
                == closest_approach_out_of_step(swapped, floor_s, rate)["3d"])


def test_planned_tracks_of_two_drones_on_one_time_base() -> None:
    # Two parallel survey lines 6 m apart, flown at the same time: never closer than 6 m.
    a = planned_track(np.array([0.0, 0.0]), np.array([[50.0, 0.0]]), 10.0, "rtl", MODEL)
    b = planned_track(np.array([0.0, 6.0]), np.array([[50.0, 6.0]]), 10.0, "rtl", MODEL)
    got = closest_approach({1: a, 2: b})
    assert got["horizontal"] == pytest.approx(6.0, abs=1e-6) and got["3d"] == pytest.approx(6.0, abs=1e-6)
    assert got["at_s"] == pytest.approx(0.0, abs=1e-9)  # side by side from the start
