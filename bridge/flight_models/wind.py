"""Wind, as ArduCopter SITL flies in it: how fast a copter makes way along a leg in wind, and the current it draws.

Owns the wind model of the mock autopilot (SITL's SIM_WIND_SPD, m/s; SIM_WIND_DIR, degrees, where the wind
comes FROM, SITL's default 180; SIM_WIND_TURB, m/s), measured on ArduCopter 4.7 SITL (--model +, copter.parm,
--speedup 10) flying take-off to 20 m, 150 m legs north, east, south and RTL west (docs/wind-model.md,
bench/wind_bench.py):

- along a leg the copter keeps its commanded speed v (WPNAV_SPEED, DO_CHANGE_SPEED) until the wind's
  component against the leg, h, and across it, c, leave it less: (V + HEAD_SLOPE·h)² + (CROSS_GAIN·c)² <=
  CALM_LIMIT² bounds its ground speed V. Measured into the wind (v = 10 m/s): h = 2, 4, 6, 8, 12 m/s gave 8.88,
  7.73, 6.57, 5.43, 3.11 m/s (calm 9.83), v = 5 m/s gave 5.0 up to h = 8 and 3.12 at 12 (the same bound:
  a lean-angle limit, not a fraction of the speed); across it (c = 8, 12 m/s) 9.6 and 8.77 m/s; with the
  wind, no faster than v. CALM_LIMIT is raised to v when v is above it, so that a calm flight is never changed;
- the current: SITL's battery current hardly depends on the wind (28.1 A hover, 29.9 A cruise calm; 30.3 A into
  and 28.6 A with an 8 m/s wind, 28.3 A hovering in it): it rises by CURRENT_UP per m/s the airspeed exceeds
  the ground speed and falls by CURRENT_DOWN per m/s below it (at most CURRENT_DOWN_MAX), plus CURRENT_TURB per
  (m/s)² of turbulence. The battery used in wind grows mostly because the flight takes longer;
- turbulence: SITL's gusts are fast random changes that the copter loses to on every leg where the bound holds
  (8 m/s with 4 m/s of turbulence: 4.6-4.9 m/s into the wind instead of 5.43, 8.9-9.1 across instead of 9.6; with
  the wind unchanged), so the bound drops by TURB_LOSS per m/s of SIM_WIND_TURB. On top, each motion (a leg,
  RTL's way home) flies in the steady wind plus a gust of its own, each component drawn from a normal law of
  deviation GUST_SCALE · SIM_WIND_TURB (SITL's run-to-run spread), bounded to GUST_BOUND deviations, from a
  random.Random(seed): the same seed, the same gusts.

With no wind and no turbulence every function here returns its input (motions unchanged, factor exactly 1):
the planner's times and the goldens depend on the calm flight. Not modelled: wind on the climb and the
descent, the cross-track error (SITL's stayed within 1.5 m at 12 m/s), SIM_WIND_T (wind profile) and
SIM_WIND_DIR_Z, a headwind above ~17 m/s (where SITL would make no way; here the copter crawls at
MIN_GROUND_SPEED).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, replace

from .copter_model import Motion

WIND_PARAMS = {"SIM_WIND_SPD": 0.0, "SIM_WIND_DIR": 180.0, "SIM_WIND_TURB": 0.0}  # SITL's defaults
CALM_LIMIT = 10.03    # m/s: the ground speed bound with no wind (fitted to the headwind legs)
HEAD_SLOPE = 0.577    # ground speed lost per m/s of headwind once at the bound (fit, h = 2..12 m/s)
CROSS_GAIN = 0.405    # weight of the crosswind in the bound (fit to c = 8 and 12 m/s)
MIN_GROUND_SPEED = 0.5
CURRENT_UP = 0.002    # per m/s of airspeed above the ground speed (into the wind, hovering in it)
CURRENT_DOWN = 0.0075  # per m/s of airspeed below the ground speed (with the wind)
CURRENT_DOWN_MAX = 0.045
CURRENT_TURB = 0.002  # per (m/s)² of SIM_WIND_TURB (turbulence 4 m/s: +1 to +6 %; 2 m/s: +-0.3 %)
TURB_LOSS = 0.15      # m/s off the bound per m/s of SIM_WIND_TURB (fit: 8 m/s + 4, 4 m/s + 2)
GUST_SCALE = 0.25     # a motion's gust deviation per m/s of SIM_WIND_TURB
GUST_BOUND = 2.0      # gusts are cut at this many deviations


@dataclass(frozen=True)
class Wind:
    """The wind as SITL's parameters give it."""

    speed: float = 0.0       # SIM_WIND_SPD, m/s
    from_deg: float = 180.0  # SIM_WIND_DIR: where it comes from
    turbulence: float = 0.0  # SIM_WIND_TURB, m/s

    @classmethod
    def from_params(cls, values: dict[str, float]) -> Wind:
        return cls(*(float(values.get(name, default)) for name, default in WIND_PARAMS.items()))

    @property
    def calm(self) -> bool:
        return self.speed <= 0.0 and self.turbulence <= 0.0

    def air_motion(self) -> tuple[float, float]:
        """Where the air moves (north, east m/s): away from where the wind comes from."""
        heading = math.radians(self.from_deg)
        return -self.speed * math.cos(heading), -self.speed * math.sin(heading)


def ground_speed_bound(speed: float, unit: tuple[float, float], air: tuple[float, float],
                       turbulence: float = 0.0) -> float:
    """The ground speed along the unit vector `unit` (north, east) for a commanded `speed` in the air motion
    `air` (north, east m/s) and SIM_WIND_TURB `turbulence`: the lean-angle bound of the module doc."""
    head = -(air[0] * unit[0] + air[1] * unit[1])  # wind against the leg (negative: with it)
    cross = air[0] * unit[1] - air[1] * unit[0]
    limit = max(CALM_LIMIT, speed)  # a calm flight keeps its speed, whatever it is
    room = limit * limit - (CROSS_GAIN * cross) ** 2
    bound = (math.sqrt(room) if room > 0 else 0.0) - HEAD_SLOPE * head - TURB_LOSS * max(turbulence, 0.0)
    return min(speed, max(bound, MIN_GROUND_SPEED))


def current_factor(ground: tuple[float, float], air: tuple[float, float], turbulence: float) -> float:
    """The battery current relative to the calm one, flying at `ground` (north, east m/s) in `air`."""
    excess = math.hypot(ground[0] - air[0], ground[1] - air[1]) - math.hypot(*ground)  # airspeed - ground speed
    change = CURRENT_UP * excess if excess >= 0 else max(CURRENT_DOWN * excess, -CURRENT_DOWN_MAX)
    return 1.0 + change + CURRENT_TURB * max(turbulence, 0.0) ** 2


class WindField:
    """The wind one vehicle flies in: the steady wind and its gusts (a seeded random.Random)."""

    def __init__(self, wind: Wind, seed: int = 0) -> None:
        self.wind = wind
        self.seed = seed
        self._rng = random.Random(seed)
        self.air = wind.air_motion()  # the steady wind plus the gust of the motion flown now

    def _gust(self) -> tuple[float, float]:
        sigma = GUST_SCALE * self.wind.turbulence
        if sigma <= 0:
            return 0.0, 0.0
        return tuple(max(-GUST_BOUND * sigma, min(GUST_BOUND * sigma, self._rng.gauss(0.0, sigma)))  # type: ignore
                     for _ in range(2))

    def apply(self, motions: list[Motion]) -> list[Motion]:
        """The motions as flown in this wind: each horizontal one no faster than the bound, in the steady wind
        plus a gust of its own. Calm: the very same list."""
        if self.wind.calm:
            return motions
        out = []
        steady = self.wind.air_motion()
        for motion in motions:
            dn, de = motion.end[0] - motion.start[0], motion.end[1] - motion.start[1]
            length = math.hypot(dn, de)
            if length <= 1e-6:
                out.append(motion)
                continue
            gust = self._gust()
            self.air = (steady[0] + gust[0], steady[1] + gust[1])
            speed = ground_speed_bound(motion.speed, (dn / length, de / length), self.air, self.wind.turbulence)
            out.append(replace(motion, speed=speed) if speed < motion.speed else motion)
        return out

    def leg_speed(self, speed: float, dn: float, de: float) -> float:
        """The ground speed of a straight leg (north, east metres) flown at `speed`, in the steady wind."""
        length = math.hypot(dn, de)
        if self.wind.calm or length <= 1e-9:
            return speed
        return ground_speed_bound(speed, (dn / length, de / length), self.wind.air_motion(), self.wind.turbulence)

    def current_factor(self, vn: float, ve: float) -> float:
        """The current relative to the calm one at ground velocity (vn, ve); exactly 1 in a calm."""
        if self.wind.calm:
            return 1.0
        return current_factor((vn, ve), self.air, self.wind.turbulence)
