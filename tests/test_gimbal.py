"""The camera gimbal: the item every mission carries before its first photo (per autopilot), `plan --gimbal-pitch`,
the mock's mount and its reports, and the geotags' pitch (the camera's, in OpenDroneMap's convention in geo.txt).

Mocks listen on 127.0.0.1 only; every wait is bounded."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavwp

from missionplan.bridge.formats.gimbal import gimbal_item, planned_pitch, quaternion_pitch_roll
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.formats.mission_items import (CMD_DO_GIMBAL_MANAGER_PITCHYAW, CMD_DO_MOUNT_CONTROL,
                                                      CMD_DO_SET_CAM_TRIGG_DIST, Flavour, Mission, MissionItem,
                                                      to_wire)
from missionplan.bridge.formats.px4_rules import item_result
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan
from missionplan.cli import main
from missionplan.flight.geotag import geo_txt, photos_csv
from missionplan.flight.ledger import LedgerPhoto
from missionplan.flight.photo_positions import camera_attitude
from missionplan.flight.record import DroneRecord

HOME = (45.0, 7.0, 200.0)
FAST = Timeouts(item_timeout=0.2, retries=10)
QUATERNION_DEG = 0.05  # a float32 quaternion holds -90 degrees of pitch to 0.015 (SITL: -89.99)


# ------------------------------------------------------------------------------------------- the item
def test_each_autopilot_gets_its_own_gimbal_command() -> None:
    ardupilot = gimbal_item(Flavour.ARDUPILOT)
    assert (ardupilot.command, ardupilot.param1, ardupilot.param3) == (CMD_DO_MOUNT_CONTROL, -90.0, 0.0)
    assert ardupilot.z == mavlink.MAV_MOUNT_MODE_MAVLINK_TARGETING  # param7: the angles of this command
    assert gimbal_item(Flavour.PX4) == ardupilot  # PX4 turns its gimbal for this one from a mission (measured)
    v2 = gimbal_item(Flavour.GENERIC, -60.0)  # the gimbal protocol v2 for any other autopilot
    assert (v2.command, v2.param1, v2.param2) == (CMD_DO_GIMBAL_MANAGER_PITCHYAW, -60.0, 0.0)
    # rates not used (NaN, as MAVLink says), no flags, the primary gimbal
    assert math.isnan(v2.param3) and math.isnan(v2.param4) and (v2.x, v2.z) == (0.0, 0.0)
    assert v2.frame == ardupilot.frame == mavlink.MAV_FRAME_MISSION
    for wire in to_wire(Mission([ardupilot, v2]), Flavour.PX4):
        assert item_result(wire) == mavlink.MAV_MISSION_ACCEPTED  # PX4 takes both in frame 2
    for pitch in (-91.0, 0.5, math.nan):
        with pytest.raises(ValueError):
            gimbal_item(Flavour.PX4, pitch)


def _plan(tmp_path: Path, *args: str) -> Path:
    out = tmp_path / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--quiet", *args]) == 0
    return out


@pytest.mark.parametrize("autopilot, command", [("ardupilot", CMD_DO_MOUNT_CONTROL), ("px4", CMD_DO_MOUNT_CONTROL)])
def test_every_mission_points_the_camera_before_its_first_photo(tmp_path, autopilot, command) -> None:
    out = _plan(tmp_path, "--autopilot", autopilot, "--gimbal-pitch", "-70")
    for k in (1, 2):
        items = read_mission_file(out / f"uav{k}.plan").mission.items
        first_photo = next(i for i, item in enumerate(items) if item.command == CMD_DO_SET_CAM_TRIGG_DIST)
        gimbal = [i for i, item in enumerate(items) if item.command in (CMD_DO_MOUNT_CONTROL,
                                                                         CMD_DO_GIMBAL_MANAGER_PITCHYAW)]
        assert gimbal == [first_photo - 1] and items[gimbal[0]].command == command
        assert planned_pitch(items) == -70.0
    report = json.loads((out / "report.json").read_text())
    assert report["settings"]["mission"]["gimbal_pitch_deg"] == -70.0  # a re-plan keeps it


def test_a_nadir_plan_records_no_gimbal_setting_and_its_waypoints_load_in_mavwp(tmp_path) -> None:
    out = _plan(tmp_path)
    report = json.loads((out / "report.json").read_text())
    assert "gimbal_pitch_deg" not in report["settings"]["mission"]  # the default, as before the gimbal item
    loader = mavwp.MAVWPLoader()
    loader.load(str(out / "uav1.waypoints"))
    mount = [loader.wp(i) for i in range(loader.count()) if loader.wp(i).command == mavlink.MAV_CMD_DO_MOUNT_CONTROL]
    assert len(mount) == 1 and (mount[0].param1, mount[0].z) == (-90.0, mavlink.MAV_MOUNT_MODE_MAVLINK_TARGETING)


@pytest.mark.parametrize("value", ["10", "-95", "nan"])
def test_a_gimbal_pitch_out_of_range_is_one_line(tmp_path, capsys, value) -> None:
    out = tmp_path / "run"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--gimbal-pitch", value]) == 2
    err = capsys.readouterr().err
    assert err == f"missionplan: --gimbal-pitch {value}: must be a gimbal pitch (-90 straight down), from -90 to 0 " \
                  "degrees\n"
    assert not out.exists()


def test_ardupilot_hands_the_mount_mode_back() -> None:
    # Measured on ArduCopter 4.7-dev SITL: DO_MOUNT_CONTROL comes back in frame 0 with its z (2) kept.
    sent = to_wire(Mission([gimbal_item(Flavour.ARDUPILOT)], home=HOME), Flavour.ARDUPILOT)
    from dataclasses import replace
    got = [sent[0], replace(sent[1], frame=mavlink.MAV_FRAME_GLOBAL)]
    assert compare_wire(sent, got, skip_home=True, flavour=Flavour.ARDUPILOT) == []


# ------------------------------------------------------------------------------------------- the geotags
def test_quaternion_pitch() -> None:
    half = math.radians(-90.0) / 2
    assert quaternion_pitch_roll([math.cos(half), 0.0, math.sin(half), 0.0]) == pytest.approx((-90.0, 0.0))
    # ArduCopter SITL's servo mount before any command: q = (0.9536, 0, -0.3012, 0)
    assert quaternion_pitch_roll([0.9535717964172363, 0.0, -0.30116569995880127, 0.0]) == (-35.1, 0.0)
    # and at -90 through float32 (SITL's -89.985), to a tenth of a degree
    assert quaternion_pitch_roll([0.70710677, 0.0, -0.70710677, 0.0]) == (-90.0, 0.0)
    assert quaternion_pitch_roll([math.nan] * 4) is None


def _record(wire_pitch: float | None) -> DroneRecord:
    rec = DroneRecord(id=1)
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=10.0)]
    if wire_pitch is not None:
        items.append(gimbal_item(Flavour.ARDUPILOT, wire_pitch))
    items.append(MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=2.0))
    rec.wire = to_wire(Mission(items, home=HOME), Flavour.ARDUPILOT)
    rec.add_photo(1, 100.0, HOME[0], HOME[1], 10.0, attitude=(2.0, -8.0, 45.0))  # the airframe's, tilted forward
    rec.add_photo(2, 200.0, HOME[0], HOME[1], 10.0, attitude=(1.0, -7.0, 46.0))
    return rec


def test_the_photos_pitch_is_the_cameras_not_the_airframes() -> None:
    planned = _record(-80.0)
    assert camera_attitude(planned, 1, 100.0) == (0.0, -80.0, 45.0)  # no report: as planned, level across
    planned.add_gimbal(150.0, -89.5, 0.3)  # the gimbal's own report counts from when it came
    assert camera_attitude(planned, 1, 100.0) == (0.0, -80.0, 45.0)
    assert camera_attitude(planned, 2, 200.0) == (0.3, -89.5, 46.0)
    assert camera_attitude(_record(None), 1, 100.0) == (None, None, 45.0)  # no gimbal item, no report: unknown


def _photo(pitch: float | None) -> LedgerPhoto:
    return LedgerPhoto(plan=".", flight=1, vehicle=1, img_idx=7, time=0.0, lat=45.0, lon=7.0, alt_amsl=230.0, alt_rel=30.0,
                       roll=0.0, pitch=pitch, yaw=90.0, source="camera")


def test_geo_txt_writes_odms_pitch_and_the_csv_mavlinks() -> None:
    # OpenDroneMap: pitch 0 is a nadir camera, 90 one looking forward (opendm/photo.py); MAVLink: -90 is nadir.
    assert geo_txt([_photo(-90.0)]).splitlines()[1].split()[4:7] == ["90.00", "0.00", "0.00"]
    assert geo_txt([_photo(-60.0)]).splitlines()[1].split()[5] == "30.00"
    assert geo_txt([_photo(None)]).splitlines()[1].split()[5] == "0.00"  # unknown: 0, as ODM asks
    row = photos_csv([_photo(-90.0)]).splitlines()[1].split(",")
    assert row[10] == "-90.00"


# ------------------------------------------------------------------------------------------- the mock's mount
def _command(link: Link, command: int, *params: float) -> int | None:
    return link.command_long(1, command, list(params), time.monotonic() + 3.0)


def _gimbal_reports(flavour: Flavour, pitch: float, sitl_like: bool = False) -> list[Any]:
    """Fly a take-off and the gimbal item on a mock of this flavour, asking for GIMBAL_DEVICE_ATTITUDE_STATUS;
    every gimbal report it sent (bounded)."""
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=5.0),
             gimbal_item(flavour, pitch),
             MissionItem(mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1])]
    with MockAutopilot("udpin:127.0.0.1:0", flavour=flavour, speedup=20.0, homes={1: HOME}, request_interval=0.02,
                       upload_timeout=2.0, sitl_like=sitl_like) as mock:
        backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
        try:
            assert upload_plan(backend, [Mission(items, home=HOME)], verify=True).verified
            link = backend.link
            assert _command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                            mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS, 100_000.0) == mavlink.MAV_RESULT_ACCEPTED
            assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0) == mavlink.MAV_RESULT_ACCEPTED
            assert _command(link, mavlink.MAV_CMD_MISSION_START, 0.0, 0.0) == mavlink.MAV_RESULT_ACCEPTED
            reports: list[Any] = []
            deadline = time.monotonic() + 8.0
            while (msg := link.recv(deadline)) is not None:
                if msg.get_type() in ("GIMBAL_DEVICE_ATTITUDE_STATUS", "MOUNT_ORIENTATION"):
                    reports.append(msg)
                    angles = quaternion_pitch_roll(list(msg.q)) if hasattr(msg, "q") else None
                    if angles is not None and abs(angles[0] - pitch) < QUATERNION_DEG:
                        deadline = min(deadline, time.monotonic() + 0.3)  # and what is sent with it
            return reports
        finally:
            backend.close()


@pytest.mark.flight
@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4])
def test_the_mocks_mount_turns_and_reports_as_the_sitls_do(flavour) -> None:
    reports = _gimbal_reports(flavour, -90.0)
    status = [m for m in reports if m.get_type() == "GIMBAL_DEVICE_ATTITUDE_STATUS"]
    assert status and quaternion_pitch_roll(list(status[-1].q)) == pytest.approx((-90.0, 0.0), abs=QUATERNION_DEG)
    last = status[-1]
    assert last.get_srcComponent() == 1  # the autopilot stands in for the gimbal device, on both SITLs
    if flavour is Flavour.ARDUPILOT:  # ArduCopter 4.7: gimbal device 1, NaN rates, yaw in the vehicle frame
        assert last.gimbal_device_id == 1 and math.isnan(last.angular_velocity_y)
        assert last.flags & mavlink.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
        assert not [m for m in reports if m.get_type() == "MOUNT_ORIENTATION"]
    else:  # PX4 v1.15: gimbal device 0, zero rates, MOUNT_ORIENTATION beside it
        assert last.gimbal_device_id == 0 and last.angular_velocity_y == 0.0
        assert any(m.get_type() == "MOUNT_ORIENTATION" for m in reports)


@pytest.mark.flight
def test_a_sitl_like_mock_without_a_mount_reports_none() -> None:
    assert _gimbal_reports(Flavour.ARDUPILOT, -90.0, sitl_like=True) == []  # MNT1_TYPE 0, as SITL starts
