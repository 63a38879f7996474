"""The camera gimbal in a mission: which command points the camera on each autopilot, and which pitch a
mission or a vehicle's report says the camera has.

Owns:
- gimbal_item: the one mission item that points the camera before the first photo: MAV_CMD_DO_MOUNT_CONTROL
  on ArduPilot (its mount library, AP_Mount) and on PX4 (the one its gimbal module turns for from a mission,
  measured), MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (the gimbal protocol v2) on any other autopilot;
- check_gimbal_pitch: the pitches a plan may ask for (GIMBAL_PITCH_RANGE: -90 straight down .. 0 level);
- planned_pitch: the pitch the first gimbal item of a mission asks for (what the camera points at when the
  vehicle reports nothing about its gimbal);
- quaternion_pitch_roll: the pitch and roll of a GIMBAL_DEVICE_ATTITUDE_STATUS quaternion.

Angles are MAVLink's: degrees, pitch negative down (-90 = nadir), yaw 0 = the vehicle's heading.

Measured on ArduCopter 4.7.0-dev SITL (MNT1_TYPE 1, a servo mount, SERVO9_FUNCTION 7 its tilt) and PX4 SIH
v1.15.4 (MNT_MODE_IN 0, MNT_MODE_OUT 0 at boot): both store both commands. ArduCopter turns its mount for
either. PX4 turns its gimbal for a mission's DO_MOUNT_CONTROL, but not for a DO_GIMBAL_MANAGER_PITCHYAW that comes
first (NaN or zero rates, MNT_MODE_IN 0 or 4: it reports pitch 0 all flight; after a DO_MOUNT_CONTROL it follows
one), so PX4 gets DO_MOUNT_CONTROL too. docs/autopilots.md has the table. DO_GIMBAL_MANAGER_PITCHYAW's rates
(param3 / 4) are NaN, "not used" in MAVLink's words (ArduCopter refuses NaN there, MAV_MISSION_INVALID_PARAM3, but
it is not sent this item). ArduCopter hands DO_MOUNT_CONTROL's param7
(the mount mode) back on download, unlike the z of its other non-positional items (formats.readback).

Pure Python with no MAVLink library, like formats.mission_items.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from .mission_items import (CMD_DO_GIMBAL_MANAGER_PITCHYAW, CMD_DO_MOUNT_CONTROL, CMD_DO_SET_CAM_TRIGG_DIST,
                            FRAME_MISSION, MAV_MOUNT_MODE_MAVLINK_TARGETING, Flavour, MissionItem)

NADIR_PITCH_DEG = -90.0
GIMBAL_PITCH_RANGE = (-90.0, 0.0)  # straight down .. level: a survey camera never looks up
GIMBAL_COMMANDS = frozenset({CMD_DO_MOUNT_CONTROL, CMD_DO_GIMBAL_MANAGER_PITCHYAW})
NO_GIMBAL_MANAGER_FLAGS = 0.0  # DO_GIMBAL_MANAGER_PITCHYAW's param5: no flag, the yaw follows the vehicle
PRIMARY_GIMBAL = 0.0  # its param7: the gimbal manager's primary gimbal (0 = all / the primary one)
# A float32 quaternion holds a pitch near -90 only to about 0.015 degrees (SITL's -90 reads -89.985): reported
# angles are kept to a tenth of a degree (REPORT_DEG), finer than any gimbal points.
REPORT_DIGITS = 1
REPORT_DEG = 10.0 ** -REPORT_DIGITS


def command_for(flavour: Flavour | str) -> int:
    """The MAV_CMD that points the camera in a mission of this autopilot."""
    return CMD_DO_MOUNT_CONTROL if Flavour(flavour) in (Flavour.ARDUPILOT, Flavour.PX4) else CMD_DO_GIMBAL_MANAGER_PITCHYAW


def check_gimbal_pitch(pitch_deg: float) -> str | None:
    """Why `pitch_deg` cannot be a plan's gimbal pitch (None when it can)."""
    low, high = GIMBAL_PITCH_RANGE
    if not math.isfinite(pitch_deg) or not low <= pitch_deg <= high:
        return f"{pitch_deg:g}: not a gimbal pitch from {low:g} (straight down) to {high:g} (level) degrees"
    return None


def gimbal_item(flavour: Flavour | str, pitch_deg: float = NADIR_PITCH_DEG) -> MissionItem:
    """The item that points the camera at `pitch_deg` (yaw 0: along the vehicle's heading, roll 0), for a
    vehicle of this flavour. ValueError for a pitch outside GIMBAL_PITCH_RANGE."""
    problem = check_gimbal_pitch(pitch_deg)
    if problem is not None:
        raise ValueError(problem)
    if command_for(flavour) == CMD_DO_MOUNT_CONTROL:
        # param1 pitch, param2 roll, param3 yaw, param7 the mount mode that takes the angles given here.
        return MissionItem(CMD_DO_MOUNT_CONTROL, FRAME_MISSION, param1=float(pitch_deg), param2=0.0, param3=0.0,
                           z=float(MAV_MOUNT_MODE_MAVLINK_TARGETING))
    # param1 pitch, param2 yaw, param3 / param4 pitch and yaw rates (NaN: not used, angles only), param5 flags,
    # param7 gimbal id.
    return MissionItem(CMD_DO_GIMBAL_MANAGER_PITCHYAW, FRAME_MISSION, param1=float(pitch_deg), param2=0.0,
                       param3=math.nan, param4=math.nan, x=NO_GIMBAL_MANAGER_FLAGS, z=PRIMARY_GIMBAL)


def item_pitch(command: int, param1: float) -> float | None:
    """The pitch a mission item asks the gimbal for (param1 of both gimbal commands), None for another item."""
    return float(param1) if command in GIMBAL_COMMANDS else None


def planned_pitch(items: Iterable[object]) -> float | None:
    """The pitch the camera is pointed at before the first photo: that of the last gimbal item before the
    first DO_SET_CAM_TRIGG_DIST (MissionItem or WireItem alike), or of the first gimbal item after it;
    None for a mission without one."""
    pitch: float | None = None
    for item in items:
        command = int(getattr(item, "command"))
        found = item_pitch(command, float(getattr(item, "param1")))
        if found is not None:
            pitch = found
        elif command == CMD_DO_SET_CAM_TRIGG_DIST and pitch is not None:
            return pitch
    return pitch


def quaternion_pitch_roll(q: Sequence[float]) -> tuple[float, float] | None:
    """(pitch, roll) in degrees of a unit quaternion w, x, y, z (GIMBAL_DEVICE_ATTITUDE_STATUS.q: Hamilton,
    the earth frame for pitch and roll), to REPORT_DEG; None for a quaternion of NaNs (a gimbal that does not know)."""
    if len(q) != 4 or not all(math.isfinite(v) for v in q):
        return None
    w, x, y, z = (float(v) for v in q)
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x)))))
    roll = math.degrees(math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)))
    return round(pitch, REPORT_DIGITS) + 0.0, round(roll, REPORT_DIGITS) + 0.0  # + 0.0: no -0.0
