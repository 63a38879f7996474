"""Separation by construction: the altitude layers that keep every two drones --min-separation apart.

The guarantee is measured on the timeline `fly` judges a flight against (missionplan.mission.timeline: all
drones of a sortie start together, climb at their launch points, fly straight legs at the cruise
speed, return and descend), over the whole flight: take-off, survey, return and landing. Sortie J
of every drone is one flight (`fly --sortie J` starts them together), so each sortie is measured
on its own and the guarantee is the smallest of them.

Method, cheapest first, the first that keeps the minimum wins:
1. the altitudes as asked (one altitude, or --altitude-step layers): drones far apart need nothing;
2. one layer per drone, `min_separation` apart (or the asked step if larger): during the survey
   any two drones are then at least that far apart vertically; what remains are the climbs and
   descents through other layers, which the timeline measures.
A top layer above --max-altitude, or a pair still too close on every candidate, is refused: the
caller names the pair, the sortie, the time and the place (SeparationError, exit 2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..maps.gridmap import MapError
from .timeline import closest_approach

DEFAULT_MIN_SEPARATION_M = 5.0
DEFAULT_MAX_ALTITUDE_M = 120.0  # the usual legal ceiling for open-category drones (EU, US)


@dataclass
class Layering:
    step_m: float  # drone k flies at altitude + k * step_m
    approach: dict[str, Any]  # closest approach over every sortie (timeline.closest_approach + `sortie`)
    method: str


def closest_over_sorties(sortie_tracks: list[dict[int, np.ndarray]],
                         measure: Callable[[dict[int, np.ndarray]], dict[str, Any]] = closest_approach) -> dict[str, Any]:
    """`measure` (closest_approach, or another with its keys) of each sortie's tracks (started together),
    the smallest of them; `sortie` is the 1-based sortie of the 3-D minimum (None when no two drones fly
    the same sortie)."""
    best: dict[str, Any] | None = None
    horizontal: tuple[float, list[int]] | None = None
    for index, tracks in enumerate(sortie_tracks):
        approach = measure(tracks)
        if approach["3d"] is None:
            continue
        if best is None or approach["3d"] < best["3d"]:
            best = {**approach, "sortie": index + 1}
        if horizontal is None or approach["horizontal"] < horizontal[0]:
            horizontal = (approach["horizontal"], approach["pair_horizontal"])
    if best is None or horizontal is None:
        return {"horizontal": None, "3d": None, "pair_horizontal": [], "pair_3d": [], "at_s": None, "sortie": None}
    best["horizontal"], best["pair_horizontal"] = horizontal
    return best


def position_at(track: np.ndarray, t: float) -> np.ndarray:
    """(row_m, col_m, up_m) of a timed track (timeline.planned_track) at time t."""
    return np.array([np.interp(t, track[:, 0], track[:, k]) for k in (1, 2, 3)])


def choose_layers(tracks_for: Callable[[float], list[dict[int, np.ndarray]]], uavs: int, altitude_m: float,
                  asked_step_m: float, min_separation_m: float, max_altitude_m: float,
                  measure: Callable[[dict[int, np.ndarray]], dict[str, Any]] = closest_approach) -> Layering:
    """The first candidate (see the module docstring) that keeps `min_separation_m`; SeparationError
    otherwise, carrying the last candidate tried (the caller names its closest pair and the place).

    tracks_for(step) gives, per sortie, sysid -> timed track with drone k at altitude + k * step;
    `measure` says how close a candidate's tracks come (closest_approach: flown exactly in step)."""
    candidates = [(asked_step_m, "altitudes as asked" if asked_step_m > 0 else "one altitude, horizontal spacing")]
    if uavs > 1 and min_separation_m > asked_step_m:
        candidates.append((min_separation_m, f"altitude layers {min_separation_m:g} m apart"))
    last: Layering | None = None
    ceiling = ""
    for step, method in candidates:
        top = altitude_m + (uavs - 1) * step
        if top > max_altitude_m + 1e-9:
            ceiling = (f"; layers {step:g} m apart would put uav{uavs} at {top:g} m, above --max-altitude "
                       f"{max_altitude_m:g} m")
            continue
        layering = Layering(step, closest_over_sorties(tracks_for(step), measure), method)
        if layering.approach["3d"] is None or layering.approach["3d"] >= min_separation_m - 1e-6:
            return layering
        last = layering
    raise SeparationError(last, ceiling)


class SeparationError(MapError):
    """The asked separation cannot be guaranteed: `layering` is the closest failing candidate (or None
    when every candidate was above the ceiling), `ceiling` says which layers the ceiling refused."""

    def __init__(self, layering: Layering | None, ceiling: str) -> None:
        super().__init__("separation cannot be guaranteed" + ceiling)
        self.layering, self.ceiling = layering, ceiling
