"""How ArduCopter flies a mission, in time: its navigation parameters and the timed motion of each phase.

Owns the one kinematic model that both the planner's timeline (missionplan.mission.timeline: planned times,
report.json, the separation promise) and the mock autopilot's SITL-like flight (mock_flight) use, so
that plan, mock and judge agree. Measured against ArduCopter 4.7 SITL flying 20 m street plans
(docs/flight-timeline.md):

- take-off: the motors spool up for TAKEOFF_SPOOL_S, then a vertical move to the altitude at
  WPNAV_SPEED_UP with WPNAV_ACCEL_Z;
- waypoint legs: from rest to rest at the mission's speed (DO_CHANGE_SPEED, else WPNAV_SPEED) with
  WPNAV_ACCEL. The copter all but stops at every corner of our missions: the plan's acceptance radius,
  written to WPNAV_RADIUS, leaves its S-curves almost no room to blend one leg into the next;
- RTL: after RTL_START_S, a climb to RTL_ALT (never a descent; less near home, RTL_CONE_SLOPE), the
  way home at RTL_SPEED (0: WPNAV_SPEED, not the mission's speed), RTL_LOIT_TIME above home plus
  RTL_SETTLE_S, then the landing;
- landing (RTL's or NAV_LAND's): down at LAND_SPEED_HIGH (0: WPNAV_SPEED_DN) to LAND_ALT_LOW, the
  last LAND_ALT_LOW metres at LAND_SPEED, then TOUCHDOWN_S until the vehicle disarms.

Every motion is a Motion: a straight move from `start` to `end` (metres, any local frame: x, y, up)
with a trapezoidal speed profile (or a wait, start == end). No jerk limit: measured, ArduCopter's
S-curves and the little corner blending the radius allows cancel out to within a few per cent a leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

# Measured on ArduCopter 4.7 SITL (docs/flight-timeline.md), not parameters of the vehicle.
TAKEOFF_SPOOL_S = 3.8   # MISSION_START accepted -> leaves the ground (arming spool-up, take-off start)
RTL_START_S = 1.5       # last waypoint reached -> moving home
RTL_SETTLE_S = 1.5      # above home, on top of RTL_LOIT_TIME, before the descent starts
TOUCHDOWN_S = 2.8       # on the ground -> landed detected and disarmed
RTL_ABS_MIN_CLIMB_M = 2.5  # ArduCopter's RTL_ABS_MIN_CLIMB (250 cm) for the cone near home
RTL_MIN_CONE_SLOPE = 0.5


@dataclass(frozen=True)
class CopterParams:
    """The ArduCopter parameters the flight depends on, in SI units; defaults are ArduCopter 4.x's
    (the values SITL's copter.parm leaves alone)."""

    wp_speed: float = 10.0        # WPNAV_SPEED, m/s
    wp_accel: float = 2.5         # WPNAV_ACCEL, m/s/s
    wp_radius: float = 2.0        # WPNAV_RADIUS, m
    speed_up: float = 2.5         # WPNAV_SPEED_UP, m/s
    speed_dn: float = 1.5         # WPNAV_SPEED_DN, m/s
    accel_z: float = 1.0          # WPNAV_ACCEL_Z, m/s/s
    rtl_alt: float = 15.0         # RTL_ALT, m
    rtl_speed: float = 0.0        # RTL_SPEED, m/s (0: WPNAV_SPEED)
    rtl_loiter_s: float = 5.0     # RTL_LOIT_TIME, s
    rtl_cone_slope: float = 3.0   # RTL_CONE_SLOPE
    land_speed: float = 0.5       # LAND_SPEED, m/s
    land_speed_high: float = 0.0  # LAND_SPEED_HIGH, m/s (0: WPNAV_SPEED_DN)
    land_alt_low: float = 10.0    # LAND_ALT_LOW, m

    @classmethod
    def from_params(cls, values: dict[str, float]) -> CopterParams:
        """From ArduCopter parameter values (their own units: cm, cm/s, ms); missing ones keep the default."""
        changes = {attr: float(values[name]) * scale for name, (attr, scale) in PARAMETERS.items()
                   if name in values and math.isfinite(float(values[name]))}
        return replace(cls(), **changes)

    def as_params(self) -> dict[str, float]:
        """Back to ArduCopter's names and units."""
        return {name: getattr(self, attr) / scale for name, (attr, scale) in PARAMETERS.items()}

    @property
    def return_speed(self) -> float:
        return self.rtl_speed if self.rtl_speed > 0 else self.wp_speed

    @property
    def descent_speed(self) -> float:
        return self.land_speed_high if self.land_speed_high > 0 else self.speed_dn


# ArduCopter name -> (CopterParams field, factor from the parameter's unit to SI).
PARAMETERS: dict[str, tuple[str, float]] = {
    "WPNAV_SPEED": ("wp_speed", 0.01), "WPNAV_ACCEL": ("wp_accel", 0.01), "WPNAV_RADIUS": ("wp_radius", 0.01),
    "WPNAV_SPEED_UP": ("speed_up", 0.01), "WPNAV_SPEED_DN": ("speed_dn", 0.01),
    "WPNAV_ACCEL_Z": ("accel_z", 0.01), "RTL_ALT": ("rtl_alt", 0.01), "RTL_SPEED": ("rtl_speed", 0.01),
    "RTL_LOIT_TIME": ("rtl_loiter_s", 0.001), "RTL_CONE_SLOPE": ("rtl_cone_slope", 1.0),
    "LAND_SPEED": ("land_speed", 0.01), "LAND_SPEED_HIGH": ("land_speed_high", 0.01),
    "LAND_ALT_LOW": ("land_alt_low", 0.01),
}
assert {attr for attr, _ in PARAMETERS.values()} == {f.name for f in fields(CopterParams)}


@dataclass(frozen=True)
class Motion:
    """A straight move (or a wait) with a trapezoidal speed profile: from v0, accelerating at `accel`
    to the peak speed, cruising, decelerating to v1. Positions (x, y, up) in metres."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    speed: float = 1.0   # top speed, m/s
    accel: float = 1.0   # m/s/s
    v0: float = 0.0
    v1: float = 0.0
    wait_s: float = 0.0  # a wait (start == end) of this long
    kind: str = "move"   # move, wait, takeoff, leg, climb, home, descent, land

    @property
    def distance(self) -> float:
        return math.dist(self.start, self.end)

    def _profile(self) -> tuple[float, float, float, float, float, float]:
        """(peak speed, t accelerating, t cruising, t decelerating, d accelerating, d cruising)."""
        d, a = self.distance, max(self.accel, 1e-6)
        v0, v1 = min(self.v0, self.speed), min(self.v1, self.speed)
        peak = min(self.speed, math.sqrt(max((2.0 * a * d + v0 * v0 + v1 * v1) / 2.0, 0.0)))
        peak = max(peak, v0, v1, 1e-6)
        ta, tc = (peak - v0) / a, (peak - v1) / a
        da, dc = (v0 + peak) / 2.0 * ta, (peak + v1) / 2.0 * tc
        cruise = max(d - da - dc, 0.0)
        return peak, ta, cruise / peak, tc, da, cruise

    @property
    def duration(self) -> float:
        if self.distance <= 1e-9:
            return self.wait_s
        _, ta, tm, tc, _, _ = self._profile()
        return ta + tm + tc

    def travelled(self, t: np.ndarray | float) -> np.ndarray:
        """Distance covered along the move after t seconds (clipped to [0, duration])."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        d = self.distance
        if d <= 1e-9:
            return np.zeros_like(t)
        peak, ta, tm, tc, da, dm = self._profile()
        v0 = min(self.v0, self.speed)
        a = max(self.accel, 1e-6)
        t2, t3 = t - ta, t - ta - tm
        s = np.where(t <= ta, v0 * t + 0.5 * a * t * t,
                     np.where(t <= ta + tm, da + peak * t2, da + dm + peak * t3 - 0.5 * a * t3 * t3))
        return np.minimum(s, d)

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """(n, 3) positions after t seconds."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        start, end = np.array(self.start), np.array(self.end)
        d = self.distance
        frac = self.travelled(t) / d if d > 1e-9 else np.zeros_like(t)
        return start + frac[:, None] * (end - start)


def wait(where: tuple[float, float, float], seconds: float, kind: str = "wait") -> Motion:
    return Motion(where, where, wait_s=max(seconds, 0.0), kind=kind)


def takeoff(ground: tuple[float, float, float], altitude: float, p: CopterParams) -> list[Motion]:
    """Spool up on the ground, then straight up to `altitude` (above the ground point)."""
    top = (ground[0], ground[1], ground[2] + altitude)
    return [wait(ground, TAKEOFF_SPOOL_S, "spool"), Motion(ground, top, p.speed_up, p.accel_z, kind="takeoff")]


def leg(here: tuple[float, float, float], target: tuple[float, float, float], speed: float,
        p: CopterParams) -> Motion:
    """One waypoint leg, from rest to rest at the mission's speed."""
    return Motion(here, target, max(speed, 0.1), p.wp_accel, kind="leg")


def rtl_altitude(here: tuple[float, float, float], home: tuple[float, float, float], p: CopterParams) -> float:
    """The altitude (above home) RTL returns at: RTL_ALT, less near home (the cone), never below the
    current one (ArduCopter's ModeRTL::compute_return_target)."""
    current = here[2] - home[2]
    target = p.rtl_alt
    if p.rtl_cone_slope >= RTL_MIN_CONE_SLOPE:
        dist = math.dist(here[:2], home[:2])
        target = min(target, max(dist * p.rtl_cone_slope, current + RTL_ABS_MIN_CLIMB_M))
    return max(target, current)


def landing(here: tuple[float, float, float], ground: float, p: CopterParams) -> list[Motion]:
    """Down to `ground`: at the descent speed to LAND_ALT_LOW above it, at LAND_SPEED below, then touchdown."""
    x, y, z = here
    low = min(z, ground + p.land_alt_low)
    slow_v = min(p.land_speed, p.descent_speed)
    out = []
    if z - low > 1e-6:
        out.append(Motion(here, (x, y, low), p.descent_speed, p.accel_z, v1=slow_v, kind="descent"))
    if low - ground > 1e-6:
        v0 = slow_v if out else 0.0
        out.append(Motion((x, y, low), (x, y, ground), slow_v, p.accel_z, v0=v0, v1=slow_v, kind="land"))
    out.append(wait((x, y, ground), TOUCHDOWN_S, "touchdown"))
    return out


def rtl(here: tuple[float, float, float], home: tuple[float, float, float], p: CopterParams) -> list[Motion]:
    """Return to launch and land there (`home` is on the ground)."""
    alt = home[2] + rtl_altitude(here, home, p)
    up = (here[0], here[1], alt)
    above = (home[0], home[1], alt)
    out = [wait(here, RTL_START_S, "rtl")]
    if alt - here[2] > 1e-6:
        out.append(Motion(here, up, p.speed_up, p.accel_z, kind="climb"))
    out.append(Motion(up, above, p.return_speed, p.wp_accel, kind="home"))
    out.append(wait(above, p.rtl_loiter_s + RTL_SETTLE_S, "loiter"))
    return out + landing(above, home[2], p)


def total_time(motions: list[Motion]) -> float:
    return float(sum(m.duration for m in motions))


def sample(motions: list[Motion], t0: float = 0.0, step_s: float = 0.5) -> np.ndarray:
    """(n, 4) t, x, y, up through the motions: every end, and every step_s inside a move, so that
    linear interpolation between the rows stays within centimetres of the profile."""
    rows = []
    t = t0
    for m in motions:
        dur = m.duration
        if not rows:
            rows.append((t, *m.start))
        if m.distance > 1e-9 and dur > 0:
            inner = np.arange(step_s, dur, step_s)
            for ti, pos in zip(inner, m.position(inner)):
                rows.append((t + ti, *pos))
        t += dur
        rows.append((t, *m.end))
    return np.array(rows, dtype=float).reshape(-1, 4)
