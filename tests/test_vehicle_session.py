"""A vehicle session (missionplan.bridge.session) against the mock autopilot: each request the flight loop makes
of a vehicle goes through its one place there (streams, readiness, the mission, parameters, each action), what
the vehicle says meanwhile reaches the session's observer, and the vehicle receives the commands in order."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import pytest

from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, to_wire
from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.link.readiness import (ARDUPILOT_AUTO, ARDUPILOT_GUIDED, PX4_AUTO_MAIN, PX4_LAND_SUB,
                                               PX4_LOITER_SUB)
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts

pytestmark = pytest.mark.flight  # flies mock autopilots

HOME = (45.0, 7.0, 200.0)
WAIT_S = 10.0  # wall seconds for any one thing the mock does
ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
SET_MODE, ARM, START = mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_CMD_MISSION_START


def _point(north: float) -> tuple[float, float]:
    return HOME[0] + math.degrees(north / 6_378_137.0), HOME[1]


def _mission() -> Mission:
    rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
    return Mission([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, rel, x=HOME[0], y=HOME[1], z=20.0),
                    *[MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, rel, x=_point(n)[0], y=_point(n)[1], z=20.0)
                      for n in (200.0, 400.0, 600.0)],
                    MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)], home=HOME)


@dataclass
class Vehicle:
    session: VehicleSession
    received: list[tuple[int, tuple[float, float, float]]]  # every COMMAND_LONG the vehicle got: command, params 1-3
    heard: list[str] = field(default_factory=list)  # the types of what the session's observer got

    def until(self, done: Callable[[], bool]) -> bool:
        deadline = time.monotonic() + WAIT_S
        while not done():
            msg = self.session.recv(deadline)
            if msg is None:
                return False
            self.session.take(msg)
        return True

    def commands_since(self, start: int) -> list[tuple[int, tuple[float, float, float]]]:
        return self.received[start:]


def _deadline() -> float:
    return time.monotonic() + WAIT_S


@contextmanager
def session_on(flavour: Flavour) -> Iterator[Vehicle]:
    """A session on a mock vehicle that sends nothing but HEARTBEAT until asked (as ArduPilot), its
    COMMAND_LONGs recorded as they arrive; ArduPilot's like ArduCopter SITL (its navigation parameters)."""
    with MockAutopilot(homes={1: HOME}, flavour=flavour, speedup=20.0, streams_until_asked=True,
                       sitl_like=flavour is Flavour.ARDUPILOT).start() as mock:
        received: list[tuple[int, tuple[float, float, float]]] = []
        vehicle = mock.vehicle(1)
        handle = vehicle.handle

        def recording(msg: Any, now: float) -> None:
            if msg.get_type() == "COMMAND_LONG" and msg.target_system == 1:
                received.append((int(msg.command), (msg.param1, msg.param2, msg.param3)))
            handle(msg, now)

        vehicle.handle = recording  # type: ignore[method-assign]
        with Link(mock.client_url) as link:
            heard: list[str] = []
            session = VehicleSession.open(link, 1, 5.0, Timeouts(item_timeout=0.3, retries=10),
                                          observe=lambda msg: heard.append(msg.get_type()))
            try:
                yield Vehicle(session, received, heard)
            finally:
                session.close()


def _ready_with_mission(v: Vehicle) -> None:
    session = v.session
    session.wait_heartbeat(_deadline())
    assert session.state.armed is False
    assert session.request_streams(10.0, _deadline()) == []
    assert session.wait_ready(_deadline()) == []
    assert session.mission.upload([_mission()]).verified
    assert session.mission.differences(to_wire(_mission(), session.flavour)) == []


def test_an_ardupilot_start_hold_release_and_return_go_through_the_session_in_order() -> None:
    with session_on(Flavour.ARDUPILOT) as v:
        session, action = v.session, v.session.action
        _ready_with_mission(v)
        params = session.navigation_params()
        assert params is not None and params["WPNAV_SPEED"] > 0  # what it flies with, as it reports it
        start = len(v.received)
        assert action.guided(_deadline()) == ACCEPTED
        assert action.arm(_deadline()) == (True, "")
        assert action.start_mission(_deadline()) == ACCEPTED
        assert v.until(lambda: session.state.mode_name() == "AUTO")
        assert action.hold(_deadline()) == ACCEPTED and action.hold_mode() == "GUIDED"
        assert v.until(lambda: session.state.mode_name() == "GUIDED")
        assert action.mission_mode(_deadline()) == ACCEPTED
        assert v.until(lambda: session.state.mode_name() == "AUTO")
        assert action.return_to_launch(_deadline()) == ACCEPTED
        assert v.until(lambda: session.state.mode_name() == "RTL")
        assert v.commands_since(start) == [
            (SET_MODE, (1.0, ARDUPILOT_GUIDED, 0.0)), (ARM, (1.0, 0.0, 0.0)), (START, (0.0, 0.0, 0.0)),
            (SET_MODE, (1.0, ARDUPILOT_GUIDED, 0.0)), (SET_MODE, (1.0, ARDUPILOT_AUTO, 0.0)),
            (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, (0.0, 0.0, 0.0))]
        # What came while the commands waited for their answers reached the observer; a sent-home RTL is no
        # mode this run's mission asked for.
        assert "GLOBAL_POSITION_INT" in v.heard and "HEARTBEAT" in v.heard
        assert action.commanded == {"GUIDED"}


def test_a_px4_vehicle_holds_in_hold_and_lands_in_its_own_modes() -> None:
    with session_on(Flavour.PX4) as v:
        session, action = v.session, v.session.action
        _ready_with_mission(v)
        start = len(v.received)
        assert action.arm(_deadline()) == (True, "")
        assert action.start_mission(_deadline()) == ACCEPTED
        assert v.until(lambda: session.state.mode_name() == "MISSION")
        assert action.hold(_deadline()) == ACCEPTED and action.hold_mode() == "HOLD"
        assert v.until(lambda: session.state.mode_name() == "HOLD")
        assert action.homing_mode("land", _deadline(), observe=False) == ACCEPTED
        assert v.until(lambda: session.state.mode_name() == "LAND")
        assert v.commands_since(start) == [
            (ARM, (1.0, 0.0, 0.0)), (START, (0.0, 0.0, 0.0)), (SET_MODE, (1.0, PX4_AUTO_MAIN, PX4_LOITER_SUB)),
            (SET_MODE, (1.0, PX4_AUTO_MAIN, PX4_LAND_SUB))]
        assert action.commanded == {"GUIDED", "HOLD", "LAND", "RTL"}  # none said as leaving the mission


def test_a_vehicle_that_will_not_fly_is_left_safe_by_the_session() -> None:
    with session_on(Flavour.ARDUPILOT) as v:
        session = v.session
        _ready_with_mission(v)
        assert session.action.guided(_deadline()) == ACCEPTED
        assert session.action.arm(_deadline()) == (True, "")
        assert v.until(lambda: session.state.armed is True)
        assert session.action.make_safe(_deadline()) == "left disarmed in GUIDED, not flown"
        assert session.reboots() == 0 and session.ack_rtt_s() is not None and session.signing_hint() == ""


def test_an_ardupilot_whose_ekf_stream_never_came_is_asked_again_while_the_session_waits() -> None:
    """A request for the EKF_STATUS_REPORT stream lost on the way (or the report dropped on it): the
    session asks for it again (once now, and the stream) every EKF_ASK_S while none has come, and is then ready."""
    from missionplan.bridge.link.readiness import EKF_ASK_S, request_streams, stream_rates

    ekf = mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT
    with session_on(Flavour.ARDUPILOT) as v:
        session = v.session
        session.wait_heartbeat(_deadline())
        rates = {msgid: hz for msgid, hz in stream_rates(10.0).items() if msgid != ekf}  # the EKF request lost
        assert request_streams(session.link, 1, rates, _deadline()) == []
        first = len(v.received)
        assert session.wait_ready(time.monotonic() + EKF_ASK_S + WAIT_S) == []
        asked = [(command, params[0]) for command, params in v.commands_since(first)]
        assert (mavlink.MAV_CMD_REQUEST_MESSAGE, float(ekf)) in asked
        assert (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, float(ekf)) in asked
