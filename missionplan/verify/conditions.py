"""What each verification run meets: the wind and the faults, drawn from the crew's ranges.

A run's conditions depend only on the base seed, the run's index and the plan (its drones and the length of each
one's mission), never on which worker or node flies it: the run's seed is numpy's SeedSequence of (base seed,
index), and every draw comes from a generator of that seed, in a fixed order.

A fault strikes when its drone reaches a drawn mission item (a place in the mission, not a wall-clock moment, so a
sped-up or loaded simulator meets it at the same point of the flight):
- lost-drone: the drone's autopilot is killed there, silent for good (a crash, a flyaway out of radio range);
- battery-failsafe: its battery reads below BATT_LOW_VOLT from there on (a cell failing), with BATT_FS_LOW_ACT set
  to RTL as a team configures it: after BATT_LOW_TIMER the autopilot returns home by itself;
- link-gap: the ground station's link to every drone drops there for a drawn 5-20 simulated seconds (the drones
  fly on with their missions, unheard);
- gps-glitch: the drone's GPS jumps by a drawn 10-30 m in a random direction for a drawn 5-20 simulated seconds.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from missionplan.base.naming import Named

FAULT_KINDS = ("lost-drone", "link-gap", "battery-failsafe", "gps-glitch")
GUST_SHARE = 0.25  # turbulence amplitude as a share of the drawn mean wind (SITL's SIM_WIND_TURB, m/s)
LINK_GAP_S = (5.0, 20.0)  # simulated seconds a dropped link stays down
GLITCH_M = (10.0, 30.0)  # how far a GPS glitch moves the reported position
GLITCH_S = (5.0, 20.0)  # simulated seconds it lasts
FIRST_ITEM = 2  # a fault strikes from this mission item on: after the take-off, never at the last item


class ConditionsError(ValueError):
    """A range or fault list the crew gave that cannot be drawn from: one line naming it."""


@dataclass(frozen=True)
class Fault:
    """One fault of one run: its kind, the drone (system id) it strikes, the mission item it strikes at, and for a
    link gap or a GPS glitch how long it lasts (simulated seconds) and, for a glitch, its offset (north, east m)."""

    kind: str
    drone: int
    at_item: int
    seconds: float = 0.0
    north_m: float = 0.0
    east_m: float = 0.0


@dataclass(frozen=True)
class Conditions:
    """One run's world: its index and seed, the wind (mean speed m/s, the direction it blows from, degrees,
    turbulence m/s) and its faults."""

    run: int
    seed: int
    wind_mps: float
    wind_from_deg: float
    turbulence_mps: float
    faults: tuple[Fault, ...]

    def to_json(self) -> dict[str, Any]:
        doc = asdict(self)
        doc["faults"] = [asdict(f) for f in self.faults]
        return doc

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> Conditions:
        return cls(run=int(doc["run"]), seed=int(doc["seed"]), wind_mps=float(doc["wind_mps"]),
                   wind_from_deg=float(doc["wind_from_deg"]), turbulence_mps=float(doc["turbulence_mps"]),
                   faults=tuple(Fault(**f) for f in doc["faults"]))


def parse_wind(text: str) -> tuple[float, float]:
    """The wind range MIN-MAX (or one speed) in m/s -> (min, max)."""
    parts = text.strip().split("-")
    try:
        low, high = (float(parts[0]), float(parts[-1])) if len(parts) <= 2 else (None, None)
    except ValueError:
        low = high = None
    if low is None or high is None or not (0.0 <= low <= high <= 30.0):
        raise ConditionsError(Named("{wind} {0!r}: give MIN-MAX in m/s, 0 <= MIN <= MAX <= 30 (e.g. 2-6)", text))
    return low, high


def parse_faults(text: str) -> tuple[str, ...]:
    """The fault list "a,b" -> the fault kinds, each once, in the order given; "" or "none" -> none."""
    kinds = [k.strip() for k in text.split(",") if k.strip() and k.strip() != "none"]
    unknown = [k for k in kinds if k not in FAULT_KINDS]
    if unknown:
        raise ConditionsError(Named("{faults} {0!r}: choose among {1}", unknown[0], ", ".join(FAULT_KINDS)))
    return tuple(dict.fromkeys(kinds))


def run_seed(base_seed: int, index: int) -> int:
    """Run `index`'s own seed: the same whatever worker or node flies it."""
    return int(np.random.SeedSequence([base_seed, index]).generate_state(1)[0])


def draw_conditions(index: int, base_seed: int, wind: tuple[float, float], kinds: tuple[str, ...],
                    mission_items: dict[int, int]) -> Conditions:
    """Run `index`'s conditions. mission_items: each drone's system id -> the number of items its mission has."""
    seed = run_seed(base_seed, index)
    rng = np.random.default_rng(seed)
    speed = float(rng.uniform(wind[0], wind[1])) if wind[1] > wind[0] else float(wind[0])
    from_deg = float(rng.uniform(0.0, 360.0))
    drones = sorted(mission_items)
    faults = []
    for kind in kinds:
        drone = int(drones[int(rng.integers(len(drones)))])
        last = max(mission_items[drone] - 1, FIRST_ITEM + 1)
        at_item = int(rng.integers(FIRST_ITEM, last))
        seconds = north = east = 0.0
        if kind == "link-gap":
            seconds = float(rng.uniform(*LINK_GAP_S))
        elif kind == "gps-glitch":
            seconds = float(rng.uniform(*GLITCH_S))
            far, bearing = float(rng.uniform(*GLITCH_M)), float(rng.uniform(0.0, 2.0 * np.pi))
            north, east = far * float(np.cos(bearing)), far * float(np.sin(bearing))
        faults.append(Fault(kind, drone, at_item, round(seconds, 2), round(north, 2), round(east, 2)))
    return Conditions(index, seed, round(speed, 2), round(from_deg, 1), round(speed * GUST_SHARE, 2), tuple(faults))
