"""QGroundControl's `.plan` (JSON), read and written, and its legacy `.mission`, read.

- `.plan`: fileType "Plan", version 1; mission.items of SimpleItem (command, frame, params[7] with
  null for NaN, autoContinue, doJumpId), plannedHomePosition; geoFence polygons and circles become
  fence items (MAV_CMD_NAV_FENCE_*), rallyPoints become rally items (MAV_CMD_NAV_RALLY_POINT).
  Items are read as QGroundControl reads them: the older item layouts and the legacy `.mission`
  file go through formats.qgc_legacy; a survey or corridor-scan ComplexItem contributes the
  waypoints QGroundControl stored in it ("TransectStyleComplexItem".Items, the ones QGroundControl
  flies from a loaded plan); a ComplexItem without stored waypoints (structure scan, landing
  pattern, old surveys), whose waypoints QGroundControl generates on load, is refused. An item "calculated
  above terrain" (AltitudeMode 3) is read as the altitude above sea level QGroundControl computed for it
  (frame 0); one saved before QGroundControl had terrain data for it (no such altitude), or in a terrain frame
  without an altitude, is refused: this tool has no terrain data to convert it with.
- Altitude modes written: a plan with an item in frame 0 (above sea level) or 10 (above terrain) gives every
  item that has an altitude QGroundControl's three keys (ALTITUDE_MODE_KEYS): "AltitudeMode" from its frame
  (ALTITUDE_MODES), "Altitude" its altitude, "AMSLAltAboveTerrain" null, as QGroundControl's
  SimpleMissionItem::save writes them. Frame 0 is written as absolute (2), not as calculated above terrain
  (3): QGroundControl recomputes a mode 3 item's altitude from its own terrain data when it loads the plan,
  and would replace the altitudes of the DEM the plan was made with. A plan of relative items (frame 3) has
  none of those keys, as before.
DO_JUMP targets: a `.plan` names them by doJumpId; they become the model's 1-based item number, and a plan
written here gives each item its number as doJumpId. Every item goes through formats.item_checks; a JSON file
larger than any legal one (MAX_JSON_BYTES) is refused unread.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import qgc_legacy
from ..errors import BridgeUsageError
from ..limits import ALTITUDE_RELATIVE_M, MAVLINK_MAX_ITEMS, MAX_MISSION_ITEMS, SPEED_M_S, check_range
from .file_text import check_file, read_text, write_text
from .item_checks import (POSITIONAL_COMMANDS, check_home, check_item, check_jumps, default_home, refuse_terrain_altitude,
                          too_many)
from .mission_items import (
    CMD_DO_JUMP,
    CMD_FENCE_CIRCLE_EXCLUSION,
    CMD_FENCE_CIRCLE_INCLUSION,
    CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_TERRAIN_ALT,
    MAV_TYPE_QUADROTOR,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    is_global,
    normalize_frame,
)

PLAN_MISSION_VERSION = 2  # the only mission.version QGroundControl reads
SIMPLE_ITEM_TYPES = ("SimpleItem", "missionItem")  # "missionItem": the version 1 name of a SimpleItem

# ComplexItems QGroundControl reads (complexItemType -> what it is). Survey and corridor scan are
# TransectStyleComplexItems: QGroundControl saves their generated waypoints as "Items" and flies those
# from a loaded plan; the others are generated from their settings every time the plan is loaded.
COMPLEX_ITEM_KINDS = {"survey": "survey pattern", "CorridorScan": "corridor scan",
                      "StructureScan": "structure scan", "fwLandingPattern": "fixed-wing landing pattern",
                      "vtolLandingPattern": "VTOL landing pattern"}
STORED_ITEMS_KINDS = ("survey", "CorridorScan")
SURVEY_VERSIONS = range(2, 6)  # QGroundControl reads survey versions 2-5; 2 and 3 hold no waypoints

# A JSON mission file larger than this is not read: QGroundControl writes a mission item in 420-960 bytes
# (measured: its sample survey plan's items, and an item of 17-digit numbers at a survey's depth), a fence
# vertex or rally point in under 150, so a plan whose mission, fence and rally lists are all at the MAVLink
# limit (65,535 items each) stays under 75 MiB. A larger file cannot be a mission any vehicle takes; refusing it
# before it is read keeps a 1,000,000-item file from being parsed into a gigabyte of objects.
MAX_JSON_BYTES = 96 * 2**20

# QGroundControl's AltitudeMode (QGroundControlQmlGlobal::AltMode: Mixed 0, Relative 1, Absolute 2,
# CalcAboveTerrain 3, TerrainFrame 4) for the frame an item is in, as SimpleMissionItem maps them.
ALT_MODE_MIXED = 0
ALTITUDE_MODES = {FRAME_GLOBAL_RELATIVE_ALT: 1, FRAME_GLOBAL: 2, FRAME_GLOBAL_TERRAIN_ALT: 4}
ALTITUDE_MODE_KEYS = ("AMSLAltAboveTerrain", "Altitude", "AltitudeMode")  # all three on an item, or none
GLOBAL_PLAN_ALTITUDE_MODE = 1  # what a plan of relative items names as the mode for new items


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


def _latlon(value: Any, where: str, path: Path, length: int = 2) -> list[float]:
    if not isinstance(value, list) or len(value) < length:
        raise BridgeUsageError(f"{path}: {where}: expected [lat, lon{', alt' if length == 3 else ''}], "
                               f"got {_short(value)}")
    return [_number(v, where, path) for v in value[:length]]


def read_json(path: Path) -> Any:
    """The JSON document in a mission file, refused unread when it is larger than any mission (MAX_JSON_BYTES)."""
    check_file(path)
    try:
        size = path.stat().st_size
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None
    if size > MAX_JSON_BYTES:
        raise BridgeUsageError(f"{path}: {size / 2**20:,.0f} MiB, larger than any mission MAVLink can carry (at most "
                               f"{MAVLINK_MAX_ITEMS:,} items per list, under {MAX_JSON_BYTES // 2**20} MiB as "
                               "QGroundControl writes them); not read")
    try:
        return json.loads(read_text(path))
    except json.JSONDecodeError as err:
        raise BridgeUsageError(f"{path}: not valid JSON (line {err.lineno}: {err.msg})") from None
    except RecursionError:
        raise BridgeUsageError(f"{path}: not a plan (JSON nested too deeply)") from None


def looks_like_mission_file(doc: dict[str, Any]) -> bool:
    """A legacy QGroundControl .mission document: fileType "Mission" (version 2) or none (version 1)."""
    return doc.get("fileType", qgc_legacy.MISSION_FILE_TYPE) == qgc_legacy.MISSION_FILE_TYPE and "items" in doc


def read_plan(path: str | os.PathLike[str]) -> PlanFile:
    """A QGroundControl `.plan`: its mission, fence and rally points."""
    path = Path(path)
    return plan_from_document(read_json(path), path)


def plan_from_document(doc: Any, path: Path) -> PlanFile:
    """The PlanFile of a `.plan` JSON document read from `path` (named in every error)."""
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        hint = " (a QGroundControl .mission file? name it .mission)" if (
            isinstance(doc, dict) and looks_like_mission_file(doc)) else ""
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
    return plan_from_mission_file(read_json(path), path)


def plan_from_mission_file(doc: Any, path: Path) -> PlanFile:
    """The PlanFile of a legacy `.mission` JSON document (or of a `.plan` under that name) read from `path`."""
    if isinstance(doc, dict) and doc.get("fileType") == "Plan":
        return plan_from_document(doc, path)  # a .plan under another name: it is what it says
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
        home = check_home((lat, lon, alt), "mission.plannedHomePosition", path)

    # (item, its doJumpId, where it is in the file, whether it is a SimpleItem of the mission). QGroundControl
    # resolves doJumpIds among the mission's SimpleItems only: a ComplexItem's stored items are neither
    # targets nor have their own DO_JUMP targets rewritten.
    raw_items: list[tuple[MissionItem, int | None, str, bool]] = []
    if len(mission_doc["items"]) > MAX_MISSION_ITEMS:  # before any item is read
        raise too_many(path, "mission", MAX_MISSION_ITEMS, count=len(mission_doc["items"]))
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
                    raise too_many(path, "mission", MAX_MISSION_ITEMS, f"{inner}: ")
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
    refuse_terrain_altitude(item, where, path, entry.get("AltitudeMode"), entry.get("AMSLAltAboveTerrain"))
    check_item(item, where, path)
    jump_id = entry.get("doJumpId")
    return item, None if jump_id is None else _integer(jump_id, f"{where} doJumpId", path)


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
            raise too_many(path, "fence", MAVLINK_MAX_ITEMS, f"{where}: ")
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
            raise too_many(path, "fence", MAVLINK_MAX_ITEMS, f"{where}: ")
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
        raise too_many(path, "rally", MAVLINK_MAX_ITEMS, count=len(points))
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


def _altitude_mode(item: MissionItem) -> int | None:
    """QGroundControl's AltitudeMode for an item that has an altitude (a position in a global frame), else None."""
    if item.command not in POSITIONAL_COMMANDS or not is_global(item.frame):
        return None
    return ALTITUDE_MODES[normalize_frame(item.frame)]


def plan_document(plan: PlanFile) -> dict[str, Any]:
    """The QGroundControl JSON document for a plan (doJumpId = item number, so DO_JUMP is unchanged)."""
    modes = [_altitude_mode(item) for item in plan.mission.items]
    # Relative items alone need no altitude mode: such a plan is written as it always was.
    with_modes = any(mode not in (None, ALTITUDE_MODES[FRAME_GLOBAL_RELATIVE_ALT]) for mode in modes)
    items = []
    for number, (item, mode) in enumerate(zip(plan.mission.items, modes), start=1):
        entry: dict[str, Any] = {}
        if with_modes and mode is not None:  # QGroundControl's keys sort first, as it writes them
            entry.update(zip(ALTITUDE_MODE_KEYS, (None, _json_number(item.z), mode)))
        entry.update({"autoContinue": bool(item.autocontinue), "command": int(item.command), "doJumpId": number,
                      "frame": int(item.frame), "params": [_json_number(v) for v in item.params],
                      "type": "SimpleItem"})
        items.append(entry)
    used = {mode for mode in modes if mode is not None}
    global_mode = GLOBAL_PLAN_ALTITUDE_MODE if not with_modes else used.pop() if len(used) == 1 else ALT_MODE_MIXED
    home = default_home(plan.mission)
    firmware = plan.firmware or Flavour.ARDUPILOT
    mission_doc: dict[str, Any] = {
        "cruiseSpeed": plan.cruise_speed if plan.cruise_speed is not None else 5,
        "firmwareType": firmware.autopilot,
        "globalPlanAltitudeMode": global_mode,
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
    write_text(Path(path), json.dumps(plan_document(plan), indent=4) + "\n")

