"""MAVLink numbers come from pymavlink's generated enums (`mavutil.mavlink`), except in the modules that stay
free of pymavlink (the planner's side of the bridge), and those take theirs from bridge/formats/mission_items.py, the
one module that writes MAVLink numbers down itself.

- bridge/formats/mission_items.py: every MAVLink number it holds (its module-level int constants named MAV_*, CMD_*,
  FRAME_* or SPEED_TYPE_*, and MissionType) equals pymavlink's value of the same MAVLink name;
  PYMAVLINK_NAMES says which name each one is, and a constant added there without an entry fails the test.
- Everywhere else in bridge/, geo/, missionplan/, sitl_tests/, bench/ and tests/ (every .py file, parsed with
  `ast`), no module-level assignment (tuple assignments included) binds an int literal (or an expression of
  int literals only, such as `1 << 7`) to
    * a name starting with MAV_ that pymavlink also defines (MAV_CMD_*, MAV_MODE_FLAG_*, MAV_LANDED_STATE_*,
      MAV_MISSION_*, MAV_RESULT_*, MAV_SEVERITY_*, MAV_FRAME_*, MAV_TYPE_*, MAV_STATE_*, ...), whatever the
      value; or
    * a name starting with CMD_, MODE_FLAG_, FRAME_, LANDED_STATE_ or MSG_ whose value is one of pymavlink's
      values of that family (MAV_CMD_*, MAV_MODE_FLAG_*, MAV_FRAME_*, MAV_LANDED_STATE_*, MAVLINK_MSG_ID_*):
      `MODE_FLAG_ARMED = 128` is MAV_MODE_FLAG_SAFETY_ARMED under another name, `CMD_ARM = 400`
      MAV_CMD_COMPONENT_ARM_DISARM.
  Use `mavlink.<NAME>` there instead (missionplan.bridge.link.connection's `mavlink` is mavutil.mavlink), or, in a
  module free of pymavlink, import the number from missionplan.bridge.formats.mission_items.
- In the same files, the command and frame of a `MissionItem(...)` or `WireItem(...)` call (positional, in the
  field order of bridge/formats/mission_items.py: MissionItem(command, frame, ...), WireItem(seq, frame, command,
  ...); or keyword command= / frame=) are not int literals (nor expressions of int literals only): write
  `MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, ...)` or `mavlink.MAV_CMD_NAV_WAYPOINT`, not
  `MissionItem(16, 3, ...)`. A number that is deliberately a raw wire value under test (an unknown command, a
  frame the vehicle refuses) is allowed by a comment starting `# raw` on the line of that number.
"""

from __future__ import annotations

import ast
import dataclasses
import io
import tokenize
from pathlib import Path

import pytest

from missionplan.bridge.formats import mission_items as mission
from missionplan.bridge.link.connection import mavlink

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("bridge", "geo", "missionplan", "sitl_tests", "bench", "tests")
THE_ONE_MODULE = ROOT / "bridge" / "formats" / "mission_items.py"

# bridge/formats/mission_items.py's name -> pymavlink's name of the same number.
PYMAVLINK_NAMES = {
    "MAV_AUTOPILOT_GENERIC": "MAV_AUTOPILOT_GENERIC",
    "MAV_AUTOPILOT_ARDUPILOTMEGA": "MAV_AUTOPILOT_ARDUPILOTMEGA",
    "MAV_AUTOPILOT_INVALID": "MAV_AUTOPILOT_INVALID",
    "MAV_AUTOPILOT_PX4": "MAV_AUTOPILOT_PX4",
    "MAV_TYPE_QUADROTOR": "MAV_TYPE_QUADROTOR",
    "MAV_MISSION_ACCEPTED": "MAV_MISSION_ACCEPTED",
    "MAV_MISSION_ERROR": "MAV_MISSION_ERROR",
    "MAV_MISSION_UNSUPPORTED_FRAME": "MAV_MISSION_UNSUPPORTED_FRAME",
    "MAV_MISSION_UNSUPPORTED": "MAV_MISSION_UNSUPPORTED",
    "FRAME_GLOBAL": "MAV_FRAME_GLOBAL",
    "FRAME_MISSION": "MAV_FRAME_MISSION",
    "FRAME_GLOBAL_RELATIVE_ALT": "MAV_FRAME_GLOBAL_RELATIVE_ALT",
    "FRAME_GLOBAL_INT": "MAV_FRAME_GLOBAL_INT",
    "FRAME_GLOBAL_RELATIVE_ALT_INT": "MAV_FRAME_GLOBAL_RELATIVE_ALT_INT",
    "FRAME_GLOBAL_TERRAIN_ALT": "MAV_FRAME_GLOBAL_TERRAIN_ALT",
    "FRAME_GLOBAL_TERRAIN_ALT_INT": "MAV_FRAME_GLOBAL_TERRAIN_ALT_INT",
    "CMD_NAV_WAYPOINT": "MAV_CMD_NAV_WAYPOINT",
    "CMD_NAV_LOITER_UNLIM": "MAV_CMD_NAV_LOITER_UNLIM",
    "CMD_NAV_LOITER_TURNS": "MAV_CMD_NAV_LOITER_TURNS",
    "CMD_NAV_LOITER_TIME": "MAV_CMD_NAV_LOITER_TIME",
    "CMD_NAV_RETURN_TO_LAUNCH": "MAV_CMD_NAV_RETURN_TO_LAUNCH",
    "CMD_NAV_LAND": "MAV_CMD_NAV_LAND",
    "CMD_NAV_TAKEOFF": "MAV_CMD_NAV_TAKEOFF",
    "CMD_NAV_LOITER_TO_ALT": "MAV_CMD_NAV_LOITER_TO_ALT",
    "CMD_NAV_SPLINE_WAYPOINT": "MAV_CMD_NAV_SPLINE_WAYPOINT",
    "CMD_NAV_VTOL_TAKEOFF": "MAV_CMD_NAV_VTOL_TAKEOFF",
    "CMD_NAV_VTOL_LAND": "MAV_CMD_NAV_VTOL_LAND",
    "CMD_NAV_DELAY": "MAV_CMD_NAV_DELAY",
    "CMD_NAV_LAST": "MAV_CMD_NAV_LAST",
    "CMD_CONDITION_DELAY": "MAV_CMD_CONDITION_DELAY",
    "CMD_CONDITION_YAW": "MAV_CMD_CONDITION_YAW",
    "CMD_DO_JUMP": "MAV_CMD_DO_JUMP",
    "CMD_DO_CHANGE_SPEED": "MAV_CMD_DO_CHANGE_SPEED",
    "CMD_DO_LAND_START": "MAV_CMD_DO_LAND_START",
    "CMD_NAV_LAND_LOCAL": "MAV_CMD_NAV_LAND_LOCAL",
    "CMD_NAV_CONTINUE_AND_CHANGE_ALT": "MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT",
    "CMD_NAV_PAYLOAD_PLACE": "MAV_CMD_NAV_PAYLOAD_PLACE",
    "CMD_DO_SET_HOME": "MAV_CMD_DO_SET_HOME",
    "CMD_DO_REPOSITION": "MAV_CMD_DO_REPOSITION",
    "CMD_DO_SET_ROI_LOCATION": "MAV_CMD_DO_SET_ROI_LOCATION",
    "CMD_DO_SET_ROI": "MAV_CMD_DO_SET_ROI",
    "CMD_DO_DIGICAM_CONTROL": "MAV_CMD_DO_DIGICAM_CONTROL",
    "CMD_DO_MOUNT_CONTROL": "MAV_CMD_DO_MOUNT_CONTROL",
    "CMD_DO_SET_CAM_TRIGG_DIST": "MAV_CMD_DO_SET_CAM_TRIGG_DIST",
    "CMD_DO_SET_CAM_TRIGG_INTERVAL": "MAV_CMD_DO_SET_CAM_TRIGG_INTERVAL",
    "CMD_DO_GIMBAL_MANAGER_PITCHYAW": "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW",
    "CMD_IMAGE_START_CAPTURE": "MAV_CMD_IMAGE_START_CAPTURE",
    "CMD_IMAGE_STOP_CAPTURE": "MAV_CMD_IMAGE_STOP_CAPTURE",
    "CMD_DO_VTOL_TRANSITION": "MAV_CMD_DO_VTOL_TRANSITION",
    "CMD_FENCE_POLYGON_VERTEX_INCLUSION": "MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION",
    "CMD_FENCE_POLYGON_VERTEX_EXCLUSION": "MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION",
    "CMD_FENCE_CIRCLE_INCLUSION": "MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION",
    "CMD_FENCE_CIRCLE_EXCLUSION": "MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION",
    "CMD_RALLY_POINT": "MAV_CMD_NAV_RALLY_POINT",
    "SPEED_TYPE_GROUNDSPEED": "SPEED_TYPE_GROUNDSPEED",
    "MAV_MOUNT_MODE_MAVLINK_TARGETING": "MAV_MOUNT_MODE_MAVLINK_TARGETING",
}

# A local name with one of these prefixes holding a value of the pymavlink family is a re-declaration.
FAMILIES = {"CMD_": "MAV_CMD_", "MODE_FLAG_": "MAV_MODE_FLAG_", "FRAME_": "MAV_FRAME_",
            "LANDED_STATE_": "MAV_LANDED_STATE_", "MSG_": "MAVLINK_MSG_ID_"}


def _int_value(node: ast.expr) -> int | None:
    """The value of an int literal, or of an expression made of int literals only (`1 << 7`, `-1`)."""
    if not all(isinstance(n, (ast.Constant, ast.BinOp, ast.UnaryOp, ast.operator, ast.unaryop))
               for n in ast.walk(node)):
        return None
    if any(isinstance(n, ast.Constant) and type(n.value) is not int for n in ast.walk(node)):
        return None
    try:
        value = eval(compile(ast.Expression(node), "<constant>", "eval"), {"__builtins__": {}})  # noqa: S307
    except Exception:  # 1 << -1 and the like: no number
        return None
    return value if type(value) is int else None


def module_ints(source: str) -> list[tuple[str, int, int]]:
    """(name, value, line) of every module-level int constant, tuple assignments included."""
    found = []
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign):
            pairs = []
            for target in node.targets:
                if isinstance(target, ast.Name):
                    pairs.append((target, node.value))
                elif isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple) \
                        and len(target.elts) == len(node.value.elts):
                    pairs += zip(target.elts, node.value.elts)
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            pairs = [(node.target, node.value)]
        else:
            continue
        for target, value in pairs:
            number = _int_value(value)
            if isinstance(target, ast.Name) and number is not None:
                found.append((target.id, number, node.lineno))
    return found


def _family_values(prefix: str) -> frozenset[int]:
    return frozenset(v for name in dir(mavlink) if name.startswith(prefix)
                     and type(v := getattr(mavlink, name)) is int)


FAMILY_VALUES = {local: _family_values(theirs) for local, theirs in FAMILIES.items()}


def re_declared(source: str) -> list[str]:
    """The module-level constants of `source` that re-declare a pymavlink number (the module doc's rule)."""
    out = []
    for name, value, line in module_ints(source):
        if name.startswith("MAV_") and hasattr(mavlink, name):
            out.append(f"line {line}: {name} = {value} (mavlink.{name})")
            continue
        for prefix in FAMILIES:
            if name.startswith(prefix) and value in FAMILY_VALUES[prefix]:
                out.append(f"line {line}: {name} = {value} (a {FAMILIES[prefix]}* number)")
                break
    return out


def sources() -> list[Path]:
    return sorted(p for folder in FOLDERS for p in (ROOT / folder).rglob("*.py")
                  if "__pycache__" not in p.parts and p != THE_ONE_MODULE)


@pytest.mark.parametrize("local", sorted(PYMAVLINK_NAMES))
def test_the_pymavlink_free_numbers_are_pymavlinks(local: str) -> None:
    theirs = PYMAVLINK_NAMES[local]
    assert getattr(mission, local) == getattr(mavlink, theirs), f"mission_items.{local} is not mavlink.{theirs}"


def test_every_mavlink_number_of_the_one_module_is_checked() -> None:
    held = {name for name, _, _ in module_ints(THE_ONE_MODULE.read_text(encoding="utf-8"))
            if name.startswith(("MAV_", "CMD_", "FRAME_", "SPEED_TYPE_"))}
    assert held == set(PYMAVLINK_NAMES), (
        "map each MAVLink constant of bridge/formats/mission_items.py to its pymavlink name")


def test_mission_types_are_pymavlinks() -> None:
    for kind in mission.MissionType:
        assert int(kind) == getattr(mavlink, f"MAV_MISSION_TYPE_{kind.name}"), kind


@pytest.mark.parametrize("path", sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_module_re_declares_a_mavlink_number(path: Path) -> None:
    assert re_declared(path.read_text(encoding="utf-8")) == [], (
        "use mavlink.<NAME> (missionplan.bridge.link.connection's mavutil.mavlink), or import the number from "
        "bridge/formats/mission_items.py in a module free of pymavlink")


def test_the_rule_finds_a_re_declaration() -> None:
    # The checker itself: a re-declared number is found under its own name, under another name of its
    # family, in a tuple or an expression; other numbers, other names and non-literals are not.
    assert re_declared("MAV_TYPE_GCS = 6\n") == ["line 1: MAV_TYPE_GCS = 6 (mavlink.MAV_TYPE_GCS)"]
    assert re_declared("X = 1\nMODE_FLAG_ARMED = 1 << 7\n") == [
        "line 2: MODE_FLAG_ARMED = 128 (a MAV_MODE_FLAG_* number)"]
    assert [hit.split(":")[1] for hit in re_declared("TRIES, CMD_ARM, MSG_HOME = 5, 400, 242\n")] == [
        " CMD_ARM = 400 (a MAV_CMD_* number)", " MSG_HOME = 242 (a MAVLINK_MSG_ID_* number)"]
    assert re_declared("MAV_RESULT_ACCEPTED: int = 0\n") != []
    assert re_declared("CMD_ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM\nTIMEOUT_S = 6\nARDUPILOT_AUTO = 3\n"
                       "FRAME_COUNT = 99999\nMAV_NOT_A_MAVLINK_NAME = 1\nCMD_TEXT = 'x'\n") == []
    assert re_declared("def f():\n    CMD_ARM = 400\n") == []  # module level only


# The fields of bridge/formats/mission_items.py's dataclasses that hold a MAV_CMD or a MAV_FRAME, with their
# positional index, read from the dataclasses: MissionItem(command, frame, ...), WireItem(seq, frame, command, ...).
ITEM_FIELDS = {item.__name__: {field.name: index for index, field in enumerate(dataclasses.fields(item))
                               if field.name in ("command", "frame")}
               for item in (mission.MissionItem, mission.WireItem)}
RAW_MARK = "# raw"  # a comment starting so, on the line of a number, allows it as a deliberate raw wire value


def _raw_lines(source: str) -> set[int]:
    """The lines holding a comment that starts with RAW_MARK."""
    return {tok.start[0] for tok in tokenize.generate_tokens(io.StringIO(source).readline)
            if tok.type == tokenize.COMMENT and tok.string.startswith(RAW_MARK)}


def bare_item_numbers(source: str) -> list[str]:
    """The int literals written as the command or frame of a MissionItem / WireItem call (the module doc's rule)."""
    out = []
    raw = _raw_lines(source)
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        called = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
        if called not in ITEM_FIELDS:
            continue
        fields = ITEM_FIELDS[called]
        given = {name: node.args[index] for name, index in fields.items() if index < len(node.args)}
        given |= {kw.arg: kw.value for kw in node.keywords if kw.arg in fields}
        for name, value in sorted(given.items(), key=lambda pair: pair[1].lineno):
            number = _int_value(value)
            if number is not None and value.lineno not in raw:
                out.append(f"line {value.lineno}: {called} {name} {number}")
    return out


@pytest.mark.parametrize("path", sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_mission_item_has_a_bare_command_or_frame(path: Path) -> None:
    assert bare_item_numbers(path.read_text(encoding="utf-8")) == [], (
        "name the command and frame (mavlink.MAV_CMD_* / MAV_FRAME_*, or CMD_* / FRAME_* of "
        f"bridge/formats/mission_items.py), or mark a deliberate raw wire value with a trailing `{RAW_MARK}` comment")


def test_the_rule_finds_a_bare_item_number() -> None:
    # The checker itself: positional and keyword numbers of both dataclasses are found (WireItem's seq is not
    # a command), names and non-literals are not, and a `# raw` comment allows the numbers of its line.
    assert bare_item_numbers("MissionItem(16, 3)\n") == ["line 1: MissionItem command 16",
                                                         "line 1: MissionItem frame 3"]
    assert bare_item_numbers("MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT)\n") == []
    assert bare_item_numbers("m.MissionItem(command=mavlink.MAV_CMD_NAV_LAND, frame=-1 + 4, z=5)\n") == [
        "line 1: MissionItem frame 3"]
    assert bare_item_numbers("WireItem(0, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0.0, 0)\n") == [
        "line 1: WireItem frame 3", "line 1: WireItem command 16"]
    assert bare_item_numbers("WireItem(seq=1, frame=f, command=c)\nMissionItem(CMD_NAV_LAND, frame)\n") == []
    assert bare_item_numbers("MissionItem(31000, FRAME_MISSION)  # raw: an unknown command\n"
                             "MissionItem(16,\n            99)  # raw\n") == ["line 2: MissionItem command 16"]
