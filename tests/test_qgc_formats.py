"""QGroundControl's own files read the way QGroundControl reads them (missionplan.bridge.formats.missionfile,
missionplan.bridge.formats.qgc_legacy).

Two kinds of fixture: copies of QGroundControl's and MAVSDK's own test plans in tests/data/qgc/ (their
sources and licences in tests/data/qgc/NOTICE), whose expected contents come from those projects' own
tests and from QGroundControl's loader; and small files written here, each modelled on one of them, for
the cases no published file covers. Every refusal is one line naming the file and the item.
"""

from __future__ import annotations

import copy
import json
import math
import os
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from missionplan.bridge import BridgeUsageError  # noqa: E402
from missionplan.bridge.formats.mission_items import Flavour, to_wire  # noqa: E402
from missionplan.bridge.formats.missionfile import (PlanFile, read_mission_file, read_plan,  # noqa: E402
                                                    read_qgc_mission)

DATA = Path(__file__).resolve().parent / "data" / "qgc"


def _refusal(path: Path) -> str:
    """The one-line BridgeUsageError the reader gives for the file."""
    with pytest.raises(BridgeUsageError) as err:
        read_mission_file(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    return message


def _write(tmp_path: Path, name: str, doc: Any) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc, indent=4) + "\n")
    return path


def _uploadable(plan: PlanFile) -> None:
    """Every item packs into a MISSION_ITEM_INT for both autopilots: nothing the wire cannot carry."""
    packer = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for flavour in (Flavour.ARDUPILOT, Flavour.PX4):
        for part in plan.parts():
            for item in to_wire(part, flavour):
                mavlink.MAVLink_mission_item_int_message(1, 1, **item.fields()).pack(packer)


def _plan(items: list[Any], firmware: int = 3) -> dict[str, Any]:
    return {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
            "mission": {"version": 2, "firmwareType": firmware, "vehicleType": 2, "cruiseSpeed": 15,
                        "hoverSpeed": 5, "plannedHomePosition": [47.3980, 8.5461, 488.2], "items": items},
            "geoFence": {"version": 2, "polygons": [], "circles": []}, "rallyPoints": {"version": 2, "points": []}}


def _simple(command: int, jump_id: int, frame: int, params: list[Any], **extra: Any) -> dict[str, Any]:
    return {"type": "SimpleItem", "autoContinue": True, "command": command, "doJumpId": jump_id, "frame": frame,
            "params": params, **extra}


# ------------------------------------------------------------------------------- legacy .mission files

def test_qgc_old_file_format_mission_reads_its_six_items() -> None:
    """QGroundControl's PlanMasterControllerTest loads OldFileFormat.mission into 7 visual items: the
    mission settings (home) and 6 mission items, each in the V2 layout (coordinate + 4 params)."""
    plan = read_mission_file(DATA / "OldFileFormat.mission")
    items = plan.mission.items
    assert [(i.command, i.frame) for i in items] == [(22, 2), (18, 3), (18, 3), (16, 3), (16, 3), (21, 3)]
    assert [i.param1 for i in items] == [0, 1, 3, 0, 0, 0]  # LOITER_TURNS: 1 and 3 turns
    assert (items[1].x, items[1].y, items[1].z) == (47.660316610000002, -122.29423867, 10)
    assert (items[5].x, items[5].y, items[5].z) == (47.660153620000003, -122.29410455999999, 3)
    assert plan.mission.home == (47.660137763851573, -122.29411931627152, 0.0)
    assert plan.firmware is Flavour.ARDUPILOT
    assert not plan.fence.items and not plan.rally.items  # a .mission file holds a mission only
    _uploadable(plan)


def test_legacy_mission_is_read_under_other_names_and_a_plan_named_mission_is_a_plan(tmp_path: Path) -> None:
    text = (DATA / "OldFileFormat.mission").read_text()
    other = tmp_path / "old.txt"  # any other name: recognised by its content, as .plan and QGC WPL files are
    other.write_text(text)
    commands = [i.command for i in read_mission_file(other).mission.items]
    assert commands == [mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_LOITER_TURNS, mavlink.MAV_CMD_NAV_LOITER_TURNS,
                        mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LAND]
    misnamed = tmp_path / "old.plan"  # QGroundControl reads a .plan only if fileType is "Plan"
    misnamed.write_text(text)
    message = _refusal(misnamed)
    assert "not a QGroundControl plan" in message and "name it .mission" in message
    section = tmp_path / "section.mission"
    section.write_text((DATA / "SectionTest.plan").read_text())
    assert len(read_qgc_mission(section).mission.items) == 5


def _mission_v2(items: list[Any]) -> dict[str, Any]:
    """A version 2 .mission, as QGroundControl wrote it: the .plan mission object at the top level."""
    return {"fileType": "Mission", "groundStation": "QGroundControl", "version": 2, "firmwareType": 12,
            "vehicleType": 2, "plannedHomePosition": [45.07, 7.68, 240.0], "items": items}


def test_legacy_mission_v2_resolves_do_jump_ids_like_a_plan(tmp_path: Path) -> None:
    path = _write(tmp_path, "jump.mission", _mission_v2([
        {"type": "SimpleItem", "autoContinue": True, "command": mavlink.MAV_CMD_NAV_TAKEOFF, "doJumpId": 7,
         "frame": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, "coordinate": [45.07, 7.68, 30], "params": [0, 0, 0, None]},
        {"type": "SimpleItem", "autoContinue": True, "command": mavlink.MAV_CMD_NAV_WAYPOINT, "doJumpId": 8,
         "frame": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, "coordinate": [45.071, 7.681, 35], "params": [0, 2, 0, None]},
        _simple(mavlink.MAV_CMD_DO_JUMP, 9, mavlink.MAV_FRAME_MISSION, [8, 3, 0, 0, 0, 0, 0])]))
    plan = read_mission_file(path)
    assert [i.command for i in plan.mission.items] == [mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_WAYPOINT,
                                                       mavlink.MAV_CMD_DO_JUMP]
    assert plan.mission.items[2].param1 == 2 and plan.mission.items[2].param2 == 3  # doJumpId 8 is item 2
    assert (plan.mission.items[1].x, plan.mission.items[1].z, plan.mission.items[1].param2) == (45.071, 35, 2)
    assert math.isnan(plan.mission.items[1].param4)
    assert plan.firmware is Flavour.PX4 and plan.mission.home == (45.07, 7.68, 240.0)


def _mission_v1(items: list[Any], complex_items: list[Any] | None = None) -> dict[str, Any]:
    """A version 1 .mission: version "1.0", MAV_AUTOPILOT, home as an item, items with id and param1-4."""
    return {"MAV_AUTOPILOT": 3, "complexItems": complex_items or [], "groundStation": "QGroundControl",
            "items": items, "version": "1.0",
            "plannedHomePosition": {"autoContinue": True, "command": mavlink.MAV_CMD_NAV_WAYPOINT,
                                    "coordinate": [45.07, 7.68, 240.0], "frame": mavlink.MAV_FRAME_GLOBAL, "id": 0,
                                    "param1": 0, "param2": 0, "param3": 0, "param4": 0, "type": "missionItem"}}


def _v1_item(item_id: int, command: int, frame: int, p1: float, coordinate: list[float]) -> dict[str, Any]:
    return {"autoContinue": True, "command": command, "coordinate": coordinate, "frame": frame, "id": item_id,
            "param1": p1, "param2": 0, "param3": 0, "param4": 0, "type": "missionItem"}


def test_legacy_mission_v1_reads_its_items_home_firmware_and_jump_by_id(tmp_path: Path) -> None:
    path = _write(tmp_path, "v1.mission", _mission_v1([
        _v1_item(1, mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0, [45.07, 7.68, 25]),
        _v1_item(2, mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 4, [45.072, 7.682, 25]),
        _v1_item(3, mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0, [45.073, 7.683, 30]),
        # version 1 DO_JUMP: param1 is the target's id
        _v1_item(4, mavlink.MAV_CMD_DO_JUMP, mavlink.MAV_FRAME_MISSION, 2, [0, 0, 0]),
        _v1_item(5, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION, 0, [0, 0, 0])]))
    plan = read_mission_file(path)
    items = plan.mission.items
    assert [i.command for i in items] == [mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_WAYPOINT,
                                          mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_DO_JUMP,
                                          mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH]
    assert (items[1].param1, items[1].x, items[1].y, items[1].z) == (4, 45.072, 7.682, 25)  # hold 4 s
    assert items[3].param1 == 2
    assert plan.mission.home == (45.07, 7.68, 240.0) and plan.firmware is Flavour.ARDUPILOT
    _uploadable(plan)
    doc = _mission_v1([_v1_item(1, mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0,
                                [45.07, 7.68, 25]),
                       _v1_item(2, mavlink.MAV_CMD_DO_JUMP, mavlink.MAV_FRAME_MISSION, 9, [0, 0, 0])])
    assert "mission item 2: DO_JUMP to doJumpId 9, which no item has" in _refusal(_write(tmp_path, "j.mission", doc))


def test_legacy_mission_v1_survey_and_bad_shapes_are_refused_in_one_line(tmp_path: Path) -> None:
    survey = {"id": 2, "type": "survey", "version": 1, "polygon": [[45.0, 7.0], [45.1, 7.0], [45.1, 7.1]]}
    takeoff = _v1_item(1, mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0, [45, 7, 20])
    message = _refusal(_write(tmp_path, "s.mission", _mission_v1([takeoff], [survey])))
    assert "complexItems item 1 is a QGroundControl survey pattern" in message
    assert "generates when it loads the file" in message and "save it as a .plan" in message
    missing = _v1_item(1, mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0, [45, 7, 20])
    del missing["param3"]
    assert "mission item 1: a version 1 item needs param1 to param4, param3 missing" in _refusal(
        _write(tmp_path, "p.mission", _mission_v1([missing])))
    assert "unsupported .mission version the number 3" in _refusal(
        _write(tmp_path, "v.mission", {**_mission_v2([]), "version": 3}))
    assert "not a QGroundControl mission" in _refusal(
        _write(tmp_path, "t.mission", {**_mission_v2([]), "fileType": "GeoFence"}))


# -------------------------------------------------------------------- SectionTest-style (V2) SimpleItems

def test_qgc_section_test_plan_items_with_coordinate_and_four_params() -> None:
    plan = read_mission_file(DATA / "SectionTest.plan")
    items = plan.mission.items
    assert [(i.command, i.frame) for i in items] == [(22, 3), (16, 3), (16, 3), (205, 2), (16, 3)]
    assert (items[1].x, items[1].y, items[1].z) == (47.63369112, -122.08925023, 20)
    assert math.isnan(items[1].param4)  # null yaw: unchanged
    mount = items[3]  # DO_MOUNT_CONTROL: the coordinate is params 5-7, so param 7 (mode) is 2
    assert (mount.x, mount.y, mount.z) == (0, 0, 2)
    assert plan.mission.home == (47.633389756176875, -122.09076300000001, 20.0)
    assert plan.firmware is Flavour.PX4 and plan.cruise_speed == 15 and plan.hover_speed == 5
    assert not plan.fence.items  # its geoFence is version 1, which QGroundControl no longer reads either
    _uploadable(plan)


@pytest.mark.parametrize("item, message", [
    ({"coordinate": [45.07, 7.68, 30], "params": [0, 0, 0, None, 45.07, 7.68, 30]},
     "mission item 1: params must be a list of 4 numbers beside a coordinate [lat, lon, alt], got a list of 7"),
    ({"coordinate": [45.07, 7.68], "params": [0, 0, 0, None]},
     "mission item 1: coordinate must be [lat, lon, alt], got a list of 2"),
    ({"coordinate": [45.07, "7.68", 30], "params": [0, 0, 0, None]}, "mission item 1 params: expected a number"),
    ({"params": [0, 0, 0, None]}, "mission item 1: params must be a list of 7 numbers (or of 4 beside a coordinate"),
])
def test_section_test_style_items_with_a_wrong_shape_are_refused(tmp_path: Path, item: dict[str, Any],
                                                                 message: str) -> None:
    entry = {"type": "SimpleItem", "autoContinue": True, "command": mavlink.MAV_CMD_NAV_WAYPOINT, "doJumpId": 1,
             "frame": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, **item}
    assert message in _refusal(_write(tmp_path, "section.plan", _plan([entry])))


# --------------------------------------------------------------------------------- terrain altitudes

TERRAIN_WORDS = ("altitude is terrain-relative", "no terrain data to convert it with",
                 "set the item's altitude to relative", "`missionplan plan`")


def test_qgc_terrain_test_plan_is_refused_at_its_calc_above_terrain_item() -> None:
    """Item 6 of QGroundControl's TerrainTest plans has AltitudeMode 3 and a null altitude: QGroundControl
    fills it in from its terrain data when it loads the plan."""
    message = _refusal(DATA / "TerrainTest-ArduCopter.plan")
    assert message.startswith(f"{DATA / 'TerrainTest-ArduCopter.plan'}: mission item 6: altitude is terrain-relative "
                              "(QGroundControl's AltitudeMode 3")
    assert all(words in message for words in TERRAIN_WORDS), message


def test_terrain_items_refused_unless_the_vehicle_gets_a_number_it_can_fly(tmp_path: Path) -> None:
    takeoff = _simple(mavlink.MAV_CMD_NAV_TAKEOFF, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                      [0, 0, 0, None, 47.633, -122.086, 30])
    calc = _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 2, mavlink.MAV_FRAME_GLOBAL,
                   [0, 0, 0, None, 47.6035618, -122.046391, 240.5], AltitudeMode=3, Altitude=80,
                   AMSLAltAboveTerrain=240.5)  # the altitude QGC computed from its terrain data: what it uploads
    item = read_mission_file(_write(tmp_path, "calc.plan", _plan([takeoff, calc]))).mission.items[1]
    assert (item.frame, item.z, item.x) == (0, 240.5, 47.6035618)
    for frame, name in ((10, "MAV_FRAME_GLOBAL_TERRAIN_ALT"), (11, "MAV_FRAME_GLOBAL_TERRAIN_ALT_INT")):
        blank = _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 2, frame, [0, 0, 0, None, 47.6035618, -122.1263702, None],
                        AltitudeMode=4)
        message = _refusal(_write(tmp_path, f"blank{frame}.plan", _plan([takeoff, blank])))
        assert f"mission item 2: altitude is terrain-relative (frame {frame}, {name}) and has no value" in message
        assert all(words in message for words in TERRAIN_WORDS[1:]), message
    # QGroundControl's AltitudeMode 4 (terrain frame) with a height: sent as it is, the autopilot follows terrain.
    follow = _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 2, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
                     [0, 0, 0, None, 47.6035618, -122.1263702, 50], AltitudeMode=4, Altitude=50,
                     AMSLAltAboveTerrain=None)
    item = read_mission_file(_write(tmp_path, "follow.plan", _plan([takeoff, follow]))).mission.items[1]
    assert (item.frame, item.z, item.x) == (10, 50, 47.6035618)
    relative = _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 2, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                       [0, 0, 0, None, 47.6, -122.1, None], AltitudeMode=1)
    assert "mission item 2: altitude is nan" in _refusal(_write(tmp_path, "rel.plan", _plan([takeoff, relative])))


def test_terrain_frame_without_altitude_in_waypoints_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "terrain.waypoints"
    path.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47.6\t-122.1\t9.3\t1\n"
                    "1\t0\t10\t16\t0\t0\t0\t0\t47.61\t-122.11\tnan\t1\n")
    message = _refusal(path)
    assert "line 3 (item 1): altitude is terrain-relative (frame 10, MAV_FRAME_GLOBAL_TERRAIN_ALT)" in message
    path.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47.6\t-122.1\t9.3\t1\n"
                    "1\t0\t10\t16\t0\t0\t0\t0\t47.61\t-122.11\t40\t1\n")
    assert read_mission_file(path).mission.items[0].z == 40  # Mission Planner's terrain frame with a height


# ---------------------------------------------------------------------------- survey ComplexItems

# MAVSDK's mission_import_test.cpp, ImportSamplePlanWithComplexMissionSurvey: the 13 items MAVSDK uploads
# from its qgroundcontrol_sample_with_survey.plan (waypoint positions in degE7, as MISSION_ITEM_INT).
# SET_CAMERA_MODE, then waypoints and DO_SET_CAM_TRIGG_DIST (the commands of the data file's items, as stored)
MAVSDK_SURVEY_COMMANDS = [530, 16, 206, 16, 206, 16, 16, 16, 16, 206, 16, 16, 206]
MAVSDK_SURVEY_WAYPOINTS = [(473977060, 85463397), (473977060, 85462068), (473977060, 85457443),
                           (473977060, 85456115), (473974811, 85456316), (473974811, 85457645),
                           (473974811, 85462092), (473974811, 85463421)]


def test_mavsdk_survey_plan_expands_into_the_items_qgc_stored() -> None:
    plan = read_mission_file(DATA / "qgroundcontrol_sample_with_survey.plan")
    items = plan.mission.items
    assert [i.command for i in items] == MAVSDK_SURVEY_COMMANDS
    waypoints = [i for i in items if i.command == mavlink.MAV_CMD_NAV_WAYPOINT]
    assert [(round(i.x * 1e7), round(i.y * 1e7)) for i in waypoints] == MAVSDK_SURVEY_WAYPOINTS
    assert {(i.frame, i.z) for i in waypoints} == {(3, 50)} and all(math.isnan(i.param4) for i in waypoints)
    # the trigger distance; 0 = stop
    assert [i.param1 for i in items if i.command == mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST] == [25, 25, 25, 0]
    assert items[0].param2 == 2 and math.isnan(items[0].param3)  # SET_CAMERA_MODE 2 (survey), nulls are NaN
    assert plan.firmware is Flavour.PX4
    _uploadable(plan)


def _transect_items() -> list[dict[str, Any]]:
    """A survey's stored items as QGroundControl saves them (doJumpId = their sequence number then)."""
    return [_simple(mavlink.MAV_CMD_NAV_WAYPOINT, 2, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    [0, 0, 0, None, 45.0700, 7.6800, 40]),
            _simple(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, 3, mavlink.MAV_FRAME_MISSION, [12, 0, 1, 0, 0, 0, 0]),
            _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 4, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    [0, 0, 0, None, 45.0710, 7.6800, 40]),
            _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 5, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    [0, 0, 0, None, 45.0710, 7.6805, 40]),
            _simple(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, 6, mavlink.MAV_FRAME_MISSION, [0, 0, 1, 0, 0, 0, 0])]


def _complex(kind: str, version: int, stored: list[Any] | None) -> dict[str, Any]:
    inner: dict[str, Any] = {"version": 2, "TurnAroundDistance": 10, "CameraTriggerInTurnAround": True,
                             "HoverAndCapture": False, "Refly90Degrees": False, "CameraShots": 4,
                             "CameraCalc": {"version": 1, "DistanceToSurface": 40, "DistanceToSurfaceRelative": True,
                                            "CameraName": "Manual (no camera specs)"},
                             "VisualTransectPoints": [[45.07, 7.68], [45.071, 7.6805]]}
    if stored is not None:
        inner["Items"] = stored
    return {"type": "ComplexItem", "complexItemType": kind, "version": version, "TransectStyleComplexItem": inner,
            "angle": 0, "entryLocation": 0, "flyAlternateTransects": False, "splitConcavePolygons": False,
            "polygon": [[45.07, 7.68], [45.071, 7.68], [45.071, 7.681]]}


def test_survey_and_corridor_items_expand_in_place_and_jumps_count_them(tmp_path: Path) -> None:
    for kind, version in (("survey", 4), ("CorridorScan", 3)):
        items = [_simple(mavlink.MAV_CMD_NAV_TAKEOFF, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                         [0, 0, 0, None, 45.07, 7.68, 40]),
                 _complex(kind, version, _transect_items()),
                 _simple(mavlink.MAV_CMD_DO_JUMP, 7, mavlink.MAV_FRAME_MISSION, [8, 1, 0, 0, 0, 0, 0]),
                 _simple(mavlink.MAV_CMD_NAV_WAYPOINT, 8, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                         [0, 0, 0, None, 45.0705, 7.6802, 40]),
                 _simple(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 9, mavlink.MAV_FRAME_MISSION, [0, 0, 0, 0, 0, 0, 0])]
        plan = read_mission_file(_write(tmp_path, f"{kind}.plan", _plan(items)))
        got = plan.mission.items
        assert [i.command for i in got] == [mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_WAYPOINT,
                                            mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_CMD_NAV_WAYPOINT,
                                            mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST,
                                            mavlink.MAV_CMD_DO_JUMP, mavlink.MAV_CMD_NAV_WAYPOINT,
                                            mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH], kind
        assert got[6].param1 == 8  # doJumpId 8 is the model's item 8: after the 5 stored items
        assert (got[3].x, got[3].y, got[3].z, got[2].param1) == (45.0710, 7.6800, 40, 12)
    # QGroundControl finds DO_JUMP targets among SimpleItems only: a stored item's doJumpId is none.
    items = [_simple(mavlink.MAV_CMD_NAV_TAKEOFF, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                     [0, 0, 0, None, 45.07, 7.68, 40]),
             _complex("survey", 5, _transect_items()),
             _simple(mavlink.MAV_CMD_DO_JUMP, 7, mavlink.MAV_FRAME_MISSION, [4, 1, 0, 0, 0, 0, 0])]
    assert "mission item 3: DO_JUMP to doJumpId 4, which no item has" in _refusal(
        _write(tmp_path, "inner.plan", _plan(items)))
    bad = _transect_items()
    bad[2]["params"][4] = 95.0
    assert "mission item 1 (survey item 3): latitude 95.0 is out of range" in _refusal(
        _write(tmp_path, "bad.plan", _plan([_complex("survey", 5, bad)])))


SURVEY_WORDS = ("a QGroundControl survey pattern whose waypoints QGroundControl generates when it loads the plan",
                "the file does not hold them and this tool does not generate them",
                "open the plan in QGroundControl and save it again")


def test_complex_items_without_stored_waypoints_are_refused_with_what_to_do(tmp_path: Path) -> None:
    takeoff = _simple(mavlink.MAV_CMD_NAV_TAKEOFF, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                      [0, 0, 0, None, 45.07, 7.68, 40])
    for name, survey in (("empty", _complex("survey", 5, [])), ("none", _complex("survey", 5, None)),
                         ("v3", {"type": "ComplexItem", "complexItemType": "survey", "version": 3,
                                 "polygon": [[45.07, 7.68], [45.071, 7.68], [45.071, 7.681]],
                                 "grid": {"altitude": 40, "angle": 0, "spacing": 20, "turnAroundDistance": 10}})):
        path = _write(tmp_path, f"{name}.plan", _plan([takeoff, survey]))
        message = _refusal(path)
        assert message.startswith(f"{path}: mission item 2 is a survey ComplexItem, "), message
        assert all(words in message for words in SURVEY_WORDS), message
        assert f"`missionplan plan --area {path}`" in message
    structure = _refusal(DATA / "qgroundcontrol_sample_with_structured_scan.plan")
    assert "mission item 2 is a StructureScan ComplexItem, a QGroundControl structure scan whose waypoints" in structure
    assert "QGroundControl never stores a structure scan's waypoints in a plan" in structure
    assert "read the mission back with `missionplan download`" in structure
    landing = {"type": "ComplexItem", "complexItemType": "fwLandingPattern", "version": 2}
    assert "mission item 2 is a fwLandingPattern ComplexItem, a QGroundControl fixed-wing landing pattern" in _refusal(
        _write(tmp_path, "land.plan", _plan([takeoff, landing])))
    unknown = _complex("SectorScan", 1, _transect_items())
    assert ("mission item 2 is a ComplexItem of type 'SectorScan', which QGroundControl does not read"
            in _refusal(_write(tmp_path, "sector.plan", _plan([takeoff, unknown]))))
    assert "mission item 2 is a survey ComplexItem of version 6, which QGroundControl does not read" in _refusal(
        _write(tmp_path, "v6.plan", _plan([takeoff, _complex("survey", 6, _transect_items())])))


# ----------------------------------------------------------------------------------- through the CLI

def test_upload_reports_a_refusal_in_one_line_with_exit_2_before_connecting(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import missionplan.bridge.transfer.uploader
    from missionplan.cli import main

    def never(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("upload opened a link for a file it should have refused")

    monkeypatch.setattr(missionplan.bridge.transfer.uploader, "open_backend", never)
    survey = _write(tmp_path, "survey.plan", _plan([_complex("survey", 5, None)]))
    for path, words in ((DATA / "TerrainTest-ArduCopter.plan", "mission item 6: altitude is terrain-relative"),
                        (survey, "mission item 1 is a survey ComplexItem")):
        code = main(["upload", str(path), "--sysid", "1", "--connect", "udpout:127.0.0.1:14550", "--quiet"])
        out, err = capsys.readouterr()
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and err.startswith(f"missionplan: {path}: {words}"), err


# ------------------------------------------------------------------- whatever the file: plan or refusal

PROPERTY_SETTINGS = settings(max_examples=80, deadline=None,
                             suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
numbers = st.integers(-(2**40), 2**40) | st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([1, 2, 5])
scalars = st.none() | st.booleans() | numbers | st.text(max_size=6) | st.sampled_from(["1.0", "survey", "Mission"])
json_values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(max_size=10), inner, max_size=4), max_leaves=15)


def _places(node: Any, out: list[tuple[Any, Any]]) -> list[tuple[Any, Any]]:
    for key in (list(node.keys()) if isinstance(node, dict) else list(range(len(node)))):
        out.append((node, key))
        if isinstance(node[key], (dict, list)):
            _places(node[key], out)
    return out


def _documents() -> list[tuple[str, dict[str, Any]]]:
    legacy = _mission_v1([_v1_item(1, mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0,
                                   [45.07, 7.68, 25]),
                          _v1_item(2, mavlink.MAV_CMD_DO_JUMP, mavlink.MAV_FRAME_MISSION, 1, [0, 0, 0])])
    survey = _plan([_simple(mavlink.MAV_CMD_NAV_TAKEOFF, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                            [0, 0, 0, None, 45.07, 7.68, 40]),
                    _complex("survey", 5, _transect_items())])
    return [("v1.mission", legacy), ("old.mission", json.loads((DATA / "OldFileFormat.mission").read_text())),
            ("survey.plan", survey)]


@PROPERTY_SETTINGS
@given(st.data())
def test_a_qgc_file_broken_anywhere_is_a_plan_or_a_one_line_refusal(tmp_path: Path, data: st.DataObject) -> None:
    name, doc = data.draw(st.sampled_from(_documents()))
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 2))):
        container, key = data.draw(st.sampled_from(_places(doc, [])))
        container[key] = data.draw(json_values)
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    try:
        plan = read_mission_file(path)
    except BridgeUsageError as err:
        assert "\n" not in str(err) and str(path) in str(err)
        return
    _uploadable(plan)


def test_the_unbroken_property_documents_read(tmp_path: Path) -> None:
    counts = []
    for name, doc in _documents():
        path = _write(tmp_path, name, doc)
        counts.append(len((read_plan(path) if name.endswith(".plan") else read_qgc_mission(path)).mission.items))
    assert counts == [2, 6, 6]
