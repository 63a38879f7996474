"""missionplan.bridge.formats.missionfile: .plan and .waypoints readers and writers, checked against pymavlink's
mavwp."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavwp  # noqa: E402

from missionplan.bridge import BridgeUsageError  # noqa: E402
from missionplan.bridge.formats.mission_items import (  # noqa: E402
    CMD_DO_CHANGE_SPEED,
    CMD_DO_JUMP,
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_FENCE_CIRCLE_EXCLUSION,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Mission,
    MissionItem,
    MissionType,
)
from missionplan.bridge.formats.missionfile import (  # noqa: E402
    PlanFile,
    read_mission_file,
    read_plan,
    read_waypoints,
    write_mission_file,
    write_plan,
    write_waypoints,
)


def _mission(n: int = 6) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=30.0),
             MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=12.5)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=2.0, param4=math.nan, x=45.07 + i * 1e-4,
                          y=7.68 - i * 1e-4, z=30.0 + i)
              for i in range(n)]
    items += [MissionItem(CMD_DO_JUMP, FRAME_MISSION, param1=3, param2=1),
              MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION),
              MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)]
    return Mission(items=items, home=(45.07, 7.68, 241.5))


def test_plan_round_trip_keeps_every_item(tmp_path: Path) -> None:
    plan = PlanFile(mission=_mission())
    plan.fence = Mission([MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.0, y=7.0),
                          MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.0),
                          MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.1),
                          MissionItem(CMD_FENCE_CIRCLE_EXCLUSION, FRAME_GLOBAL, param1=25, x=45.05, y=7.05)],
                         MissionType.FENCE)
    plan.rally = Mission([MissionItem(CMD_RALLY_POINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.02, y=7.03, z=20)],
                         MissionType.RALLY)
    path = tmp_path / "m.plan"
    write_plan(path, plan)
    doc = json.loads(path.read_text())
    assert doc["fileType"] == "Plan" and doc["version"] == 1
    assert set(doc) >= {"mission", "geoFence", "rallyPoints", "groundStation"}
    first_wp = doc["mission"]["items"][2]
    assert first_wp["type"] == "SimpleItem" and len(first_wp["params"]) == 7 and first_wp["params"][3] is None
    assert doc["mission"]["plannedHomePosition"] == [45.07, 7.68, 241.5]
    assert doc["geoFence"]["polygons"][0]["inclusion"] is True and len(doc["geoFence"]["polygons"][0]["polygon"]) == 3
    assert doc["geoFence"]["circles"][0]["inclusion"] is False
    back = read_plan(path)
    assert back.mission.home == (45.07, 7.68, 241.5)
    assert len(back.mission.items) == len(plan.mission.items)
    for a, b in zip(plan.mission.items, back.mission.items):
        assert a.command == b.command and a.frame == b.frame
        assert all((math.isnan(x) and math.isnan(y)) or x == y for x, y in zip(a.params, b.params))
    assert [i.command for i in back.fence.items] == [CMD_FENCE_POLYGON_VERTEX_INCLUSION] * 3 + [
        CMD_FENCE_CIRCLE_EXCLUSION]
    assert back.rally.items[0].z == 20
    assert [p.mission_type for p in back.parts()] == [MissionType.MISSION, MissionType.FENCE, MissionType.RALLY]


def test_plan_do_jump_targets_follow_do_jump_ids(tmp_path: Path) -> None:
    doc = {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
           "mission": {"version": 2, "firmwareType": 12, "plannedHomePosition": [45, 7, 200], "items": [
               {"type": "SimpleItem", "command": CMD_NAV_TAKEOFF, "frame": FRAME_GLOBAL_RELATIVE_ALT, "doJumpId": 10,
                "autoContinue": True, "params": [0, 0, 0, None, 0, 0, 30]},
               {"type": "SimpleItem", "command": CMD_NAV_WAYPOINT, "frame": FRAME_GLOBAL_RELATIVE_ALT, "doJumpId": 20,
                "autoContinue": True, "params": [0, 0, 0, None, 45.1, 7.1, 30]},
               {"type": "SimpleItem", "command": CMD_DO_JUMP, "frame": FRAME_MISSION, "doJumpId": 30,
                "autoContinue": True, "params": [20, 2, 0, 0, 0, 0, 0]}]},
           "geoFence": {"version": 2, "polygons": [], "circles": []}, "rallyPoints": {"version": 2, "points": []}}
    path = tmp_path / "jump.plan"
    path.write_text(json.dumps(doc))
    plan = read_plan(path)
    assert plan.mission.items[2].param1 == 2  # doJumpId 20 is the model's item 2
    assert plan.firmware is not None and plan.firmware.value == "px4"


@pytest.mark.parametrize("content, message", [  # file texts as on disk: their MAVLink numbers stay raw
    ("{not json", "not valid JSON"),
    ('{"fileType": "Mission"}', "not a QGroundControl plan"),
    ('{"fileType": "Plan", "version": 1, "mission": {"items": [{"type": "ComplexItem", '
     '"complexItemType": "survey"}]}}', "survey ComplexItem"),
    ('{"fileType": "Plan", "version": 1, "mission": {"items": [{"type": "SimpleItem", "command": 16, '
     '"frame": 3, "params": [1, 2]}]}}', "params must be a list of 7"),
    ('{"fileType": "Plan", "version": 1, "mission": {"items": [{"type": "SimpleItem", "command": 177, '
     '"frame": 2, "doJumpId": 1, "params": [9, 1, 0, 0, 0, 0, 0]}]}}', "DO_JUMP to doJumpId 9"),
])
def test_bad_plans_give_one_line_errors_naming_the_file(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.plan"
    path.write_text(content)
    with pytest.raises(BridgeUsageError) as err:
        read_plan(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


def test_waypoints_are_read_by_pymavlink_mavwp(tmp_path: Path) -> None:
    mission = _mission()
    path = tmp_path / "m.waypoints"
    write_waypoints(path, mission)
    text = path.read_bytes()
    assert text.startswith(b"QGC WPL 110\n") and b"\r" not in text
    assert all(len(line.split(b"\t")) == 12 for line in text.splitlines()[1:])
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == len(mission.items) + 1  # line 0 is home
    home = loader.wp(0)
    assert math.isclose(home.x, 45.07, abs_tol=1e-7) and math.isclose(home.z, 241.5)
    for number, item in enumerate(mission.items, start=1):
        wp = loader.wp(number)
        assert (wp.command, wp.frame, bool(wp.autocontinue)) == (item.command, item.frame, item.autocontinue)
        # mavwp keeps float degrees: compare as MISSION_ITEM_INT integers.
        assert round(wp.x * 1e7) == round(item.x * 1e7) and round(wp.y * 1e7) == round(item.y * 1e7)
        assert math.isclose(wp.z, item.z, abs_tol=1e-6)
        assert (math.isnan(wp.param4) and math.isnan(item.param4)) or wp.param4 == item.param4
    assert loader.wp(len(mission.items) - 2).param1 == 3  # DO_JUMP target: the model's item number


def test_waypoints_round_trip_and_errors(tmp_path: Path) -> None:
    path = tmp_path / "m.waypoints"
    write_mission_file(path, PlanFile(mission=_mission()))
    back = read_mission_file(path)
    assert back.mission.home == (45.07, 7.68, 241.5)
    assert [i.command for i in back.mission.items] == [i.command for i in _mission().items]
    bad = tmp_path / "bad.waypoints"
    bad.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t45\t7\t200\t1\n1\t0\t3\t16\t0\t0\n")
    with pytest.raises(BridgeUsageError, match="line 3: expected 12"):
        read_waypoints(bad)
    bad.write_text("hello\n")
    with pytest.raises(BridgeUsageError, match="not a waypoints file"):
        read_waypoints(bad)


def test_missing_and_unknown_files(tmp_path: Path) -> None:
    with pytest.raises(BridgeUsageError, match="no such file"):
        read_mission_file(tmp_path / "nope.plan")
    other = tmp_path / "m.txt"
    other.write_text("x")
    with pytest.raises(BridgeUsageError, match="not a mission file"):
        read_mission_file(other)
    with pytest.raises(BridgeUsageError, match="unknown mission file type"):
        write_mission_file(tmp_path / "m.kml", PlanFile(mission=_mission()))


# ------------------------------------------------------------------------- numbers the wire cannot carry

def _plan_with(params: list, command: int = CMD_NAV_WAYPOINT, frame: int = FRAME_GLOBAL_RELATIVE_ALT) -> str:
    """A plan text with one item; json.dumps writes NaN / Infinity literals, as some tools do."""
    return json.dumps({"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
                       "mission": {"version": 2, "plannedHomePosition": [45, 7, 200], "items": [
                           {"type": "SimpleItem", "command": CMD_NAV_TAKEOFF, "frame": FRAME_GLOBAL_RELATIVE_ALT,
                            "doJumpId": 1, "autoContinue": True, "params": [0, 0, 0, None, 45.0, 7.0, 30]},
                           {"type": "SimpleItem", "command": command, "frame": frame, "doJumpId": 2,
                            "autoContinue": True, "params": params}]},
                       "geoFence": {"version": 2, "polygons": [], "circles": []},
                       "rallyPoints": {"version": 2, "points": []}})


@pytest.mark.parametrize("params, message", [
    ([0, 0, 0, 0, math.nan, 7.68, 30], "mission item 2: latitude is NaN"),
    ([0, 0, 0, 0, None, 7.68, 30], "mission item 2: latitude is NaN"),
    ([0, 0, 0, 0, 45.07, math.nan, 30], "mission item 2: longitude is NaN"),
    ([0, 0, 0, 0, math.inf, 7.68, 30], "mission item 2: latitude inf is out of range"),
    ([0, 0, 0, 0, 91.0, 7.68, 30], "mission item 2: latitude 91.0 is out of range"),
    ([0, 0, 0, 0, 45.07, -180.5, 30], "mission item 2: longitude -180.5 is out of range"),
    ([0, 0, 0, 0, 45.07, 7.68, math.inf], "mission item 2: altitude is inf"),
    ([0, 0, 0, 0, 45.07, 7.68, None], "mission item 2: altitude is nan"),
    ([0, -math.inf, 0, 0, 45.07, 7.68, 30], "mission item 2: param2 is -inf"),
])
def test_plan_non_finite_or_out_of_range_numbers_are_bad_input(tmp_path: Path, params: list, message: str) -> None:
    path = tmp_path / "nan.plan"
    path.write_text(_plan_with(params))
    with pytest.raises(BridgeUsageError) as err:
        read_mission_file(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


def test_plan_nan_where_nan_is_meaningful_is_kept(tmp_path: Path) -> None:
    """null yaw (param4) means "unchanged"; a DO_CHANGE_SPEED has no position, so its null x / y are 0."""
    path = tmp_path / "ok.plan"
    path.write_text(_plan_with([0, 2.0, 0, None, 45.07, 7.68, 30]))
    assert math.isnan(read_plan(path).mission.items[1].param4)
    path.write_text(_plan_with([1, 5.0, -1, 0, None, None, None], command=CMD_DO_CHANGE_SPEED, frame=FRAME_MISSION))
    item = read_plan(path).mission.items[1]
    assert (item.x, item.y) == (0.0, 0.0)


@pytest.mark.parametrize("part, message", [
    ({"geoFence": {"polygons": [{"inclusion": True, "polygon": [[45, 7], [45.1, None], [45.1, 7.1]]}]}},
     "geoFence polygon 1 point 2: longitude is NaN"),
    ({"geoFence": {"circles": [{"inclusion": True, "circle": {"center": [95, 7], "radius": 10}}]}},
     "geoFence circle 1: latitude 95.0 is out of range"),
    ({"geoFence": {"circles": [{"inclusion": True, "circle": {"center": [45, 7], "radius": math.inf}}]}},
     "geoFence circle 1: radius must be a positive number"),
    ({"rallyPoints": {"points": [[45, 7, math.nan]]}}, "rally point 1: altitude is nan"),
    ({"mission": {"version": 2, "plannedHomePosition": [math.nan, 7, 200], "items": []}},
     "mission.plannedHomePosition: [nan, 7.0] is not a latitude / longitude"),
])
def test_plan_fence_rally_and_home_numbers_are_checked(tmp_path: Path, part: dict, message: str) -> None:
    doc = json.loads(_plan_with([0, 0, 0, 0, 45.07, 7.68, 30]))
    doc.update(part)
    path = tmp_path / "f.plan"
    path.write_text(json.dumps(doc))
    with pytest.raises(BridgeUsageError) as err:
        read_plan(path)
    assert message in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("row, message", [
    ("1\t0\t3\t16\t0\t0\t0\t0\tnan\t7.68\t30\t1", "line 3 (item 1): latitude is NaN"),
    ("1\t0\t3\t16\t0\t0\t0\t0\t45.07\tinf\t30\t1", "line 3 (item 1): longitude inf is out of range"),
    ("1\t0\t3\t16\t0\t0\t0\t0\t-90.5\t7.68\t30\t1", "line 3 (item 1): latitude -90.5 is out of range"),
    ("1\t0\t3\t16\t0\t0\t0\t0\t45.07\t7.68\tnan\t1", "line 3 (item 1): altitude is nan"),
    ("1\t0\t3\t16\tinf\t0\t0\t0\t45.07\t7.68\t30\t1", "line 3 (item 1): param1 is inf"),
    ("1\t0\t3\t16\t0\t0\t0\t0\t45.07\t7.68\t30\tinf", "line 3: a column is not a number"),
    ("1\t0\t300\t16\t0\t0\t0\t0\t45.07\t7.68\t30\t1", "line 3: frame 300 or command 16 out of range"),
])
def test_waypoints_non_finite_or_out_of_range_numbers_are_bad_input(tmp_path: Path, row: str, message: str) -> None:
    path = tmp_path / "nan.waypoints"
    path.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t45\t7\t200\t1\n" + row + "\n")
    with pytest.raises(BridgeUsageError) as err:
        read_mission_file(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)
    path.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tnan\t7\t200\t1\n")
    with pytest.raises(BridgeUsageError, match="line 2 \\(home\\)"):
        read_mission_file(path)


# -------------------------------------------------------------------------- versions and file names

def test_plan_mission_version_other_than_2_is_refused(tmp_path: Path) -> None:
    doc = json.loads(_plan_with([0, 0, 0, 0, 45.07, 7.68, 30]))
    path = tmp_path / "v.plan"
    for version in (1, 3, "2", 2.5):
        doc["mission"]["version"] = version
        path.write_text(json.dumps(doc))
        with pytest.raises(BridgeUsageError, match="unsupported mission.version"):
            read_plan(path)
    doc["mission"]["version"] = 2
    path.write_text(json.dumps(doc))
    assert len(read_plan(path).mission.items) == 2


@pytest.mark.parametrize("name", ["mp.waypoints.txt", "mp.txt", "MP.TXT", "noext"])
def test_waypoints_under_other_names_are_read_by_their_header(tmp_path: Path, name: str) -> None:
    """Mission Planner saves QGC WPL 110 files as .waypoints.txt or .txt: the header decides."""
    path = tmp_path / name
    write_waypoints(tmp_path / "m.waypoints", _mission())
    path.write_bytes((tmp_path / "m.waypoints").read_bytes().replace(b"\n", b"\r\n"))  # as Windows writes it
    plan = read_mission_file(path)
    assert [i.command for i in plan.mission.items] == [i.command for i in _mission().items]
    plan_txt = tmp_path / "qgc.plan.txt"
    write_plan(tmp_path / "q.plan", PlanFile(mission=_mission()))
    plan_txt.write_text((tmp_path / "q.plan").read_text())
    assert len(read_mission_file(plan_txt).mission.items) == len(_mission().items)
    out = tmp_path / "out.txt"
    write_mission_file(out, plan)
    assert out.read_text().startswith("QGC WPL 110\n")
