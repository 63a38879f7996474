"""plan --capture: the camera protocol's mission items, photo counts and capture records.

relay (the default) and camera missions are the same items (DO_SET_CAM_TRIGG_DIST; with a MAVLink camera the
autopilot forwards each trigger to it); camera-interval has one IMAGE_START_CAPTURE (interval = trigger distance /
speed, count 0) where the survey starts and one IMAGE_STOP_CAPTURE after its last waypoint, and predicts as many
photos as planned_photos places. The mock's MAVLink camera (bridge/sim/mock_camera.py) reports each photo with
CAMERA_IMAGE_CAPTURED from MAV_COMP_ID_CAMERA; with --capture camera the flight judge takes those (capture_result
1 only, a failed capture counted apart), not the autopilot's CAMERA_FEEDBACK. Mocks listen on 127.0.0.1 only."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import (CMD_DO_SET_CAM_TRIGG_DIST, CMD_IMAGE_START_CAPTURE,
                                                      CMD_IMAGE_STOP_CAPTURE, Flavour, to_wire)
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.formats.px4_rules import item_result
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.sim.mock_camera import CAMERA_COMPONENT_ID, MockCamera
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.flight.record import DroneRecord
from missionplan.flight.telemetry_record import TelemetryRecorder
from missionplan.mission.drone_missions import MissionSettings, build_mission
from missionplan.mission.layers import planned_photos

M_PER_DEG = 111_000.0
SPEEDUP = 10.0
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1904")


def _mission(capture: str, resumes: bool = False, route: tuple[tuple[float, float], ...] = ((0, 30), (20, 30), (20, 0))):
    settings = MissionSettings(altitude_m=30.0, footprint_m=45.0, capture=capture)  # a photo every 5 m at 5 m/s
    metres = np.array(route, dtype=float)
    latlon = np.column_stack([45.0 + metres[:, 0] / M_PER_DEG, 7.0 + metres[:, 1] / M_PER_DEG])
    built = build_mission(0, (45.0, 7.0), latlon, metres, np.zeros(2), settings, resumes=resumes)
    placed = planned_photos(built.mission.items, settings.trigger_distance_m,
                            lambda lat, lon: np.array([(lat - 45.0) * M_PER_DEG, (lon - 7.0) * M_PER_DEG]))
    return settings, built, placed


def test_camera_missions_are_the_relays_items() -> None:
    _, relay, _ = _mission("relay")
    _, camera, _ = _mission("camera")
    assert camera.mission.items == relay.mission.items and camera.photos == relay.photos


@pytest.mark.parametrize("resumes", [False, True])
def test_camera_interval_starts_at_the_survey_and_stops_after_its_last_waypoint(resumes: bool) -> None:
    settings, built, placed = _mission("camera-interval", resumes=resumes)
    commands = [item.command for item in built.mission.items]
    assert CMD_DO_SET_CAM_TRIGG_DIST not in commands
    assert commands.count(CMD_IMAGE_START_CAPTURE) == commands.count(CMD_IMAGE_STOP_CAPTURE) == 1
    start = built.mission.items[commands.index(CMD_IMAGE_START_CAPTURE)]
    assert start.param2 == pytest.approx(settings.trigger_distance_m / settings.speed_m_s) == 1.0
    assert start.param3 == 0.0  # until the stop
    # At once after the speed and gimbal items (the survey starts at the launch point), or after the first
    # waypoint of a resumed sortie; the stop right after the last waypoint.
    assert commands.index(CMD_IMAGE_START_CAPTURE) == (4 if resumes else 3)
    assert commands.index(CMD_IMAGE_STOP_CAPTURE) == len(commands) - 2
    # Survey 30 + 20 + 30 m (resumed: 20 + 30 m) at a photo every 5 m, plus the one at the start.
    assert built.photos == len(placed) == (11 if resumes else 17)


def test_camera_interval_items_pass_the_file_writers_and_px4s_checks(tmp_path: Path) -> None:
    plan_dir = tmp_path / "plan"
    area = tmp_path / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(plan_dir), "--quiet",
            "--capture", "camera-interval", "--launch", LAUNCHES[0]]
    assert main(args) == 0
    report = json.loads((plan_dir / "report.json").read_text())
    assert report["settings"]["mission"]["capture"] == "camera-interval"
    for name in ("uav1.plan", "uav1.waypoints"):
        items = read_mission_file(plan_dir / name).mission.items
        assert [i.command for i in items].count(CMD_IMAGE_START_CAPTURE) == 1, name
    wire = to_wire(read_mission_file(plan_dir / "uav1.plan").mission, Flavour.PX4)
    assert all(item_result(item) == mavlink.MAV_MISSION_ACCEPTED for item in wire)


def test_without_capture_report_json_has_no_capture_key(tmp_path: Path) -> None:
    area = tmp_path / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    assert main(["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(tmp_path / "p"),
                 "--quiet", "--launch", LAUNCHES[0]]) == 0
    assert "capture" not in json.loads((tmp_path / "p" / "report.json").read_text())["settings"]["mission"]


# ------------------------------------------------------------------------------------------- the recorder
class _Msg(SimpleNamespace):
    def get_type(self) -> str:
        return self.kind

    def get_srcSystem(self) -> int:  # noqa: N802 (pymavlink's name)
        return 1

    def get_srcComponent(self) -> int:  # noqa: N802
        return self.component


def _captured(index: int, component: int = CAMERA_COMPONENT_ID, result: int = 1, url: str = "") -> _Msg:
    return _Msg(kind="CAMERA_IMAGE_CAPTURED", component=component, image_index=index, capture_result=result,
                lat=450000000 + index, lon=70000000, alt=130000, relative_alt=10000, q=[1.0, 0.0, 0.0, 0.0],
                file_url=url)


def _feedback(index: int) -> _Msg:
    return _Msg(kind="CAMERA_FEEDBACK", component=1, img_idx=index, lat=1, lng=1, alt_rel=10.0, alt_msl=130.0,
                roll=0.0, pitch=0.0, yaw=0.0, completed_captures=index)


def _record(camera_records: bool, messages: list[_Msg]) -> tuple[DroneRecord, list[object]]:
    rec, published = DroneRecord(id=1), []
    recorder = TelemetryRecorder(rec, SimpleNamespace(flavour=Flavour.ARDUPILOT), set(), published.append,
                                 camera_records=camera_records)
    for msg in messages:
        recorder.take(msg)
    return rec, published


def test_with_a_mavlink_camera_the_cameras_records_are_the_photos() -> None:
    messages = [_feedback(1), _captured(0, url="DCIM/IMG_0000.JPG"), _feedback(2), _captured(1, result=0),
                _captured(0, component=1), _feedback(3), _captured(2, url="DCIM/IMG_0002.JPG")]
    rec, published = _record(True, messages)
    assert [p.index for p in published] == [0, 2]  # the camera's, capture_result 1; not the autopilot's own
    assert rec.failed_captures == 1 and rec.captures == 3
    assert [p.file_url for p in published] == ["DCIM/IMG_0000.JPG", "DCIM/IMG_0002.JPG"]  # journaled with the photo
    # Without the camera mode both counts would be taken as one: the autopilot's img_idx 1, 2 and the camera's 0.
    _, relay = _record(False, messages[:3])
    assert [p.index for p in relay] == [1, 0, 2]


# ------------------------------------------------------------------------------------------- the mock camera
class _Sent:
    """A stand-in pymavlink encoder: what the camera sends, by message name."""

    def __init__(self) -> None:
        self.sent: list[tuple[str, tuple[object, ...]]] = []

    def __getattr__(self, name: str):
        return lambda *args: self.sent.append((name.removesuffix("_send"), args))


def _command(command: int, *params: float, component: int = CAMERA_COMPONENT_ID) -> _Msg:
    padded = [*params, *([0.0] * (7 - len(params)))]
    return _Msg(kind="COMMAND_LONG", component=1, target_system=1, target_component=component, command=command,
                **{f"param{i + 1}": v for i, v in enumerate(padded)})


def test_the_mock_camera_answers_as_a_camera_of_the_protocol() -> None:
    clock = [100.0]
    mav = _Sent()
    camera = MockCamera(mav, 1, clock=lambda: clock[0])
    camera.tick()
    assert mav.sent[0][0] == "heartbeat" and mav.sent[0][1][0] == mavlink.MAV_TYPE_CAMERA
    camera.handle(_command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION))
    assert [name for name, _ in mav.sent[1:]] == ["camera_information", "command_ack"]
    camera.handle(_Msg(kind="GLOBAL_POSITION_INT", component=1, lat=450000000, lon=70000000, alt=130000,
                       relative_alt=10000))
    camera.handle(_command(mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 2.0, 0))  # every 2 s until stopped
    for now in (101.0, 102.0, 103.0, 104.0):
        clock[0] = now
        camera.tick()
    camera.handle(_command(mavlink.MAV_CMD_IMAGE_STOP_CAPTURE))
    clock[0] = 110.0
    camera.tick()
    camera.handle(_command(mavlink.MAV_CMD_DO_DIGICAM_CONTROL, 0, 0, 0, 0, 1, component=0))  # PX4's, broadcast
    assert [image.image_index for image in camera.images] == [0, 1, 2]  # at 100, 102, 104 s
    assert all(image.capture_result == 1 and image.file_url for image in camera.images)


# ------------------------------------------------------------------------------------------- a mock flight
@pytest.mark.flight
def test_fly_judges_a_camera_plan_by_the_cameras_records(tmp_path: Path) -> None:
    area = tmp_path / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    plan_dir = tmp_path / "plan"
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(plan_dir), "--quiet",
            "--capture", "camera"]
    for point in LAUNCHES:
        args += ["--launch", point]
    assert main(args) == 0
    failures = (3,)
    mock = start_mock_fleet(plan_dir, SPEEDUP, mavlink_camera=True, camera_failures=failures)
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=120.0, progress=False, time_scale=SPEEDUP,
                     telemetry_hz=25.0)
    finally:
        mock.stop()
    doc = json.loads((plan_dir / "flight.json").read_text())
    assert result.ok, doc["problems"]
    assert doc["photos_from"] == "camera" and doc["coverage"] >= 99.0
    for row in doc["drones"]:
        camera = mock.vehicle(row["id"]).mavlink_camera
        taken = [image for image in camera.images if image.capture_result == 1]
        # The camera's photos (its image_index from 0), one fewer than the autopilot triggered: index 3 failed.
        assert row["photos"] == len(taken) == len(camera.images) - len(failures), row
    shutil.rmtree(plan_dir)


def test_a_camera_peer_leaves_this_process_reading_ardupilots_own_messages() -> None:
    """pymavlink's dialect belongs to the whole process: a camera peer that opened its link with the common dialect
    made every link opened after it drop EKF_STATUS_REPORT and CAMERA_FEEDBACK (ArduPilot's own messages) as
    unknown, so readiness waited for an EKF report and photo recovery found no CAMERA_FEEDBACK."""
    from pymavlink import mavutil

    from missionplan.bridge.sim.mock_camera import CameraPeer
    from missionplan.testing.loopback import free_udp_port

    dialect = mavutil.current_dialect
    with CameraPeer(f"udpin:127.0.0.1:{free_udp_port()}", 1):
        later = mavutil.mavlink_connection(f"udpin:127.0.0.1:{free_udp_port()}", source_system=255)
        try:
            sent = mavlink.MAVLink_ekf_status_report_message(0x1F, 0.1, 0.1, 0.1, 0.1, 0.0).pack(mavlink.MAVLink(None, 1, 1))
            parsed = later.mav.parse_char(sent)
        finally:
            later.close()
    assert mavutil.current_dialect == dialect
    assert parsed is not None and parsed.get_type() == "EKF_STATUS_REPORT" and parsed.flags == 0x1F
