"""Limits before work: the one check every numeric value a command takes goes through, and the ranges that
the mission files and the commands share.

Owns:
- check_range: a number is finite and within [low, high] (either end may be open), or one line naming the
  setting (or the file and item) and the value, raised as the caller's layer's error type. Every command's
  numeric options (plan, replan, train, demo, fly, upload / download / clear, mock) go through it, so a
  `--rotation 1e308` or a `--timeout nan` fails before any work, in the same words everywhere. The CLI
  names its options itself ("--rotation"); the library names a setting by what it means
  (`Setting("rotation")`, missionplan.base.naming), which the CLI spells as its option;
- the ranges of what a mission file holds (formats.item_checks applies them; docs/file-formats.md has the
  table): altitudes by frame, angles, speeds, hold times, and the item count MAVLink can carry.

Why these ranges: each says what no mission anywhere on Earth can mean, not what a careful plan would do
(the planner's own options are far tighter): a value outside is a typo or a damaged file, and an autopilot
would either refuse it (ArduPilot answers MAV_MISSION_INVALID_PARAM7 to an altitude of 83 km or more: its
Location keeps altitudes as 24-bit centimetres, measured on ArduCopter SITL) or store something else (PX4 keeps
float32 metres and would fly 1e38 m as given; ArduPilot wraps a hold time above 65,535 s).
"""

from __future__ import annotations

import math

from missionplan.base.naming import Named, Setting

from .errors import BridgeUsageError

# MISSION_COUNT's count is a uint16: one transfer carries at most 65,535 items. ArduPilot sends its home as
# item 0 of the mission, so a mission file may hold one item fewer than its fence and rally lists.
MAVLINK_MAX_ITEMS = 65_535
MAX_MISSION_ITEMS = MAVLINK_MAX_ITEMS - 1

# Altitudes of positional items, metres. Above mean sea level (frame 0): from below the lowest dry land (the
# Dead Sea shore, -430 m) to 30 km, above the ceiling of every aircraft that flies missions (the highest a
# propeller aircraft has flown, NASA's Helios UAV, is 29.5 km); a mountain site's 5,000 m AMSL is well inside.
# Relative to home or to the terrain (frames 3 and 10): down to -10 km (a home on the highest summit, 8,849 m,
# above a waypoint on the lowest shore is -9,279 m) and up to the same 30 km. ArduPilot refuses 83 km and more
# either way; a few km either way is already absurd for a multirotor, but the reader does not know the vehicle.
ALTITUDE_AMSL_M = (-500.0, 30_000.0)
ALTITUDE_RELATIVE_M = (-10_000.0, 30_000.0)
# Angles in degrees (yaw, pitch, roll, heading): one full turn either way; 1e30 degrees means nothing.
ANGLE_DEG = (-360.0, 360.0)
# DO_CHANGE_SPEED: m/s, -1 "no change" and -2 "the vehicle's default" (MAVLink), up to 300 m/s (faster than any
# propeller aircraft flies); throttle in percent, with the same -1 / -2.
SPEED_M_S = (-2.0, 300.0)
THROTTLE_PCT = (-2.0, 100.0)
# Hold and loiter times, seconds: ArduPilot keeps them as a uint16 (1e6 s was stored as 16,960 s on SITL).
HOLD_S = (0.0, 65_535.0)
# Seeds: numpy seeds its generators from non-negative integers; 2**32 - 1 is the largest every one of them takes.
SEED_MAX = 2**32 - 1


def check_range(value: float, name: str | Setting, low: float, high: float, *, unit: str = "", low_open: bool = False,
                high_open: bool = False, what: str = "", error: type[Exception] = BridgeUsageError) -> float:
    """`value` when it is a finite number within low..high (low_open / high_open: that end excluded); else
    `error` (the caller's layer's one error type) with one line: the name, the value and the range.

    name: how the user gave it ("--rotation", or "FILE: mission item 3 altitude"), or the setting it is
    (Setting("rotation"): the front end spells it); unit: appended to the bounds (" m", " degrees"); what: a
    word on what it is ("a grid angle"), before the range."""
    number = _as_float(value)
    if number is not None and math.isfinite(number) and (low < number if low_open else low <= number) and (
            number < high if high_open else number <= high):
        return number
    if low_open or high_open:
        bounds = (f"{'above' if low_open else 'at least'} {low:,g} and {'below' if high_open else 'at most'} "
                  f"{high:,g}{unit}")
    else:
        bounds = f"from {low:,g} to {high:,g}{unit}"
    kind = f"{what}, " if what else ""
    raise error(_said(name, value, f"must be {kind}{bounds}"))


def check_integer(value: int, name: str | Setting, low: int, high: int, *, what: str = "",
                  error: type[Exception] = BridgeUsageError) -> int:
    """`value` when it is an integer within low..high (both included); else `error` with one line."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        kind = f"{what}, " if what else ""
        raise error(_said(name, value, f"must be {kind}an integer from {low:,} to {high:,}"))
    return value


def _said(name: str | Setting, value: object, problem: str) -> str | Named:
    """`NAME VALUE: problem`, the name as given, or a setting for the front end to spell."""
    if isinstance(name, Setting):
        return Named("{name} {0}: {1}", _shown(value), problem, name=name)
    return f"{name} {_shown(value)}: {problem}"


def _as_float(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer with hundreds of digits
        return None


def _shown(value: object) -> str:
    """The value as a user would recognise it, short (a 400-digit integer is not printed whole)."""
    text = f"{value:g}" if isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
