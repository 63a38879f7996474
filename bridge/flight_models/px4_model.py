"""How a PX4 multicopter flies a mission, in time: its navigation parameters and the timed phases.

The PX4 counterpart of flight_models.copter_model (ArduCopter), built from the same Motion pieces so that the
planner's timeline (missionplan.mission.timeline, with FlightModel.px4) and the judge's re-timing use one
ruler. Measured on PX4 v1.15.4 SIH (../shared/px4, docs/px4-flight.md) flying our 20 m survey missions:

- take-off (NAV_TAKEOFF): PX4_SPOOL_S from MISSION_START until the climb (spool-up, MPC_TKO_RAMP_T's
  ramp), the climb at MPC_TKO_SPEED with MPC_ACC_UP_MAX, then PX4_TAKEOFF_SETTLE_S before the first
  waypoint is taken as reached (its last NAV_MC_ALT_RAD metres, the heading);
- waypoint legs from rest to rest at the mission's speed (DO_CHANGE_SPEED, else MPC_XY_CRUISE) with
  MPC_ACC_HOR, each after turning the nose to the new leg (MPC_YAW_MODE 0: towards the waypoint):
  the turn angle at MPC_YAWRAUTO_MAX deg/s times PX4_TURN_FACTOR (measured: the yaw, its settling and
  the corner's slow-down; a straight-on waypoint costs nothing extra);
- RTL (NAV_RETURN_TO_LAUNCH): PX4_RTL_START_S, a climb to the return altitude (farther than
  RTL_MIN_DIST from home: RTL_RETURN_ALT within the cone of RTL_CONE_ANG, at least RTL_DESCEND_ALT,
  never a descent), home at MPC_XY_CRUISE, RTL_LAND_DELAY, then the landing;
- landing: MPC_Z_V_AUTO_DN down to MPC_LAND_ALT1, the blend to MPC_LAND_SPEED down to MPC_LAND_ALT2,
  MPC_LAND_SPEED below, then PX4_TOUCHDOWN_S (slow last metre, land detector, COM_DISARM_LAND) until
  disarmed.

The constants in capitals are measurements of PX4 SIH, not parameters; the parameters (Px4Params,
PX4's names and units in PARAMETERS) default to PX4 v1.15's values for a multicopter, as SIH has them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

from . import copter_model as cm
from .copter_model import Motion

# Measured on PX4 v1.15.4 SIH (docs/px4-flight.md), not parameters of the vehicle.
PX4_SPOOL_S = 4.0            # MISSION_START accepted -> climbing at MPC_TKO_SPEED
PX4_TAKEOFF_SETTLE_S = 1.8   # take-off altitude -> first waypoint reached (the last NAV_MC_ALT_RAD, heading)
PX4_TURN_FACTOR = 1.4        # a turn of A degrees at a waypoint costs A / MPC_YAWRAUTO_MAX * this, s
PX4_RTL_START_S = 7.6        # last waypoint reached -> RTL moving home or descending ("RTL: land at destination")
PX4_TOUCHDOWN_S = 4.0        # at the ground by the model -> disarmed (crawl, land detector, COM_DISARM_LAND)
FIRST_TURN_DEG = 90.0        # the first leg's turn: the heading at take-off is not the plan's to know
                             # (SIH faces north, a real vehicle where it was put): a uniform one averages 90
NEAR_M = 0.5                 # a waypoint this close is reached where the vehicle is: no turn, no leg (inside
                             # any acceptance radius PX4 uses; the vehicle's own rounding of positions)


@dataclass(frozen=True)
class Px4Params:
    """The PX4 parameters the flight depends on (SI units, as PX4 has them)."""

    xy_cruise: float = 5.0        # MPC_XY_CRUISE, m/s
    acc_hor: float = 3.0          # MPC_ACC_HOR, m/s/s
    tko_speed: float = 1.5        # MPC_TKO_SPEED, m/s
    acc_up: float = 4.0           # MPC_ACC_UP_MAX, m/s/s
    acc_down: float = 3.0         # MPC_ACC_DOWN_MAX, m/s/s
    z_auto_dn: float = 1.5        # MPC_Z_V_AUTO_DN, m/s
    z_auto_up: float = 3.0        # MPC_Z_V_AUTO_UP, m/s
    land_speed: float = 0.7       # MPC_LAND_SPEED, m/s
    land_alt1: float = 10.0       # MPC_LAND_ALT1, m: below it the descent slows down
    land_alt2: float = 5.0        # MPC_LAND_ALT2, m: below it at MPC_LAND_SPEED
    yaw_rate: float = 45.0        # MPC_YAWRAUTO_MAX, deg/s
    rtl_return_alt: float = 30.0  # RTL_RETURN_ALT, m
    rtl_descend_alt: float = 10.0  # RTL_DESCEND_ALT, m
    rtl_land_delay: float = 0.0   # RTL_LAND_DELAY, s
    rtl_cone_ang: float = 45.0    # RTL_CONE_ANG, deg (0: no cone)
    rtl_min_dist: float = 10.0    # RTL_MIN_DIST, m: closer to home RTL does not climb

    @classmethod
    def from_params(cls, values: dict[str, float]) -> Px4Params:
        """From PX4 parameter values; missing or non-finite ones keep the default."""
        changes = {attr: float(values[name]) for name, attr in PARAMETERS.items()
                   if name in values and math.isfinite(float(values[name]))}
        return replace(cls(), **changes)

    def as_params(self) -> dict[str, float]:
        return {name: getattr(self, attr) for name, attr in PARAMETERS.items()}


# PX4 name -> Px4Params field (same units).
PARAMETERS: dict[str, str] = {
    "MPC_XY_CRUISE": "xy_cruise", "MPC_ACC_HOR": "acc_hor", "MPC_TKO_SPEED": "tko_speed",
    "MPC_ACC_UP_MAX": "acc_up", "MPC_ACC_DOWN_MAX": "acc_down", "MPC_Z_V_AUTO_DN": "z_auto_dn",
    "MPC_Z_V_AUTO_UP": "z_auto_up", "MPC_LAND_SPEED": "land_speed", "MPC_LAND_ALT1": "land_alt1",
    "MPC_LAND_ALT2": "land_alt2", "MPC_YAWRAUTO_MAX": "yaw_rate", "RTL_RETURN_ALT": "rtl_return_alt",
    "RTL_DESCEND_ALT": "rtl_descend_alt", "RTL_LAND_DELAY": "rtl_land_delay", "RTL_CONE_ANG": "rtl_cone_ang",
    "RTL_MIN_DIST": "rtl_min_dist",
}
assert set(PARAMETERS.values()) == {f.name for f in fields(Px4Params)}
# INT32 parameters: PX4 sends them byte-wise in PARAM_VALUE's float, so a reader that takes the float
# as a number gets nonsense; ask a vehicle only for the others (FLOAT_PARAMETERS).
INT_PARAMETERS = frozenset({"RTL_CONE_ANG"})
FLOAT_PARAMETERS = [name for name in PARAMETERS if name not in INT_PARAMETERS]


def heading_deg(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    """Direction of travel from a to b in the plane (degrees; any fixed zero: only differences count)."""
    return math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))


def turn_deg(h0: float, h1: float) -> float:
    return abs((h1 - h0 + 180.0) % 360.0 - 180.0)


def turn_s(angle_deg: float, p: Px4Params) -> float:
    """Seconds PX4 spends turning its nose by angle_deg before a leg."""
    return angle_deg / max(p.yaw_rate, 1e-6) * PX4_TURN_FACTOR


def takeoff(ground: tuple[float, float, float], altitude: float, p: Px4Params) -> list[Motion]:
    top = (ground[0], ground[1], ground[2] + altitude)
    return [cm.wait(ground, PX4_SPOOL_S, "spool"), Motion(ground, top, p.tko_speed, p.acc_up, kind="takeoff"),
            cm.wait(top, PX4_TAKEOFF_SETTLE_S, "settle")]


def leg(here: tuple[float, float, float], target: tuple[float, float, float], speed: float,
        p: Px4Params) -> Motion:
    """One straight leg from rest to rest (the turn before it is legs()'s)."""
    return Motion(here, target, max(speed, 0.1), p.acc_hor, kind="leg")


def legs(start: tuple[float, float, float], targets: list[tuple[float, float, float]], speed: float | Sequence[float],
         p: Px4Params, heading: float | None = None) -> tuple[list[Motion], float | None]:
    """Each leg from rest to rest after turning to it; (motions, the heading at the end). `speed`: one for
    every leg, or the speed of the leg to each target (a mission that changes speed on the way). `heading`
    None: not known yet (before the first leg), the turn counts FIRST_TURN_DEG."""
    out: list[Motion] = []
    here = start
    speeds = [float(speed)] * len(targets) if isinstance(speed, (int, float)) else [float(v) for v in speed]
    for target, leg_speed in zip(targets, speeds, strict=True):
        if math.dist(here[:2], target[:2]) <= NEAR_M:
            continue  # within the acceptance radius already: reached
        new = heading_deg(here, target)
        angle = FIRST_TURN_DEG if heading is None else turn_deg(heading, new)
        turn = turn_s(angle, p)
        if turn > 1e-9:
            out.append(cm.wait(here, turn, "turn"))
        out.append(leg(here, target, leg_speed, p))
        here, heading = target, new
    return out, heading


def landing(here: tuple[float, float, float], ground: float, p: Px4Params) -> list[Motion]:
    """Down to `ground` in PX4's three speed bands, then the touchdown until disarmed."""
    x, y, z = here
    out: list[Motion] = []
    mid = (p.z_auto_dn + p.land_speed) / 2.0  # the linear blend between MPC_LAND_ALT1 and MPC_LAND_ALT2
    bands = ((ground + p.land_alt1, p.z_auto_dn), (ground + p.land_alt2, mid), (ground, p.land_speed))
    top = z
    for floor, speed in bands:
        low = max(min(top, floor), ground)
        if top - low > 1e-6:
            v0 = out[-1].speed if out else 0.0
            out.append(Motion((x, y, top), (x, y, low), speed, p.acc_down, v0=min(v0, speed), v1=speed,
                              kind="descent" if floor > ground else "land"))
            top = low
    out.append(cm.wait((x, y, ground), PX4_TOUCHDOWN_S, "touchdown"))
    return out


def return_altitude(here: tuple[float, float, float], home: tuple[float, float, float], p: Px4Params) -> float:
    """Above home: the altitude RTL flies home at (never below the current one)."""
    current = here[2] - home[2]
    dist = math.dist(here[:2], home[:2])
    if dist < p.rtl_min_dist:
        return current
    target = p.rtl_return_alt
    if 0.0 < p.rtl_cone_ang < 90.0:  # within the cone above home a lower return altitude will do
        target = min(target, max(p.rtl_descend_alt, dist / math.tan(math.radians(p.rtl_cone_ang))))
    return max(target, current)


def rtl(here: tuple[float, float, float], home: tuple[float, float, float], p: Px4Params) -> list[Motion]:
    alt = home[2] + return_altitude(here, home, p)
    up, above = (here[0], here[1], alt), (home[0], home[1], alt)
    out = [cm.wait(here, PX4_RTL_START_S, "rtl")]
    if alt - here[2] > 1e-6:
        out.append(Motion(here, up, p.z_auto_up, p.acc_up, kind="climb"))
    if math.dist(up[:2], above[:2]) > 1e-9:
        out.append(Motion(up, above, p.xy_cruise, p.acc_hor, kind="home"))
    if p.rtl_land_delay > 0:
        out.append(cm.wait(above, p.rtl_land_delay, "loiter"))
    return out + landing(above, home[2], p)


def flight(ground: tuple[float, float, float], altitude: float, targets: list[tuple[float, float, float]],
           end: str, speed: float | Sequence[float], p: Px4Params) -> list[Motion]:
    """A whole survey mission: take-off at `ground`, the waypoints `targets` (`speed` as legs() takes it),
    then RTL or LAND."""
    motions = takeoff(ground, altitude, p)
    flown, _ = legs(motions[-1].end, targets, speed, p)
    motions += flown
    here = motions[-1].end
    return motions + (rtl(here, ground, p) if end == "rtl" else landing(here, ground[2], p))
