"""Mission files: QGroundControl `.plan` (JSON) and QGC WPL 110 `.waypoints`, read and written;
QGroundControl's legacy `.mission` read.

Owns the translation between those formats and formats.mission_items's model:
- `.plan`: fileType "Plan", version 1; mission.items of SimpleItem (command, frame, params[7] with
  null for NaN, autoContinue, doJumpId), plannedHomePosition; geoFence polygons and circles become
  fence items (MAV_CMD_NAV_FENCE_*), rallyPoints become rally items (MAV_CMD_NAV_RALLY_POINT).
  Items are read as QGroundControl reads them: the older item layouts and the legacy `.mission`
  file go through formats.qgc_legacy; a survey or corridor-scan ComplexItem contributes the
  waypoints QGroundControl stored in it ("TransectStyleComplexItem".Items, the ones QGroundControl
  flies from a loaded plan); a ComplexItem without stored waypoints (structure scan, landing
  pattern, old surveys), whose waypoints QGroundControl generates on load, is refused, as is an item
  whose altitude QGroundControl computes from its terrain data (AltitudeMode 3, or a terrain frame
  without an altitude): this tool has no terrain data to convert it with.
- `.waypoints`: first line "QGC WPL 110", then one tab-separated line of 12 columns per item; line 0
  is the home position (Mission Planner's convention), so mission items are lines 1..n.
DO_JUMP targets: a `.plan` names them by doJumpId, a `.waypoints` by line number; both become the
model's 1-based item number. Which reader runs: `.plan`, `.mission` and `.waypoints` by suffix; any
other name (Mission Planner's `.waypoints.txt` / `.txt`) by content, the `QGC WPL 110` header or a
JSON plan or mission.
Bad files raise BridgeUsageError naming the file, the item and the problem, and nothing else: a
reader never lets a number through that the wire cannot carry faithfully (a NaN or infinite
coordinate, a latitude beyond +-90, a frame that is not a uint8) because MISSION_ITEM_INT would carry
it as 0 or as garbage and the read-back would still agree with it. Nor anything beyond bridge.limits,
checked before any vehicle is contacted: more items than one MAVLink transfer carries (a .waypoints is read
line by line and refused at the first item too many; a JSON file larger than any legal one, MAX_JSON_BYTES,
is refused unread), a positional altitude outside its frame's range, an angle / speed / hold time outside
its range (PARAM_RANGES), a DO_JUMP outside the mission or repeating for ever in place (check_jumps).
Writes are atomic (temp file, then rename) with LF line endings.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

# A leaf utility with no planner imports: bridge still knows nothing about grids.
from missionplan.base.atomic import write_text_atomic

from . import qgc_legacy
from ..errors import BridgeError, BridgeUsageError
from ..limits import (ALTITUDE_AMSL_M, ALTITUDE_RELATIVE_M, ANGLE_DEG, HOLD_S, MAVLINK_MAX_ITEMS, MAX_MISSION_ITEMS,
                      SPEED_M_S, THROTTLE_PCT, check_range)
from .mission_items import (
    CMD_CONDITION_YAW,
    CMD_DO_CHANGE_SPEED,
    CMD_DO_GIMBAL_MANAGER_PITCHYAW,
    CMD_DO_JUMP,
    CMD_DO_MOUNT_CONTROL,
    CMD_DO_SET_ROI,
    CMD_DO_SET_ROI_LOCATION,
    CMD_FENCE_CIRCLE_EXCLUSION,
    CMD_FENCE_CIRCLE_INCLUSION,
    CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_LAND,
    CMD_NAV_LAST,
    CMD_NAV_LOITER_TIME,
    CMD_NAV_LOITER_TO_ALT,
    CMD_NAV_LOITER_TURNS,
    CMD_NAV_LOITER_UNLIM,
    CMD_NAV_SPLINE_WAYPOINT,
    CMD_NAV_TAKEOFF,
    CMD_NAV_VTOL_LAND,
    CMD_NAV_VTOL_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_INT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_GLOBAL_TERRAIN_ALT_INT,
    MAV_TYPE_QUADROTOR,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    is_global,
)

WPL_HEADER = "QGC WPL 110"
SUFFIXES = (".plan", ".waypoints")
PLAN_MISSION_VERSION = 2  # the only mission.version QGroundControl reads
SIMPLE_ITEM_TYPES = ("SimpleItem", "missionItem")  # "missionItem": the version 1 name of a SimpleItem

# QGroundControl's AltitudeMode (QGroundControlQmlGlobal::AltMode) that it turns into an altitude above
# sea level from its own terrain data when it loads the plan: the number in the file is not what it flies.
ALT_MODE_CALC_ABOVE_TERRAIN = 3
TERRAIN_FRAMES = {FRAME_GLOBAL_TERRAIN_ALT: "MAV_FRAME_GLOBAL_TERRAIN_ALT",
                  FRAME_GLOBAL_TERRAIN_ALT_INT: "MAV_FRAME_GLOBAL_TERRAIN_ALT_INT"}
TERRAIN_ADVICE = ("this tool has no terrain data to convert it with: in QGroundControl set the item's altitude "
                  "to relative (or absolute) and save the plan again, or fly a plan written by `missionplan plan`")

# ComplexItems QGroundControl reads (complexItemType -> what it is). Survey and corridor scan are
# TransectStyleComplexItems: QGroundControl saves their generated waypoints as "Items" and flies those
# from a loaded plan; the others are generated from their settings every time the plan is loaded.
COMPLEX_ITEM_KINDS = {"survey": "survey pattern", "CorridorScan": "corridor scan",
                      "StructureScan": "structure scan", "fwLandingPattern": "fixed-wing landing pattern",
                      "vtolLandingPattern": "VTOL landing pattern"}
STORED_ITEMS_KINDS = ("survey", "CorridorScan")
SURVEY_VERSIONS = range(2, 6)  # QGroundControl reads survey versions 2-5; 2 and 3 hold no waypoints

# Commands whose x / y are a position the vehicle flies to (or fences / rallies at). MISSION_ITEM_INT
# carries x / y as integers, so a NaN there would reach the vehicle as 0, 0 and read back "verified".
POSITIONAL_COMMANDS = frozenset({
    CMD_NAV_WAYPOINT, CMD_NAV_LOITER_UNLIM, CMD_NAV_LOITER_TURNS, CMD_NAV_LOITER_TIME, CMD_NAV_LAND,
    CMD_NAV_TAKEOFF, CMD_NAV_LOITER_TO_ALT, CMD_NAV_SPLINE_WAYPOINT, CMD_NAV_VTOL_TAKEOFF, CMD_NAV_VTOL_LAND,
    CMD_DO_SET_ROI_LOCATION, CMD_DO_SET_ROI,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION, CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
    CMD_FENCE_CIRCLE_INCLUSION, CMD_FENCE_CIRCLE_EXCLUSION, CMD_RALLY_POINT,
})


# Frames whose altitude is above mean sea level; every other frame's altitude is relative (home, terrain).
AMSL_FRAMES = frozenset({FRAME_GLOBAL, FRAME_GLOBAL_INT})

# The parameters a command defines as an angle, a speed or a time, checked within limits' ranges:
# command -> (param number, what it is, (low, high), unit).
_ANGLE = (ANGLE_DEG, " degrees")
PARAM_RANGES: dict[int, tuple[tuple[int, str, tuple[float, float], str], ...]] = {
    CMD_NAV_WAYPOINT: ((1, "hold time", HOLD_S, " s"), (4, "yaw", *_ANGLE)),
    CMD_NAV_LOITER_UNLIM: ((4, "yaw", *_ANGLE),),
    CMD_NAV_LOITER_TIME: ((1, "loiter time", HOLD_S, " s"),),
    CMD_NAV_LAND: ((4, "yaw", *_ANGLE),),
    CMD_NAV_TAKEOFF: ((1, "pitch", *_ANGLE), (4, "yaw", *_ANGLE)),
    CMD_NAV_SPLINE_WAYPOINT: ((1, "hold time", HOLD_S, " s"),),
    CMD_NAV_VTOL_TAKEOFF: ((4, "yaw", *_ANGLE),),
    CMD_NAV_VTOL_LAND: ((4, "yaw", *_ANGLE),),
    CMD_CONDITION_YAW: ((1, "heading", *_ANGLE),),
    CMD_DO_CHANGE_SPEED: ((2, "speed", SPEED_M_S, " m/s"), (3, "throttle", THROTTLE_PCT, " %")),
    CMD_DO_MOUNT_CONTROL: ((1, "pitch", *_ANGLE), (2, "roll", *_ANGLE), (3, "yaw", *_ANGLE)),
    CMD_DO_GIMBAL_MANAGER_PITCHYAW: ((1, "pitch", *_ANGLE), (2, "yaw", *_ANGLE)),
}

# A JSON mission file larger than this is not read: QGroundControl writes a mission item in 420-960 bytes
# (measured: its sample survey plan's items, and an item of 17-digit numbers at a survey's depth), a fence
# vertex or rally point in under 150, so a plan whose mission, fence and rally lists are all at the MAVLink
# limit (65,535 items each) stays under 75 MiB. A larger file cannot be a mission any vehicle takes; refusing it
# before it is read keeps a 1,000,000-item file from being parsed into a gigabyte of objects.
MAX_JSON_BYTES = 96 * 2**20
MAX_WAYPOINTS_LINE = 4096  # characters: a QGC WPL line of 12 numbers is under 400
SNIFF_CHARS = 4096  # how much of a file of another suffix is read to tell its format
JUMP_REPEAT_MAX = 32_767  # DO_JUMP's repeat count: ArduPilot keeps it as an int16


@dataclass
class PlanFile:
    """Everything a mission file holds: the mission, and for `.plan` files also fence and rally points."""

    mission: Mission = field(default_factory=Mission)
    fence: Mission = field(default_factory=lambda: Mission(mission_type=MissionType.FENCE))
    rally: Mission = field(default_factory=lambda: Mission(mission_type=MissionType.RALLY))
    firmware: Flavour | None = None
    cruise_speed: float | None = None
    hover_speed: float | None = None
    fence_max_altitude: float | None = None  # geoFence "maxAltitude" (metres above home), our extension

    def parts(self) -> list[Mission]:
        """The mission, then the fence and rally lists that have items."""
        return [self.mission] + [m for m in (self.fence, self.rally) if m.items]


class FirmwareMismatch(BridgeUsageError, BridgeError):
    """A .plan written for one autopilot, about to go to the other: bad input (exit 2 for `upload`),
    and a BridgeError too, so that a fleet flight fails that vehicle like any other upload failure."""


AUTOPILOT_NAMES = {Flavour.ARDUPILOT: "ArduPilot", Flavour.PX4: "PX4"}


def check_firmware(plan: PlanFile, path: str | os.PathLike[str], flavour: Flavour | None,
                   sysid: int | None = None) -> None:
    """FirmwareMismatch when `plan` says (its .plan firmwareType) it was written for ArduPilot and the
    vehicle is PX4, or the other way round. A file that names no autopilot (a .waypoints, a generic
    firmwareType) and a vehicle of another flavour are not checked."""
    written = plan.firmware
    if written not in AUTOPILOT_NAMES or flavour not in AUTOPILOT_NAMES or written is flavour:
        return
    vehicle = "the vehicle" if sysid is None else f"vehicle {sysid}"
    raise FirmwareMismatch(f"{path}: written for {AUTOPILOT_NAMES[written]} (firmwareType {written.autopilot}), but "
                           f"{vehicle} is {AUTOPILOT_NAMES[flavour]}: plan it again with `missionplan plan "
                           f"--autopilot {flavour.value}` (docs/px4-missions.md)")


# ---------------------------------------------------------------------------------------------- I/O

def _write_atomic(path: Path, text: str) -> None:
    """Temp file beside the target then rename (atomic): a reader never sees half a file."""
    if not path.parent.is_dir():
        raise BridgeUsageError(f"{path}: folder {path.parent} does not exist")
    write_text_atomic(path, text)


def _check_file(path: Path) -> None:
    if not path.exists():
        raise BridgeUsageError(f"{path}: no such file")
    if not path.is_file():
        raise BridgeUsageError(f"{path}: not a file")


def _read_text(path: Path, limit: int | None = None) -> str:
    """The file's text (its first `limit` characters when given); one-line BridgeUsageError otherwise."""
    _check_file(path)
    try:
        with path.open(encoding="utf-8-sig") as stream:
            return stream.read() if limit is None else stream.read(limit)
    except UnicodeDecodeError:
        raise BridgeUsageError(f"{path}: not a text file (expected a .plan or .waypoints mission)") from None
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None


def _too_many(path: Path, label: str, limit: int, where: str = "", count: int | None = None) -> BridgeUsageError:
    """The one line for a list longer than a MAVLink transfer carries (MISSION_COUNT's count is a uint16)."""
    home = ", ArduPilot's home item one of them" if limit == MAX_MISSION_ITEMS else ""
    held = f"more than {limit:,}" if count is None else f"{count:,}"
    return BridgeUsageError(f"{path}: {where}{held} {label} items: one upload carries at most {limit:,} (MAVLink's "
                            f"MISSION_COUNT counts {MAVLINK_MAX_ITEMS:,} items at most{home}); split it")


def read_mission_file(path: str | os.PathLike[str]) -> PlanFile:
    """Read a `.plan`, `.mission` or `.waypoints` file: by suffix, or for any other name by its content."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        return read_plan(path)
    if suffix == ".mission":
        return read_qgc_mission(path)
    if suffix == ".waypoints":
        return PlanFile(mission=read_waypoints(path))
    # Mission Planner and QGroundControl also save QGC WPL files as `.waypoints.txt` or `.txt`: told by
    # their first characters, without reading the whole file.
    start = _read_text(path, SNIFF_CHARS).lstrip()
    if start.startswith("QGC WPL"):
        return PlanFile(mission=read_waypoints(path))
    if start.startswith("{"):
        doc = _read_json(path)
        if isinstance(doc, dict) and doc.get("fileType") != "Plan" and _looks_like_mission_file(doc):
            return _plan_from_mission_file(doc, path)
        return _plan_from_document(doc, path)
    raise BridgeUsageError(f"{path}: not a mission file (expected a QGroundControl .plan or a file whose first line "
                           f"is \"{WPL_HEADER}\")")


def output_format(path: str | os.PathLike[str]) -> str:
    """"plan" or "waypoints": what write_mission_file writes to this name; BridgeUsageError otherwise."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        return "plan"
    if suffix in (".waypoints", ".txt"):  # .txt: Mission Planner's other name for a QGC WPL file
        return "waypoints"
    raise BridgeUsageError(f"{path}: unknown mission file type {path.suffix!r} (expected .plan, .waypoints "
                           "or .txt)")


def write_mission_file(path: str | os.PathLike[str], plan: PlanFile) -> None:
    """Write a `.plan` or `.waypoints` (or `.txt`) file, chosen by its suffix (.waypoints keeps only the mission)."""
    if output_format(path) == "plan":
        write_plan(path, plan)
    else:
        write_waypoints(path, plan.mission)


# -------------------------------------------------------------------------------------------- .plan

def _number(value: Any, where: str, path: Path) -> float:
    """A JSON number, with null meaning NaN (QGroundControl's way of writing NaN)."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BridgeUsageError(f"{path}: {where}: expected a number, got {_short(value)}")
    try:
        return float(value)
    except OverflowError:  # a JSON integer with hundreds of digits
        raise BridgeUsageError(f"{path}: {where}: number out of range") from None


def _integer(value: Any, where: str, path: Path, low: int = -(2**31), high: int = 2**31 - 1) -> int:
    """A JSON integer (or integral float) in [low, high]: the range of the MAVLink field it goes to."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (
            isinstance(value, float) and not (math.isfinite(value) and value.is_integer())):
        raise BridgeUsageError(f"{path}: {where}: expected an integer, got {_short(value)}")
    if not low <= value <= high:
        raise BridgeUsageError(f"{path}: {where}: {_short(value)} is out of range ({low}..{high})")
    return int(value)


def _short(value: Any) -> str:
    """A value for an error message: one line, not the whole of a large JSON structure."""
    text = repr(value).replace("\n", " ")
    return text if len(text) <= 60 else text[:57] + "..."


def _list(value: Any, where: str, path: Path) -> list[Any]:
    """An optional JSON list (absent or null is empty)."""
    if value is None:
        return []
    if not isinstance(value, list):
        raise BridgeUsageError(f"{path}: {where} must be a list, got {_short(value)}")
    return value


def check_item(item: MissionItem, where: str, path: str | os.PathLike[str]) -> MissionItem:
    """Refuse numbers the wire cannot carry faithfully; NaN x / y of items without a position become 0.

    Parameters 1-4 may be NaN (QGroundControl's null: "unchanged", e.g. yaw) but not infinite. In a
    global frame a positional command needs a finite latitude in [-90, 90], longitude in [-180, 180]
    and altitude; other items' NaN x / y are written as 0 (all MISSION_ITEM_INT can carry).
    """
    for number, value in enumerate((item.param1, item.param2, item.param3, item.param4), start=1):
        if math.isinf(value):
            raise BridgeUsageError(f"{path}: {where}: param{number} is {value} (parameters must be finite; "
                                   "null means unset)")
        if not _fits_float32(value):
            raise BridgeUsageError(f"{path}: {where}: param{number} {value:g} does not fit a MAVLink float")
    positional = item.command in POSITIONAL_COMMANDS and is_global(item.frame)
    for name, value, limit in (("latitude", item.x, 90.0), ("longitude", item.y, 180.0)):
        if not is_global(item.frame):
            name, limit = ("x" if name == "latitude" else "y"), 2.0**31 - 1  # an int32 on the wire
        if math.isnan(value):
            if positional:
                raise BridgeUsageError(f"{path}: {where}: {name} is NaN / null, but command {item.command} "
                                       "needs a position")
        elif not abs(value) <= limit:
            raise BridgeUsageError(f"{path}: {where}: {name} {value} is out of range (-{limit:g}..{limit:g})")
    if math.isinf(item.z) or (positional and math.isnan(item.z)):
        raise BridgeUsageError(f"{path}: {where}: altitude is {item.z}, but command {item.command} needs a finite "
                               "altitude")
    if not _fits_float32(item.z):
        raise BridgeUsageError(f"{path}: {where}: altitude {item.z:g} does not fit a MAVLink float")
    if item.command in POSITIONAL_COMMANDS and not math.isnan(item.z):  # NaN: refused above where it matters
        low, high = ALTITUDE_AMSL_M if item.frame in AMSL_FRAMES else ALTITUDE_RELATIVE_M
        check_range(item.z, f"{path}: {where}: altitude", low, high, unit=" m",
                    what=_altitude_kind(item.frame))
    _check_params(item, where, path)
    if math.isnan(item.x) or math.isnan(item.y):
        item.x = 0.0 if math.isnan(item.x) else item.x
        item.y = 0.0 if math.isnan(item.y) else item.y
    return item


def _altitude_kind(frame: int) -> str:
    """What an altitude in this frame measures, for a message."""
    if frame in AMSL_FRAMES:
        return f"metres above sea level (frame {frame})"
    if frame in TERRAIN_FRAMES:
        return f"metres above the terrain (frame {frame})"
    return f"metres above home (frame {frame})" if is_global(frame) else f"metres (frame {frame})"


def _check_params(item: MissionItem, where: str, path: str | os.PathLike[str]) -> None:
    """The parameters the item's command defines as an angle, a speed or a hold time, within limits.ANGLE_DEG,
    SPEED_M_S / THROTTLE_PCT and HOLD_S; NaN (QGroundControl's null: "unchanged") passes."""
    for number, name, limits, unit in PARAM_RANGES.get(item.command, ()):
        value = item.params[number - 1]
        if not math.isnan(value):
            check_range(value, f"{path}: {where}: param{number} ({name})", *limits, unit=unit)


def _fits_float32(value: float) -> bool:
    """Whether MAVLink's float fields (params, z) can carry the value (NaN can)."""
    try:
        struct.pack("<f", value)
    except OverflowError:
        return False
    return True


def _check_home(home: tuple[float, float, float], where: str, path: Path) -> tuple[float, float, float]:
    lat, lon, alt = home
    if not (abs(lat) <= 90.0 and abs(lon) <= 180.0):
        raise BridgeUsageError(f"{path}: {where}: [{lat}, {lon}] is not a latitude / longitude")
    if math.isinf(alt) or not _fits_float32(alt):
        raise BridgeUsageError(f"{path}: {where}: altitude {alt:g} is not a usable number")
    if not math.isnan(alt):
        check_range(alt, f"{path}: {where}: altitude", *ALTITUDE_AMSL_M, unit=" m", what="metres above sea level")
    return (lat, lon, 0.0 if math.isnan(alt) else alt)


def _latlon(value: Any, where: str, path: Path, length: int = 2) -> list[float]:
    if not isinstance(value, list) or len(value) < length:
        raise BridgeUsageError(f"{path}: {where}: expected [lat, lon{', alt' if length == 3 else ''}], "
                               f"got {_short(value)}")
    return [_number(v, where, path) for v in value[:length]]


def _read_json(path: Path) -> Any:
    _check_file(path)
    try:
        size = path.stat().st_size
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None
    if size > MAX_JSON_BYTES:
        raise BridgeUsageError(f"{path}: {size / 2**20:,.0f} MiB, larger than any mission MAVLink can carry (at most "
                               f"{MAVLINK_MAX_ITEMS:,} items per list, under {MAX_JSON_BYTES // 2**20} MiB as "
                               "QGroundControl writes them); not read")
    try:
        return json.loads(_read_text(path))
    except json.JSONDecodeError as err:
        raise BridgeUsageError(f"{path}: not valid JSON (line {err.lineno}: {err.msg})") from None
    except RecursionError:
        raise BridgeUsageError(f"{path}: not a plan (JSON nested too deeply)") from None


def _looks_like_mission_file(doc: dict[str, Any]) -> bool:
    """A legacy QGroundControl .mission document: fileType "Mission" (version 2) or none (version 1)."""
    return doc.get("fileType", qgc_legacy.MISSION_FILE_TYPE) == qgc_legacy.MISSION_FILE_TYPE and "items" in doc


def read_plan(path: str | os.PathLike[str]) -> PlanFile:
    path = Path(path)
    return _plan_from_document(_read_json(path), path)


def _plan_from_document(doc: Any, path: Path) -> PlanFile:
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        hint = " (a QGroundControl .mission file? name it .mission)" if (
            isinstance(doc, dict) and _looks_like_mission_file(doc)) else ""
        raise BridgeUsageError(f"{path}: not a QGroundControl plan (fileType is not \"Plan\"){hint}")
    if type(doc.get("version")) is not int or doc["version"] != 1:
        raise BridgeUsageError(f"{path}: unsupported plan version {_short(doc.get('version'))} (expected 1)")
    mission_doc = doc.get("mission")
    if not isinstance(mission_doc, dict) or not isinstance(mission_doc.get("items"), list):
        raise BridgeUsageError(f"{path}: the plan has no mission.items list")
    plan = _read_mission(mission_doc, path)
    plan.fence = _read_fence(doc.get("geoFence"), path)
    if isinstance(doc.get("geoFence"), dict) and doc["geoFence"].get("maxAltitude") is not None:
        plan.fence_max_altitude = check_range(_number(doc["geoFence"]["maxAltitude"], "geoFence maxAltitude", path),
                                              f"{path}: geoFence maxAltitude", *ALTITUDE_RELATIVE_M, unit=" m",
                                              what="metres above home")
    plan.rally = _read_rally(doc.get("rallyPoints"), path)
    return plan


def read_qgc_mission(path: str | os.PathLike[str]) -> PlanFile:
    """QGroundControl's legacy `.mission` file (version "1.0" or 2): its mission, no fence or rally points."""
    path = Path(path)
    return _plan_from_mission_file(_read_json(path), path)


def _plan_from_mission_file(doc: Any, path: Path) -> PlanFile:
    if isinstance(doc, dict) and doc.get("fileType") == "Plan":
        return _plan_from_document(doc, path)  # a .plan under another name: it is what it says
    if not isinstance(doc, dict) or doc.get("fileType", qgc_legacy.MISSION_FILE_TYPE) != qgc_legacy.MISSION_FILE_TYPE:
        raise BridgeUsageError(f"{path}: not a QGroundControl mission (fileType is not \"Mission\" or \"Plan\")")
    return _read_mission(qgc_legacy.mission_object(doc, path), path)


def _read_mission(mission_doc: dict[str, Any], path: Path) -> PlanFile:
    """A `.plan` mission object (mission.items, plannedHomePosition, firmwareType, speeds) as a PlanFile."""
    # QGroundControl refuses any other mission version; a later format may mean something else.
    if "version" in mission_doc and (type(mission_doc["version"]) is not int
                                     or mission_doc["version"] != PLAN_MISSION_VERSION):
        raise BridgeUsageError(f"{path}: unsupported mission.version {_short(mission_doc['version'])} "
                               f"(QGroundControl plans have {PLAN_MISSION_VERSION})")

    home = None
    if mission_doc.get("plannedHomePosition") is not None:
        lat, lon, alt = _latlon(mission_doc["plannedHomePosition"], "mission.plannedHomePosition", path, 3)
        home = _check_home((lat, lon, alt), "mission.plannedHomePosition", path)

    # (item, its doJumpId, where it is in the file, whether it is a SimpleItem of the mission). QGroundControl
    # resolves doJumpIds among the mission's SimpleItems only: a ComplexItem's stored items are neither
    # targets nor have their own DO_JUMP targets rewritten.
    raw_items: list[tuple[MissionItem, int | None, str, bool]] = []
    if len(mission_doc["items"]) > MAX_MISSION_ITEMS:  # before any item is read
        raise _too_many(path, "mission", MAX_MISSION_ITEMS, count=len(mission_doc["items"]))
    for index, entry in enumerate(mission_doc["items"]):
        where = f"mission item {index + 1}"
        if not isinstance(entry, dict):
            raise BridgeUsageError(f"{path}: {where}: expected an object")
        kind = entry.get("type")
        if kind == "ComplexItem":
            name = entry.get("complexItemType")
            for number, stored in enumerate(_stored_complex_items(entry, where, path), start=1):
                inner = f"{where} ({name} item {number})"
                if not isinstance(stored, dict) or stored.get("type") not in SIMPLE_ITEM_TYPES:
                    raise BridgeUsageError(f"{path}: {inner}: expected a SimpleItem object")
                if len(raw_items) == MAX_MISSION_ITEMS:  # a survey's stored items count too
                    raise _too_many(path, "mission", MAX_MISSION_ITEMS, f"{inner}: ")
                raw_items.append((_simple_item(stored, inner, path)[0], None, inner, False))
            continue
        if kind not in SIMPLE_ITEM_TYPES:
            raise BridgeUsageError(f"{path}: {where}: unknown item type {_short(kind)}")
        item, jump_id = _simple_item(entry, where, path)
        raw_items.append((item, jump_id, where, True))

    # DO_JUMP names its target by doJumpId; the model counts items from 1.
    by_jump_id = {jump_id: number for number, (_, jump_id, _, simple) in enumerate(raw_items, start=1)
                  if simple and jump_id is not None}
    items: list[MissionItem] = []
    for item, _, where, simple in raw_items:
        if item.command == CMD_DO_JUMP and simple:
            if not math.isfinite(item.param1):
                raise BridgeUsageError(f"{path}: {where}: DO_JUMP without a target doJumpId")
            target = int(round(item.param1))
            if target not in by_jump_id:
                raise BridgeUsageError(f"{path}: {where}: DO_JUMP to doJumpId {target}, which no item has")
            item.param1 = float(by_jump_id[target])
        items.append(item)
    check_jumps(items, [where for _, _, where, _ in raw_items], path)

    firmware = None
    if "firmwareType" in mission_doc:
        firmware = Flavour.from_autopilot(_integer(mission_doc["firmwareType"], "mission.firmwareType", path))
    return PlanFile(mission=Mission(items=items, mission_type=MissionType.MISSION, home=home), firmware=firmware,
                    cruise_speed=_optional_speed(mission_doc.get("cruiseSpeed"), path, "mission.cruiseSpeed"),
                    hover_speed=_optional_speed(mission_doc.get("hoverSpeed"), path, "mission.hoverSpeed"))


def check_jumps(items: list[MissionItem], wheres: list[str], path: str | os.PathLike[str]) -> None:
    """Every DO_JUMP of the mission (its target the model's 1-based item number) jumps to an item of the
    mission, repeats a number of times an autopilot can count, and does not loop forever without flying.

    A jump that repeats forever (repeat -1) back over items none of which is a navigation command (its own
    item, or only DO_ / CONDITION_ items) goes nowhere: the vehicle hovers where it is and the rest of the
    mission is never flown. Measured on ArduCopter SITL: it takes such a mission (takeoff, a DO_JUMP to itself
    with repeat -1, a waypoint 550 m away: MISSION_ACK ACCEPTED, stored as sent), flies it in AUTO, says
    "Mission: 2 Jump 64/unlimited" as its AP_Mission gives up looking for the next navigation command, and
    hovers over its takeoff point with the takeoff still current, the waypoint never flown, until its battery
    or a pilot ends it. A target outside the mission it refuses with MAV_MISSION_ERROR (target 0 or past the
    last item); PX4 SIH takes either and stores the repeat -1 as 65535 (its repeat count is a uint16).
    """
    for number, (item, where) in enumerate(zip(items, wheres), start=1):
        if item.command != CMD_DO_JUMP:
            continue
        if not math.isfinite(item.param1) or not 1 <= round(item.param1) <= len(items):
            raise BridgeUsageError(f"{path}: {where}: DO_JUMP to item {item.param1:g}, outside the mission's "
                                   f"items 1..{len(items)}")
        target = int(round(item.param1))
        repeat = item.param2
        if not (math.isfinite(repeat) and repeat == int(repeat) and -1 <= repeat <= JUMP_REPEAT_MAX):
            raise BridgeUsageError(f"{path}: {where}: DO_JUMP repeat {repeat:g} is not a count (-1 for ever, or 0 "
                                   f"to {JUMP_REPEAT_MAX:,}: ArduPilot keeps it as an int16)")
        loop = items[target - 1:number] if target <= number else []
        if repeat == -1 and loop and not any(it.command < CMD_NAV_LAST for it in loop):
            span = "to itself" if target == number else f"back to item {target}"
            raise BridgeUsageError(f"{path}: {where}: DO_JUMP {span} repeats for ever (repeat -1) over no "
                                   "navigation command: the vehicle would stay where it is and never fly the rest "
                                   "of the mission")


def _optional_speed(value: Any, path: Path, where: str) -> float | None:
    """A plan's cruiseSpeed / hoverSpeed: absent, or metres per second from 0 to limits.SPEED_M_S's top."""
    if value is None:
        return None
    return check_range(_number(value, where, path), f"{path}: {where}", 0.0, SPEED_M_S[1], unit=" m/s")


def _simple_item(entry: dict[str, Any], where: str, path: Path) -> tuple[MissionItem, int | None]:
    """One SimpleItem in any layout QGroundControl reads, checked, and its doJumpId."""
    params = qgc_legacy.item_params(entry, where, path)
    p = [_number(v, f"{where} params", path) for v in params]
    frame = _integer(entry.get("frame"), f"{where} frame", path, 0, 255)  # uint8 on the wire
    command = _integer(entry.get("command"), f"{where} command", path, 0, 65535)  # uint16
    item = MissionItem(command=command, frame=frame, param1=p[0], param2=p[1], param3=p[2], param4=p[3],
                       x=p[4], y=p[5], z=p[6], autocontinue=bool(entry.get("autoContinue", True)))
    refuse_terrain_altitude(item, where, path, entry.get("AltitudeMode"))
    check_item(item, where, path)
    jump_id = entry.get("doJumpId")
    return item, None if jump_id is None else _integer(jump_id, f"{where} doJumpId", path)


def refuse_terrain_altitude(item: MissionItem, where: str, path: str | os.PathLike[str],
                            altitude_mode: Any = None) -> None:
    """BridgeUsageError for an item whose altitude is above terrain and known only from terrain data.

    QGroundControl's AltitudeMode 3 ("calculated above terrain") keeps the height above terrain aside and
    puts into param 7 an altitude above sea level that it computes from its terrain data whenever it loads
    the plan (null until that data has come). A terrain frame (10, 11) without an altitude is the same
    question unanswered. A terrain frame with an altitude goes to the vehicle as it is, as QGroundControl
    sends it: the autopilot follows the terrain itself (ArduPilot does; PX4 refuses the frame).
    """
    if type(altitude_mode) in (int, float) and altitude_mode == ALT_MODE_CALC_ABOVE_TERRAIN:
        raise BridgeUsageError(f"{path}: {where}: altitude is terrain-relative (QGroundControl's AltitudeMode 3: a "
                               "height above terrain that QGroundControl turns into an altitude above sea level "
                               f"from its terrain data when it loads the plan); {TERRAIN_ADVICE}")
    positional = item.command in POSITIONAL_COMMANDS and is_global(item.frame)
    if item.frame in TERRAIN_FRAMES and positional and math.isnan(item.z):
        raise BridgeUsageError(f"{path}: {where}: altitude is terrain-relative (frame {item.frame}, "
                               f"{TERRAIN_FRAMES[item.frame]}) and has no value; {TERRAIN_ADVICE}")


def _stored_complex_items(entry: dict[str, Any], where: str, path: Path) -> list[Any]:
    """The mission items QGroundControl stored in a ComplexItem and flies, or BridgeUsageError why none."""
    name = entry.get("complexItemType")
    name = name if isinstance(name, str) else None
    if name not in COMPLEX_ITEM_KINDS:
        raise BridgeUsageError(f"{path}: {where} is a ComplexItem of type {_short(name)}, which QGroundControl "
                               f"does not read (it reads {', '.join(COMPLEX_ITEM_KINDS)})")
    version = entry.get("version")
    if name == "survey" and not (type(version) in (int, float) and version in SURVEY_VERSIONS):
        raise BridgeUsageError(f"{path}: {where} is a survey ComplexItem of version {_short(version)}, which "
                               "QGroundControl does not read (it reads versions 2 to 5)")
    inner = entry.get("TransectStyleComplexItem")
    stored = inner.get("Items") if isinstance(inner, dict) else None
    if name in STORED_ITEMS_KINDS and isinstance(stored, list) and stored:
        return stored
    if name in STORED_ITEMS_KINDS:
        fix = ("open the plan in QGroundControl and save it again (QGroundControl then stores the generated "
               f"waypoints in it), or plan the area with `missionplan plan --area {path}`")
    else:
        fix = (f"QGroundControl never stores a {COMPLEX_ITEM_KINDS[name]}'s waypoints in a plan, so upload it with "
               "QGroundControl and read the mission back with `missionplan download`")
    raise BridgeUsageError(f"{path}: {where} is a {name} ComplexItem, a QGroundControl {COMPLEX_ITEM_KINDS[name]} "
                           "whose waypoints QGroundControl generates when it loads the plan; the file does not "
                           f"hold them and this tool does not generate them: {fix}")


def _optional_number(value: Any, path: Path, where: str) -> float | None:
    return None if value is None else _number(value, where, path)


def _read_fence(doc: Any, path: Path) -> Mission:
    fence = Mission(mission_type=MissionType.FENCE)
    if doc is None:
        return fence
    if not isinstance(doc, dict):
        raise BridgeUsageError(f"{path}: geoFence must be an object")
    for index, poly in enumerate(_list(doc.get("polygons"), "geoFence.polygons", path)):
        where = f"geoFence polygon {index + 1}"
        if not isinstance(poly, dict) or not isinstance(poly.get("polygon"), list) or len(poly["polygon"]) < 3:
            raise BridgeUsageError(f"{path}: {where}: needs a polygon of at least 3 [lat, lon] points")
        command = CMD_FENCE_POLYGON_VERTEX_INCLUSION if poly.get("inclusion", True) else CMD_FENCE_POLYGON_VERTEX_EXCLUSION
        vertices = poly["polygon"]
        if len(fence.items) + len(vertices) > MAVLINK_MAX_ITEMS:
            raise _too_many(path, "fence", MAVLINK_MAX_ITEMS, f"{where}: ")
        for number, vertex in enumerate(vertices, start=1):
            lat, lon = _latlon(vertex, where, path)
            # autocontinue 0: a fence point is no navigation step, and ArduPilot stores (and reads back) 0
            fence.items.append(check_item(MissionItem(command=command, frame=FRAME_GLOBAL,
                                                      param1=float(len(vertices)), x=lat, y=lon, z=0.0,
                                                      autocontinue=False),
                                          f"{where} point {number}", path))
    for index, circle in enumerate(_list(doc.get("circles"), "geoFence.circles", path)):
        where = f"geoFence circle {index + 1}"
        if len(fence.items) == MAVLINK_MAX_ITEMS:
            raise _too_many(path, "fence", MAVLINK_MAX_ITEMS, f"{where}: ")
        body = circle.get("circle") if isinstance(circle, dict) else None
        if not isinstance(body, dict):
            raise BridgeUsageError(f"{path}: {where}: expected {{\"circle\": {{\"center\": [lat, lon], \"radius\": r}}}}")
        lat, lon = _latlon(body.get("center"), where, path)
        radius = _number(body.get("radius"), f"{where} radius", path)
        if not (math.isfinite(radius) and radius > 0):
            raise BridgeUsageError(f"{path}: {where}: radius must be a positive number of metres, got {radius}")
        command = CMD_FENCE_CIRCLE_INCLUSION if circle.get("inclusion", True) else CMD_FENCE_CIRCLE_EXCLUSION
        fence.items.append(check_item(MissionItem(command=command, frame=FRAME_GLOBAL, param1=radius, x=lat, y=lon,
                                                  z=0.0, autocontinue=False), where, path))
    return fence


def _read_rally(doc: Any, path: Path) -> Mission:
    rally = Mission(mission_type=MissionType.RALLY)
    if doc is None:
        return rally
    if not isinstance(doc, dict):
        raise BridgeUsageError(f"{path}: rallyPoints must be an object")
    points = _list(doc.get("points"), "rallyPoints.points", path)
    if len(points) > MAVLINK_MAX_ITEMS:
        raise _too_many(path, "rally", MAVLINK_MAX_ITEMS, count=len(points))
    for index, point in enumerate(points):
        where = f"rally point {index + 1}"
        lat, lon, alt = _latlon(point, where, path, 3)
        rally.items.append(check_item(MissionItem(command=CMD_RALLY_POINT, frame=FRAME_GLOBAL_RELATIVE_ALT, x=lat,
                                                  y=lon, z=alt), where, path))
    return rally


def _json_number(value: float) -> float | int | None:
    if math.isnan(value):
        return None  # QGroundControl writes NaN as null
    if math.isinf(value):
        raise BridgeUsageError(f"cannot write an infinite parameter ({value}) to a plan")
    return int(value) if float(value).is_integer() and abs(value) < 2**53 else value


def _default_home(mission: Mission) -> tuple[float, float, float]:
    if mission.home is not None:
        return mission.home
    for item in mission.items:
        if is_global(item.frame) and (item.x or item.y):
            return (item.x, item.y, 0.0)
    return (0.0, 0.0, 0.0)


def plan_document(plan: PlanFile) -> dict[str, Any]:
    """The QGroundControl JSON document for a plan (doJumpId = item number, so DO_JUMP is unchanged)."""
    items = []
    for number, item in enumerate(plan.mission.items, start=1):
        items.append({"autoContinue": bool(item.autocontinue), "command": int(item.command), "doJumpId": number,
                      "frame": int(item.frame), "params": [_json_number(v) for v in item.params],
                      "type": "SimpleItem"})
    home = _default_home(plan.mission)
    firmware = plan.firmware or Flavour.ARDUPILOT
    mission_doc: dict[str, Any] = {
        "cruiseSpeed": plan.cruise_speed if plan.cruise_speed is not None else 5,
        "firmwareType": firmware.autopilot,
        "globalPlanAltitudeMode": 1,
        "hoverSpeed": plan.hover_speed if plan.hover_speed is not None else 5,
        "items": items,
        "plannedHomePosition": [home[0], home[1], home[2]],
        "vehicleType": MAV_TYPE_QUADROTOR,
        "version": 2,
    }
    fence = _fence_document(plan.fence)
    if plan.fence_max_altitude is not None:  # QGroundControl ignores it; the autopilot's ceiling is a parameter
        fence["maxAltitude"] = plan.fence_max_altitude
    return {"fileType": "Plan", "geoFence": fence, "groundStation": "QGroundControl",
            "mission": mission_doc, "rallyPoints": _rally_document(plan.rally), "version": 1}


def _fence_document(fence: Mission) -> dict[str, Any]:
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    items = fence.items
    i = 0
    while i < len(items):
        item = items[i]
        if item.command in (CMD_FENCE_POLYGON_VERTEX_INCLUSION, CMD_FENCE_POLYGON_VERTEX_EXCLUSION):
            count = max(1, int(round(item.param1)))
            vertices = items[i:i + count]
            polygons.append({"inclusion": item.command == CMD_FENCE_POLYGON_VERTEX_INCLUSION,
                             "polygon": [[v.x, v.y] for v in vertices], "version": 1})
            i += count
        elif item.command in (CMD_FENCE_CIRCLE_INCLUSION, CMD_FENCE_CIRCLE_EXCLUSION):
            circles.append({"circle": {"center": [item.x, item.y], "radius": item.param1},
                            "inclusion": item.command == CMD_FENCE_CIRCLE_INCLUSION, "version": 1})
            i += 1
        else:
            raise BridgeUsageError(f"fence item {i + 1}: command {item.command} cannot be written to a plan's geoFence")
    return {"circles": circles, "polygons": polygons, "version": 2}


def _rally_document(rally: Mission) -> dict[str, Any]:
    return {"points": [[p.x, p.y, p.z] for p in rally.items], "version": 2}


def write_plan(path: str | os.PathLike[str], plan: PlanFile) -> None:
    _write_atomic(Path(path), json.dumps(plan_document(plan), indent=4) + "\n")


# --------------------------------------------------------------------------------------- .waypoints

def read_waypoints(path: str | os.PathLike[str]) -> Mission:
    """A QGC WPL 110 file: line 0 is home, lines 1..n the mission items.

    Read line by line: a file of more items than MAVLink can carry is refused at the first item too many,
    and a line longer than any QGC WPL line at its first MAX_WAYPOINTS_LINE characters, so no file is ever
    held whole in memory."""
    path = Path(path)
    _check_file(path)
    try:
        with path.open(encoding="utf-8-sig") as stream:
            return _parse_waypoints(stream, path)
    except UnicodeDecodeError:
        raise BridgeUsageError(f"{path}: not a text file (expected a .plan or .waypoints mission)") from None
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None


def _lines(stream: TextIO, path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of each line that is not blank, none longer than MAX_WAYPOINTS_LINE."""
    number = 0
    while line := stream.readline(MAX_WAYPOINTS_LINE + 1):
        number += 1
        if len(line) > MAX_WAYPOINTS_LINE and not line.endswith("\n"):
            raise BridgeUsageError(f"{path}: line {number} is longer than {MAX_WAYPOINTS_LINE:,} characters: not a "
                                   "waypoints file")
        if line.strip():
            yield number, line.rstrip("\r\n")


def _parse_waypoints(stream: TextIO, path: Path) -> Mission:
    lines = _lines(stream, path)
    header = next(lines, (0, ""))[1].strip()
    if not header.startswith("QGC WPL"):
        raise BridgeUsageError(f"{path}: not a waypoints file (first line is not \"{WPL_HEADER}\")")
    if header.split()[-1] != "110":
        raise BridgeUsageError(f"{path}: unsupported waypoints version {header.split()[-1]!r} (expected 110)")
    items: list[MissionItem] = []
    wheres: list[str] = []
    home: tuple[float, float, float] | None = None
    for position, (line_no, line) in enumerate(lines):
        if position > MAX_MISSION_ITEMS:
            raise _too_many(path, "mission", MAX_MISSION_ITEMS, f"line {line_no}: ")
        fields = [f.strip() for f in (line.split("\t") if "\t" in line else line.split())]
        if len(fields) != 12:
            raise BridgeUsageError(f"{path}: line {line_no}: expected 12 tab-separated columns, got {len(fields)}")
        try:
            index, _current, frame, command = (int(fields[0]), int(fields[1]), int(fields[2]), int(fields[3]))
            p1, p2, p3, p4, x, y, z = (float(v) for v in fields[4:11])
            autocontinue = int(float(fields[11]))
        except (ValueError, OverflowError):
            raise BridgeUsageError(f"{path}: line {line_no}: a column is not a number") from None
        if index != position:
            raise BridgeUsageError(f"{path}: line {line_no}: item index {index}, expected {position}")
        if not (0 <= frame <= 255 and 0 <= command <= 65535):
            raise BridgeUsageError(f"{path}: line {line_no}: frame {frame} or command {command} out of range")
        if position == 0:
            home = None if (x, y, z) == (0.0, 0.0, 0.0) else _check_home((x, y, z), f"line {line_no} (home)", path)
            continue
        item = MissionItem(command=command, frame=frame, param1=p1, param2=p2, param3=p3, param4=p4, x=x, y=y, z=z,
                           autocontinue=bool(autocontinue))
        where = f"line {line_no} (item {position})"
        refuse_terrain_altitude(item, where, path)
        items.append(check_item(item, where, path))
        wheres.append(where)
    check_jumps(items, wheres, path)
    return Mission(items=items, mission_type=MissionType.MISSION, home=home)


def _wpl_number(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return f"{value:.8f}"


def waypoints_text(mission: Mission) -> str:
    lat, lon, alt = _default_home(mission)
    rows = [WPL_HEADER,
            "\t".join(["0", "1", str(FRAME_GLOBAL), str(CMD_NAV_WAYPOINT)] + [_wpl_number(0.0)] * 4
                      + [_wpl_number(lat), _wpl_number(lon), _wpl_number(alt), "1"])]
    for number, item in enumerate(mission.items, start=1):
        rows.append("\t".join([str(number), "0", str(int(item.frame)), str(int(item.command))]
                              + [_wpl_number(v) for v in item.params] + ["1" if item.autocontinue else "0"]))
    return "\n".join(rows) + "\n"


def write_waypoints(path: str | os.PathLike[str], mission: Mission) -> None:
    if mission.mission_type != MissionType.MISSION:
        raise BridgeUsageError(f"{path}: a .waypoints file holds a mission, not {mission.mission_type.label} items")
    _write_atomic(Path(path), waypoints_text(mission))
