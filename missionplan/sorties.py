"""Battery sorties: one drone's survey route cut into flights that each fit its endurance.

A drone whose route is longer than one battery flies it in sorties: take off at the launch point,
fly (sortie 1 starts at the launch point; sortie J >= 2 first transits, camera off, to where sortie
J - 1 stopped), survey, return to launch and land (battery swap), and so on. The last sortie ends
with the plan's end action (RTL or LAND). Each sortie's whole flight - climb, transit out, survey,
way home, descent - stays within the budget `endurance x (1 - reserve)`.

The cut is greedy along the route: as many waypoints as fit, then the point along the next leg
where the budget runs out (found by bisection), so no survey distance is wasted. Times are the
timeline's (missionplan.timeline) with every leg flown in full: the acceptance radius only ever
shortens a leg, so the estimate is an upper bound of the timeline's own duration.

Metres in the grid frame throughout (row axis, column axis), as the timeline uses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gridmap import MapError
from .timeline import FlightModel

DEFAULT_ENDURANCE_MIN = 20.0
DEFAULT_RESERVE = 0.2  # fraction of the endurance kept for landing (wind, a go-around, a slow descent)


def sortie_file(sysid: int, sortie: int, suffix: str = ".plan") -> str:
    """uavK.plan for the first sortie, uavK-sJ.plan for sortie J >= 2."""
    return f"uav{sysid}{suffix}" if sortie == 1 else f"uav{sysid}-s{sortie}{suffix}"


@dataclass(frozen=True)
class Sortie:
    waypoints_m: np.ndarray  # (n, 2) survey waypoints in order, the first one where the survey (re)starts
    resumes: bool  # True for sortie 2 and later: a camera-off transit from the launch point first
    end: str  # "rtl" for every sortie but the last; the plan's end action for the last


def _flight_s(launch: np.ndarray, start: np.ndarray, survey_m: float, last: np.ndarray, altitude: float,
              end: str, model: FlightModel) -> float:
    """Upper bound of one sortie's duration: climb, transit out, survey, way home (RTL), descent."""
    horizontal = float(np.hypot(*(start - launch))) + survey_m
    if end == "rtl":
        horizontal += float(np.hypot(*(last - launch)))
    return altitude / model.climb_rate_m_s + horizontal / model.speed_m_s + altitude / model.land_rate_m_s


def split_sorties(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                  model: FlightModel, budget_s: float | None, name: str = "drone") -> list[Sortie]:
    """The route `waypoints_m` (n, 2) of a drone launching at `launch_m` cut into sorties of at most
    `budget_s` seconds each (None: one sortie, however long). MapError when even one leg's worth of
    flight cannot fit (the budget is shorter than the climb, a transit and the way back)."""
    launch = np.asarray(launch_m, dtype=float)
    route = np.asarray(waypoints_m, dtype=float).reshape(-1, 2)
    if budget_s is None or len(route) == 0:
        return [Sortie(route, False, end)]

    def too_short(start: np.ndarray) -> MapError:
        need = _flight_s(launch, start, 0.0, start, altitude_m, "rtl", model)
        return MapError(f"{name}: a sortie cannot fly out to where its survey starts and back within the endurance "
                        f"budget ({budget_s:.0f} s usable; the climb, the transit and the way back alone take "
                        f"{need:.0f} s): raise --endurance or lower --reserve")

    sorties: list[Sortie] = []
    start, nxt, resumes = route[0], 1, False  # where this sortie's survey starts; the next route waypoint
    while True:
        points, survey, j = [start], 0.0, nxt
        while j < len(route):
            step = float(np.hypot(*(route[j] - points[-1])))
            ending = end if j == len(route) - 1 else "rtl"
            if _flight_s(launch, start, survey + step, route[j], altitude_m, ending, model) > budget_s:
                break
            points.append(route[j])
            survey += step
            j += 1
        if j == len(route):
            if _flight_s(launch, start, survey, points[-1], altitude_m, end, model) > budget_s:
                raise too_short(start)
            sorties.append(Sortie(np.array(points), resumes, end))
            return sorties
        # The budget runs out on the leg points[-1] -> route[j]: the farthest point along it that still fits.
        a, b = points[-1], route[j]
        leg = float(np.hypot(*(b - a)))
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            fits = _flight_s(launch, start, survey + mid * leg, a + (b - a) * mid, altitude_m, "rtl", model) <= budget_s
            lo, hi = (mid, hi) if fits else (lo, mid)
        if len(points) == 1 and lo * leg < 1e-6:
            raise too_short(start)
        stop = a + (b - a) * lo
        if lo * leg >= 1e-6:
            points.append(stop)
        sorties.append(Sortie(np.array(points), resumes, "rtl"))
        start, nxt, resumes = stop, (j + 1 if (1.0 - lo) * leg < 1e-6 else j), True
        if nxt >= len(route):  # the cut fell on the last waypoint (rounding): nothing is left to survey
            return sorties
