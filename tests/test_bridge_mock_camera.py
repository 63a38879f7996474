"""The mock autopilot's camera and telemetry additions: photos placed where their trigger distance was
reached within a long step, one CAMERA_FEEDBACK per photo with consecutive img_idx, the position
stream's rate set by MAV_CMD_SET_MESSAGE_INTERVAL, and the in-flight reboot fault.

Mocks listen on 127.0.0.1 only; every wait is bounded."""

from __future__ import annotations

import math
import random
import time
from typing import Any

import pytest

from missionplan.bridge.flight_models.copter_model import CopterParams
from missionplan.bridge.flight_models.px4_model import Px4Params
from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, to_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS, FlightSim
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan

HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
FAST = Timeouts(item_timeout=0.2, retries=10)
ALT = 10.0

DEFAULT_HZ = 4.0  # VehicleOptions.telemetry_hz


def _at(north: float, east: float = 0.0) -> tuple[float, float]:
    lat = HOME[0] + north / M_PER_DEG_LAT
    lon = HOME[1] + east / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))
    return lat, lon


def _local(lat: float, lon: float) -> tuple[float, float]:
    """The FlightSim's own flat-earth metres north, east of home."""
    return ((lat - HOME[0]) * M_PER_DEG_LAT, (lon - HOME[1]) * M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))


def _wire_local(sim: FlightSim, seq: int) -> tuple[float, float]:
    """Where wire item seq of the sim's mission points, in the sim's metres north, east of home."""
    item = sim.items[seq]
    return _local(item.x / 1e7, item.y / 1e7)


def _waypoint(north: float, east: float = 0.0, radius: float = 0.0) -> MissionItem:
    lat, lon = _at(north, east)
    return MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=radius, x=lat,
                       y=lon, z=ALT)


# ------------------------------------------------------------------------------------------- FlightSim
def _sim(items: list[MissionItem]) -> FlightSim:
    sim = FlightSim(HOME, cruise_speed=5.0)
    sim.load(to_wire(Mission(items, home=HOME), Flavour.PX4), 0)  # PX4: no home item, seq 0 is the takeoff
    sim.state.armed = True
    sim.start_mission()
    return sim


def test_photos_of_one_long_step_are_placed_at_their_trigger_distances() -> None:
    # Takeoff to 10 m, trigger every 1 m with a photo right away (param3 = 1), a 10.5 m leg north.
    sim = _sim([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
                MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=1.0, param3=1.0),
                _waypoint(10.5)])
    sim.advance(30.0)  # climb (4 s), leg (2.1 s) and the end of the mission in one step
    s = sim.state
    assert s.mission_done
    points = [(*_local(lat, lon), alt) for lat, lon, alt in s.photo_points]
    assert s.photos == len(points) == 11  # the one at the trigger item, then one at 1, 2, ..., 10 m
    for k, (north, east, alt) in enumerate(points):
        assert north == pytest.approx(float(k), abs=1e-6)  # not all at the end of the step (10.5 m)
        assert east == pytest.approx(0.0, abs=1e-6)
        assert alt == pytest.approx(ALT, abs=1e-9)


def test_photos_keep_their_spacing_across_a_corner_within_one_step() -> None:
    # 10.5 m north, then 4 m east: the trigger distance runs on around the corner.
    sim = _sim([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
                MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=1.0),
                _waypoint(10.5),
                _waypoint(10.5, 4.0)])
    sim.advance(4.0)  # the climb alone
    assert sim.state.photos == 0
    sim.advance(60.0)  # both legs in one step
    points = [_local(lat, lon) for lat, lon, _ in sim.state.photo_points]
    # The waypoints as the wire carries them (1e-7 degree): the corner is about 10.497 m north.
    (corner_n, corner_e), (end_n, end_e) = _wire_local(sim, 2), _wire_local(sim, 3)
    assert corner_e == 0.0 and end_n == corner_n and end_e == pytest.approx(4.0, abs=0.01)
    left = corner_n - 10.0  # flown past the last photo of the first leg when the corner comes
    expected = [(float(k), 0.0) for k in range(1, 11)] + [(corner_n, k - left) for k in (1, 2, 3, 4)]
    assert expected[-1][1] < end_e
    assert len(points) == len(expected) == sim.state.photos
    for (north, east), (n, e) in zip(points, expected):
        assert north == pytest.approx(n, abs=1e-6) and east == pytest.approx(e, abs=1e-6)


def test_photos_of_many_small_steps_match_one_long_step() -> None:
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=1.5),
             _waypoint(11.0, radius=0.01)]
    long_step, small_steps = _sim(items), _sim(items)
    long_step.advance(30.0)
    for _ in range(3000):
        small_steps.advance(0.01)
    a = [_local(lat, lon) for lat, lon, _ in long_step.state.photo_points]
    b = [_local(lat, lon) for lat, lon, _ in small_steps.state.photo_points]
    assert len(a) == len(b) == 7  # 1.5, 3.0, ..., 10.5 m
    for (n1, e1), (n2, e2) in zip(a, b):
        assert n1 == pytest.approx(n2, abs=1e-6) and e1 == pytest.approx(e2, abs=1e-6)


@pytest.mark.parametrize("model", ["straight", "arducopter", "px4"])
def test_photos_do_not_depend_on_the_ticks(model: str) -> None:
    """A street survey as the planner writes it: corners, an acceptance radius, legs that are whole
    multiples of the trigger distance (a photo due exactly at every corner). Flown in even ticks and in
    irregular ones (a loaded machine), every photo is the same: `fly` against a mock measures the plan,
    not the scheduler."""
    corners = [(0.0, 0.0), (12.0, 0.0), (12.0, 6.0), (3.0, 6.0), (3.0, 10.5), (13.5, 10.5)]
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=1.5, param3=1.0),
             *[_waypoint(north, east, radius=0.4) for north, east in corners],
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0),
             MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)]
    rng = random.Random(7)
    photos = []
    for ticks in (lambda: 0.01, lambda: rng.uniform(0.005, 0.7)):
        sim = FlightSim(HOME, cruise_speed=5.0, copter=CopterParams() if model != "straight" else None,
                        px4=Px4Params() if model == "px4" else None)
        sim.load(to_wire(Mission(items, home=HOME), Flavour.PX4), 0)  # no home item: seq 0 is the takeoff
        sim.state.armed = True
        sim.start_mission()
        while sim.state.armed and sim.state.sim_time < 300.0:
            sim.advance(ticks())
        assert sim.state.mission_done and not sim.state.armed, model
        photos.append([(*_local(lat, lon), alt) for lat, lon, alt in sim.state.photo_points])
    even, irregular = photos
    assert len(even) == len(irregular) == 1 + 42 / 1.5  # at the trigger item, then every 1.5 m of the 42 m
    for a, b in zip(even, irregular):
        assert a == pytest.approx(b, abs=1e-6)


def test_nav_land_touches_down_and_disarms() -> None:
    sim = _sim([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
                MissionItem(mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT)])
    sim.advance(ALT / 2.5)  # the climb: takeoff reached, LAND is current
    assert sim.state.current == 1 and sim.state.alt == pytest.approx(ALT)
    events = sim.advance((ALT - 0.005) / 1.5)  # a descent that stops 5 mm above the ground
    for _ in range(5):
        events += sim.advance(1.0)
    assert [e.kind for e in events].count("reached") == 1 and sim.state.mission_done
    assert any(e.kind == "landed" for e in events)
    assert not sim.state.armed


# ------------------------------------------------------------------------------------------- MockAutopilot
def _command(link: Link, command: int, *params: float, sysid: int = 1, timeout: float = 3.0) -> int:
    p = (list(params) + [0.0] * 7)[:7]
    link.mav.command_long_send(sysid, 1, command, 0, *p)
    deadline = time.monotonic() + timeout
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == sysid and msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
            return int(msg.result)
    raise AssertionError(f"no COMMAND_ACK for command {command} within {timeout} s")


def _count(link: Link, kind: str, seconds: float, sysid: int = 1) -> int:
    deadline = time.monotonic() + seconds
    n = 0
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == sysid and msg.get_type() == kind:
            n += 1
    return n


def _mock(**kw: Any) -> MockAutopilot:
    kw.setdefault("homes", {1: HOME})
    kw.setdefault("request_interval", 0.02)
    kw.setdefault("upload_timeout", 2.0)
    return MockAutopilot("udpin:127.0.0.1:0", **kw)


def test_set_message_interval_speeds_up_the_position_stream() -> None:
    with _mock() as mock:
        assert mock.address[0] == "127.0.0.1"
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            link = backend.link
            assert _command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 20_000.0) == mavlink.MAV_RESULT_ACCEPTED
            window = 1.0
            fast = _count(link, "GLOBAL_POSITION_INT", window)
            assert fast > 2 * DEFAULT_HZ * window  # 50 Hz asked for; the default is 4 Hz
            # Only the position stream can be changed.
            assert _command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE, 20_000.0) == mavlink.MAV_RESULT_UNSUPPORTED
            assert mock.vehicle(1).position_interval == pytest.approx(0.02)
            # Interval 0 puts the default back.
            assert _command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 0.0) == mavlink.MAV_RESULT_ACCEPTED
            assert mock.vehicle(1).position_interval == pytest.approx(1.0 / DEFAULT_HZ)
        finally:
            backend.close()


def _survey(trigger_m: float, legs_north: list[float]) -> Mission:
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=ALT),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=trigger_m)]
    items += [_waypoint(north, radius=0.5) for north in legs_north]
    # Trigger off, return to launch. (Not NAV_LAND: see test_nav_land_touches_down_and_disarms below.)
    items += [MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0),
              MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)]
    return Mission(items, home=HOME)


def _fly(link: Link, until: Any, timeout: float) -> list[Any]:
    """Arm, MISSION_START, and collect every message of system 1 until until(msgs) or the time-out."""
    assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0) == mavlink.MAV_RESULT_ACCEPTED
    assert _command(link, mavlink.MAV_CMD_MISSION_START, 0.0, 0.0) == mavlink.MAV_RESULT_ACCEPTED
    msgs: list[Any] = []
    deadline = time.monotonic() + timeout
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == 1:
            msgs.append(msg)
            if until(msgs):
                break
    return msgs


def _drain(link: Link, msgs: list[Any], seconds: float) -> None:
    """Append what system 1 sends in the next `seconds` (bounded)."""
    until = time.monotonic() + seconds
    while (msg := link.recv(until)) is not None:
        if msg.get_srcSystem() == 1:
            msgs.append(msg)


def _story(msgs: list[Any]) -> str:
    """What the vehicle said about its progress, for failure messages."""
    words = []
    for m in msgs:
        kind = m.get_type()
        if kind == "MISSION_ITEM_REACHED":
            words.append(f"reached {m.seq}")
        elif kind == "HEARTBEAT":
            words.append(f"hb armed={bool(m.base_mode & 128)} status={m.system_status}")
    return ", ".join(words)


def _landed(msgs: list[Any]) -> bool:
    """The last item (RTL, seq 5 of _survey with one leg) reached and a disarmed HEARTBEAT after it."""
    reached = [i for i, m in enumerate(msgs) if m.get_type() == "MISSION_ITEM_REACHED" and m.seq == 5]
    return bool(reached) and any(m.get_type() == "HEARTBEAT" and not m.base_mode & 128 for m in msgs[reached[0]:])


@pytest.mark.flight
def test_one_camera_feedback_per_photo_with_consecutive_img_idx() -> None:
    with _mock(speedup=20.0) as mock:
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            report = upload_plan(backend, [_survey(2.0, [21.0])], verify=True)
            assert report.verified
            msgs = _fly(backend.link, _landed, timeout=8.0)
            _drain(backend.link, msgs, 0.3)  # whatever was sent with the landing
        finally:
            backend.close()
        assert _landed(msgs), f"the vehicle did not land and disarm in time: {_story(msgs)}"
    truth = list(mock.vehicle(1).flight.state.photo_points)  # read after the mock's thread stopped
    feedback = [m for m in msgs if m.get_type() == "CAMERA_FEEDBACK"]
    assert len(truth) >= 9  # about 21 m / 2 m of leg with the trigger on
    assert len(feedback) == len(truth) == mock.vehicle(1).flight.state.photos
    assert [int(m.img_idx) for m in feedback] == list(range(len(truth)))
    assert [int(m.completed_captures) for m in feedback] == list(range(1, len(truth) + 1))
    for m, (lat, lon, alt) in zip(feedback, truth):
        assert (int(m.lat), int(m.lng)) == (int(round(lat * 1e7)), int(round(lon * 1e7)))
        assert m.alt_rel == pytest.approx(alt, abs=1e-3)
        assert m.alt_msl == pytest.approx(HOME[2] + alt, abs=1e-3)
    # Where they were taken: 2 m apart along the leg north.
    north = [_local(lat, lon)[0] for lat, lon, _ in truth]
    gaps = [b - a for a, b in zip(north, north[1:])]
    assert all(g == pytest.approx(2.0, abs=1e-3) for g in gaps)


@pytest.mark.flight
def test_reboot_in_flight_after_an_item() -> None:
    # Wire (ArduPilot): 0 home, 1 takeoff, 2 trigger, 3 WP 10 m, 4 WP 60 m, 5 trigger off, 6 RTL.
    # Item 4 is 50 m (2.5 wall seconds at 20x) past item 3: no loop stall reaches both in one tick.
    with _mock(speedup=20.0) as mock:
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            upload_plan(backend, [_survey(2.0, [10.0, 60.0])], verify=True)
            assert len(mock.mission(1)) == 7
            mock.reboot_in_flight(1, 3)

            def rebooted(msgs: list[Any]) -> bool:
                return any(m.get_type() == "HEARTBEAT" and m.system_status == 1 for m in msgs)  # MAV_STATE_BOOT

            msgs = _fly(backend.link, rebooted, timeout=8.0)
            _drain(backend.link, msgs, 0.8)  # a little of what it says after the boot (positions at 4 Hz)
        finally:
            backend.close()
        assert rebooted(msgs), "no boot heartbeat after the reboot"
        assert mock.wait_until(lambda m: m.vehicle(1).reboots == 1, timeout=2.0)
        held = mock.mission(1)
    # The mission is forgotten: only ArduPilot's own home item is left.
    assert len(held) == 1 and held[0].seq == 0 and held[0].command == mavlink.MAV_CMD_NAV_WAYPOINT
    vehicle = mock.vehicle(1)
    assert vehicle.reboots == 1 and vehicle.reboot_at_item is None
    state = vehicle.flight.state
    assert not state.armed and state.on_ground and state.photos == 0  # the flight is forgotten too
    reached = [int(m.seq) for m in msgs if m.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [1, 3]  # rebooted once item 3 was reached, before item 4
    # Its clock restarted: positions after the boot heartbeat count time_boot_ms from a new, later boot.
    boot = next(i for i, m in enumerate(msgs) if m.get_type() == "HEARTBEAT" and m.system_status == 1)
    before = [m.time_boot_ms for m in msgs[:boot] if m.get_type() == "GLOBAL_POSITION_INT"]
    after = [m.time_boot_ms for m in msgs[boot:] if m.get_type() == "GLOBAL_POSITION_INT"]
    assert before and after and after[0] < before[-1]


@pytest.mark.flight
def test_a_repeated_mission_start_does_not_restart_a_running_mission() -> None:
    # A ground station repeats MISSION_START when its acknowledgement is lost; ArduCopter then keeps flying.
    with _mock(speedup=5.0) as mock:
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            upload_plan(backend, [_survey(2.0, [10.0, 60.0])], verify=True)
            link = backend.link

            def past_first_waypoint(m: MockAutopilot) -> bool:
                return 3 in m.vehicle(1).reached

            _fly(link, lambda msgs: any(x.get_type() == "MISSION_ITEM_REACHED" and x.seq == 3 for x in msgs), 8.0)
            assert mock.wait_until(past_first_waypoint, 2.0)
            assert _command(link, mavlink.MAV_CMD_MISSION_START, 0.0, 0.0) == mavlink.MAV_RESULT_ACCEPTED
            current = mock.vehicle(1).flight.state.current
        finally:
            backend.close()
    assert current >= 4  # still heading for the second waypoint, not back to the take-off
