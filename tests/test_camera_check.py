"""The vehicle checked before a plan whose photos a MAVLink camera takes (bridge/link/camera_check.py).

`fly` and `upload` of a `plan --capture camera` / `camera-interval` plan read the autopilot's camera parameters
(ArduPilot CAM1_TYPE 6; PX4 TRIG_MODE 4 and TRIG_INTERFACE 3 for `camera`) and listen for the camera's HEARTBEAT
(MAV_TYPE_CAMERA from components 100-105) before anything is uploaded: a vehicle without them is refused in one
line naming it, what it lacks and what to set, nothing is uploaded and nobody arms. A relay plan checks nothing
new. A camera's HEARTBEAT beside the autopilot (base_mode 0) says nothing of the vehicle's arming or mode.
Mocks listen on 127.0.0.1 only."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.camera_check import camera_params, camera_problem
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.link.readiness import VehicleState
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.mock_fleet import start_mock_fleet

SPEEDUP = 10.0
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCH = "45.4641,9.1891"


# ------------------------------------------------------------------------------------------- the rule, alone
def test_what_each_autopilot_needs_for_each_mode() -> None:
    def needs(flavour: Flavour, capture: str) -> list[tuple[str, float]]:
        return [(p.name, p.value) for p in camera_params(flavour, capture)]

    assert needs(Flavour.ARDUPILOT, "relay") == needs(Flavour.PX4, "relay") == []
    assert needs(Flavour.ARDUPILOT, "camera") == needs(Flavour.ARDUPILOT, "camera-interval") == [("CAM1_TYPE", 6.0)]
    assert needs(Flavour.PX4, "camera") == [("TRIG_MODE", 4.0), ("TRIG_INTERFACE", 3.0)]
    assert needs(Flavour.PX4, "camera-interval") == []  # it forwards the mission's IMAGE_START_CAPTURE as it is


def test_the_refusal_says_what_is_missing_and_what_to_set() -> None:
    cam1 = camera_params(Flavour.ARDUPILOT, "camera")
    assert camera_problem("camera", cam1, {"CAM1_TYPE": 6.0}, True, 3.0) == ""
    assert camera_problem("relay", [], {}, False, 3.0) == ""
    assert camera_problem("camera", cam1, {"CAM1_TYPE": 0.0}, False) == (
        "the plan captures with a MAVLink camera (--capture camera) and CAM1_TYPE is 0 and no MAVLink camera was "
        "heard (no HEARTBEAT of MAV_TYPE_CAMERA from components 100-105): set CAM1_TYPE 6 (MAVLinkCamV2) "
        "and reboot, and connect the camera")
    assert camera_problem("camera-interval", cam1, {"CAM1_TYPE": 5.0}, True, 3.0) == (
        "the plan captures with a MAVLink camera (--capture camera-interval) and CAM1_TYPE is 5 (the older MAVLink "
        "camera type: it sends DO_DIGICAM_CONTROL, which a camera of the camera protocol does not take): set "
        "CAM1_TYPE 6 (MAVLinkCamV2) and reboot")
    assert "the vehicle has no CAM1_TYPE parameter" in camera_problem("camera", cam1, {}, True, 3.0)
    trig = camera_params(Flavour.PX4, "camera")
    assert camera_problem("camera", trig, {"TRIG_MODE": 4.0, "TRIG_INTERFACE": 4.0}, True, 3.0) == (
        "the plan captures with a MAVLink camera (--capture camera) and TRIG_INTERFACE is 4: set TRIG_INTERFACE 3 "
        "(MAVLink) and reboot")
    assert camera_problem("camera-interval", [], {}, False, 9.0).endswith("within 9 s): connect the camera")


def _heartbeat(component: int, mav_type: int, autopilot: int, base_mode: int, custom_mode: int) -> SimpleNamespace:
    return SimpleNamespace(get_type=lambda: "HEARTBEAT", get_srcComponent=lambda: component, type=mav_type,
                           autopilot=autopilot, base_mode=base_mode, custom_mode=custom_mode)


def test_a_cameras_heartbeat_is_heard_as_a_camera_not_as_the_autopilot() -> None:
    state = VehicleState(Flavour.ARDUPILOT)
    armed = mavlink.MAV_MODE_FLAG_SAFETY_ARMED | mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    state.take(_heartbeat(1, mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, armed, 3))  # AUTO
    state.take(_heartbeat(mavlink.MAV_COMP_ID_CAMERA, mavlink.MAV_TYPE_CAMERA, mavlink.MAV_AUTOPILOT_INVALID, 0, 0))
    assert state.armed is True and state.mode_name() == "AUTO"
    assert state.cameras == {mavlink.MAV_COMP_ID_CAMERA}
    state.take(_heartbeat(mavlink.MAV_COMP_ID_GIMBAL, mavlink.MAV_TYPE_GIMBAL, mavlink.MAV_AUTOPILOT_INVALID, 0, 0))
    assert state.armed is True and state.cameras == {mavlink.MAV_COMP_ID_CAMERA}


# ------------------------------------------------------------------------------------------- on the mock
def _plan(tmp_path: Path, capture: str, *extra: str) -> Path:
    area = tmp_path / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(plan_dir), "--quiet",
                 "--capture", capture, "--launch", LAUNCH, *extra]) == 0
    return plan_dir


@pytest.mark.flight
@pytest.mark.parametrize("flavour", ["ardupilot", "px4"])
def test_fly_refuses_a_vehicle_without_a_mavlink_camera_before_the_upload(tmp_path: Path, flavour: str) -> None:
    plan_dir = _plan(tmp_path, "camera", "--autopilot", flavour)
    mock = start_mock_fleet(plan_dir, SPEEDUP, flavour=flavour)  # its camera on the relay / PWM, no MAVLink camera
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=60.0, progress=False, time_scale=SPEEDUP, ready_s=20.0)
        held = mock.mission(1)
        uploads = mock.vehicle(1).uploads_completed
    finally:
        mock.stop()
    assert not result.ok
    lines = [p for p in result.doc["problems"] if "MAVLink camera" in p]
    wrong = ("CAM1_TYPE is 1" if flavour == "ardupilot" else "TRIG_INTERFACE is 4")
    fix = ("set CAM1_TYPE 6 (MAVLinkCamV2) and reboot" if flavour == "ardupilot"
           else "set TRIG_INTERFACE 3 (MAVLink) and reboot")
    assert lines == [f"uav1: the plan captures with a MAVLink camera (--capture camera) and {wrong} and no MAVLink "
                     f"camera was heard (no HEARTBEAT of MAV_TYPE_CAMERA from components 100-105): {fix}, and "
                     "connect the camera"]
    assert uploads == 0 and len(held) <= 1  # nothing uploaded (ArduPilot's home item only)
    assert not result.doc["drones"][0]["events"] or "armed" not in [e[1] for e in result.doc["drones"][0]["events"]]


@pytest.mark.flight
def test_fly_waits_for_the_camera_within_the_readiness_bound(tmp_path: Path) -> None:
    """CAM1_TYPE 6 but no camera on the link: refused once the readiness bound has passed, naming only the camera."""
    plan_dir = _plan(tmp_path, "camera-interval")
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    try:
        with mock._lock:
            mock.vehicle(1).params["CAM1_TYPE"] = 6.0
        result = fly(plan_dir, mock.client_url, timeout_s=60.0, progress=False, time_scale=SPEEDUP, ready_s=3.0)
        uploads = mock.vehicle(1).uploads_completed
    finally:
        mock.stop()
    lines = [p for p in result.doc["problems"] if "MAVLink camera" in p]
    assert len(lines) == 1 and "CAM1_TYPE" not in lines[0]
    assert lines[0].startswith("uav1: the plan captures with a MAVLink camera (--capture camera-interval) and no "
                               "MAVLink camera was heard")
    assert lines[0].endswith(": connect the camera") and uploads == 0


@pytest.mark.flight
def test_upload_refuses_a_camera_plan_in_one_line_and_uploads_it_with_the_camera(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan_dir = _plan(tmp_path, "camera")
    for camera in (False, True):
        mock = start_mock_fleet(plan_dir, SPEEDUP, mavlink_camera=camera)
        try:
            code = main(["upload", str(plan_dir / "uav1.plan"), "--sysid", "1", "--connect", mock.client_url,
                         "--quiet", "--timeout", "5"])
            uploads = mock.vehicle(1).uploads_completed
        finally:
            mock.stop()
        err = capsys.readouterr().err
        if camera:
            assert code == 0 and uploads >= 1 and err == ""
        else:
            assert code == 1 and uploads == 0
            assert err.startswith("missionplan upload: vehicle 1: the plan captures with a MAVLink camera "
                                  "(--capture camera) and CAM1_TYPE is 1 and no MAVLink camera was heard")
            assert err.endswith("set CAM1_TYPE 6 (MAVLinkCamV2) and reboot, and connect the camera\n")
            assert err.count("\n") == 1


@pytest.mark.flight
def test_a_relay_plan_checks_no_camera(tmp_path: Path) -> None:
    plan_dir = _plan(tmp_path, "relay")
    mock = start_mock_fleet(plan_dir, SPEEDUP)  # CAM1_TYPE 1, no MAVLink camera: what a relay plan needs
    try:
        code = main(["upload", str(plan_dir / "uav1.plan"), "--sysid", "1", "--connect", mock.client_url, "--quiet"])
    finally:
        mock.stop()
    assert code == 0
