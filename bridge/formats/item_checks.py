"""What every mission file reader checks of what it reads, whatever the format, before any vehicle is contacted.

A reader never lets a number through that the wire cannot carry faithfully (a NaN or infinite coordinate, a
latitude beyond +-90, a frame that is not a uint8) because MISSION_ITEM_INT would carry it as 0 or as garbage
and the read-back would still agree with it. Nor anything beyond bridge.limits: more items than one MAVLink
transfer carries (`too_many`), a positional altitude outside its frame's range, an angle / speed / hold time
outside its range (PARAM_RANGES), a DO_JUMP outside the mission or repeating for ever in place (`check_jumps`),
an altitude only QGroundControl's terrain data could give (`refuse_terrain_altitude`, which reads the ones it
did give as altitudes above sea level), a home position that is no place (`check_home`). Also the home a writer
puts in a file when the mission names none (`default_home`).
Each problem is one BridgeUsageError naming the file, the item and the problem.
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path
from typing import Any

from ..errors import BridgeUsageError
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
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_GLOBAL_TERRAIN_ALT_INT,
    Mission,
    MissionItem,
    is_global,
)

# QGroundControl's AltitudeMode (QGroundControlQmlGlobal::AltMode) whose altitude QGroundControl computes: it keeps
# the height above terrain aside ("Altitude") and puts terrain + height into param 7, in MAV_FRAME_GLOBAL, from its
# own terrain data, again whenever that data comes (SimpleMissionItem::_terrainAltChanged).
ALT_MODE_CALC_ABOVE_TERRAIN = 3
TERRAIN_FRAMES = {FRAME_GLOBAL_TERRAIN_ALT: "MAV_FRAME_GLOBAL_TERRAIN_ALT",
                  FRAME_GLOBAL_TERRAIN_ALT_INT: "MAV_FRAME_GLOBAL_TERRAIN_ALT_INT"}
TERRAIN_ADVICE = ("this tool has no terrain data to convert it with: in QGroundControl set the item's altitude "
                  "to relative (or absolute) and save the plan again, or fly a plan written by `missionplan plan`")

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

JUMP_REPEAT_MAX = 32_767  # DO_JUMP's repeat count: ArduPilot keeps it as an int16


def too_many(path: Path, label: str, limit: int, where: str = "", count: int | None = None) -> BridgeUsageError:
    """The one line for a list longer than a MAVLink transfer carries (MISSION_COUNT's count is a uint16)."""
    home = ", ArduPilot's home item one of them" if limit == MAX_MISSION_ITEMS else ""
    held = f"more than {limit:,}" if count is None else f"{count:,}"
    return BridgeUsageError(f"{path}: {where}{held} {label} items: one upload carries at most {limit:,} (MAVLink's "
                            f"MISSION_COUNT counts {MAVLINK_MAX_ITEMS:,} items at most{home}); split it")


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


def check_home(home: tuple[float, float, float], where: str, path: Path) -> tuple[float, float, float]:
    lat, lon, alt = home
    if not (abs(lat) <= 90.0 and abs(lon) <= 180.0):
        raise BridgeUsageError(f"{path}: {where}: [{lat}, {lon}] is not a latitude / longitude")
    if math.isinf(alt) or not _fits_float32(alt):
        raise BridgeUsageError(f"{path}: {where}: altitude {alt:g} is not a usable number")
    if not math.isnan(alt):
        check_range(alt, f"{path}: {where}: altitude", *ALTITUDE_AMSL_M, unit=" m", what="metres above sea level")
    return (lat, lon, 0.0 if math.isnan(alt) else alt)


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


def refuse_terrain_altitude(item: MissionItem, where: str, path: str | os.PathLike[str], altitude_mode: Any = None,
                            amsl_above_terrain: Any = None) -> MissionItem:
    """The item as the vehicle is to fly it, or BridgeUsageError when its altitude is above terrain and known
    only from terrain data this tool does not have.

    QGroundControl's AltitudeMode 3 ("calculated above terrain") keeps the height above terrain aside and puts
    into param 7 the altitude above sea level it computed from its terrain data (null until that data came),
    in frame 0, and the same number into AMSLAltAboveTerrain when it saves. Such an item is read as what
    QGroundControl would upload: an item in frame 0 at that altitude (param 7, else AMSLAltAboveTerrain); with
    neither, it is refused. A terrain frame (10, 11) without an altitude is the same question unanswered. A
    terrain frame with an altitude goes to the vehicle as it is, as QGroundControl sends it: the autopilot
    follows the terrain itself (ArduPilot does; PX4 refuses the frame).
    """
    positional = item.command in POSITIONAL_COMMANDS and is_global(item.frame)
    if type(altitude_mode) in (int, float) and altitude_mode == ALT_MODE_CALC_ABOVE_TERRAIN and positional:
        mode = "QGroundControl's AltitudeMode 3, a height above terrain QGroundControl turns into an altitude above " \
               "sea level from its terrain data"
        if item.frame not in AMSL_FRAMES:
            raise BridgeUsageError(f"{path}: {where}: altitude is terrain-relative ({mode}) but the item is in frame "
                                   f"{item.frame}, not 0 (MAV_FRAME_GLOBAL) where QGroundControl puts that altitude; "
                                   f"{TERRAIN_ADVICE}")
        stored = amsl_above_terrain if type(amsl_above_terrain) in (int, float) else math.nan
        altitude = item.z if math.isfinite(item.z) else float(stored)
        if not math.isfinite(altitude):
            raise BridgeUsageError(f"{path}: {where}: altitude is terrain-relative ({mode}) and the file holds none "
                                   "above sea level for it (param 7 and AMSLAltAboveTerrain are null: QGroundControl "
                                   "saved the plan before its terrain data came); open the plan in QGroundControl, let "
                                   f"its terrain heights load and save it again, or {TERRAIN_ADVICE}")
        item.frame, item.z = FRAME_GLOBAL, altitude
    if item.frame in TERRAIN_FRAMES and positional and math.isnan(item.z):
        raise BridgeUsageError(f"{path}: {where}: altitude is terrain-relative (frame {item.frame}, "
                               f"{TERRAIN_FRAMES[item.frame]}) and has no value; {TERRAIN_ADVICE}")
    return item


def default_home(mission: Mission) -> tuple[float, float, float]:
    if mission.home is not None:
        return mission.home
    for item in mission.items:
        if is_global(item.frame) and (item.x or item.y):
            return (item.x, item.y, 0.0)
    return (0.0, 0.0, 0.0)

