"""missionplan.flight.flight_report: coverage rule, photo positions from CAMERA_FEEDBACK (and without it),
the vehicle clock and the time-scale estimate, on synthetic recordings in a small GridFrame."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    MissionType,
    WireItem,
)
from missionplan.geo.frame import GridFrame
from missionplan.flight import flight_report as fr
from missionplan.flight.record import DroneRecord

CELL = 4.0
EARTH = 6_378_137.0


@pytest.fixture(scope="module", params=[0.0, 30.0], ids=["north-up", "rotated"])
def frame(request: pytest.FixtureRequest) -> GridFrame:
    built = GridFrame.at(45.0703, 7.6869, cell_m=CELL, rows=20, cols=20, rotation_deg=request.param)
    assert GridFrame.from_meta(built.to_meta()) == built  # the way report.json carries it
    return built


def _latlon(frame: GridFrame, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid metres (row axis, column axis; cell centres at integers * cell_m) -> lat, lon."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 2)
    return frame.grid_to_latlon(points_m[:, 0] / frame.cell_m, points_m[:, 1] / frame.cell_m)


# ------------------------------------------------------------------------------------------- coverage
TARGETS = np.array([(r, c) for r in range(3, 8) for c in range(3, 8)], dtype=np.int64)


def _covered(frame: GridFrame, photo_cells: list[tuple[float, float]], footprint_cells: float,
             slack_cells: float) -> set[tuple[int, int]]:
    # Through lat/lon and back, as reported positions are.
    lat, lon = _latlon(frame, np.array(photo_cells) * frame.cell_m)
    photos = fr.to_grid_m(frame, lat, lon)
    mask = fr.coverage(frame, TARGETS, photos, footprint_cells * frame.cell_m, slack_cells * frame.cell_m)
    return {tuple(int(v) for v in cell) for cell in TARGETS[mask]}


def test_photo_at_a_cell_centre_covers_that_cell_with_no_slack(frame: GridFrame) -> None:
    # A one-cell footprint exactly on cell (5, 5): the whole square is in it (the micrometre absorbs the round trip).
    for slack in (0.0, 0.25, 0.5):
        assert _covered(frame, [(5.0, 5.0)], 1.0, slack) == {(5, 5)}
    # A three-cell footprint holds the 3 x 3 block around it, whatever the slack up to half a cell.
    block = {(r, c) for r in (4, 5, 6) for c in (4, 5, 6)}
    for slack in (0.0, 0.25, 0.5):
        assert _covered(frame, [(5.0, 5.0)], 3.0, slack) == block


def test_photo_offset_by_a_fifth_of_a_cell(frame: GridFrame) -> None:
    photo = [(5.0, 5.2)]
    # One-cell footprint: 0.2 cell of the square sticks out. Not whole; inside a quarter-cell slack.
    assert _covered(frame, photo, 1.0, 0.0) == set()
    assert _covered(frame, photo, 1.0, fr.SLACK_CELLS) == {(5, 5)}
    assert _covered(frame, photo, 1.0, 0.5) == {(5, 5)}
    # Three-cell footprint: reaches cols 5.2 +- 1.5 = 3.7 .. 6.7, so column 4's square (3.5 .. 4.5) is 0.2 short.
    rows = (4, 5, 6)
    assert _covered(frame, photo, 3.0, 0.0) == {(r, c) for r in rows for c in (5, 6)}
    assert _covered(frame, photo, 3.0, 0.25) == {(r, c) for r in rows for c in (4, 5, 6)}
    assert _covered(frame, photo, 3.0, 0.5) == {(r, c) for r in rows for c in (4, 5, 6)}


def test_quarter_and_half_cell_slack_differ_past_a_quarter(frame: GridFrame) -> None:
    # 0.3 cell off: too far for the quarter-cell rule, enough for the cell-centre rule.
    assert _covered(frame, [(5.3, 5.0)], 1.0, 0.25) == set()
    assert _covered(frame, [(5.3, 5.0)], 1.0, 0.5) == {(5, 5)}
    # Exactly a quarter off (diagonally) still counts under the quarter-cell rule.
    assert _covered(frame, [(5.25, 4.75)], 1.0, 0.25) == {(5, 5)}
    # Past half a cell the photo's centre lies in the neighbour, which is the one the centre rule counts.
    assert _covered(frame, [(5.0, 5.6)], 1.0, 0.5) == {(5, 6)}


def test_coverage_of_nothing() -> None:
    frame = GridFrame.at(45.0703, 7.6869, cell_m=CELL, rows=20, cols=20)
    assert fr.coverage(frame, TARGETS, np.zeros((0, 2)), 8.0, 1.0).tolist() == [False] * len(TARGETS)
    assert len(fr.coverage(frame, np.zeros((0, 2), dtype=np.int64), np.zeros((1, 2)), 8.0, 1.0)) == 0


# ------------------------------------------------------------------------------------------- photo positions
# A straight survey line along the column axis at row 8 m, flown at 4 m/s from column 0 m, one sample a second.
ROW_M, SPEED, TRIGGER, FIRST_S = 8.0, 4.0, 3.0, 1.5


def _straight_record(frame: GridFrame, seconds: int = 10) -> DroneRecord:
    rec = DroneRecord(id=1)
    t = np.arange(seconds, dtype=float)
    lat, lon = _latlon(frame, np.column_stack([np.full_like(t, ROW_M), SPEED * t]))
    rec.samples = [(1000.0 + ti, la, lo, 20.0, SPEED, ti) for ti, la, lo in zip(t, lat, lon)]
    return rec


def _photo_s(k: np.ndarray | int) -> np.ndarray:
    """Arc length of photo k along the line: one every TRIGGER metres from FIRST_S."""
    return FIRST_S + TRIGGER * np.asarray(k, dtype=float)


def _report(frame: GridFrame, rec: DroneRecord, k: int, delay_s: float = 0.0) -> None:
    s = float(_photo_s(k))
    lat, lon = _latlon(frame, [[ROW_M, s]])
    rec.camera[k] = (1000.0 + s / SPEED + delay_s, float(lat[0]), float(lon[0]), 20.0)


def test_lost_camera_reports_are_placed_on_the_track(frame: GridFrame) -> None:
    rec = _straight_record(frame)
    total = 12  # photos 0..11 along 1.5 .. 34.5 m of the 36 m line
    known = [0, 1, 2, 3, 6, 7, 8, 9]  # 4 and 5 lost in the middle, 10 and 11 lost at the end
    for k in known:
        _report(frame, rec, k)
    rec.captures = total  # completed_captures says 12 photos: more than the highest idx + 1
    positions, placed, source = fr.photo_positions(frame, rec, TRIGGER)
    assert source == "camera"
    assert positions.shape == (len(known), 2)  # confirmed: the reported ones
    assert len(placed) == total - len(known) == 4  # not confirmed, counted apart
    truth = np.column_stack([np.full(total, ROW_M), _photo_s(np.arange(total))])
    np.testing.assert_allclose(positions, truth[known], atol=0.005)
    np.testing.assert_allclose(placed, truth[[4, 5, 10, 11]], atol=0.005)  # placed within 5 mm of the truth


def test_photos_are_counted_from_the_first_index_this_flight_reported(frame: GridFrame) -> None:
    # ArduPilot's img_idx starts at 1 and keeps counting across flights until a reboot: this flight's
    # first photo is index 584. Indices 0..583 are earlier flights' photos, not lost reports.
    rec = _straight_record(frame)
    base = 584
    for k in (0, 1, 3, 4):  # photo 2 (index 586) lost on the link
        s = float(_photo_s(k))
        lat, lon = _latlon(frame, [[ROW_M, s]])
        rec.camera[base + k] = (1000.0 + s / SPEED, float(lat[0]), float(lon[0]), 20.0)
    rec.captures = base + 5  # completed_captures counts from the boot too
    positions, placed, source = fr.photo_positions(frame, rec, TRIGGER)
    assert (source, len(placed), len(positions)) == ("camera", 1, 4)  # was 589 photos, 585 of them invented
    truth = np.column_stack([np.full(5, ROW_M), _photo_s(np.arange(5))])
    np.testing.assert_allclose(positions, truth[[0, 1, 3, 4]], atol=0.005)
    np.testing.assert_allclose(placed, truth[[2]], atol=0.005)


def test_a_lost_first_report_is_not_invented(frame: GridFrame) -> None:
    # Indistinguishable from a counter carried over from an earlier flight: only what was reported counts.
    rec = _straight_record(frame)
    for k in (2, 3, 4):
        _report(frame, rec, k)
    positions, placed, source = fr.photo_positions(frame, rec, TRIGGER)
    assert (source, len(placed), len(positions)) == ("camera", 0, 3)
    np.testing.assert_allclose(positions, np.column_stack([np.full(3, ROW_M), _photo_s(np.arange(2, 5))]), atol=0.005)


def test_lost_camera_reports_are_placed_in_proportion_when_reports_arrive_late(frame: GridFrame) -> None:
    rec = _straight_record(frame, seconds=10)
    # Samples every second (4 m); photo k at 1.5 + 3k m. Each report arrives just after the first
    # sample taken at or past 0.3 m beyond the photo: the sample is 0.3 m or more ahead of it.
    known = [0, 1, 2, 3, 6, 7, 8, 9]
    sample_s = SPEED * np.arange(10, dtype=float)
    for k in known:
        s = float(_photo_s(k))
        after = float(sample_s[np.argmax(sample_s >= s + 0.3)])
        lat, lon = _latlon(frame, [[ROW_M, s]])
        rec.camera[k] = (1000.0 + after / SPEED + 0.01, float(lat[0]), float(lon[0]), 20.0)
    rec.captures = 10
    _, placed, _ = fr.photo_positions(frame, rec, TRIGGER)
    assert len(placed) == 2
    truth = np.column_stack([np.full(10, ROW_M), _photo_s(np.arange(10))])
    np.testing.assert_allclose(placed, truth[[4, 5]], atol=0.005)


def _wire(seq: int, command: int, param1: float = 0.0) -> WireItem:
    return WireItem(seq=seq, frame=FRAME_GLOBAL_RELATIVE_ALT, command=command, current=0, autocontinue=1,
                    param1=param1, param2=0.0, param3=0.0, param4=0.0, x=0, y=0, z=0.0,
                    mission_type=MissionType.MISSION)


def test_without_camera_reports_photos_only_when_asked_every_trigger_distance_along_the_survey(frame: GridFrame) -> None:
    # Mission: home, takeoff, trigger on, WP 3 (survey start), WP 4, WP 5 (survey end), trigger off, RTL.
    rec = DroneRecord(id=2)
    rec.wire = [_wire(0, CMD_NAV_WAYPOINT), _wire(1, CMD_NAV_TAKEOFF), _wire(2, CMD_DO_SET_CAM_TRIGG_DIST, TRIGGER),
                _wire(3, CMD_NAV_WAYPOINT), _wire(4, CMD_NAV_WAYPOINT), _wire(5, CMD_NAV_WAYPOINT),
                _wire(6, CMD_DO_SET_CAM_TRIGG_DIST, 0.0), _wire(7, CMD_NAV_RETURN_TO_LAUNCH)]
    # An L-shaped track at 2 m/s, one sample a second: along the columns to (8, 20), then down the rows.
    # The survey runs from t = 5 s (reached WP 3 at (8, 10)) to t = 15 s (reached WP 5 at (18, 20)).
    t = np.arange(21, dtype=float)
    path = np.array([(ROW_M, 2.0 * ti) if ti <= 10 else (ROW_M + 2.0 * (ti - 10), 20.0) for ti in t])
    lat, lon = _latlon(frame, path)
    rec.samples = [(50.0 + ti, la, lo, 20.0, 2.0, ti) for ti, la, lo in zip(t, lat, lon)]
    rec.reached = [(52.0, 1), (55.0, 3), (59.0, 4), (65.0, 5), (65.01, 5), (70.0, 7)]  # 5 duplicated on the link
    # Photos the vehicle never reported are no evidence: none, unless the user asks for them explicitly.
    positions, placed, source = fr.photo_positions(frame, rec, TRIGGER)
    assert (len(positions), len(placed), source) == (0, 0, "none")
    positions, placed, source = fr.photo_positions(frame, rec, TRIGGER, from_track=True)
    assert source == "track"
    # The survey is 20 m long (10 m along the columns, 10 m down the rows): photos at 0, 3, ..., 18 m,
    # counted as the user asked (none of them reported).
    s = np.arange(0.0, 20.0 + 1e-9, TRIGGER)
    assert len(positions) == len(s) == 7 and len(placed) == 0
    truth = np.array([(ROW_M, 10.0 + si) if si <= 10 else (ROW_M + si - 10.0, 20.0) for si in s])
    np.testing.assert_allclose(positions, truth, atol=0.005)


def test_no_samples_no_photos(frame: GridFrame) -> None:
    positions, placed, source = fr.photo_positions(frame, DroneRecord(id=3), TRIGGER)
    assert (positions.shape, placed.shape, source) == ((0, 2), (0, 2), "none")


# ------------------------------------------------------------------------------------------- clocks
def test_vehicle_clock_shifts_by_the_smallest_arrival_delay() -> None:
    boot = np.array([10.0, 10.1, 10.2, 10.3, 10.4])
    delays = np.array([0.05, 0.02, 0.08, 0.03, 0.20])  # our threads' jitter on top of the one-way delay
    samples = np.zeros((5, 6))
    samples[:, 0] = 500.0 + boot + delays
    samples[:, 5] = boot
    np.testing.assert_allclose(fr.vehicle_clock(samples), boot + 500.02, atol=1e-9)


def test_a_record_too_short_to_fit_the_rate_runs_at_the_fleets_time_scale() -> None:
    # 1.6 s of our time at 50x (a short flight): too short to fit the clock's rate. Taken as real time,
    # its take-off landed 80 s of our time early and the fleet's start spread read 3872 s.
    boot = np.arange(0.0, 80.0, 1.0)
    samples = np.zeros((len(boot), 6))
    samples[:, 0] = 700.0 + boot / 50.0 + 0.01
    samples[:, 5] = boot
    assert fr.vehicle_rate(samples) is None
    np.testing.assert_allclose(fr.vehicle_clock(samples, 50.0), 700.0 + boot / 50.0 + 0.01, atol=1e-9)


def test_flown_seconds_are_the_vehicles_own_from_start_to_end() -> None:
    # A loaded machine: SITL asked for 10x ran at about 6x; the vehicle's clock says 120 s were flown.
    rec = DroneRecord(id=1, t_start=100.0, t_end=120.0)
    rec.samples = [(100.0 + k * 0.5, 45.0, 7.0, 10.0, 5.0, 30.0 + k * 3.0, 0.0) for k in range(-2, 43)]
    assert fr.flown_seconds(rec, 10.0) == pytest.approx(120.0)  # not 20 s wall x 10
    # Too few samples: our clock times the scale.
    assert fr.flown_seconds(DroneRecord(id=2, t_start=0.0, t_end=20.0), 10.0) == pytest.approx(200.0)


def _flown_at(scale: float, start_lat: float = 45.07, n: int = 12, speed: float = 5.0,
              wall_dt: float = 0.5) -> list[tuple[float, float, float, float, float, float]]:
    """Samples of a straight diagonal flight at `speed` simulated m/s, sped up `scale` times."""
    out = []
    lat, lon, t = start_lat, 7.68, 100.0
    step = speed * scale * wall_dt  # metres flown per sample
    north, east = 0.6 * step, 0.8 * step
    for i in range(n):
        out.append((t, lat, lon, 20.0, speed, i * wall_dt * scale))
        t += wall_dt * (1.0 + 0.02 * ((-1) ** i))  # some scheduling jitter
        lat += math.degrees(north / EARTH)
        lon += math.degrees(east / (EARTH * math.cos(math.radians(lat))))
    return out


def test_estimate_time_scale_recovers_the_speedup() -> None:
    rec = DroneRecord(id=1, samples=_flown_at(2.0))
    assert fr.estimate_time_scale([rec]) == pytest.approx(2.0, rel=0.03)
    # Hovering samples (no speed) and a vehicle with a single sample do not disturb it.
    hover = DroneRecord(id=2, samples=[(200.0 + i, 45.0, 7.0, 20.0, 0.0, i) for i in range(5)])
    lone = DroneRecord(id=3, samples=[(300.0, 45.0, 7.0, 20.0, 5.0, 0.0)])
    other = DroneRecord(id=4, samples=_flown_at(2.0, start_lat=45.2, speed=3.0))
    assert fr.estimate_time_scale([rec, hover, lone, other]) == pytest.approx(2.0, rel=0.03)
    assert fr.estimate_time_scale([DroneRecord(id=5, samples=_flown_at(1.0))]) == pytest.approx(1.0, rel=0.03)


def test_estimate_time_scale_defaults_to_real_time_without_enough_motion() -> None:
    assert fr.estimate_time_scale([]) == 1.0
    assert fr.estimate_time_scale([DroneRecord(id=1, samples=_flown_at(2.0, n=3))]) == 1.0  # only 2 intervals


def test_lift_off_is_not_taken_from_an_estimate_wandering_on_the_ground() -> None:
    # PX4 SIH on the ground: relative altitude up to 0.8 m and climb rate up to 0.9 m/s, then at t = 10 s
    # it climbs at 1.5 m/s to its 20 m take-off altitude.
    rec = DroneRecord(id=1, wire=[WireItem(seq=0, frame=FRAME_GLOBAL_RELATIVE_ALT, command=CMD_NAV_TAKEOFF, current=0,
                                           autocontinue=1, param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=0,
                                           y=0, z=20.0, mission_type=MissionType.MISSION)])
    t = np.arange(0.0, 20.0, 0.1)
    up = np.where(t < 10.0, 0.8 * np.abs(np.sin(t)), 1.5 * (t - 10.0))
    climb = np.where(t < 10.0, 0.9 * np.cos(t), 1.5)
    samples = np.column_stack([t, np.full_like(t, 45.0), np.full_like(t, 7.0), up, np.zeros_like(t), t, climb])
    assert fr.liftoff_height([rec]) == fr.LIFTOFF_M
    assert fr.lifted_off_at(samples, t, 1.0, fr.liftoff_height([rec])) == pytest.approx(10.0, abs=0.05)
    # A fleet with a low flight (the demo's 1.2 m layer): every drone counts from half that altitude.
    low = DroneRecord(id=2, wire=[WireItem(seq=0, frame=FRAME_GLOBAL_RELATIVE_ALT, command=CMD_NAV_TAKEOFF, current=0,
                                           autocontinue=1, param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=0,
                                           y=0, z=1.2, mission_type=MissionType.MISSION)])
    flat = np.column_stack([t, np.full_like(t, 45.0), np.full_like(t, 7.0), np.clip(1.5 * (t - 10.0), 0, 1.2),
                            np.zeros_like(t), t, np.where((t > 10.0) & (t < 10.8), 1.5, 0.0)])
    assert fr.liftoff_height([rec, low]) == pytest.approx(0.6)
    assert fr.lifted_off_at(flat, t, 1.0, fr.liftoff_height([rec, low])) == pytest.approx(10.0, abs=0.1)
