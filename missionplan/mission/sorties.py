"""Battery sorties: one drone's survey route cut into flights that each fit its endurance.

A drone whose route is longer than one battery flies it in sorties: take off at the launch point,
fly (sortie 1 starts at the launch point; sortie J >= 2 first transits, camera off, to where sortie
J - 1 stopped), survey, fly home and land (battery swap), and so on. The last sortie ends with the
plan's end action (RTL or LAND). Each sortie's whole flight - climb, transit out, survey, way home,
descent - stays within the budget `endurance x (1 - reserve)`.

The transit out and the way home do not cross buildings: `home_m(point)` gives their length (the
caller measures it along free cells, flightplan routes them the same way); by default a straight
line. The cut is greedy along the route: as many points as fit, where the points are the route's
waypoints plus every `step_m` along its axis-aligned legs (grid cell centres, so a cut never falls
where a drone could not be routed from). Times are the timeline's model of the plan's autopilot
(missionplan.bridge.flight_models.copter_model for ArduCopter: spool-up and climb, legs from rest to rest, RTL with its
loiter and slow final descent; missionplan.bridge.flight_models.px4_model for PX4: the same plus a turn of the nose
before every leg, PX4's RTL and landing), with a stop at every cut point too, and on PX4 a half turn where a sortie's
survey starts: the sortie flies fewer stops and smaller turns, so the estimate is an upper bound of
its planned time. The transit out flies at the model's transit speed, the survey at its survey speed (a camera
whose capture interval slows the survey does not slow the way out).

Metres in the grid frame throughout (row axis, column axis), as the timeline uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from missionplan.bridge.flight_models import copter_model as cm
from missionplan.bridge.flight_models import px4_model

from missionplan.base.naming import Named

from ..maps.gridmap import MapError
from .timeline import FlightModel

DEFAULT_ENDURANCE_MIN = 20.0
DEFAULT_RESERVE = 0.2  # fraction of the endurance kept for landing (wind, a go-around, a slow descent)


def sortie_file(sysid: int, sortie: int, suffix: str = ".plan") -> str:
    """uavK.plan for the first sortie, uavK-sJ.plan for sortie J >= 2."""
    return f"uav{sysid}{suffix}" if sortie == 1 else f"uav{sysid}-s{sortie}{suffix}"


# Re-balance the zones for sorties only when the drones' total flight times differ more than this.
REBALANCE_SPREAD = 0.05


def sortie_shares(zone_cells: np.ndarray, flight_s: np.ndarray, sorties: np.ndarray) -> np.ndarray | None:
    """Zone shares that even out the drones' total flight times when some fly several sorties, or None.

    A drone whose sorties spend longer in transit (a zone far from its launch point) photographs fewer
    cells per second of flight; giving each drone cells in proportion to its measured rate (cells per
    second, transits, climbs and descents included) evens out the busiest drone's time."""
    zone_cells, flight_s = np.asarray(zone_cells, dtype=float), np.asarray(flight_s, dtype=float)
    if len(zone_cells) < 2 or int(np.max(sorties)) < 2 or np.any(flight_s <= 0) or np.any(zone_cells <= 0):
        return None
    if flight_s.max() <= (1.0 + REBALANCE_SPREAD) * flight_s.min():
        return None
    rate = zone_cells / flight_s
    return rate / rate.sum()


@dataclass(frozen=True)
class Sortie:
    waypoints_m: np.ndarray  # (n, 2) survey waypoints in order, the first one where the survey (re)starts
    resumes: bool  # True for sortie 2 and later: a camera-off transit from the launch point first
    end: str  # "rtl" for every sortie but the last; the plan's end action for the last


def _flight_s(start_home_m: float, survey_s: float, end_home_m: float, altitude: float, end: str,
              model: FlightModel) -> float:
    """Upper bound of one sortie's duration: take-off, transit out (one leg, at the transit speed: the camera
    is off), `survey_s` seconds of survey, the way home and the landing (RTL) or the landing (LAND)."""
    if model.px4 is not None:
        return _px4_flight_s(start_home_m, survey_s, end_home_m, altitude, end, model)
    p = model.copter
    t = cm.total_time(cm.takeoff((0.0, 0.0, 0.0), altitude, p))
    t += cm.leg((0.0, 0.0, altitude), (start_home_m, 0.0, altitude), model.transit_m_s, p).duration
    if end == "rtl":
        return t + survey_s + cm.total_time(cm.rtl((end_home_m, 0.0, altitude), (0.0, 0.0, 0.0), p))
    return t + survey_s + cm.total_time(cm.landing((0.0, 0.0, altitude), 0.0, p))


def _px4_flight_s(start_home_m: float, survey_s: float, end_home_m: float, altitude: float, end: str,
                  model: FlightModel) -> float:
    """_flight_s as PX4 flies: its take-off, the transit with its first turn, a half turn onto the
    survey (its direction is not known here), PX4's RTL or landing."""
    p = model.px4
    assert p is not None
    top = (0.0, 0.0, altitude)
    t = cm.total_time(px4_model.takeoff((0.0, 0.0, 0.0), altitude, p))
    t += cm.total_time(px4_model.legs(top, [(start_home_m, 0.0, altitude)], model.transit_m_s, p)[0])
    t += px4_model.turn_s(180.0, p)
    if end == "rtl":
        return t + survey_s + cm.total_time(px4_model.rtl((end_home_m, 0.0, altitude), (0.0, 0.0, 0.0), p))
    return t + survey_s + cm.total_time(px4_model.landing((0.0, 0.0, altitude), 0.0, p))


def _densify(route: np.ndarray, step_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(the route with a point every step_m along its axis-aligned legs, which of them are the route's own)."""
    if step_m is None or len(route) < 2:
        return route, np.ones(len(route), dtype=bool)
    points, own = [route[0]], [True]
    for a, b in zip(route[:-1], route[1:]):
        gap = b - a
        length = float(np.hypot(*gap))
        if length > step_m and min(abs(gap[0]), abs(gap[1])) < 1e-9:
            for n in range(1, int(np.floor(length / step_m - 1e-9)) + 1):
                points.append(a + gap * (n * step_m / length))
                own.append(False)
        points.append(b)
        own.append(True)
    return np.array(points), np.array(own)


def _merge(points: np.ndarray, own: np.ndarray) -> np.ndarray:
    """A sortie's points without the inserted ones, but with its ends."""
    keep = own.copy()
    keep[0] = keep[-1] = True
    return points[keep]


def _survey_timer(points: np.ndarray, own: np.ndarray, model: FlightModel) -> Callable[[int, int], float]:
    """survey_s(i, j): seconds to fly points[i] -> points[j] along the route, stopping (rest to rest)
    at the route's own waypoints and at both ends, as the copter flies a sortie cut there. The cut
    points inserted by `_densify` lie on straight legs and are no stops in between. On PX4 every own
    waypoint passed also costs its turn (the turn onto the first leg is _flight_s's)."""
    def leg_s(length: float) -> float:
        if length <= 0.0:
            return 0.0
        if model.px4 is not None:
            return px4_model.leg((0.0, 0.0, 0.0), (float(length), 0.0, 0.0), model.speed_m_s, model.px4).duration
        return cm.leg((0.0, 0.0, 0.0), (float(length), 0.0, 0.0), model.speed_m_s, model.copter).duration

    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))]) if len(points) > 1 \
        else np.zeros(len(points))
    own_at = np.flatnonzero(own)
    turn = _turns_s(points[own_at], model)  # turn[m]: seconds turning at own waypoint m onto the next leg
    # Seconds from the first own waypoint to each own waypoint, one rest-to-rest leg (and its turn) at a time.
    own_s = np.concatenate([[0.0], np.cumsum([leg_s(b - a) + (turn[m] if m > 0 else 0.0) for m, (a, b)
                                              in enumerate(zip(arc[own_at][:-1], arc[own_at][1:]))])])
    rank = np.cumsum(own) - 1  # index into own_at of the last own waypoint at or before each point

    def survey_s(i: int, j: int) -> float:
        if j <= i:
            return 0.0
        after_i = rank[i] + (0 if own[i] else 1)  # first own waypoint at or after i
        before_j = rank[j]  # last own waypoint at or before j
        if after_i > before_j:  # both on one straight leg
            return leg_s(arc[j] - arc[i])
        tail = arc[j] - arc[own_at[before_j]]
        return (leg_s(arc[own_at[after_i]] - arc[i]) + float(own_s[before_j] - own_s[after_i])
                + leg_s(tail) + (turn[before_j] if tail > 0.0 else 0.0))

    return survey_s


def _turns_s(waypoints: np.ndarray, model: FlightModel) -> np.ndarray:
    """Seconds turning at each waypoint onto the leg after it: zero on ArduCopter (the timeline has no
    turn); on PX4 the angle between the legs in and out at MPC_YAWRAUTO_MAX, the first and last none."""
    turns = np.zeros(len(waypoints))
    if model.px4 is None or len(waypoints) < 3:
        return turns
    points = [(float(x), float(y), 0.0) for x, y in waypoints]
    heading = [px4_model.heading_deg(a, b) for a, b in zip(points[:-1], points[1:])]
    turns[1:-1] = [px4_model.turn_s(px4_model.turn_deg(h0, h1), model.px4) for h0, h1 in zip(heading[:-1], heading[1:])]
    return turns


def split_sorties(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                  model: FlightModel, budget_s: float | None, name: str = "drone",
                  home_m: Callable[[np.ndarray], float] | None = None, step_m: float | None = None) -> list[Sortie]:
    """The route `waypoints_m` (n, 2) of a drone launching at `launch_m` cut into sorties of at most
    `budget_s` seconds each (None: one sortie, however long). `home_m(p)`: length of the way from the
    launch point to p (default straight); `step_m`: spacing of the cut points on axis-aligned legs
    (default: cut at waypoints only). MapError when not even the first leg of a sortie fits."""
    launch = np.asarray(launch_m, dtype=float)
    route = np.asarray(waypoints_m, dtype=float).reshape(-1, 2)
    if budget_s is None or len(route) == 0:
        return [Sortie(route, False, end)]
    distance = home_m if home_m is not None else (lambda p: float(np.hypot(*(np.asarray(p) - launch))))
    points, own = _densify(route, step_m)
    home = np.array([distance(p) for p in points])
    survey_s = _survey_timer(points, own, model)

    def too_short(i: int) -> MapError:
        need = _flight_s(home[i], 0.0, home[i], altitude_m, "rtl", model)
        return MapError(Named("{0}: a sortie cannot fly out to where its survey resumes and back within the "
                              "endurance budget ({1:.0f} s usable; the climb, the transit and the way back alone "
                              "take {2:.0f} s): raise {endurance} or lower {reserve}", name, budget_s, need))

    sorties: list[Sortie] = []
    first, last = 0, len(points) - 1
    while True:
        if first == last:  # a route of one point: up, (a photo,) down
            if _flight_s(home[first], 0.0, home[first], altitude_m, end, model) > budget_s:
                raise too_short(first)
            j = first
        else:
            # Times grow along the route: the farthest point that still fits ends the sortie.
            j = first
            while j < last and _flight_s(home[first], survey_s(first, j + 1), home[j + 1], altitude_m,
                                         end if j + 1 == last else "rtl", model) <= budget_s:
                j += 1
            # Not where the next sortie could not even fly its first step and come back: stop earlier.
            while first < j < last and _flight_s(home[j], survey_s(j, j + 1), home[j + 1], altitude_m,
                                                 end if j + 1 == last else "rtl", model) > budget_s:
                j -= 1
            if j == first:
                raise too_short(first)
        sorties.append(Sortie(_merge(points[first:j + 1], own[first:j + 1]), first > 0, end if j == last else "rtl"))
        if j == last:
            return sorties
        first = j
