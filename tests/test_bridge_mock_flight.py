"""The mock autopilot flies: commands with COMMAND_ACK, a mission flown as a kinematic point with
progress messages, camera triggers counted, return to launch; and the flight model on its own."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest

from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle
from missionplan.bridge.link.readiness import ARDUPILOT_AUTO, mode_params
from missionplan.bridge.formats.mission_items import (
    CMD_DO_CHANGE_SPEED,
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_NAV_LAND,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    to_wire,
)
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import FlightSim
from missionplan.bridge.transfer.protocol import MissionClient, Timeouts

HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = 111_319.49


def _survey() -> Mission:
    legs = [(0.0, 0.0), (100.0, 0.0), (100.0, 50.0), (0.0, 50.0)]  # metres north, east of home
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=20.0),
             MissionItem(CMD_DO_CHANGE_SPEED, FRAME_MISSION, param1=1, param2=10.0),
             MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=10.0)]
    for north, east in legs:
        lat = HOME[0] + north / M_PER_DEG_LAT
        lon = HOME[1] + east / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))
        items.append(MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, x=lat, y=lon, z=20.0))
    items += [MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=0.0),
              MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)]
    return Mission(items, home=HOME)


def _command(link: Link, command: int, *params: float) -> int:
    p = list(params) + [0.0] * (7 - len(params))
    link.mav.command_long_send(1, 1, command, 0, *p)
    deadline = time.monotonic() + 2
    while True:
        msg = link.recv(deadline)
        assert msg is not None, f"no COMMAND_ACK for {command}"
        if msg.get_type() == "COMMAND_ACK" and msg.command == command:
            return int(msg.result)


@pytest.mark.flight
def test_arm_mode_start_fly_and_land() -> None:
    with MockAutopilot(homes={1: HOME}, speedup=40.0, request_interval=0.02).start() as mock:
        with Link(mock.client_url) as link:
            vehicle = wait_vehicle(link, 1, timeout=3)
            client = MissionClient(link, vehicle, Timeouts(item_timeout=0.2))
            assert _command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_DENIED  # no mission yet
            client.upload(0, to_wire(_survey(), Flavour.ARDUPILOT))
            assert _command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_DENIED  # not armed yet
            assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
            auto = mode_params(ARDUPILOT_AUTO)
            assert _command(link, mavlink.MAV_CMD_DO_SET_MODE, *auto) == mavlink.MAV_RESULT_ACCEPTED
            assert _command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED
            assert _command(link, 31337) == mavlink.MAV_RESULT_UNSUPPORTED  # raw: a command no one defines
            reached: list[int] = []
            currents: set[int] = set()
            armed_seen = landed = False
            deadline = time.monotonic() + 15
            while time.monotonic() < deadline:
                msg = link.recv(deadline)
                if msg is None or msg.get_srcSystem() != 1:
                    continue
                kind = msg.get_type()
                if kind == "MISSION_ITEM_REACHED":
                    reached.append(int(msg.seq))
                elif kind == "MISSION_CURRENT":
                    currents.add(int(msg.seq))
                elif kind == "HEARTBEAT":
                    armed = bool(msg.base_mode & 128)
                    armed_seen |= armed
                    if armed_seen and not armed and not landed:
                        landed = True
                        deadline = time.monotonic() + 0.3  # collect what was sent with the landing
            assert landed, "the vehicle did not land and disarm"
        state = mock.vehicle(1).flight.state
    # Nav items: takeoff (seq 1), waypoints (4..7), RTL (9); the first waypoint is above home.
    assert reached == [1, 4, 5, 6, 7, 9]
    assert {2, 3, 4, 9} <= currents  # (1 came with the MISSION_START answer)
    assert state.on_ground and not state.armed
    assert math.isclose(state.lat, HOME[0], abs_tol=1e-6) and math.isclose(state.lon, HOME[1], abs_tol=1e-6)
    # Triggering covers the 250 m of legs flown with the camera on, one photo every 10 m.
    assert 24 <= state.photos <= 26
    assert len(state.track) > 10


@pytest.mark.flight
def test_a_repeated_mission_start_restarts_nothing(monkeypatch) -> None:
    """Like ArduCopter (GCS_MAVLINK_Copter::handle_MAV_CMD_MISSION_START starts the mission only when it
    is not running): a start repeated while the vehicle still climbs off the ground is accepted and
    leaves the running mission alone. fly repeats a start whose acknowledgement was lost."""
    with MockAutopilot(homes={1: HOME}, speedup=1.0, request_interval=0.02).start() as mock:
        flight = mock.vehicle(1).flight
        starts: list[int] = []
        monkeypatch.setattr(flight, "start_mission", lambda *a, run=flight.start_mission: starts.append(1) or run(*a))
        with Link(mock.client_url) as link:
            vehicle = wait_vehicle(link, 1, timeout=3)
            MissionClient(link, vehicle, Timeouts(item_timeout=0.2)).upload(0, to_wire(_survey(), Flavour.ARDUPILOT))
            assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
            assert _command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED
            assert flight.state.alt < 1.0  # 20 m take-off at real time: still near the ground
            assert _command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED
            assert flight.state.alt < 1.0
    assert starts == [1]


def _items(mission: Mission) -> list[Any]:
    return to_wire(mission, Flavour.PX4)


def test_flight_model_speed_acceptance_and_hold() -> None:
    sim = FlightSim(HOME, cruise_speed=5.0, climb_rate=2.0)
    north = 50.0
    lat = HOME[0] + north / M_PER_DEG_LAT
    mission = Mission([MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=10.0),
                       MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param1=4.0, param2=2.0, x=lat,
                                   y=HOME[1], z=10.0),
                       MissionItem(CMD_NAV_LAND, FRAME_GLOBAL_RELATIVE_ALT)])
    sim.load(_items(mission), 0)
    sim.state.armed = True
    sim.start_mission()
    events = sim.advance(5.0)  # 10 m climb at 2 m/s
    assert any(e.kind == "reached" and e.seq == 0 for e in events)
    assert math.isclose(sim.state.alt, 10.0)
    sim.advance(9.5)  # 48 m of the 50 m leg: inside the 2 m acceptance radius
    assert sim.state.current == 1 and sim.state.distance > 47
    events = sim.advance(3.0)  # holding 4 s at the waypoint
    assert sim.state.current == 1
    events = sim.advance(1.6)  # 0.5 s to close the last 2.5 m, then the 4 s hold ends
    assert any(e.kind == "reached" and e.seq == 1 for e in events)
    events = sim.advance(20.0)  # land where it is
    assert sim.state.on_ground and not sim.state.armed
    assert any(e.kind == "landed" for e in events)
