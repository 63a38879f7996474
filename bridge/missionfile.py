"""Mission files: QGroundControl `.plan` (JSON) and QGC WPL 110 `.waypoints`, read and written.

Owns the translation between those formats and bridge.mission's model:
- `.plan`: fileType "Plan", version 1; mission.items of SimpleItem (command, frame, params[7] with
  null for NaN, autoContinue, doJumpId), plannedHomePosition; geoFence polygons and circles become
  fence items (MAV_CMD_NAV_FENCE_*), rallyPoints become rally items (MAV_CMD_NAV_RALLY_POINT).
- `.waypoints`: first line "QGC WPL 110", then one tab-separated line of 12 columns per item; line 0
  is the home position (Mission Planner's convention), so mission items are lines 1..n.
DO_JUMP targets: a `.plan` names them by doJumpId, a `.waypoints` by line number; both become the
model's 1-based item number. Bad files raise BridgeUsageError naming the file and the problem.
Writes are atomic (temp file, then rename) with LF line endings.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# A leaf utility with no planner imports: bridge still knows nothing about grids.
from missionplan.atomic import write_text_atomic

from .errors import BridgeUsageError
from .mission import (
    CMD_DO_JUMP,
    CMD_FENCE_CIRCLE_EXCLUSION,
    CMD_FENCE_CIRCLE_INCLUSION,
    CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    is_global,
)

WPL_HEADER = "QGC WPL 110"
MAV_TYPE_QUADROTOR = 2
SUFFIXES = (".plan", ".waypoints")


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


# ---------------------------------------------------------------------------------------------- I/O

def _write_atomic(path: Path, text: str) -> None:
    """Temp file beside the target then rename (missionplan.atomic): a reader never sees half a file."""
    if not path.parent.is_dir():
        raise BridgeUsageError(f"{path}: folder {path.parent} does not exist")
    write_text_atomic(path, text)


def _read_text(path: Path) -> str:
    if not path.exists():
        raise BridgeUsageError(f"{path}: no such file")
    if not path.is_file():
        raise BridgeUsageError(f"{path}: not a file")
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise BridgeUsageError(f"{path}: not a text file (expected a .plan or .waypoints mission)") from None
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None


def read_mission_file(path: str | os.PathLike[str]) -> PlanFile:
    """Read a `.plan` or `.waypoints` file, chosen by its suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        return read_plan(path)
    if suffix == ".waypoints":
        return PlanFile(mission=read_waypoints(path))
    raise BridgeUsageError(f"{path}: unknown mission file type {path.suffix!r} (expected .plan or .waypoints)")


def write_mission_file(path: str | os.PathLike[str], plan: PlanFile) -> None:
    """Write a `.plan` or `.waypoints` file, chosen by its suffix (.waypoints keeps only the mission)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        write_plan(path, plan)
    elif suffix == ".waypoints":
        write_waypoints(path, plan.mission)
    else:
        raise BridgeUsageError(f"{path}: unknown mission file type {path.suffix!r} (expected .plan or .waypoints)")


# -------------------------------------------------------------------------------------------- .plan

def _number(value: Any, where: str, path: Path) -> float:
    """A JSON number, with null meaning NaN (QGroundControl's way of writing NaN)."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BridgeUsageError(f"{path}: {where}: expected a number, got {value!r}")
    return float(value)


def _integer(value: Any, where: str, path: Path) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or float(value) != int(value):
        raise BridgeUsageError(f"{path}: {where}: expected an integer, got {value!r}")
    return int(value)


def _latlon(value: Any, where: str, path: Path, length: int = 2) -> list[float]:
    if not isinstance(value, list) or len(value) < length:
        raise BridgeUsageError(f"{path}: {where}: expected [lat, lon{', alt' if length == 3 else ''}], got {value!r}")
    return [_number(v, where, path) for v in value[:length]]


def read_plan(path: str | os.PathLike[str]) -> PlanFile:
    path = Path(path)
    try:
        doc = json.loads(_read_text(path))
    except json.JSONDecodeError as err:
        raise BridgeUsageError(f"{path}: not valid JSON (line {err.lineno}: {err.msg})") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise BridgeUsageError(f"{path}: not a QGroundControl plan (fileType is not \"Plan\")")
    if doc.get("version") != 1:
        raise BridgeUsageError(f"{path}: unsupported plan version {doc.get('version')!r} (expected 1)")
    mission_doc = doc.get("mission")
    if not isinstance(mission_doc, dict) or not isinstance(mission_doc.get("items"), list):
        raise BridgeUsageError(f"{path}: the plan has no mission.items list")

    home = None
    if mission_doc.get("plannedHomePosition") is not None:
        lat, lon, alt = _latlon(mission_doc["plannedHomePosition"], "mission.plannedHomePosition", path, 3)
        home = (lat, lon, 0.0 if math.isnan(alt) else alt)

    raw_items: list[tuple[MissionItem, int | None]] = []
    for index, entry in enumerate(mission_doc["items"]):
        where = f"mission item {index + 1}"
        if not isinstance(entry, dict):
            raise BridgeUsageError(f"{path}: {where}: expected an object")
        kind = entry.get("type")
        if kind == "ComplexItem":
            raise BridgeUsageError(f"{path}: {where} is a {entry.get('complexItemType', 'complex')} ComplexItem; "
                                   "only SimpleItem missions can be uploaded (let QGroundControl or missionplan "
                                   "expand it into waypoints first)")
        if kind != "SimpleItem":
            raise BridgeUsageError(f"{path}: {where}: unknown item type {kind!r}")
        params = entry.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise BridgeUsageError(f"{path}: {where}: params must be a list of 7 numbers")
        p = [_number(v, f"{where} params", path) for v in params]
        frame = _integer(entry.get("frame"), f"{where} frame", path)
        command = _integer(entry.get("command"), f"{where} command", path)
        jump_id = entry.get("doJumpId")
        raw_items.append((MissionItem(command=command, frame=frame, param1=p[0], param2=p[1], param3=p[2],
                                      param4=p[3], x=0.0 if math.isnan(p[4]) and is_global(frame) else p[4],
                                      y=0.0 if math.isnan(p[5]) and is_global(frame) else p[5], z=p[6],
                                      autocontinue=bool(entry.get("autoContinue", True))),
                          None if jump_id is None else _integer(jump_id, f"{where} doJumpId", path)))

    # DO_JUMP names its target by doJumpId; the model counts items from 1.
    by_jump_id = {jump_id: number for number, (_, jump_id) in enumerate(raw_items, start=1) if jump_id is not None}
    items: list[MissionItem] = []
    for number, (item, _) in enumerate(raw_items, start=1):
        if item.command == CMD_DO_JUMP:
            target = int(round(item.param1))
            if target not in by_jump_id:
                raise BridgeUsageError(f"{path}: mission item {number}: DO_JUMP to doJumpId {target}, which no item has")
            item.param1 = float(by_jump_id[target])
        items.append(item)

    firmware = None
    if "firmwareType" in mission_doc:
        firmware = Flavour.from_autopilot(_integer(mission_doc["firmwareType"], "mission.firmwareType", path))
    plan = PlanFile(mission=Mission(items=items, mission_type=MissionType.MISSION, home=home), firmware=firmware,
                    cruise_speed=_optional_number(mission_doc.get("cruiseSpeed"), path, "mission.cruiseSpeed"),
                    hover_speed=_optional_number(mission_doc.get("hoverSpeed"), path, "mission.hoverSpeed"))
    plan.fence = _read_fence(doc.get("geoFence"), path)
    if isinstance(doc.get("geoFence"), dict) and doc["geoFence"].get("maxAltitude") is not None:
        plan.fence_max_altitude = _number(doc["geoFence"]["maxAltitude"], "geoFence maxAltitude", path)
    plan.rally = _read_rally(doc.get("rallyPoints"), path)
    return plan


def _optional_number(value: Any, path: Path, where: str) -> float | None:
    return None if value is None else _number(value, where, path)


def _read_fence(doc: Any, path: Path) -> Mission:
    fence = Mission(mission_type=MissionType.FENCE)
    if doc is None:
        return fence
    if not isinstance(doc, dict):
        raise BridgeUsageError(f"{path}: geoFence must be an object")
    for index, poly in enumerate(doc.get("polygons", []) or []):
        where = f"geoFence polygon {index + 1}"
        if not isinstance(poly, dict) or not isinstance(poly.get("polygon"), list) or len(poly["polygon"]) < 3:
            raise BridgeUsageError(f"{path}: {where}: needs a polygon of at least 3 [lat, lon] points")
        command = CMD_FENCE_POLYGON_VERTEX_INCLUSION if poly.get("inclusion", True) else CMD_FENCE_POLYGON_VERTEX_EXCLUSION
        vertices = poly["polygon"]
        for vertex in vertices:
            lat, lon = _latlon(vertex, where, path)
            # autocontinue 0: a fence point is no navigation step, and ArduPilot stores (and reads back) 0
            fence.items.append(MissionItem(command=command, frame=FRAME_GLOBAL, param1=float(len(vertices)),
                                           x=lat, y=lon, z=0.0, autocontinue=False))
    for index, circle in enumerate(doc.get("circles", []) or []):
        where = f"geoFence circle {index + 1}"
        body = circle.get("circle") if isinstance(circle, dict) else None
        if not isinstance(body, dict):
            raise BridgeUsageError(f"{path}: {where}: expected {{\"circle\": {{\"center\": [lat, lon], \"radius\": r}}}}")
        lat, lon = _latlon(body.get("center"), where, path)
        radius = _number(body.get("radius"), f"{where} radius", path)
        command = CMD_FENCE_CIRCLE_INCLUSION if circle.get("inclusion", True) else CMD_FENCE_CIRCLE_EXCLUSION
        fence.items.append(MissionItem(command=command, frame=FRAME_GLOBAL, param1=radius, x=lat, y=lon, z=0.0,
                                       autocontinue=False))
    return fence


def _read_rally(doc: Any, path: Path) -> Mission:
    rally = Mission(mission_type=MissionType.RALLY)
    if doc is None:
        return rally
    if not isinstance(doc, dict):
        raise BridgeUsageError(f"{path}: rallyPoints must be an object")
    for index, point in enumerate(doc.get("points", []) or []):
        lat, lon, alt = _latlon(point, f"rally point {index + 1}", path, 3)
        rally.items.append(MissionItem(command=CMD_RALLY_POINT, frame=FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=alt))
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
    """A QGC WPL 110 file: line 0 is home, lines 1..n the mission items."""
    path = Path(path)
    lines = [line for line in _read_text(path).splitlines() if line.strip()]
    if not lines or not lines[0].strip().startswith("QGC WPL"):
        raise BridgeUsageError(f"{path}: not a waypoints file (first line is not \"{WPL_HEADER}\")")
    if lines[0].split()[-1] != "110":
        raise BridgeUsageError(f"{path}: unsupported waypoints version {lines[0].split()[-1]!r} (expected 110)")
    rows: list[list[str]] = []
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split("\t") if "\t" in line else line.split()
        if len(fields) != 12:
            raise BridgeUsageError(f"{path}: line {number}: expected 12 tab-separated columns, got {len(fields)}")
        rows.append([f.strip() for f in fields])

    items: list[MissionItem] = []
    home: tuple[float, float, float] | None = None
    for position, fields in enumerate(rows):
        line_no = position + 2
        try:
            index, _current, frame, command = (int(fields[0]), int(fields[1]), int(fields[2]), int(fields[3]))
            p1, p2, p3, p4, x, y, z = (float(v) for v in fields[4:11])
            autocontinue = int(float(fields[11]))
        except ValueError:
            raise BridgeUsageError(f"{path}: line {line_no}: a column is not a number") from None
        if index != position:
            raise BridgeUsageError(f"{path}: line {line_no}: item index {index}, expected {position}")
        if position == 0:
            home = None if (x, y, z) == (0.0, 0.0, 0.0) else (x, y, z)
            continue
        items.append(MissionItem(command=command, frame=frame, param1=p1, param2=p2, param3=p3, param4=p4,
                                 x=x, y=y, z=z, autocontinue=bool(autocontinue)))
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
