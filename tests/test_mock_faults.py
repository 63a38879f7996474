"""The mock autopilot's faults that real autopilots have, seen at the MAVLink level (what a ground station
gets): a vehicle killed in flight (silent for good; the transport closed when it was the last one),
ArduCopter's battery failsafe (SIM_BATT_VOLTAGE below BATT_LOW_VOLT for BATT_LOW_TIMER: its STATUSTEXT,
RTL, landing, disarm), and another ground station's upload (MAV_MISSION_DENIED, as ArduPilot's
MissionItemProtocol answers). Every wait is bounded on a message or on the mock's state."""

from __future__ import annotations

import math
import socket
import time
from typing import Any

import pytest

from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, to_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import MissionClient, MissionTransferError, Timeouts

HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = 111_319.49
MISSION_TYPE = mavlink.MAV_MISSION_TYPE_MISSION


def _survey(legs: int = 4, side_m: float = 100.0) -> Mission:
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=20.0)]
    for k in range(legs):
        north, east = (side_m if k % 2 else 0.0), 20.0 * k
        lat = HOME[0] + north / M_PER_DEG_LAT
        lon = HOME[1] + east / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))
        items.append(MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon,
                                 z=20.0))
    items.append(MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION))
    return Mission(items, home=HOME)


def _command(link: Link, sysid: int, command: int, *params: float) -> int | None:
    p = [float(x) for x in params] + [0.0] * (7 - len(params))
    return link.command_long(sysid, command, p, time.monotonic() + 3.0)


def _start(link: Link, sysid: int, mission: Mission) -> None:
    """Upload, arm, AUTO, MISSION_START (ArduCopter's way)."""
    vehicle = wait_vehicle(link, sysid, timeout=3)
    MissionClient(link, vehicle, Timeouts(item_timeout=0.3)).upload(MISSION_TYPE, to_wire(mission, Flavour.ARDUPILOT))
    assert _command(link, sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
    assert _command(link, sysid, mavlink.MAV_CMD_DO_SET_MODE, 1, 3) == mavlink.MAV_RESULT_ACCEPTED
    assert _command(link, sysid, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED


def _until(link: Link, seconds: float, stop: Any) -> list[Any]:
    """Every message heard until stop(msg, heard) is true or `seconds` pass (bounded)."""
    heard: list[Any] = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        msg = link.recv(deadline)
        if msg is None:
            break
        heard.append(msg)
        if stop(msg, heard):
            break
    return heard


def _heartbeats(heard: list[Any], sysid: int) -> int:
    return sum(1 for m in heard if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == sysid)


# ------------------------------------------------------------------------------ a vehicle killed in flight
@pytest.mark.flight
def test_a_killed_vehicle_goes_silent_for_good_and_the_others_fly_on() -> None:
    with MockAutopilot(sysids=(1, 2), homes={1: HOME, 2: (HOME[0] + 0.001, HOME[1], HOME[2])}, speedup=20.0,
                       request_interval=0.05) as mock, Link(mock.client_url) as link:
        mission = _survey()
        _start(link, 2, mission)
        assert mock.wait_until(lambda m: m.vehicle(2).flight.state.current >= 3, 10.0)
        mock.kill(2)
        killed_at = mock.vehicle(2).flight.state
        assert killed_at.armed and killed_at.alt > 1.0 and mock.killed(2)
        # A marker: what was sent before the kill (still on its way) comes before this command's answer.
        assert _command(link, 1, mavlink.MAV_CMD_REQUEST_MESSAGE,
                        mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == mavlink.MAV_RESULT_ACCEPTED
        # Four heartbeats of the living vehicle (about 4 s): not one message of the killed one.
        heard = _until(link, 8.0, lambda msg, heard: _heartbeats(heard, 1) >= 4)
        assert _heartbeats(heard, 1) >= 4
        assert [m.get_type() for m in heard if m.get_srcSystem() == 2] == []
        # It hears nothing either: an RTL command gets no answer and changes nothing.
        assert _command(link, 2, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH) is None
        assert mock.vehicle(2).flight.state.mode == "AUTO"


@pytest.mark.flight
def test_a_vehicle_killed_at_a_mission_item_stops_there() -> None:
    with MockAutopilot(homes={1: HOME}, speedup=20.0, request_interval=0.05) as mock, Link(mock.client_url) as link:
        mock.kill(1, at_item=3)
        _start(link, 1, _survey())
        assert mock.wait_until(lambda m: m.killed(1), 20.0), "never killed"
        state = mock.vehicle(1).flight.state
        reached = list(mock.vehicle(1).reached)
        assert state.armed and state.alt > 1.0 and max(reached) == 3
        while link.recv(time.monotonic()) is not None:  # what it sent before (on its way already)
            pass
        link.mav.command_long_send(1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                   0, 0, 0, 0, 0, 0)
        heard = _until(link, 3.0, lambda msg, heard: False)  # the wait runs out: nothing more heard
        assert [m for m in heard if m.get_srcSystem() == 1] == []
        assert mock.vehicle(1).reached == reached  # frozen where it was killed


def test_killing_the_last_vehicle_closes_the_transport() -> None:
    """A TCP ground station of a one-vehicle mock sees its connection closed, as when SITL is killed."""
    with MockAutopilot("tcpin:127.0.0.1:0", homes={1: HOME}) as mock:
        with socket.create_connection(("127.0.0.1", mock.port), timeout=5.0) as client:
            client.settimeout(5.0)
            assert client.recv(4096)  # the greeting heartbeat
            mock.kill(1)
            deadline = time.monotonic() + 5.0
            data = b"x"
            while data and time.monotonic() < deadline:
                try:
                    data = client.recv(4096)
                except ConnectionResetError:
                    data = b""
            assert data == b"", "the connection stayed open"
        assert mock.transport_closed  # its listener too (a connect may still find the port reused)


# ------------------------------------------------------------------------------ ArduCopter's battery failsafe
def _param_set(link: Link, sysid: int, name: str, value: float) -> float:
    link.mav.param_set_send(sysid, 1, name.encode(), value, 9)
    heard = _until(link, 3.0, lambda msg, heard: msg.get_type() == "PARAM_VALUE" and msg.param_id == name)
    assert heard and heard[-1].get_type() == "PARAM_VALUE", f"no PARAM_VALUE for {name}"
    return float(heard[-1].param_value)


@pytest.mark.flight
def test_battery_failsafe_as_arducopter_does_it() -> None:
    with MockAutopilot(homes={1: HOME}, speedup=10.0, request_interval=0.05, sitl_like=True) as mock, \
            Link(mock.client_url) as link:
        vehicle = mock.vehicle(1)
        # SITL's defaults: a full 3S pack, BATT_LOW_VOLT 10.5 V for 10 s, no action until one is set.
        for name, default in (("SIM_BATT_VOLTAGE", 12.6), ("BATT_LOW_VOLT", 10.5), ("BATT_LOW_TIMER", 10.0),
                              ("BATT_FS_LOW_ACT", 0.0)):
            link.mav.param_request_read_send(1, 1, name.encode(), -1)
            got = _until(link, 3.0, lambda msg, heard, n=name: msg.get_type() == "PARAM_VALUE" and msg.param_id == n)
            assert got and got[-1].param_value == pytest.approx(default)
        assert _param_set(link, 1, "BATT_FS_LOW_ACT", 2) == 2.0  # RTL
        mission = _survey(legs=6, side_m=300.0)
        _start(link, 1, mission)
        assert mock.wait_until(lambda m: m.vehicle(1).flight.state.current >= 3, 30.0)
        assert _param_set(link, 1, "SIM_BATT_VOLTAGE", 10.0) == 10.0
        set_at = vehicle.flight.state.sim_time
        texts: list[str] = []
        modes: list[int] = []
        heard = _until(link, 30.0, lambda msg, heard: (
            msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1 and not msg.base_mode & 128))
        for msg in heard:
            if msg.get_type() == "STATUSTEXT":
                texts.append((int(msg.severity), msg.text))
            elif msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1:
                modes.append(int(msg.custom_mode))
            elif msg.get_type() == "SYS_STATUS" and msg.get_srcSystem() == 1:
                assert msg.voltage_battery in (12_600, 10_000)
        state = vehicle.flight.state
        # AP_BattMonitor::check_failsafes, then Copter::handle_battery_failsafe (announce_failsafe)
        low = [t for t in texts if t[1].startswith("Battery 1 is low")]
        assert len(low) == 1 and low[0][0] == 4, texts  # MAV_SEVERITY_WARNING
        assert low[0][1].startswith("Battery 1 is low 10.00V used ") and low[0][1].endswith(" mAh")
        assert (4, "Battery Failsafe") in texts
        assert 6 in modes  # RTL
        assert not state.armed and state.on_ground, "it did not land and disarm"
        assert math.hypot(state.lat - HOME[0], state.lon - HOME[1]) < 1e-6  # at home
        assert not state.mission_done and max(vehicle.reached) < len(mission.items)  # before the mission's end
        assert vehicle.battery_failsafe == 1
        # Not before BATT_LOW_TIMER simulated seconds below BATT_LOW_VOLT (and not much later).
        assert 10.0 < vehicle.battery_failsafe_sim_time - set_at < 12.0


@pytest.mark.flight
def test_a_battery_failsafe_without_an_action_warns_and_flies_on() -> None:
    with MockAutopilot(homes={1: HOME}, speedup=20.0, request_interval=0.05) as mock, Link(mock.client_url) as link:
        _start(link, 1, _survey(legs=6, side_m=300.0))  # BATT_FS_LOW_ACT 0: it warns and flies on
        mock.set_battery(1, 10.0)  # the Python way: SIM_BATT_VOLTAGE
        assert mock.vehicle(1).params["SIM_BATT_VOLTAGE"] == 10.0
        heard = _until(link, 3.0, lambda msg, heard: msg.get_type() == "SYS_STATUS" and msg.voltage_battery == 10_000)
        status = [m for m in heard if m.get_type() == "SYS_STATUS" and m.voltage_battery == 10_000]
        assert status and status[-1].current_battery == 1_000  # 10 A while armed
        heard += _until(link, 15.0, lambda msg, heard: msg.get_type() == "STATUSTEXT"
                        and msg.text == "Battery Failsafe")
        assert any(m.get_type() == "STATUSTEXT" and m.text == "Battery Failsafe" for m in heard)
        assert any(m.get_type() == "STATUSTEXT" and m.text.startswith("Battery 1 is low 10.00V") for m in heard)
        assert mock.vehicle(1).flight.state.mode == "AUTO"


def test_a_battery_failsafe_on_the_ground_disarms() -> None:
    """Copter::handle_battery_failsafe: armed but landed (should_disarm_on_failsafe), it disarms at once."""
    with MockAutopilot(homes={1: HOME}, speedup=20.0) as mock, Link(mock.client_url) as link:
        wait_vehicle(link, 1, timeout=3)
        assert _param_set(link, 1, "BATT_FS_LOW_ACT", 2) == 2.0
        # armed on the ground, no mission started
        assert _command(link, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
        assert _param_set(link, 1, "SIM_BATT_VOLTAGE", 10.0) == 10.0
        heard = _until(link, 10.0, lambda msg, heard: msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1
                       and not msg.base_mode & 128)
        texts = [m.text for m in heard if m.get_type() == "STATUSTEXT"]
        assert texts[-1] == "Battery Failsafe - Disarming" and texts[-2].startswith("Battery 1 is low 10.00V"), texts
        state = mock.vehicle(1).flight.state
        assert not state.armed and state.mode != "RTL"


# ------------------------------------------------------------------------------ another ground station
def test_another_ground_station_is_denied_while_one_uploads(monkeypatch: pytest.MonkeyPatch) -> None:
    """ArduPilot's MissionItemProtocol: while (sysid, compid) A uploads, B's MISSION_COUNT, items and
    clear-all are answered MAV_MISSION_DENIED (clear-all also ERROR), downloads DENIED too; A may
    restart its own upload; once A's upload is over (completed, or timed out), B may upload."""
    with MockAutopilot(homes={1: HOME}, request_interval=0.05, upload_timeout=3.0) as mock, \
            Link(mock.client_url, source_system=250, source_component=190) as holder, \
            Link(mock.client_url) as fly_link:
        vehicle = wait_vehicle(fly_link, 1, timeout=3)
        wait_vehicle(holder, 1, timeout=3)

        def acks(link: Link, n: int) -> list[int]:
            """The next n MISSION_ACKs addressed to us (GCS 255, fly's default)."""
            def ours(heard: list[Any]) -> list[int]:
                return [int(m.type) for m in heard if m.get_type() == "MISSION_ACK" and m.target_system == 255]
            return ours(_until(link, 3.0, lambda msg, heard: len(ours(heard)) >= n))

        holder.mav.mission_count_send(1, 1, 3, MISSION_TYPE)  # and then silent
        assert mock.wait_until(lambda m: m.vehicle(1).upload is not None, 3.0)
        fly_link.mav.mission_count_send(1, 1, 5, MISSION_TYPE)
        assert acks(fly_link, 1) == [mavlink.MAV_MISSION_DENIED]
        fly_link.mav.mission_clear_all_send(1, 1, MISSION_TYPE)
        assert acks(fly_link, 2) == [mavlink.MAV_MISSION_DENIED, mavlink.MAV_MISSION_ERROR]
        fly_link.mav.mission_request_list_send(1, 1, MISSION_TYPE)
        assert acks(fly_link, 1) == [mavlink.MAV_MISSION_DENIED]
        fly_link.mav.mission_item_int_send(1, 1, 0, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0,
                                           0, 0, 0, 0, 0, MISSION_TYPE)
        assert acks(fly_link, 1) == [mavlink.MAV_MISSION_DENIED]  # the item it asks for, but from the wrong sender
        fly_link.mav.mission_item_int_send(1, 1, 2, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0,
                                           0, 0, 0, 0, 0, MISSION_TYPE)
        assert acks(fly_link, 1) == [mavlink.MAV_MISSION_INVALID_SEQUENCE]  # not the one it asks for: that first
        assert mock.vehicle(1).denied_transfers == 3  # count, clear-all, item (downloads are not counted)
        # Our client: denied at the start, tried again, then one line naming the other ground station.
        monkeypatch.setattr("missionplan.bridge.transfer.protocol.DENIED_TRIES", 2)
        monkeypatch.setattr("missionplan.bridge.transfer.protocol.DENIED_WAIT_S", 0.2)
        with pytest.raises(MissionTransferError, match="another ground station"):
            MissionClient(fly_link, vehicle, Timeouts(item_timeout=0.3)).upload(
                MISSION_TYPE, to_wire(_survey(), Flavour.ARDUPILOT))
        assert mock.vehicle(1).denied_transfers == 5
        # The holder may restart its own upload (same sysid, compid): asked for item 0 again.
        holder.mav.mission_count_send(1, 1, 2, MISSION_TYPE)
        heard = _until(holder, 3.0, lambda msg, heard: msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT")
                       and msg.target_system == 250)
        assert heard and heard[-1].seq == 0
        # Silent for upload_timeout: the vehicle gives the holder up (OPERATION_CANCELLED) ...
        heard = _until(holder, 6.0, lambda msg, heard: msg.get_type() == "MISSION_ACK" and msg.target_system == 250)
        assert heard and heard[-1].get_type() == "MISSION_ACK"
        assert heard[-1].type == mavlink.MAV_MISSION_OPERATION_CANCELLED
        # ... and the other ground station's upload goes through.
        MissionClient(fly_link, vehicle, Timeouts(item_timeout=0.3)).upload(
            MISSION_TYPE, to_wire(_survey(), Flavour.ARDUPILOT))
        assert len(mock.mission(1)) == len(_survey().items) + 1


def test_no_arming_below_the_failsafe_voltage() -> None:
    with MockAutopilot(homes={1: HOME}) as mock, Link(mock.client_url) as link:
        wait_vehicle(link, 1, timeout=3)
        assert _param_set(link, 1, "SIM_BATT_VOLTAGE", 10.4) == pytest.approx(10.4)
        texts: list[str] = []
        def note(msg: Any) -> None:
            if msg.get_type() == "STATUSTEXT":
                texts.append(msg.text)

        assert link.command_long(1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0] + [0.0] * 6, time.monotonic() + 3.0,
                                 other=note) == mavlink.MAV_RESULT_FAILED
        assert "PreArm: Battery 1 low voltage failsafe" in texts
        assert _param_set(link, 1, "SIM_BATT_VOLTAGE", 12.6) == pytest.approx(12.6)
        assert _command(link, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
