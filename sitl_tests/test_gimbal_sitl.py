"""The gimbal item on the real autopilots, and the mock's mount beside them: ArduCopter SITL with a simulated servo
mount (MNT1_TYPE 1, SERVO9_FUNCTION 7: mount tilt; then a reboot) and PX4 SIH with its gimbal module (MNT_MODE_IN 0,
MNT_MODE_OUT 0 at boot) each store the item our plans carry for them (DO_MOUNT_CONTROL), fly it, and report the
camera at -90 degrees in GIMBAL_DEVICE_ATTITUDE_STATUS; the mock of each flavour, configured the same way, reports
the same. (PX4 did not turn for a first DO_GIMBAL_MANAGER_PITCHYAW: docs/autopilots.md.)

What was measured with them (docs/autopilots.md, Gimbal): neither SITL sends MOUNT_STATUS; PX4 also sends
MOUNT_ORIENTATION; ArduCopter's servo mount reports its body-frame servo demand (-90 in a hover).

Each test starts its own vehicle (own folder, own session, free ports, killed in teardown) and skips when the
binary is absent.
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from missionplan.bridge.formats.gimbal import gimbal_item, quaternion_pitch_roll
from missionplan.bridge.formats.mission_items import (CMD_DO_MOUNT_CONTROL, Flavour,
                                                      Mission, MissionItem, MissionType, to_wire)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.arducopter import ArduCopter, reboot_and_wait
from missionplan.testing.px4_mission_session import wait_home, wait_ready
from missionplan.testing.px4_sih import PX4 as PX4SIH

pytestmark = [pytest.mark.sitl, pytest.mark.flight]  # flies real autopilots and the mock beside them

NADIR = -90.0
QUATERNION_DEG = 0.05  # a float32 quaternion holds -90 degrees of pitch to about 0.015
ARDUPILOT_MOUNT = {"MNT1_TYPE": 1.0, "SERVO9_FUNCTION": 7.0}  # a servo mount, its tilt on servo 9
PX4_GIMBAL = {"MNT_MODE_IN": 0.0, "MNT_MODE_OUT": 0.0}  # the gimbal module, any input, AUX output
READY_S = 240.0
FLY_S = 150.0


def _mission(flavour: Flavour, home: tuple[float, float, float]) -> Mission:
    """Take off to 10 m, point the camera down (our plans' item for this autopilot), hold over a point 20 m
    north for 5 s, return."""
    lat, lon, _ = home
    return Mission([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=10.0),
                    gimbal_item(flavour, NADIR),
                    MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param1=5.0,
                                x=lat + 0.00018, y=lon, z=10.0),
                    MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)], home=home)


def _ask_gimbal(link: Link, sysid: int) -> None:
    result = link.command_long(sysid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                               [float(mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS), 250_000.0],
                               time.monotonic() + 5.0)
    assert result == mavlink.MAV_RESULT_ACCEPTED


def _until_nadir(link: Link, sysid: int, seconds: float) -> dict[str, Any]:
    """Every gimbal message of `sysid` until GIMBAL_DEVICE_ATTITUDE_STATUS says the camera points down (bounded):
    {"pitches": [...], "kinds": {...}, "last": the last status, "nadir": the first pitch within QUATERNION_DEG of
    NADIR, None if none came}. The tests read "nadir", not the last pitch: ArduCopter's servo mount reports its
    body-frame demand, which leaves -90 by the body's pitch once the vehicle flies on (CI saw -86.7 as the last)."""
    out: dict[str, Any] = {"pitches": [], "kinds": set(), "last": None, "nadir": None}
    deadline = time.monotonic() + seconds
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() != sysid:
            continue
        kind = msg.get_type()
        if kind in ("MOUNT_STATUS", "MOUNT_ORIENTATION", "GIMBAL_DEVICE_ATTITUDE_STATUS"):
            out["kinds"].add(kind)
        if kind == "GIMBAL_DEVICE_ATTITUDE_STATUS":
            angles = quaternion_pitch_roll(list(msg.q))
            if angles is not None:
                out["pitches"].append(angles[0])
                out["last"] = msg
                if abs(angles[0] - NADIR) < QUATERNION_DEG and out["nadir"] is None:
                    out["nadir"] = angles[0]
                    deadline = min(deadline, time.monotonic() + 2.0)  # and what comes with it
    return out


def _upload_and_read_back(backend: PymavlinkBackend, mission: Mission, flavour: Flavour) -> None:
    wire = to_wire(mission, flavour)
    backend.upload(MissionType.MISSION, wire)
    held = backend.download(MissionType.MISSION)
    assert compare_wire(wire, held, skip_home=flavour is Flavour.ARDUPILOT, flavour=flavour) == []


def _arm_and_start(link: Link, sysid: int, flavour: Flavour, deadline: float) -> None:
    while time.monotonic() < deadline:
        if flavour is Flavour.ARDUPILOT:
            link.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
        if link.command_long(sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], deadline) == mavlink.MAV_RESULT_ACCEPTED:
            break
        retry = min(deadline, time.monotonic() + 1.0)  # not ready yet: listen, then ask again
        while link.recv(retry) is not None:
            pass
    # PX4 refuses a start for a moment after an upload or a boot ("Mission start denied! No valid mission"): again.
    while (result := link.command_long(sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], deadline)) \
            != mavlink.MAV_RESULT_ACCEPTED and time.monotonic() < deadline:
        retry = min(deadline, time.monotonic() + 1.0)
        while link.recv(retry) is not None:
            pass
    assert result == mavlink.MAV_RESULT_ACCEPTED


def _ardupilot_session(url: str, sysid: int, configure: Any) -> dict[str, Any]:
    home = (45.4643, 9.1895, 120.0)
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        link = backend.link
        configure(link, backend.vehicle)
        wait_vehicle(link, sysid, timeout=30.0)
        _ask_gimbal(link, sysid)
        before = _until_nadir(link, sysid, 3.0)
        _upload_and_read_back(backend, _mission(Flavour.ARDUPILOT, home), Flavour.ARDUPILOT)
        _arm_and_start(link, sysid, Flavour.ARDUPILOT, time.monotonic() + READY_S)
        after = _until_nadir(link, sysid, FLY_S)
    return {"before": before, "after": after}


def _configure_ardupilot(link: Link, vehicle: Any) -> None:
    params = ParamClient(link, vehicle)
    for name, value in ARDUPILOT_MOUNT.items():
        params.set(name, value)
    reboot_and_wait(link, vehicle.sysid)


def test_arducopter_stores_and_flies_the_mount_item_and_reports_the_camera_down(arducopter) -> None:
    vehicle: ArduCopter = arducopter(sysid=1)
    real = _ardupilot_session(vehicle.url, 1, _configure_ardupilot)
    assert real["before"]["pitches"] and abs(real["before"]["pitches"][-1] - NADIR) > 10  # not down before the item
    assert real["after"]["nadir"] == pytest.approx(NADIR, abs=QUATERNION_DEG)
    assert real["after"]["kinds"] == {"GIMBAL_DEVICE_ATTITUDE_STATUS"}  # no MOUNT_STATUS from 4.7
    assert real["after"]["last"].gimbal_device_id == 1
    # The ArduPilot-flavoured mock, configured as a team would (configure_camera: CAM1_TYPE and MNT1_TYPE), agrees.
    with MockAutopilot("udpin:127.0.0.1:0", flavour=Flavour.ARDUPILOT, speedup=10.0, sitl_like=True,
                       streams_until_asked=True, homes={1: (45.4643, 9.1895, 120.0)}) as mock:
        mocked = _ardupilot_session(mock.client_url, 1, lambda link, v: mock.configure_camera(1))
    assert mocked["after"]["nadir"] == pytest.approx(NADIR, abs=QUATERNION_DEG)
    assert mocked["after"]["kinds"] == real["after"]["kinds"]
    assert (mocked["after"]["last"].gimbal_device_id, mocked["after"]["last"].flags) == \
           (real["after"]["last"].gimbal_device_id, real["after"]["last"].flags)


def _px4_session(url: str, sysid: int) -> dict[str, Any]:
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        link = backend.link
        _ask_gimbal(link, sysid)
        home_msg = wait_home(link, sysid, 60.0)
        assert home_msg is not None
        home = (home_msg.latitude / 1e7, home_msg.longitude / 1e7, home_msg.altitude / 1000.0)
        before = _until_nadir(link, sysid, 3.0)
        _upload_and_read_back(backend, _mission(Flavour.PX4, home), Flavour.PX4)
        assert wait_ready(link, sysid, READY_S)
        _arm_and_start(link, sysid, Flavour.PX4, time.monotonic() + READY_S)
        after = _until_nadir(link, sysid, FLY_S)
    return {"before": before, "after": after}


def test_px4_stores_and_flies_the_mount_item_and_reports_the_camera_down(px4) -> None:
    vehicle: PX4SIH = px4(params=PX4_GIMBAL)
    real = _px4_session(vehicle.gcs_url, vehicle.sysid)
    assert real["before"]["pitches"] and real["before"]["pitches"][-1] == pytest.approx(0.0, abs=QUATERNION_DEG)
    assert real["after"]["nadir"] == pytest.approx(NADIR, abs=QUATERNION_DEG)
    assert "MOUNT_STATUS" not in real["after"]["kinds"]
    assert real["after"]["last"].gimbal_device_id == 0
    with MockAutopilot("udpin:127.0.0.1:0", flavour=Flavour.PX4, speedup=10.0, sitl_like=True,
                       homes={1: vehicle.home}) as mock:
        mock.configure_camera(1)
        mocked = _px4_session(mock.client_url, 1)
    assert mocked["after"]["nadir"] == pytest.approx(NADIR, abs=QUATERNION_DEG)
    assert mocked["after"]["kinds"] == real["after"]["kinds"]  # GIMBAL_DEVICE_ATTITUDE_STATUS, MOUNT_ORIENTATION
    assert mocked["after"]["last"].gimbal_device_id == real["after"]["last"].gimbal_device_id


def test_px4_without_its_gimbal_module_stores_the_item_and_flies_on(px4) -> None:
    """SIH's default (MNT_MODE_IN -1): no gimbal module, no report; the item is kept and the mission passes it."""
    vehicle: PX4SIH = px4()
    with PymavlinkBackend(vehicle.gcs_url, vehicle.sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        link, sysid = backend.link, vehicle.sysid
        home_msg = wait_home(link, sysid, 60.0)
        assert home_msg is not None
        mission = _mission(Flavour.PX4, (home_msg.latitude / 1e7, home_msg.longitude / 1e7, 0.0))
        _upload_and_read_back(backend, mission, Flavour.PX4)
        assert [w.command for w in backend.download(MissionType.MISSION)][1] == CMD_DO_MOUNT_CONTROL
        assert wait_ready(link, sysid, READY_S)
        _arm_and_start(link, sysid, Flavour.PX4, time.monotonic() + READY_S)
        passed = False
        deadline = time.monotonic() + FLY_S
        while not passed and (msg := link.recv(deadline)) is not None:
            passed = msg.get_srcSystem() == sysid and msg.get_type() == "MISSION_CURRENT" and msg.seq >= 2
    assert passed  # on to the waypoint after the gimbal item

