"""The mock autopilot's SITL-like mode: ArduCopter's flight (the planner's timeline,
missionplan.bridge.flight_models.copter_model), no camera until CAM1_TYPE is set and the vehicle rebooted, img_idx from
1 and counting on across flights, ArduCopter's navigation parameters. Mocks listen on 127.0.0.1 only; every wait is
bounded."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest

from missionplan.bridge.flight_models import copter_model as cm
from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.formats.mission_items import Mission, MissionItem
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan
from missionplan.mission.timeline import FlightModel, planned_track
from missionplan.testing.sim_flight import fly_sim

HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
FAST = Timeouts(item_timeout=0.2, retries=10)


def _at(north: float, east: float = 0.0) -> tuple[float, float]:
    lat = HOME[0] + north / M_PER_DEG_LAT
    lon = HOME[1] + east / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))
    return lat, lon


def _mission(alt: float, points: list[tuple[float, float]], trigger_m: float = 0.0, end: int = 20) -> Mission:
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=alt),
             MissionItem(mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, param1=1, param2=5.0, param3=-1),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=trigger_m,
                         param3=1.0 if trigger_m else 0.0)]
    for north, east in points:
        lat, lon = _at(north, east)
        items.append(MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.5, x=lat,
                                 y=lon, z=alt))
    items.append(MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0))
    if end == 21:
        lat, lon = _at(*points[-1])
        items.append(MissionItem(mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=0.0))
    else:
        items.append(MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION))
    return Mission(items, home=HOME)


def _fly_sim(mission: Mission, limit_s: float = 600.0) -> np.ndarray:
    """(n, 4) t, north, east, up of the SITL-like FlightSim flying `mission` from MISSION_START to disarm."""
    return fly_sim(mission, HOME, limit_s=limit_s)[:, :4]


@pytest.mark.parametrize("alt, end", [(20.0, 20), (8.0, 20), (12.0, 21)])
def test_the_sitl_like_flight_is_the_planners_timeline(alt: float, end: int) -> None:
    points = [(30.0, 0.0), (30.0, 40.0), (5.0, 40.0), (5.0, 43.0)]
    flown = _fly_sim(_mission(alt, points, end=end))
    plan = planned_track(np.zeros(2), np.array(points), alt, "rtl" if end == 20 else "land", FlightModel(5.0, 0.5))
    assert flown[-1, 0] == pytest.approx(plan[-1, 0], abs=0.06)  # disarmed within a step of the plan's end
    for k, axis in ((1, "north"), (2, "east"), (3, "up")):
        at_plan_times = np.interp(plan[:, 0], flown[:, 0], flown[:, k])
        assert np.abs(at_plan_times - plan[:, k]).max() < 0.3, axis  # 5 m/s x one 0.05 s step, and then some


def test_rtl_climbs_to_rtl_alt_and_lands_slowly() -> None:
    flown = _fly_sim(_mission(8.0, [(60.0, 0.0)]))
    assert flown[:, 3].max() == pytest.approx(15.0, abs=1e-6)  # RTL_ALT, from 8 m
    # It climbs above the last waypoint before it heads home.
    top = int(np.argmax(flown[:, 3] > 15.0 - 1e-6))
    assert flown[top, 1] == pytest.approx(60.0, abs=0.01)
    # The last 10 m (LAND_ALT_LOW) at 0.5 m/s: 20 s from 10 m to the ground, then the touchdown pause.
    after = flown[top:]
    ten = after[np.flatnonzero(after[:, 3] <= 10.0)[0], 0]
    ground = after[np.flatnonzero(after[:, 3] <= 1e-6)[0], 0]
    assert ground - ten == pytest.approx(20.0, abs=0.11)
    assert flown[-1, 0] - ground == pytest.approx(cm.TOUCHDOWN_S, abs=0.11)  # on the ground, then disarmed
    # Home at WPNAV_SPEED (10 m/s), not the mission's 5 m/s.
    speeds = np.hypot(np.diff(flown[:, 1]), np.diff(flown[:, 2])) / np.diff(flown[:, 0])
    assert speeds.max() == pytest.approx(10.0, abs=0.05)


# ------------------------------------------------------------------------------------------- over MAVLink
def _command(link: Link, command: int, *params: float) -> int | None:
    return link.command_long(1, command, list(params), time.monotonic() + 3.0)


def _fly_and_collect(link: Link, timeout: float) -> list[Any]:
    """Arm, start, and collect CAMERA_FEEDBACK until the vehicle disarms after the mission (bounded)."""
    assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0) == 0
    assert _command(link, mavlink.MAV_CMD_MISSION_START, 0.0, 0.0) == 0
    feedback: list[Any] = []
    deadline = time.monotonic() + timeout
    flying = False
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() != 1:
            continue
        if msg.get_type() == "CAMERA_FEEDBACK":
            feedback.append(msg)
        elif msg.get_type() == "GLOBAL_POSITION_INT" and msg.relative_alt > 500:
            flying = True
        elif msg.get_type() == "HEARTBEAT" and flying and not msg.base_mode & 128:
            return feedback
    raise AssertionError("the mock did not land and disarm in time")


@pytest.mark.flight
def test_no_camera_until_configured_then_img_idx_from_1_across_flights() -> None:
    mission = _mission(6.0, [(8.0, 0.0)], trigger_m=2.0)
    with MockAutopilot("udpin:127.0.0.1:0", sitl_like=True, speedup=40.0, homes={1: HOME}) as mock:
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            link = backend.link
            params = ParamClient(link, backend.vehicle)
            assert params.get("RTL_ALT") == 1500.0 and params.get("LAND_SPEED") == 50.0  # ArduCopter's defaults
            assert upload_plan(backend, [mission], verify=True).verified
            assert _fly_and_collect(link, 20.0) == []  # photos due, but no camera: no CAMERA_FEEDBACK
            assert mock.vehicle(1).flight.state.photos > 0
            assert params.set("CAM1_TYPE", 1.0) == 1.0
            assert _fly_and_collect(link, 20.0) == []  # set, but it takes effect at boot
            reboots = link.reboots.get(1, 0)
            assert _command(link, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0
            deadline = time.monotonic() + 5.0
            while link.reboots.get(1, 0) == reboots and time.monotonic() < deadline:
                link.recv(time.monotonic() + 0.1)
            assert link.reboots.get(1, 0) == reboots + 1
            assert params.get("CAM1_TYPE") == 1.0  # parameters survive the reboot
            assert upload_plan(backend, [mission], verify=True).verified  # the mission did not
            first = _fly_and_collect(link, 20.0)
            second = _fly_and_collect(link, 20.0)
        finally:
            backend.close()
    n = len(first)
    assert n >= 4 and len(second) == n
    assert [int(m.img_idx) for m in first] == list(range(1, n + 1))  # ArduPilot counts from 1 after a boot
    assert [int(m.img_idx) for m in second] == list(range(n + 1, 2 * n + 1))  # and on, flight after flight
