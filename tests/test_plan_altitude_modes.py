"""QGroundControl's altitude modes in `.plan` files, read and written (missionplan.bridge.formats.qgc_plan), and
altitudes above sea level / above terrain in `.waypoints` files read by pymavlink's mavwp.

QGroundControl's facts these tests stand on (its source, src/MissionManager/SimpleMissionItem.cc and
src/QmlControls/QGroundControlQmlGlobal.h): AltMode is Mixed 0, Relative 1, Absolute 2, CalcAboveTerrain 3,
TerrainFrame 4; save() writes "AltitudeMode", "Altitude" and "AMSLAltAboveTerrain" on every item that has an
altitude (NaN as null) and load() wants all three if any is there; a CalcAboveTerrain item sits in
MAV_FRAME_GLOBAL with param 7 = its terrain data's height + "Altitude", recomputed whenever that data comes,
and null before. The plans written by hand here have the shape of its TerrainTest plan (tests/data/qgc).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavwp  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from missionplan.bridge import BridgeUsageError  # noqa: E402
from missionplan.bridge.formats.mission_items import (FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT,  # noqa: E402
                                                      FRAME_GLOBAL_TERRAIN_ALT, FRAME_MISSION, Flavour, Mission,
                                                      MissionItem)
from missionplan.bridge.formats.missionfile import PlanFile, read_mission_file, write_mission_file  # noqa: E402
from missionplan.bridge.formats.qgc_plan import plan_document  # noqa: E402

DATA = Path(__file__).resolve().parent / "data" / "qgc"
MODE_KEYS = {"AMSLAltAboveTerrain", "Altitude", "AltitudeMode"}
WP, TAKEOFF, LAND, SPEED, RTL = (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_LAND,
                                 mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)


def _item(jump_id: int, command: int, frame: int, params: list[Any], mode: int | None = None,
          altitude: float | None = None, amsl_above_terrain: float | None = None) -> dict[str, Any]:
    """A SimpleItem as QGroundControl writes it: its keys sorted, the altitude keys on items with an altitude."""
    entry: dict[str, Any] = {}
    if mode is not None:
        entry.update({"AMSLAltAboveTerrain": amsl_above_terrain, "Altitude": altitude, "AltitudeMode": mode})
    entry.update({"autoContinue": True, "command": command, "doJumpId": jump_id, "frame": frame, "params": params,
                  "type": "SimpleItem"})
    return entry


def _plan(items: list[dict[str, Any]], firmware: int = 12) -> dict[str, Any]:
    return {"fileType": "Plan", "geoFence": {"circles": [], "polygons": [], "version": 2},
            "groundStation": "QGroundControl",
            "mission": {"cruiseSpeed": 15, "firmwareType": firmware, "globalPlanAltitudeMode": 0, "hoverSpeed": 5,
                        "items": items, "plannedHomePosition": [44.4101, 8.9301, 212.0], "vehicleType": 2,
                        "version": 2},
            "rallyPoints": {"points": [], "version": 2}, "version": 1}


def _write(tmp_path: Path, name: str, doc: Any) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc, indent=4) + "\n")
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(BridgeUsageError) as err:
        read_mission_file(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    return message


TERRAIN_PLAN = [
    _item(1, TAKEOFF, 3, [0, 0, 0, None, 44.4101, 8.9301, 30], 1, 30),
    # calculated above terrain: 40 m over ground QGroundControl found at 272.4 m; param 7 and the key agree
    _item(2, WP, 0, [0, 0, 0, None, 44.4110, 8.9310, 312.4], 3, 40, 312.4),
    _item(3, SPEED, 2, [1, 6, -1, 0, 0, 0, 0]),
    # calculated above terrain, param 7 null but the computed altitude kept in AMSLAltAboveTerrain
    _item(4, WP, 0, [0, 0, 0, None, 44.4120, 8.9320, None], 3, 40, 298.0),
    _item(5, WP, 10, [0, 0, 0, None, 44.4130, 8.9330, 40], 4, 40),  # terrain frame: ArduPilot follows the ground
    _item(6, WP, 0, [0, 0, 0, None, 44.4140, 8.9340, 255.5], 2, 255.5),  # absolute
    _item(7, LAND, 3, [0, 0, 0, None, 44.4101, 8.9301, 0], 1, 0),
]


def test_hand_written_items_have_the_keys_qgroundcontrol_writes() -> None:
    """The items written by hand here carry the keys of the items of QGroundControl's own TerrainTest plan."""
    own = json.loads((DATA / "TerrainTest-ArduCopter.plan").read_text())["mission"]["items"]
    with_altitude = {frozenset(entry) for entry in own if "AltitudeMode" in entry}
    without = {frozenset(entry) for entry in own if "AltitudeMode" not in entry}
    assert {frozenset(entry) for entry in TERRAIN_PLAN if "AltitudeMode" in entry} == with_altitude
    assert {frozenset(entry) for entry in TERRAIN_PLAN if "AltitudeMode" not in entry} == without
    assert {entry["AltitudeMode"]: entry["frame"] for entry in own if "AltitudeMode" in entry} == {
        1: 3, 2: 0, 3: 0, 4: 10}  # QGroundControl's modes and the frames it gives them


def test_a_plan_calculated_above_terrain_reads_as_altitudes_above_sea_level(tmp_path: Path) -> None:
    plan = read_mission_file(_write(tmp_path, "terrain.plan", _plan(TERRAIN_PLAN)))
    assert [(i.command, i.frame, i.z) for i in plan.mission.items] == [
        (TAKEOFF, 3, 30), (WP, 0, 312.4), (SPEED, 2, 0), (WP, 0, 298.0), (WP, 10, 40), (WP, 0, 255.5), (LAND, 3, 0)]
    assert (plan.mission.items[1].x, plan.mission.items[1].y) == (44.4110, 8.9310)


def test_calculated_above_terrain_without_an_altitude_is_refused_saying_why_and_what_to_do(tmp_path: Path) -> None:
    message = _refusal(DATA / "TerrainTest-ArduCopter.plan")  # its item 6: param 7 and the key null
    assert ": mission item 6: altitude is terrain-relative (QGroundControl's AltitudeMode 3" in message
    assert "param 7 and AMSLAltAboveTerrain are null: QGroundControl saved the plan before its terrain data came" \
        in message
    assert "open the plan in QGroundControl, let its terrain heights load and save it again" in message
    items = [TERRAIN_PLAN[0], _item(2, WP, 3, [0, 0, 0, None, 44.4110, 8.9310, 312.4], 3, 40, 312.4)]
    message = _refusal(_write(tmp_path, "frame3.plan", _plan(items)))
    assert ("mission item 2: altitude is terrain-relative (QGroundControl's AltitudeMode 3, a height above terrain "
            "QGroundControl turns into an altitude above sea level from its terrain data) but the item is in frame 3, "
            "not 0 (MAV_FRAME_GLOBAL)") in message


def _mission() -> Mission:
    return Mission(items=[
        MissionItem(command=TAKEOFF, frame=FRAME_GLOBAL_RELATIVE_ALT, param4=math.nan, x=44.4101, y=8.9301, z=30.0),
        MissionItem(command=SPEED, frame=FRAME_MISSION, param1=1.0, param2=6.0, param3=-1.0),
        MissionItem(command=WP, frame=FRAME_GLOBAL_TERRAIN_ALT, param4=math.nan, x=44.4110, y=8.9310, z=40.0),
        MissionItem(command=WP, frame=FRAME_GLOBAL, param4=math.nan, x=44.4120, y=8.9320, z=297.25),
        MissionItem(command=mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, frame=FRAME_MISSION, param1=12.5, param3=1.0),
        MissionItem(command=RTL, frame=FRAME_MISSION),
    ], home=(44.4101, 8.9301, 212.0))


def test_terrain_and_sea_level_items_are_written_with_qgroundcontrols_altitude_modes(tmp_path: Path) -> None:
    doc = plan_document(PlanFile(mission=_mission(), firmware=Flavour.ARDUPILOT))
    items = doc["mission"]["items"]
    assert [(e.get("AltitudeMode"), e.get("Altitude"), e["frame"]) for e in items] == [
        (1, 30, 3), (None, None, 2), (4, 40, 10), (2, 297.25, 0), (None, None, 2), (None, None, 2)]
    for entry in items:  # all three keys or none; AMSLAltAboveTerrain null (never "calculated above terrain")
        assert MODE_KEYS <= set(entry) or not MODE_KEYS & set(entry)
        assert entry.get("AMSLAltAboveTerrain") is None
    assert list(items[2])[:3] == ["AMSLAltAboveTerrain", "Altitude", "AltitudeMode"]  # sorted, as QGC writes
    assert doc["mission"]["globalPlanAltitudeMode"] == 0  # mixed modes
    terrain_only = Mission(items=[_mission().items[2]])
    assert plan_document(PlanFile(mission=terrain_only))["mission"]["globalPlanAltitudeMode"] == 4


def test_a_plan_of_relative_items_has_no_altitude_mode_keys() -> None:
    relative = Mission(items=[it for it in _mission().items if it.frame in (2, 3)])
    doc = plan_document(PlanFile(mission=relative))
    assert not any(MODE_KEYS & set(entry) for entry in doc["mission"]["items"])
    assert doc["mission"]["globalPlanAltitudeMode"] == 1


@pytest.mark.parametrize("name", ["modes.plan", "modes.waypoints"])
def test_what_is_written_reads_back_the_same(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    write_mission_file(path, PlanFile(mission=_mission(), firmware=Flavour.PX4))
    back = read_mission_file(path).mission
    assert [(i.command, i.frame, i.x, i.y, i.z) for i in back.items] == [
        (i.command, i.frame, i.x, i.y, i.z) for i in _mission().items]


def test_waypoints_keep_frames_0_and_10_for_pymavlink(tmp_path: Path) -> None:
    path = tmp_path / "modes.waypoints"
    write_mission_file(path, PlanFile(mission=_mission()))
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == 1 + len(_mission().items)  # line 0 is home
    frames = [(loader.wp(i).frame, loader.wp(i).command, round(loader.wp(i).z, 2))
              for i in range(1, loader.count())]
    assert frames == [(3, TAKEOFF, 30.0), (2, SPEED, 0.0), (10, WP, 40.0), (0, WP, 297.25),
                      (2, mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, 0.0), (2, RTL, 0.0)]


@pytest.mark.parametrize("frame, altitude, what", [
    (0, 30_000.5, "must be metres above sea level (frame 0), from -500 to 30,000 m"),
    (0, -600.0, "must be metres above sea level (frame 0), from -500 to 30,000 m"),
    (10, -10_001.0, "must be metres above the terrain (frame 10), from -10,000 to 30,000 m"),
])
def test_altitudes_outside_their_frames_range_are_refused_naming_the_item(tmp_path: Path, frame: int,
                                                                         altitude: float, what: str) -> None:
    mode = {0: 2, 10: 4}[frame]
    items = [TERRAIN_PLAN[0], _item(2, WP, frame, [0, 0, 0, None, 44.4110, 8.9310, altitude], mode, altitude)]
    assert f"mission item 2: altitude {altitude:g}: {what}" in _refusal(_write(tmp_path, "far.plan", _plan(items)))
