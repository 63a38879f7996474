"""The read-back rule: what a vehicle may legally change in the mission items it stores, per flavour.

- ardupilot_stored: what ArduCopter hands back for an item (measured on ArduCopter SITL: it keeps only
  what its storage format has room for); PX4's rule is formats.px4_rules.px4_stored (measured on PX4 SIH);
- stored_form: that rule for any flavour;
- compare_items / compare_wire: the item-by-item check an upload's verify and a re-task's read-back
  make: every field equal to what was sent or to the flavour's stored form of it, within the wire's rounding.

Pure Python with no MAVLink library, like formats.mission_items and formats.px4_rules it builds on.
"""

from __future__ import annotations

import math
from dataclasses import replace

from .mission_items import (
    CMD_DO_CHANGE_SPEED,
    CMD_DO_LAND_START,
    CMD_DO_MOUNT_CONTROL,
    CMD_DO_REPOSITION,
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_DO_SET_HOME,
    CMD_DO_SET_ROI,
    CMD_DO_SET_ROI_LOCATION,
    CMD_NAV_CONTINUE_AND_CHANGE_ALT,
    CMD_NAV_LAND,
    CMD_NAV_LAND_LOCAL,
    CMD_NAV_LOITER_TIME,
    CMD_NAV_LOITER_TO_ALT,
    CMD_NAV_LOITER_TURNS,
    CMD_NAV_LOITER_UNLIM,
    CMD_NAV_PAYLOAD_PLACE,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_SPLINE_WAYPOINT,
    CMD_NAV_TAKEOFF,
    CMD_NAV_VTOL_LAND,
    CMD_NAV_VTOL_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    Flavour,
    MissionType,
    WireItem,
    as_float32,
    normalize_frame,
)
from .px4_rules import px4_stored


# ------------------------------------------------------------------------------------------------
# What a vehicle may legally change in the items it stores (the read-back rule, per flavour).
#
# Measured on ArduCopter 4.7-dev SITL (docs/autopilots.md has the table and how): it keeps only
# what its storage format has room for and hands the rest back as fixed values. Verify accepts, field
# by field, either the value sent or the value ArduPilot's storage turns it into; nothing else.
# PX4 (measured on PX4 SIH v1.15.4): formats.px4_rules.px4_stored. Other autopilots: the value sent
# (deprecated *_INT frames read as their plain number).

# Commands that carry a position (x, y, z). Everything else in a mission (DO_*, CONDITION_*, RTL,
# camera, gimbal) is non-positional: ArduPilot returns it in frame 0 with x = y = z = 0.
POSITIONAL_COMMANDS = frozenset({
    CMD_NAV_WAYPOINT, CMD_NAV_LOITER_UNLIM, CMD_NAV_LOITER_TURNS, CMD_NAV_LOITER_TIME, CMD_NAV_LAND,
    CMD_NAV_TAKEOFF, CMD_NAV_LAND_LOCAL, CMD_NAV_CONTINUE_AND_CHANGE_ALT, CMD_NAV_LOITER_TO_ALT,
    CMD_NAV_SPLINE_WAYPOINT, CMD_NAV_VTOL_TAKEOFF, CMD_NAV_VTOL_LAND, CMD_NAV_PAYLOAD_PLACE,  # NAV_* with a location
    CMD_DO_SET_HOME, CMD_DO_LAND_START, CMD_DO_REPOSITION, CMD_DO_SET_ROI_LOCATION, CMD_DO_SET_ROI,
})

# Params ArduCopter does not store, per command: the vehicle returns the value given here instead.
# Only what was seen on SITL (docs/autopilots.md); a param not listed must come back as sent.
# NAV_WAYPOINT keeps only param1 (the hold time, in whole seconds); its param2 (acceptance radius) is
# dropped: the copter flies WPNAV_RADIUS instead (see link.params).
ARDUPILOT_UNSTORED_PARAMS: dict[int, dict[str, float]] = {
    CMD_NAV_WAYPOINT: {"param2": 0.0, "param3": 0.0, "param4": 0.0},
    CMD_NAV_TAKEOFF: {"param4": 0.0},
    CMD_NAV_LAND: {"param2": 0.0, "param4": 1.0},
    CMD_NAV_RETURN_TO_LAUNCH: {"param1": 0.0},
    CMD_DO_CHANGE_SPEED: {"param4": 0.0},
    CMD_DO_SET_CAM_TRIGG_DIST: {"param2": 0.0, "param4": 0.0},
    CMD_RALLY_POINT: {"param1": 0.0},
}
UINT16_SECONDS = 65536  # NAV_WAYPOINT's hold time is a uint16 of whole seconds on ArduCopter


def is_positional(command: int) -> bool:
    return command in POSITIONAL_COMMANDS or command >= 5000  # fence and rally items are points too


def ardupilot_stored(item: WireItem) -> WireItem:
    """The item as ArduCopter stores it and returns it on download (its seq and mission_type kept).

    - altitudes: whole centimetres (truncated, and returned as cm * 0.01 in float32) in a mission, whole metres for
    rally points, none for
      fence vertices; latitude and longitude: the 1e-7 degree integers as sent;
    - non-positional mission items: frame 0 (MAV_FRAME_GLOBAL), x = y = z = 0 (DO_MOUNT_CONTROL keeps its z);
    - deprecated *_INT frames: their plain number (6 -> 3, 5 -> 0, 11 -> 10);
    - params it has no room for: ARDUPILOT_UNSTORED_PARAMS; NAV_WAYPOINT's hold time truncated to
      whole seconds;
    - fence and rally items: autocontinue 0 (they are not flown), fence items in frame 0.
    The home item (mission seq 0) is not covered: the vehicle replaces it with its own home.
    """
    frame, x, y, z = normalize_frame(item.frame), item.x, item.y, item.z
    autocontinue = item.autocontinue
    params = {"param1": item.param1, "param2": item.param2, "param3": item.param3, "param4": item.param4}
    for name, value in ARDUPILOT_UNSTORED_PARAMS.get(item.command, {}).items():
        params[name] = value
    if item.mission_type == MissionType.FENCE:
        frame, z, autocontinue = FRAME_GLOBAL, 0.0, 0
    elif item.mission_type == MissionType.RALLY:
        autocontinue = 0
        z = float(math.trunc(as_float32(z))) if math.isfinite(z) else z
    elif not is_positional(item.command):
        # DO_MOUNT_CONTROL's z is its mount mode (param7), which ArduCopter hands back (2 sent, 2 read back).
        frame, x, y, z = FRAME_GLOBAL, 0, 0, z if item.command == CMD_DO_MOUNT_CONTROL else 0.0
    else:
        if math.isfinite(z):  # int32 centimetres, truncated; returned as cm * 0.01f (float32 maths, as on board)
            z = as_float32(as_float32(math.trunc(as_float32(as_float32(z) * 100.0))) * as_float32(0.01))
    if item.command == CMD_NAV_WAYPOINT and item.mission_type == MissionType.MISSION:
        hold = item.param1
        if math.isfinite(hold) and 0.0 <= hold < UINT16_SECONDS:
            params["param1"] = float(math.trunc(hold))
        # A negative or huge hold time wraps around on the vehicle: left as sent, so it shows as a difference.
    return replace(item, frame=frame, x=x, y=y, z=z, autocontinue=autocontinue, **params)


def stored_form(item: WireItem, flavour: Flavour) -> WireItem:
    """What a vehicle of this flavour may legally hold instead of `item` (besides `item` itself)."""
    if flavour is Flavour.ARDUPILOT:
        return ardupilot_stored(item)
    if flavour is Flavour.PX4:
        return px4_stored(item)
    return replace(item, frame=normalize_frame(item.frame))


def _same_float(sent: float, got: float, abs_tol: float) -> bool:
    a, b = as_float32(sent), as_float32(got)
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=1e-6, abs_tol=abs_tol)


def _field_matches(name: str, sent: float, legal: float, got: float) -> bool:
    """got equals what was sent, or the flavour's stored form of it, within the wire's rounding."""
    for want in (sent, legal):
        if name in ("x", "y"):
            if abs(int(want) - int(got)) <= 1:  # 1e-7 degree: a vehicle may round the last digit
                return True
        elif name == "z":
            if _same_float(want, got, abs_tol=0.01):  # float32, and centimetres
                return True
        elif name == "frame":
            if normalize_frame(int(want)) == normalize_frame(int(got)):
                return True
        elif name == "autocontinue":
            if bool(want) == bool(got):
                return True
        elif name in ("command", "mission_type"):
            if int(want) == int(got):
                return True
        elif _same_float(want, got, abs_tol=1e-4):
            return True
    return False


def compare_items(sent: WireItem, got: WireItem, flavour: Flavour = Flavour.GENERIC) -> list[str]:
    """What differs between one sent item and the vehicle's copy, as short phrases, beyond what a
    vehicle of this flavour may legally change (stored_form)."""
    legal = stored_form(sent, flavour) if sent.command == got.command else sent
    diffs: list[str] = []
    for name in ("command", "frame", "autocontinue", "param1", "param2", "param3", "param4", "x", "y", "z",
                 "mission_type"):
        a, b = getattr(sent, name), getattr(got, name)
        if not _field_matches(name, a, getattr(legal, name), b):
            shown = f"{a:g}, vehicle has {b:g}" if isinstance(a, float) else f"{a}, vehicle has {b}"
            diffs.append(f"{name} sent {shown}")
    return diffs


def compare_wire(sent: list[WireItem], got: list[WireItem], skip_home: bool, limit: int = 5,
                 flavour: Flavour = Flavour.GENERIC) -> list[str]:
    """Item-by-item differences between what was sent and what the vehicle holds (empty: identical up
    to what the flavour may legally change, see stored_form).

    skip_home: ArduPilot replaces item 0 by its real home, so it is not compared (it must exist).
    """
    problems: list[str] = []
    if len(sent) != len(got):
        problems.append(f"the vehicle holds {len(got)} items, {len(sent)} were sent")
    by_seq = {it.seq: it for it in got}
    for item in sent:
        if skip_home and item.seq == 0:
            continue
        other = by_seq.get(item.seq)
        if other is None:
            problems.append(f"item {item.seq}: missing on the vehicle")
        else:
            diffs = compare_items(item, other, flavour)
            if diffs:
                problems.append(f"item {item.seq}: " + "; ".join(diffs))
        if len(problems) > limit:
            problems.append("...")
            break
    return problems
