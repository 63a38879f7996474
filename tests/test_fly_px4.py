"""`fly` on PX4, against the mock's PX4 flavour made like PX4 SIH (and the pieces it rests on).

PX4 reports photos with CAMERA_IMAGE_CAPTURED (its camera_feedback module; no CAMERA_FEEDBACK), its
landed state with EXTENDED_SYS_STATE, refuses arming with TEMPORARILY_REJECTED until ready, sends long
STATUSTEXTs in chunks, packs main / sub mode in custom_mode, and gives no MISSION_ITEM_REACHED for a
final RTL item. The SITL fleet test (sitl_tests/test_fleet_px4.py) checks the same against real PX4 SIH.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest

from missionplan.bridge.flight_models import copter_model as cm
from missionplan.bridge.flight_models import px4_model as pm
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.formats.px4_rules import reported_items
from missionplan.bridge.link.readiness import VehicleState, px4_mode, stream_rates
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.flight.phases import PX4_LANDED_STATES, landed_states, reached_items, reached_navigation_items
from missionplan.mission.timeline import FlightModel, planned_seconds

SPEEDUP = 10.0
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1898", "45.4641,9.1904")


class _Msg(SimpleNamespace):
    def get_type(self) -> str:
        return self.kind


def _text(text: str, text_id: int = 0, chunk: int = 0) -> _Msg:
    return _Msg(kind="STATUSTEXT", text=text, id=text_id, chunk_seq=chunk, severity=2)


def test_a_chunked_statustext_is_said_once_whole() -> None:
    state = VehicleState(Flavour.PX4)
    first = "Arming denied: Resolve system health failures firs"  # 50 characters: PX4 continues it
    state.take(_text(first, 7, 0))
    assert state.new_texts == []  # waits for the rest
    state.take(_text("t\t", 7, 1))
    state.take(_text("Preflight Fail: vertical velocity unstable", 8, 0))
    assert state.new_texts == ["Arming denied: Resolve system health failures first",
                               "Preflight Fail: vertical velocity unstable"]


def test_a_full_chunk_whose_rest_never_comes_is_still_said() -> None:
    state = VehicleState(Flavour.PX4)
    state.take(_text("x" * 50, 3, 0))
    state.take(_text("Takeoff detected", 4, 0))  # another text: the first one is complete as it is
    assert state.new_texts == ["x" * 50, "Takeoff detected"]


def test_px4_modes_are_named_from_main_and_sub_mode() -> None:
    state = VehicleState(Flavour.PX4)
    for custom, name in ((px4_mode(4, 3), "HOLD"), (px4_mode(4, 4), "MISSION"), (px4_mode(4, 5), "RTL"),
                         (px4_mode(4, 6), "LAND"), (px4_mode(4, 2), "TAKEOFF"), (px4_mode(3), "POSCTL")):
        state.custom_mode = custom
        assert state.mode_name() == name
    assert px4_mode(4, 4) == 0x0404_0000  # as SIH's HEARTBEAT says in a mission


def test_px4_streams_ask_for_the_landed_state_not_the_ardupilot_ekf() -> None:
    px4, ardupilot = stream_rates(10.0, Flavour.PX4), stream_rates(10.0, Flavour.ARDUPILOT)
    landed, ekf = mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT
    assert landed in px4 and ekf not in px4
    assert ekf in ardupilot and landed not in ardupilot


def test_the_px4_model_turns_before_a_leg_and_lands_in_three_bands() -> None:
    p = pm.Px4Params()
    up = pm.takeoff((0.0, 0.0, 0.0), 20.0, p)
    assert cm.total_time(up) == pytest.approx(pm.PX4_SPOOL_S + 20.0 / 1.5 + 1.5 / 4.0 + pm.PX4_TAKEOFF_SETTLE_S,
                                              abs=0.01)
    straight, heading = pm.legs((0.0, 0.0, 20.0), [(50.0, 0.0, 20.0)], 5.0, p, heading=0.0)
    turned, _ = pm.legs((50.0, 0.0, 20.0), [(50.0, 50.0, 20.0)], 5.0, p, heading)
    assert [m.kind for m in straight] == ["leg"] and [m.kind for m in turned] == ["turn", "leg"]
    assert turned[0].duration == pytest.approx(90.0 / 45.0 * pm.PX4_TURN_FACTOR)
    # The first leg (heading unknown to the plan) counts an average turn; a waypoint within half a
    # metre is reached where the vehicle is.
    first, _ = pm.legs((0.0, 0.0, 20.0), [(0.2, 0.1, 20.0), (0.0, 50.0, 20.0)], 5.0, p)
    assert [m.kind for m in first] == ["turn", "leg"] and first[0].duration == turned[0].duration
    down = pm.landing((0.0, 0.0, 20.0), 0.0, p)
    assert [m.kind for m in down] == ["descent", "descent", "land", "touchdown"]
    assert [round(m.distance, 6) for m in down[:3]] == [10.0, 5.0, 5.0]
    # Near home RTL does not climb; farther it climbs into the cone, up to RTL_RETURN_ALT.
    assert pm.return_altitude((5.0, 0.0, 20.0), (0.0, 0.0, 0.0), p) == 20.0
    assert pm.return_altitude((100.0, 0.0, 20.0), (0.0, 0.0, 0.0), p) == 30.0


def test_the_timeline_times_a_px4_plan_with_the_px4_model() -> None:
    route = [[0.0, 40.0], [40.0, 40.0], [40.0, 0.0], [0.0, 0.0]]
    px4 = planned_seconds([0.0, 0.0], route, 20.0, "rtl", FlightModel(5.0, 1.0, px4=pm.Px4Params()))
    ardupilot = planned_seconds([0.0, 0.0], route, 20.0, "rtl", FlightModel(5.0, 1.0))
    expected = cm.total_time(pm.flight((0.0, 0.0, 0.0), 20.0, [(0.0, 40.0, 20.0), (40.0, 40.0, 20.0),
                                                               (40.0, 0.0, 20.0), (0.0, 0.0, 20.0)], "rtl", 5.0,
                                       pm.Px4Params()))
    assert px4 == pytest.approx(expected) and not math.isclose(px4, ardupilot, rel_tol=0.02)


@pytest.fixture(scope="module")
def milan_plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("milan")
    area = out / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(out / "plan"), "--quiet",
            "--autopilot", "px4"]
    for point in LAUNCHES:
        args += ["--launch", point]
    assert main(args) == 0
    return out / "plan"


def _fly_px4_mocks(plan_dir: Path, cameras: bool = True, photos_from_track: bool = False, **options: object):
    mock = start_mock_fleet(plan_dir, SPEEDUP, flavour="px4", cameras=cameras, **options)
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=120.0, progress=False, time_scale=SPEEDUP,
                     telemetry_hz=25.0, photos_from_track=photos_from_track)
    finally:
        mock.stop()
    return result, json.loads((plan_dir / "flight.json").read_text()), mock


@pytest.mark.flight
def test_fly_judges_a_px4_fleet_by_its_camera_image_captured_reports(milan_plan, tmp_path) -> None:
    plan_dir = Path(shutil.copytree(milan_plan, tmp_path / "plan"))
    # Not ready for 20 simulated seconds: arming is refused TEMPORARILY_REJECTED, fly retries.
    result, doc, mock = _fly_px4_mocks(plan_dir, gps_fix_after=20.0, streams_until_asked=True)
    assert result.ok, doc["problems"]
    assert doc["photos_from"] == "camera" and doc["coverage"] >= 99.0
    for row in doc["drones"]:
        taken = mock.vehicle(row["id"]).flight.state.photos
        assert row["finished"] and row["photos"] == taken and row["photos_placed_on_track"] == 0, row
        # Re-timed with the PX4 parameters the vehicle reported, by the PX4 model the mock flies.
        assert "MPC_XY_CRUISE" in row["vehicle_params"]
        assert row["flight_s"] == pytest.approx(row["planned_flight_s_vehicle"], rel=0.05), row
        assert not any("streams not accepted" in note for note in row["notes"]), row["notes"]
        # Where the time went: PX4's landed states bound the four phases, each as the PX4 model plans it.
        # PX4 SIH goes through the same ones, now and then skipping "taking off" (sitl_tests/test_fleet_px4.py).
        assert landed_states(row) == PX4_LANDED_STATES, row["events"]
        # As PX4 reports them: the DO_ items' seq after a waypoint (take-off, speed, gimbal, trigger come first),
        # nothing for the take-off and the RTL.
        assert reached_items(row)[:2] == [5, 7], row["events"]
        commands = [int(item.command) for item in read_mission_file(plan_dir / f"uav{row['id']}.plan").mission.items]
        assert reached_navigation_items(row, commands) == reported_items(commands), row["events"]
        assert [p["phase"] for p in row["phases"]] == ["take-off", "survey", "return", "landing"]
        for phase in row["phases"]:
            assert phase["flown_s"] == pytest.approx(phase["planned_s"], rel=0.05, abs=1.0), row["phases"]


@pytest.mark.flight
def test_a_px4_fleet_without_trig_mode_reports_no_photo(milan_plan, tmp_path) -> None:
    plan_dir = Path(shutil.copytree(milan_plan, tmp_path / "plan"))
    result, doc, _ = _fly_px4_mocks(plan_dir, cameras=False)
    assert not result.ok and doc["photos_from"] == "none"
    assert all("no CAMERA_IMAGE_CAPTURED" in p and "TRIG_MODE" in p for p in doc["problems"]), doc["problems"]
    assert all(row["finished"] for row in doc["drones"])


@pytest.mark.flight
def test_a_px4_start_refused_while_px4_checks_the_new_mission_is_retried(milan_plan, tmp_path) -> None:
    # PX4 SIH refused a MISSION_START sent right after the upload ("No valid mission"): it takes a new
    # mission only after its own checks. Here they take 20 simulated seconds (2 s at 10x): fly retries.
    plan_dir = Path(shutil.copytree(milan_plan, tmp_path / "plan"))
    result, doc, _ = _fly_px4_mocks(plan_dir, mission_check_s=20.0)
    assert result.ok, doc["problems"]
    for row in doc["drones"]:
        assert row["finished"], row
        retried = [note for note in row["notes"] if note.startswith("MISSION_START accepted after ")]
        assert retried and "No valid mission" in retried[0], row["notes"]
