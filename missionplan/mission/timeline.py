"""Where every drone is when: planned missions as timed 3-D tracks, and the closest approach of two tracks.

The plan's separation promise and planned times come from here. All drones start their missions
together and fly them the way ArduCopter does (missionplan.bridge.flight_models.copter_model, measured on ArduCopter
SITL; the mock autopilot's SITL-like mode flies the same model): spool up and climb at the launch point, fly
every leg from rest to rest at the cruise speed with the copter's acceleration (with a transit speed, the ways
out and home at it and the survey at the survey speed: leg_speeds), and at the end
return (RTL: climb to RTL_ALT, home at RTL_SPEED, loiter, land) or land where the track ends (LAND),
the last LAND_ALT_LOW metres at LAND_SPEED. `plan` uses ArduCopter's documented defaults; `fly`
re-times each plan with the parameters its vehicle reports. A FlightModel with `px4` set times the
flight as PX4 flies it instead (missionplan.bridge.flight_models.px4_model: take-off at MPC_TKO_SPEED, a turn of the
nose at every corner, RTL and PX4's three landing speeds), for plans made for PX4 and PX4 vehicles. `closest_approach`
measures any set of timed tracks, planned or flown, on one time base, so plan and flight are judged by the same ruler.

Positions are in one local metric frame (the grid frame in metres: row axis, column axis, up).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from missionplan.bridge.flight_models import copter_model as cm
from missionplan.bridge.flight_models import px4_model
from missionplan.bridge.flight_models.copter_model import CopterParams
from missionplan.bridge.flight_models.px4_model import Px4Params

ASSUMES = ("all missions start together; ArduCopter's flight (missionplan.bridge.flight_models.copter_model): "
           "spool-up and climb at "
           "WPNAV_SPEED_UP, legs from rest to rest at the cruise speed with WPNAV_ACCEL, RTL at RTL_ALT and "
           "RTL_SPEED then RTL_LOIT_TIME, descent at WPNAV_SPEED_DN, the last LAND_ALT_LOW at LAND_SPEED")


PX4_ASSUMES = ("all missions start together; PX4's flight (missionplan.bridge.flight_models.px4_model): "
               "spool-up and climb at MPC_TKO_SPEED, "
               "a turn of the nose at MPC_YAWRAUTO_MAX before each leg, legs from rest to rest at the cruise speed "
               "with MPC_ACC_HOR, RTL, descent at MPC_Z_V_AUTO_DN then MPC_LAND_SPEED below MPC_LAND_ALT2")


@dataclass(frozen=True)
class FlightModel:
    speed_m_s: float  # the survey's legs (the mission's DO_CHANGE_SPEED)
    acceptance_m: float
    copter: CopterParams = field(default_factory=CopterParams)
    px4: Px4Params | None = None  # set: the flight is timed as PX4 flies it (flight_models.px4_model)
    transit_speed_m_s: float | None = None  # the ways out and home (leg_speeds); None: speed_m_s

    @classmethod
    def for_autopilot(cls, autopilot: str, speed_m_s: float, acceptance_m: float,
                      transit_speed_m_s: float | None = None) -> FlightModel:
        """The default model of `plan --autopilot` (ArduCopter's or PX4's documented defaults)."""
        return cls(speed_m_s, acceptance_m, px4=Px4Params() if autopilot == "px4" else None,
                   transit_speed_m_s=transit_speed_m_s)

    @property
    def transit_m_s(self) -> float:
        return self.speed_m_s if self.transit_speed_m_s is None else self.transit_speed_m_s

    @property
    def assumes(self) -> str:
        return PX4_ASSUMES if self.px4 is not None else ASSUMES

    @property
    def climb_rate_m_s(self) -> float:
        return self.px4.tko_speed if self.px4 is not None else self.copter.speed_up

    @property
    def land_rate_m_s(self) -> float:
        """The slowest descent rate (LAND_SPEED): altitude over it bounds the landing's duration."""
        if self.px4 is not None:
            return min(self.px4.land_speed, self.px4.z_auto_dn)
        return min(self.copter.land_speed, self.copter.descent_speed)


def leg_speeds(model: FlightModel, out: int, survey: int, back: int, resumes: bool = False) -> np.ndarray:
    """The speed of the leg into each waypoint of a flight through `out` waypoints of its way out, `survey`
    of its survey and `back` of its way home, as drone_missions.build_mission's DO_CHANGE_SPEED items set
    them: the way out and the leg onto the survey's first waypoint (a way out, or a resumed sortie: the camera
    is off until there) at the transit speed, the survey at the survey speed, the way home at the transit speed.
    RTL's own way home is the autopilot's RTL speed (the models' rtl), not the mission's."""
    speeds = np.full(out + survey + back, float(model.speed_m_s))
    speeds[:out] = model.transit_m_s
    if (resumes or out > 0) and survey:
        speeds[out] = model.transit_m_s
    speeds[out + survey:] = model.transit_m_s
    return speeds


def planned_motions(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                    model: FlightModel, speeds: np.ndarray | None = None) -> list[cm.Motion]:
    """The phases of one drone's planned flight (missionplan.bridge.flight_models.copter_model.Motion), in order.
    `speeds`: the speed of the leg into each waypoint (leg_speeds); None: model.speed_m_s for all."""
    ground = (float(launch_m[0]), float(launch_m[1]), 0.0)
    points = np.asarray(waypoints_m, dtype=float).reshape(-1, 2)
    each = np.full(len(points), float(model.speed_m_s)) if speeds is None else np.asarray(speeds, dtype=float)
    if len(each) != len(points):
        raise ValueError(f"{len(each)} leg speeds for {len(points)} waypoints")
    if model.px4 is not None:
        targets = [(float(w[0]), float(w[1]), float(altitude_m)) for w in points]
        return px4_model.flight(ground, altitude_m, targets, end, [float(v) for v in each], model.px4)
    motions = cm.takeoff(ground, altitude_m, model.copter)
    here = motions[-1].end
    for waypoint, speed in zip(points, each):
        target = (float(waypoint[0]), float(waypoint[1]), float(altitude_m))
        if np.hypot(target[0] - here[0], target[1] - here[1]) > 1e-9:
            motions.append(cm.leg(here, target, float(speed), model.copter))
        here = target
    if end == "rtl":
        motions += cm.rtl(here, ground, model.copter)
    else:
        motions += cm.landing(here, 0.0, model.copter)
    return motions


def planned_track(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                  model: FlightModel, speeds: np.ndarray | None = None) -> np.ndarray:
    """(n, 4) array of (t, row_m, col_m, up_m) of one drone's planned flight, linear in between (rows
    every corner and every half second inside a move, so the interpolation follows the speed profile)."""
    return cm.sample(planned_motions(launch_m, waypoints_m, altitude_m, end, model, speeds))


def planned_seconds(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                    model: FlightModel, speeds: np.ndarray | None = None) -> float:
    """How long that flight takes (the last row of planned_track)."""
    return cm.total_time(planned_motions(launch_m, waypoints_m, altitude_m, end, model, speeds))


Closest = dict[str, tuple[float, list[int], float]]  # "horizontal" / "3d" -> (distance, pair, at_s)


def closest_approach(tracks: dict[int, np.ndarray], step_s: float = 0.02) -> dict[str, Any]:
    """Closest approach between any two drones, horizontally and in 3-D.

    tracks[id] = (n, 4) array of t, row_m, col_m, up_m (increasing t; any common metric frame and
    clock). Each pair is compared while both were recorded, at every recorded time of either and
    every `step_s` in between, positions interpolated linearly. `at_s`: when the 3-D minimum
    happened, in seconds from the earliest start of any track."""
    best: Closest = {"horizontal": (np.inf, [], 0.0), "3d": (np.inf, [], 0.0)}
    ids = sorted(k for k, v in tracks.items() if len(v) >= 1)
    origin = min((float(tracks[k][0, 0]) for k in ids), default=0.0)
    for i, a in enumerate(ids):
        for b in ids[i + 1:]:
            ta, tb = tracks[a], tracks[b]
            t0, t1 = max(ta[0, 0], tb[0, 0]), min(ta[-1, 0], tb[-1, 0])
            if t1 < t0:
                continue
            times = np.union1d(np.arange(t0, t1 + step_s, step_s), np.concatenate([ta[:, 0], tb[:, 0]]))
            times = times[(times >= t0) & (times <= t1)]
            gap = np.column_stack([np.interp(times, ta[:, 0], ta[:, k]) - np.interp(times, tb[:, 0], tb[:, k])
                                   for k in (1, 2, 3)])
            _keep_closest(best, [a, b], gap, times - origin)
    return _approach(best)


def _keep_closest(best: Closest, pair: list[int], gap: np.ndarray, at_s: np.ndarray) -> None:
    """Update `best` with the pair's gaps (n, 3: row, col, up metres) at the times at_s."""
    horizontal = np.hypot(gap[:, 0], gap[:, 1])
    for name, dist in (("horizontal", horizontal), ("3d", np.hypot(horizontal, gap[:, 2]))):
        at = int(np.argmin(dist))
        if dist[at] < best[name][0]:
            best[name] = (float(dist[at]), pair, float(at_s[at]))


def _approach(best: Closest) -> dict[str, Any]:
    """closest_approach's answer from its bookkeeping (all None when no two tracks were compared)."""
    if not np.isfinite(best["horizontal"][0]):
        return {"horizontal": None, "3d": None, "pair_horizontal": [], "pair_3d": [], "at_s": None}
    return {"horizontal": round(best["horizontal"][0], 3), "3d": round(best["3d"][0], 3),
            "pair_horizontal": best["horizontal"][1], "pair_3d": best["3d"][1], "at_s": round(best["3d"][2], 2)}


def closest_approach_out_of_step(tracks: dict[int, np.ndarray], floor_s: float, rate: float,
                                 step_s: float = 0.25) -> dict[str, Any]:
    """closest_approach of tracks that may run out of step with each other: at time t after their
    common start, any drone may be up to floor_s + rate * t seconds ahead of or behind any other (t:
    the later of the two planned times compared).

    A timeline cannot know how much faster or slower each vehicle flies its corners, and on one altitude
    the separation of two drones rests on their timing: this is the distance they keep whatever their
    timing within that slack. Positions on a step_s grid; a track that has ended (or not started) is not
    compared. Same keys as closest_approach; `at_s` is the first-named drone's planned time."""
    best: Closest = {"horizontal": (np.inf, [], 0.0), "3d": (np.inf, [], 0.0)}
    ids = sorted(k for k, v in tracks.items() if len(v) >= 1)
    origin = min((float(tracks[k][0, 0]) for k in ids), default=0.0)
    end = max((float(tracks[k][-1, 0]) for k in ids), default=origin)
    times = np.arange(origin, end + step_s, step_s)
    grid = {}
    for k in ids:
        track = tracks[k]
        inside = (times >= track[0, 0] - 1e-9) & (times <= track[-1, 0] + 1e-9)
        grid[k] = (np.column_stack([np.interp(times, track[:, 0], track[:, j]) for j in (1, 2, 3)]), inside)
    slack = floor_s + rate * (times - origin)
    most = int(np.ceil(slack.max() / step_s)) if len(times) else 0
    for i, a in enumerate(ids):
        for b in ids[i + 1:]:
            (pa, ina), (pb, inb) = grid[a], grid[b]
            for shift in range(-most, most + 1):
                # a at its planned time i against b at its time i + shift, where the slack allows it
                lo, hi = max(0, -shift), min(len(times), len(times) - shift)
                if hi <= lo:
                    continue
                ia = np.arange(lo, hi)
                ib = ia + shift
                ok = ina[ia] & inb[ib] & (abs(shift) * step_s <= slack[np.maximum(ia, ib)] + 1e-9)
                if not ok.any():
                    continue
                _keep_closest(best, [a, b], pa[ia[ok]] - pb[ib[ok]], times[ia[ok]] - origin)
    return _approach(best)
