"""Two speeds in one mission: the ways out to the survey and home from it at the transit speed (the camera is
off there), the survey at the speed the camera keeps up with. The DO_CHANGE_SPEED items where the phase
changes, the timeline that times the same legs (leg_speeds) against the mock's flight, the battery sorties'
budget, and plans that keep one speed written as before."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from missionplan.bridge.flight_models.px4_model import Px4Params
from missionplan.bridge.formats.mission_items import (CMD_DO_CHANGE_SPEED, CMD_DO_SET_CAM_TRIGG_DIST, CMD_NAV_WAYPOINT,
                                                      MissionItem)
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.cli import main
from missionplan.geo.capture import CRUISE_SPEED_M_S, choose_transit_speed
from missionplan.mission.drone_missions import MissionSettings, build_mission
from missionplan.mission.plan_blocks import PlanSettings
from missionplan.mission.plan_record import report_path
from missionplan.mission.safety import SafetySettings
from missionplan.mission.timeline import FlightModel, leg_speeds, planned_track
from missionplan.testing.sim_flight import fly_sim

ROOT = Path(__file__).resolve().parents[1]
AREA = ROOT / "examples" / "turin-cenisia-area.geojson"
LAUNCH = "45.069450,7.652588"
HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS


def _legs(items: list[MissionItem]) -> list[tuple[float | None, bool]]:
    """(speed, camera on) of the leg into each NAV_WAYPOINT, walking the items as the autopilot runs them."""
    speed, camera, legs = None, False, []
    for item in items:
        if item.command == CMD_DO_CHANGE_SPEED:
            speed = item.param2
        elif item.command == CMD_DO_SET_CAM_TRIGG_DIST:
            camera = item.param1 > 0
        elif item.command == CMD_NAV_WAYPOINT:
            legs.append((speed, camera))
    return legs


def test_the_transit_speed_rule() -> None:
    assert choose_transit_speed(CRUISE_SPEED_M_S, None) is None  # one speed: plans as before
    assert choose_transit_speed(1.6, None) == CRUISE_SPEED_M_S  # the camera slowed the survey
    assert choose_transit_speed(8.0, None) is None  # a survey faster than the cruise speed: that one throughout
    assert choose_transit_speed(1.6, 12.0) == 12.0 and choose_transit_speed(12.0, 12.0) is None


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_camera_that_slows_the_survey_flies_out_and_home_at_the_cruise_speed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], autopilot: str) -> None:
    # The phantom's 2 s capture interval at 30 m: 3.33 m between photos, 1.67 m/s. At that speed the way out to
    # the far end of the block and back alone ate the battery; at 5 m/s it plans in sorties.
    out = tmp_path / "plan"
    code = main(["plan", "--area", str(AREA), "--launch", LAUNCH, "--camera", "dji-phantom4pro", "--altitude", "30",
                 "--autopilot", autopilot, "--out", str(out), "--quiet"])
    printed, err = capsys.readouterr()
    assert code == 0, err
    assert "    speed 1.67 m/s  min(5 m/s, fastest speed): none asked" in printed
    assert "    transit speed 5 m/s  cruise: the camera is off on the way out and home" in printed
    doc = json.loads(report_path(out).read_text())
    mission = doc["settings"]["mission"]
    assert mission["speed_m_s"] == pytest.approx(5 / 3) and mission["transit_speed_m_s"] == 5.0
    assert doc["georeference"]["camera"]["transit_speed_m_s"] == 5.0
    sorties = doc["drones"][0]["sorties"]
    budget = 20 * 60 * 0.8
    assert len(sorties) > 2 and all(s["flight_s"] <= budget for s in sorties)
    for j, sortie in enumerate(sorties):
        items = read_mission_file(out / sortie["file"]).mission.items
        legs = _legs(items)
        # Every leg flown with the camera on at the survey speed, every one with it off at the transit speed.
        assert all(speed == pytest.approx(5 / 3 if camera else 5.0) for speed, camera in legs), sortie["file"]
        changes = [item.param2 for item in items if item.command == CMD_DO_CHANGE_SPEED]
        survey = pytest.approx(5 / 3)
        if j == 0:  # from the launch point the survey starts at once: slow, then home fast
            assert changes == [survey, 5.0] and legs[0] == (survey, True)
        else:  # a resumed sortie: out fast, the survey slow, home fast
            assert changes == [5.0, survey, 5.0] and legs[0] == (5.0, False)
        assert legs[-1] == (5.0, False)


def test_a_plan_at_the_cruise_speed_keeps_one_speed_and_its_settings(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    # Sony a6000 16 mm at 60 m keeps up at 6.5 m/s: the survey flies at the cruise speed, as does all the rest.
    out = tmp_path / "plan"
    code = main(["plan", "--area", str(AREA), "--launch", LAUNCH, "--camera", "sony-a6000-16mm", "--altitude", "60",
                 "--out", str(out), "--quiet"])
    printed, err = capsys.readouterr()
    assert code == 0, err
    assert "transit speed" not in printed
    doc = json.loads(report_path(out).read_text())
    assert "transit_speed_m_s" not in doc["settings"]["mission"]
    assert "transit_speed_m_s" not in doc["georeference"]["camera"]
    for sortie in doc["drones"][0]["sorties"]:
        items = read_mission_file(out / sortie["file"]).mission.items
        assert [item.param2 for item in items if item.command == CMD_DO_CHANGE_SPEED] == [5.0]
    settings = PlanSettings.from_json(doc["settings"])
    assert settings.mission.transit_speed_m_s is None and settings.to_json() == doc["settings"]


def test_the_transit_speed_reads_back_from_the_settings() -> None:
    mission = MissionSettings(altitude_m=30.0, footprint_m=30.0, speed_m_s=1.5, transit_speed_m_s=8.0)
    settings = PlanSettings(mission, SafetySettings(), "expert", "geodesic", True, "lanes")
    doc = settings.to_json()
    assert doc["mission"]["transit_speed_m_s"] == 8.0
    assert PlanSettings.from_json(doc).mission == mission and mission.transit_m_s == 8.0


def test_a_transit_speed_above_what_the_autopilots_fly_is_one_line(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["plan", "--area", str(AREA), "--launch", LAUNCH, "--camera", "dji-phantom4pro", "--altitude", "30",
                 "--transit-speed", "25", "--out", str(tmp_path / "plan"), "--quiet"])
    assert code == 2 and capsys.readouterr().err == ("missionplan: --transit-speed 25: must be a waypoint speed "
                                                     "ArduCopter and PX4 fly, above 0 and at most 20 m/s\n")
    assert not (tmp_path / "plan").exists()


# ------------------------------------------------------------------------------------------- timeline vs mock
def _latlon(points_m: np.ndarray) -> np.ndarray:
    """(n, 2) north, east metres from HOME -> latitude, longitude as the mock converts them."""
    points = np.asarray(points_m, dtype=float).reshape(-1, 2)
    return np.column_stack([HOME[0] + points[:, 0] / M_PER_DEG_LAT,
                            HOME[1] + points[:, 1] / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))])


def _fly(items: list[MissionItem], px4_params: Px4Params | None) -> np.ndarray:
    """(n, 4) t, north, east, up of the mock's SITL-like flight of the items, MISSION_START to disarm."""
    from missionplan.bridge.formats.mission_items import Mission

    return fly_sim(Mission(items, home=HOME), HOME, px4=px4_params)[:, :4]


@pytest.mark.flight
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_mock_flies_a_resumed_sortie_in_the_time_the_timeline_plans(autopilot: str) -> None:
    settings = MissionSettings(altitude_m=20.0, footprint_m=18.0, speed_m_s=1.5, transit_speed_m_s=6.0,
                               autopilot=autopilot)
    out = np.array([[40.0, 0.0], [40.0, 30.0]])
    survey = np.array([[60.0, 30.0], [60.0, 40.0], [45.0, 40.0]])
    back = np.array([[20.0, 40.0], [0.0, 0.0]])
    mission = build_mission(0, HOME[:2], _latlon(survey), survey, np.zeros(2), settings, resumes=True,
                            transit=(_latlon(out), out), back=(_latlon(back), back))
    flown = _fly(mission.mission.items, Px4Params() if autopilot == "px4" else None)
    model = FlightModel.for_autopilot(autopilot, settings.speed_m_s, settings.acceptance_m, settings.transit_speed_m_s)
    speeds = leg_speeds(model, len(out), len(survey), len(back), resumes=True)
    assert list(speeds) == [6.0, 6.0, 6.0, 1.5, 1.5, 6.0, 6.0]
    plan = planned_track(np.zeros(2), np.vstack([out, survey, back]), 20.0, "rtl", model, speeds)
    assert flown[-1, 0] == pytest.approx(plan[-1, 0], abs=0.06)  # disarmed within a step of the plan's end
    for k, axis in ((1, "north"), (2, "east"), (3, "up")):
        at_plan_times = np.interp(plan[:, 0], flown[:, 0], flown[:, k])
        assert np.abs(at_plan_times - plan[:, k]).max() < 0.3, axis
    # One speed throughout would have been a different flight: the timeline follows the changes.
    one_speed = planned_track(np.zeros(2), np.vstack([out, survey, back]), 20.0, "rtl", model)
    assert one_speed[-1, 0] - plan[-1, 0] > 10.0
