"""missionplan.timeline: planned missions as timed 3-D tracks, and the closest approach of timed tracks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missionplan.timeline import CLIMB_RATE_M_S, LAND_RATE_M_S, FlightModel, closest_approach, planned_track

LAUNCH = np.array([10.0, 20.0])
# Two waypoints due "south" of the launch point along the row axis: a straight survey line.
WAYPOINTS = np.array([[40.0, 20.0], [90.0, 20.0]])
ALT = 15.0
MODEL = FlightModel(speed_m_s=5.0, acceptance_m=1.0)


def _expected_corners(end: str) -> list[tuple[float, float, float, float]]:
    t = ALT / CLIMB_RATE_M_S                                       # climb at the launch point
    corners = [(0.0, 10.0, 20.0, 0.0), (t, 10.0, 20.0, ALT)]
    t += (30.0 - 1.0) / 5.0                                         # leg 1: 30 m, reached 1 m early
    corners.append((t, 39.0, 20.0, ALT))
    t += (51.0 - 1.0) / 5.0                                         # leg 2: from 39 to 90, reached 1 m early
    corners.append((t, 89.0, 20.0, ALT))
    if end == "rtl":
        t += 79.0 / 5.0                                             # home at the survey altitude
        corners.append((t, 10.0, 20.0, ALT))
    t += ALT / LAND_RATE_M_S                                        # descent where the track ends
    corners.append((t, corners[-1][1], corners[-1][2], 0.0))
    return corners


def test_planned_track_rtl_corners() -> None:
    track = planned_track(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL)
    assert track.shape == (6, 4)
    np.testing.assert_allclose(track, np.array(_expected_corners("rtl")), atol=1e-9)
    # Spelled out: 6 s climb, 5.8 s and 10 s legs, 15.8 s home, 10 s descent.
    np.testing.assert_allclose(track[:, 0], [0.0, 6.0, 11.8, 21.8, 37.6, 47.6], atol=1e-9)
    # Ends on the ground at the launch point.
    np.testing.assert_allclose(track[-1, 1:], [10.0, 20.0, 0.0], atol=1e-9)


def test_planned_track_land_has_no_return_leg() -> None:
    track = planned_track(LAUNCH, WAYPOINTS, ALT, "land", MODEL)
    assert track.shape == (5, 4)
    np.testing.assert_allclose(track, np.array(_expected_corners("land")), atol=1e-9)
    # Lands where the last leg ended: one acceptance radius short of the last waypoint.
    np.testing.assert_allclose(track[-1], [31.8, 89.0, 20.0, 0.0], atol=1e-9)
    rtl = planned_track(LAUNCH, WAYPOINTS, ALT, "rtl", MODEL)
    np.testing.assert_allclose(track[:4], rtl[:4], atol=1e-12)  # the same flight up to the last waypoint


def test_acceptance_radius_shortens_each_leg_by_exactly_the_radius() -> None:
    for radius in (0.0, 0.5, 2.0):
        track = planned_track(LAUNCH, WAYPOINTS, ALT, "land", FlightModel(5.0, radius))
        legs = np.diff(track[1:4, 0]) * 5.0
        # Leg 1 is 30 m from the launch point; leg 2 starts `radius` before waypoint 1 and is 50 + radius long.
        np.testing.assert_allclose(legs, [30.0 - radius, 50.0 + radius - radius], atol=1e-9)
        np.testing.assert_allclose(track[3, 1:3], [90.0 - radius, 20.0], atol=1e-9)


def test_custom_rates_and_diagonal_leg() -> None:
    model = FlightModel(speed_m_s=2.0, acceptance_m=0.0, climb_rate_m_s=4.0, land_rate_m_s=2.0)
    track = planned_track(np.array([0.0, 0.0]), np.array([[30.0, 40.0]]), 8.0, "rtl", model)
    np.testing.assert_allclose(track[:, 0], [0.0, 2.0, 27.0, 52.0, 56.0], atol=1e-9)
    np.testing.assert_allclose(track[2, 1:], [30.0, 40.0, 8.0], atol=1e-9)


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


def test_planned_tracks_of_two_drones_on_one_time_base() -> None:
    # Two parallel survey lines 6 m apart, flown at the same time: never closer than 6 m.
    a = planned_track(np.array([0.0, 0.0]), np.array([[50.0, 0.0]]), 10.0, "rtl", MODEL)
    b = planned_track(np.array([0.0, 6.0]), np.array([[50.0, 6.0]]), 10.0, "rtl", MODEL)
    got = closest_approach({1: a, 2: b})
    assert got["horizontal"] == pytest.approx(6.0, abs=1e-6) and got["3d"] == pytest.approx(6.0, abs=1e-6)
    assert got["at_s"] == pytest.approx(0.0, abs=1e-9)  # side by side from the start
