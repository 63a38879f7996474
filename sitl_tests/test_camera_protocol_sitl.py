"""The camera protocol on real autopilots: a MAVLink camera (the mock's, bridge/sim/mock_camera.py, on a link of
its own over loopback) beside ArduCopter SITL (CAM1_TYPE 6, MAVLinkCamV2, then a reboot; the camera on SITL's
serial1 TCP port) and PX4 SIH (TRIG_MODE 4, TRIG_INTERFACE 3 at boot; the camera on its offboard link).

Before anything is flown, the ground station's camera check (bridge/link/camera_check.py) reads the real
parameter: ArduCopter SITL at its default CAM1_TYPE 0 is refused by `upload` in one line, nothing uploaded; at
CAM1_TYPE 6 with the camera on serial1 it passes (the camera's HEARTBEAT is routed to the ground station's link).

Each flies a short camera-interval mission as `plan --capture camera-interval` builds it (drone_missions: take-off
to 10 m, IMAGE_START_CAPTURE every 2 s at the survey's start, a 30 m leg out and back, IMAGE_STOP_CAPTURE, RTL)
after a distance-triggered one (DO_SET_CAM_TRIGG_DIST 5 m, as relay and camera missions are). Required: every
CAMERA_IMAGE_CAPTURED the camera sent reaches the ground station from MAV_COMP_ID_CAMERA, with its fields, an
image_index counting 0, 1, 2, ... and capture_result 1; the flight recorder with camera records takes exactly
those (not CAMERA_FEEDBACK, nor PX4's own CAMERA_IMAGE_CAPTURED); and the mock autopilot with its MAVLink camera
reports the same fields the same way."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionType, to_wire
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.link.camera_check import check_camera
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, Vehicle, mode_params
from missionplan.bridge.sim.mock_camera import CAMERA_COMPONENT_ID, CameraPeer
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.cli import main
from missionplan.flight.record import DroneRecord
from missionplan.flight.telemetry_record import TelemetryRecorder
from missionplan.mission.drone_missions import MissionSettings, build_mission
from missionplan.testing.arducopter import ArduCopter, reboot_and_wait, sitl_or_skip
from missionplan.testing.px4_sih import PX4, px4_or_skip

pytestmark = pytest.mark.sitl

HOME = (45.4643, 9.1895, 120.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
FIELDS = ("time_boot_ms", "time_utc", "lat", "lon", "alt", "relative_alt", "q", "image_index", "capture_result",
          "file_url")
FLIGHT_TIMEOUT_S = 200.0


def _mission(capture: str) -> Mission:
    """A 30 m leg north and back at 10 m, a photo every 5 m (10 m footprint, overlap 1/2; interval 5 m / 2.5 m/s)."""
    settings = MissionSettings(altitude_m=10.0, footprint_m=10.0, speed_m_s=2.5, overlap=0.5, capture=capture)
    metres = np.array([[30.0, 0.0], [0.0, 0.0]])
    latlon = np.column_stack([HOME[0] + metres[:, 0] / M_PER_DEG_LAT, np.full(2, HOME[1])])
    return build_mission(0, HOME[:2], latlon, metres, np.zeros(2), settings).mission


def _fly(backend: PymavlinkBackend, sysid: int, mission: Mission, flavour: Flavour) -> list[Any]:
    """Upload, arm (retrying until ready), start, and every message of the vehicle's system until it disarms."""
    link = backend.link
    backend.upload(MissionType.MISSION, to_wire(mission, flavour))
    deadline = time.monotonic() + FLIGHT_TIMEOUT_S
    while True:
        if flavour is Flavour.ARDUPILOT:
            link.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
        if link.command_long(sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], deadline) == 0 and \
                link.command_long(sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], deadline) == 0:
            break
        retry_at = min(deadline, time.monotonic() + 1.0)
        while link.recv(retry_at) is not None:
            pass
        assert time.monotonic() < deadline, "the vehicle never armed and started"
    heard, armed_seen = [], False
    while time.monotonic() < deadline:
        msg = link.recv(time.monotonic() + 0.5)
        if msg is None or msg.get_srcSystem() != sysid:
            continue
        heard.append(msg)
        if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1:
            if msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                armed_seen = True
            elif armed_seen:
                return heard
    raise AssertionError("the vehicle did not land and disarm in time")


def _camera_records(heard: list[Any]) -> list[Any]:
    return [m for m in heard if m.get_type() == "CAMERA_IMAGE_CAPTURED" and m.get_srcComponent() == CAMERA_COMPONENT_ID]


def _recorded(heard: list[Any], flavour: Flavour) -> list[int]:
    """The photo indices the flight recorder takes from these messages with camera records on."""
    published: list[Any] = []
    recorder = TelemetryRecorder(DroneRecord(id=1), SimpleNamespace(flavour=flavour), set(), published.append,
                                 camera_records=True)
    for msg in heard:
        if msg.get_type() in ("CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED"):
            recorder.take(msg)
    return [p.index for p in published]


def _check(heard: list[Any], first: int, flavour: Flavour) -> list[Any]:
    records = _camera_records(heard)
    mine = [m for m in records if int(m.image_index) >= first]
    assert len(mine) >= 5, [m.to_dict() for m in records]
    assert [int(m.image_index) for m in mine] == list(range(first, first + len(mine)))
    assert all(int(m.capture_result) == 1 and str(m.file_url) for m in mine)
    assert all(abs(m.lat / 1e7 - HOME[0]) < 1e-3 and abs(m.relative_alt / 1000.0 - 10.0) < 3.0 for m in mine)
    assert set(_recorded(heard, flavour)) == {int(m.image_index) for m in records}
    return mine


def _both_missions(backend: PymavlinkBackend, sysid: int, flavour: Flavour, peer: CameraPeer) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for capture in ("camera", "camera-interval"):
        first = len(peer.images())
        heard = _fly(backend, sysid, _mission(capture), flavour)
        out[capture] = _check(heard, first, flavour)
        out[capture + " feedback"] = [m for m in heard if m.get_type() == "CAMERA_FEEDBACK"]
    return out


def test_arducopter_at_cam1_type_0_is_refused_before_a_camera_plan_is_uploaded(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sitl_or_skip()
    side = 40.0 / M_PER_DEG_LAT  # a 40 m square with home near its south-west corner
    lat, lon = HOME[0] - 2.0 / M_PER_DEG_LAT, HOME[1] - 2.0 / M_PER_DEG_LAT
    area = tmp_path / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [[
        [lon, lat], [lon + side, lat], [lon + side, lat + side], [lon, lat + side], [lon, lat]]]}))
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(plan_dir), "--quiet",
                 "--capture", "camera", "--launch", f"{HOME[0]},{HOME[1]}"]) == 0
    capsys.readouterr()
    sysid = 3
    with ArduCopter(sysid=sysid, home=(*HOME, 0.0)) as vehicle:
        code = main(["upload", str(plan_dir / "uav1.plan"), "--sysid", str(sysid), "--connect", vehicle.url,
                     "--quiet", "--timeout", "30"])
        with PymavlinkBackend(vehicle.url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
            held = backend.download(MissionType.MISSION)
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert err.startswith(f"missionplan upload: vehicle {sysid}: the plan captures with a MAVLink camera (--capture "
                          "camera) and CAM1_TYPE is 0 and no MAVLink camera was heard"), err
    assert err.endswith("set CAM1_TYPE 6 (MAVLinkCamV2) and reboot, and connect the camera\n"), err
    assert len(held) <= 1  # its home item only: nothing was uploaded


def test_arducopter_forwards_each_photo_to_a_mavlink_camera_and_relays_its_records() -> None:
    sitl_or_skip()
    sysid = 4
    with ArduCopter(sysid=sysid, home=(*HOME, 0.0)) as vehicle, \
            PymavlinkBackend(vehicle.url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        assert ParamClient(backend.link, backend.vehicle).set("CAM1_TYPE", 6.0) == 6.0  # MAVLinkCamV2
        reboot_and_wait(backend.link, sysid)
        with CameraPeer(f"tcp:127.0.0.1:{vehicle.tcp_port + 2}", sysid) as peer:  # serial1
            # The camera check passes: CAM1_TYPE 6, and the camera's HEARTBEAT reaches our link from serial1.
            start = time.monotonic()
            assert check_camera(Vehicle(backend.link, backend.vehicle), "camera", start + 10.0, start) == ""
            for msgid in (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT):
                backend.link.command_long(sysid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [msgid, 200_000],
                                          time.monotonic() + 5.0)
            flown = _both_missions(backend, sysid, Flavour.ARDUPILOT, peer)
            commands = [command for command, _ in peer.camera.commands]
    # It found the camera (asked for its CAMERA_INFORMATION), sent one IMAGE_START_CAPTURE (count 1) per photo,
    # and still reported each with its own CAMERA_FEEDBACK, which camera records leave aside.
    assert mavlink.MAV_CMD_REQUEST_MESSAGE in commands and mavlink.MAV_CMD_IMAGE_START_CAPTURE in commands
    for capture in ("camera", "camera-interval"):
        assert len(flown[capture + " feedback"]) == len(flown[capture]), capture


def test_px4_forwards_each_photo_to_a_mavlink_camera_and_relays_its_records() -> None:
    px4_or_skip()
    with PX4(home=HOME, params={"TRIG_MODE": 4, "TRIG_INTERFACE": 3}) as vehicle:
        sysid = vehicle.sysid
        with CameraPeer(vehicle.offboard_url, sysid) as peer, \
                PymavlinkBackend(vehicle.gcs_url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
            flown = _both_missions(backend, sysid, Flavour.PX4, peer)
    # No CAMERA_FEEDBACK on PX4; its own CAMERA_IMAGE_CAPTURED (component 1) are left aside by _check.
    assert not flown["camera feedback"] and not flown["camera-interval feedback"]


@pytest.mark.flight
def test_the_mock_camera_reports_as_on_the_sitls() -> None:
    """The mock autopilot with its MAVLink camera: the same fields, indices from 0, capture_result 1."""
    from missionplan.bridge.sim.mock import MockAutopilot

    with MockAutopilot("udpin:127.0.0.1:0", sysids=(1,), sitl_like=True, speedup=10.0, homes={1: HOME},
                       mavlink_camera=True) as mock:
        mock.configure_cameras()
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(), connect_timeout=10) as backend:
            heard = _fly(backend, 1, _mission("camera-interval"), Flavour.ARDUPILOT)
    records = _check(heard, 0, Flavour.ARDUPILOT)
    assert all(set(FIELDS) <= set(m.to_dict()) for m in records)
