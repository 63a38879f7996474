"""PX4 missions without PX4: missionplan.bridge.formats.px4_rules's rules, the mock's PX4 flavour that follows them, the
firmwareType check of `upload` and `plan --autopilot` (what PX4 SIH showed: docs/px4-missions.md)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    WireItem,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_items
from missionplan.bridge.formats.missionfile import (FirmwareMismatch, PlanFile, check_firmware, read_plan, write_plan,
                                                    write_waypoints)
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.formats.px4_rules import (GEOFENCE_WITHOUT_HOME, START_DENIED, fence_problems, home_in_fence,
                                                  item_result, px4_millimetres, px4_stored, px4_yaw, start_refusals)
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan
from missionplan.cli import main

HOME = (45.4641, 9.1891, 120.0)
FAST = Timeouts(item_timeout=0.3, retries=4)


def _w(frame: int, command: int, mission_type: int = 0, **kw: float) -> WireItem:
    fields = dict(param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=454641000, y=91891000, z=10.0)
    fields.update(kw)
    return WireItem(0, frame, command, 0, 1, fields["param1"], fields["param2"], fields["param3"], fields["param4"],
                    int(fields["x"]), int(fields["y"]), fields["z"], mission_type)


def _near_mission(n: int = 5) -> Mission:
    lat, lon = HOME[:2]
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=10.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=0.5, x=lat + i * 1e-5, y=lon,
                          z=10.0) for i in range(1, n)]
    return Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=HOME)


# ------------------------------------------------------------------------------------ the rules

def test_px4_takes_positions_in_global_frames_and_the_rest_in_frame_2() -> None:
    assert [item_result(_w(f, 16)) for f in (0, 1, 2, 3, 5, 6, 10, 11)] == [0, 2, 3, 0, 0, 0, 2, 2]
    assert item_result(_w(2, 206)) == 0 and item_result(_w(3, 206)) == 3  # DO_* only in frame 2
    assert item_result(_w(2, 20)) == 0 and item_result(_w(3, 20)) == 3    # RTL too
    assert item_result(_w(3, 999)) == 3 and item_result(_w(3, 5100)) == 1
    assert item_result(_w(0, 5001, mission_type=1)) == 0 and item_result(_w(3, 5100, mission_type=2)) == 0


def test_photo_altitudes_are_rounded_as_px4_rounds_them_in_float32() -> None:
    # 209.99999237 m (what a float32 keeps of 209.9999924) times 1e3f is 210000.0f in float32; a double
    # product truncates to 209999, one millimetre off PX4's CAMERA_IMAGE_CAPTURED.
    assert int(209.9999924 * 1000) == 209999 and px4_millimetres(209.9999924) == 210000
    assert px4_millimetres(10.0) == 10000 and px4_millimetres(-1.5) == -1500


def test_px4_stored_form_and_verify_accept_exactly_what_px4_changes() -> None:
    sent = _w(3, 16, param1=1.7, param2=0.06, param3=0.5, param4=7.0)
    got = px4_stored(sent)
    assert (got.frame, got.param3, got.param1, got.param2) == (6, 0.0, 1.7, 0.06)
    assert got.param4 == pytest.approx(6.9999995, abs=1e-6) and px4_yaw(-90.0) == pytest.approx(270.0, abs=1e-4)
    assert math.isnan(px4_yaw(math.nan))
    assert compare_items(sent, got, Flavour.PX4) == []
    # What PX4 does not change must come back as sent: verify names it.
    assert compare_items(sent, got.__class__(**{**got.__dict__, "param1": 1.0}), Flavour.PX4) == [
        "param1 sent 1.7, vehicle has 1"]
    # The pass radius is PX4's to drop, not ArduPilot's rule applied to PX4 (param2 kept).
    assert compare_items(sent, got.__class__(**{**got.__dict__, "param2": 0.0}), Flavour.PX4) != []
    fence = px4_stored(_w(0, 5001, mission_type=1, z=7.0))
    assert (fence.frame, fence.z, fence.autocontinue) == (5, 0.0, 0)


def test_start_refusals_are_the_first_waypoint_distance_and_the_fence_must_hold_home() -> None:
    near = to_wire(_near_mission(), Flavour.PX4)
    assert start_refusals(near, HOME[:2]) == []
    far = start_refusals(near, (HOME[0] + 0.02, HOME[1]))  # 2.2 km south of the mission
    assert len(far) == 1 and far[0].startswith("First waypoint too far away: 22") and far[0].endswith("m, 900 max")
    assert start_refusals(near, (HOME[0] + 0.02, HOME[1]), dist_1wp=0) == []  # 0 turns the check off
    square = [_w(0, 5001, mission_type=1, param1=4, x=454640000 + dx, y=91890000 + dy)
              for dx, dy in ((0, 0), (0, 3000), (3000, 3000), (3000, 0))]
    assert home_in_fence(square, *HOME[:2]) and not home_in_fence(square, HOME[0] + 0.001, HOME[1])
    assert fence_problems(square, (HOME[0] + 0.001, HOME[1])) == [GEOFENCE_WITHOUT_HOME]
    assert fence_problems(square, HOME[:2]) == [] and fence_problems([], (0.0, 0.0)) == []
    excluded = [_w(0, 5004, mission_type=1, param1=50.0)]  # an exclusion circle round home
    assert not home_in_fence(excluded, *HOME[:2])


# ---------------------------------------------------------------------------- the mock's PX4

def _texts_and_ack(link: Link, sysid: int, command: int) -> tuple[int | None, list[str]]:
    texts: list[str] = []
    deadline = time.monotonic() + 2.0
    link.mav.command_long_send(sysid, 1, command, 0, 0, 0, 0, 0, 0, 0, 0)
    while (msg := link.recv(deadline)) is not None:
        if msg.get_type() == "STATUSTEXT":
            texts.append(str(msg.text))
        if msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
            return int(msg.result), texts
    return None, texts


def test_mock_px4_asks_legacy_first_stores_like_px4_and_refuses_a_start_like_px4() -> None:
    with MockAutopilot(sysids=[3], flavour="px4", homes={3: HOME}, request_interval=0.02) as mock:
        with PymavlinkBackend(mock.client_url, 3, timeouts=FAST, connect_timeout=3) as b:
            link = b.link
            link.mav.mission_count_send(3, 1, 1, 0)
            deadline = time.monotonic() + 2
            first = None
            while first is None and (msg := link.recv(deadline)) is not None:
                if msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                    first = msg.get_type()
            assert first == "MISSION_REQUEST"  # PX4: legacy until the ground station speaks *_INT
            assert upload_plan(b, [_near_mission()]).verified
            held = mock.mission(3)
            assert held[0].frame == 6 and held[0].current == 0 and held[-1].frame == 2
            down = b.download(MissionType.MISSION)
            assert down[0].current == 1 and all(it.current == 0 for it in down[1:])  # the active item
            # A first waypoint 2.2 km away: the upload is refused before anything is sent ...
            far = Mission([MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0] + 0.02, y=HOME[1],
                                       z=10.0)], home=HOME)
            with pytest.raises(Exception) as err:
                upload_plan(b, [far])
            assert "would refuse to start this mission" in str(err.value) and "First waypoint too far away" in str(
                err.value)
            assert mock.mission(3) == held
            # ... and when it gets there anyway (a raw upload), the mock refuses the start as PX4 does.
            b.upload(0, to_wire(far, Flavour.PX4))
            result, texts = _texts_and_ack(link, 3, mavlink.MAV_CMD_MISSION_START)
            assert result == mavlink.MAV_RESULT_DENIED and START_DENIED in texts


def test_mock_px4_says_when_a_fence_leaves_its_home_out() -> None:
    fence = Mission([MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=4, x=HOME[0] + 0.01 + dx,
                                 y=HOME[1] + dy)
                     for dx, dy in ((0, 0), (0, 0.01), (0.01, 0.01), (0.01, 0))], MissionType.FENCE)
    with MockAutopilot(sysids=[3], flavour="px4", homes={3: HOME}, request_interval=0.02) as mock:
        with PymavlinkBackend(mock.client_url, 3, timeouts=FAST, connect_timeout=3) as b:
            b.upload(1, to_wire(fence, Flavour.PX4))
            texts = []
            deadline = time.monotonic() + 1.0
            while (msg := b.link.recv(deadline)) is not None:
                if msg.get_type() == "STATUSTEXT":
                    texts.append(str(msg.text))
            assert GEOFENCE_WITHOUT_HOME in texts
            assert mock.vehicle(3).start_refusals() == []  # PX4 still starts the mission (unfenced)


# --------------------------------------------------------------------- firmwareType and --autopilot

def test_check_firmware_refuses_only_the_other_autopilot(tmp_path: Path) -> None:
    plan = PlanFile(mission=_near_mission(), firmware=Flavour.ARDUPILOT)
    check_firmware(plan, "a.plan", Flavour.ARDUPILOT)
    check_firmware(plan, "a.plan", Flavour.GENERIC)
    check_firmware(PlanFile(mission=_near_mission()), "a.waypoints", Flavour.PX4)  # no firmware named
    with pytest.raises(FirmwareMismatch) as err:
        check_firmware(plan, "a.plan", Flavour.PX4, 4)
    assert str(err.value) == ("a.plan: written for ArduPilot (firmwareType 3), but vehicle 4 is PX4: plan it again "
                              "with `missionplan plan --autopilot px4` (docs/px4-missions.md)")


@pytest.mark.parametrize("written, flavour", [(Flavour.ARDUPILOT, "px4"), (Flavour.PX4, "ardupilot")])
def test_upload_of_a_plan_for_the_other_autopilot_exits_2_with_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], written: Flavour, flavour: str) -> None:
    path = tmp_path / "m.plan"
    write_plan(path, PlanFile(mission=_near_mission(), firmware=written))
    with MockAutopilot(sysids=[2], flavour=flavour, homes={2: HOME}, request_interval=0.02) as mock:
        code = main(["upload", str(path), "--sysid", "2", "--connect", mock.client_url, "--timeout", "3", "--quiet"])
        assert code == 2 and mock.vehicle(2).uploads_completed == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "written for" in err[0] and f"--autopilot {flavour}" in err[0]


def test_upload_to_px4_from_the_wrong_place_exits_1_and_says_why(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "m.plan"
    write_plan(path, PlanFile(mission=_near_mission(), firmware=Flavour.PX4))
    montreal = (45.4671160, -73.7578370, 20.0)  # PX4 SIH's default home
    with MockAutopilot(sysids=[2], flavour="px4", homes={2: montreal}, request_interval=0.02) as mock:
        code = main(["upload", str(path), "--sysid", "2", "--connect", mock.client_url, "--timeout", "3", "--quiet"])
        assert code == 1 and mock.vehicle(2).uploads_completed == 0
    err = capsys.readouterr().err.strip()
    assert "would refuse to start this mission" in err and "First waypoint too far away: 61" in err


def test_plan_autopilot_px4_writes_firmware_12_and_no_waypoints(tmp_path: Path) -> None:
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "p"), "--quiet",
                 "--autopilot", "px4"]) == 0
    ardupilot, px4 = read_plan(tmp_path / "a" / "uav1.plan"), read_plan(tmp_path / "p" / "uav1.plan")
    assert ardupilot.firmware is Flavour.ARDUPILOT and px4.firmware is Flavour.PX4
    assert [it.params for it in ardupilot.mission.items] == [it.params for it in px4.mission.items]
    assert (tmp_path / "a" / "uav1.waypoints").exists() and not (tmp_path / "p" / "uav1.waypoints").exists()
    report = json.loads((tmp_path / "p" / "report.json").read_text())
    assert "uav1.waypoints" not in report["files"] and "uav1.plan" in report["files"]
    # Every item of the PX4 plan is one PX4 accepts, and its launch lies inside its fence.
    wire = to_wire(px4.mission, Flavour.PX4)
    assert [item_result(it) for it in wire] == [0] * len(wire)
    assert start_refusals(wire, px4.mission.home[:2]) == []
    assert fence_problems(to_wire(px4.fence, Flavour.PX4), px4.mission.home[:2]) == []
    # Re-planning for PX4 where ArduPilot files were removes the stale .waypoints.
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "a"), "--quiet",
                 "--autopilot", "px4"]) == 0
    assert not (tmp_path / "a" / "uav1.waypoints").exists()
    write_waypoints(tmp_path / "x.waypoints", px4.mission)  # still writable by hand for a PX4 plan


@pytest.mark.flight
def test_fly_refuses_a_plan_written_for_ardupilot_on_px4_vehicles(tmp_path: Path) -> None:
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet

    plan_dir = tmp_path / "a"
    assert main(["plan", "--map", "leonardo", "--uavs", "1", "--out", str(plan_dir), "--quiet"]) == 0  # ArduPilot
    mock = start_mock_fleet(plan_dir, 10.0, flavour="px4")
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=30.0, progress=False, time_scale=10.0)
    finally:
        mock.stop()
    assert not result.ok and mock.vehicle(1).uploads_completed == 0 and not mock.vehicle(1).flight.state.armed
    assert any("written for ArduPilot (firmwareType 3), but vehicle 1 is PX4" in p for p in result.problems), \
        result.problems
