"""Where every drone is when: planned missions as timed 3-D tracks, and the closest approach of two tracks.

The plan's separation promise comes from here. All drones start their missions together and fly
them the way a multicopter autopilot does (and the mock autopilot models): climb straight up at the
launch point, fly straight 3-D legs at the cruise speed, take a waypoint as reached once inside its
acceptance radius and head for the next from there, and at the end fly home at the survey altitude
and descend (RTL) or descend where the track ends (LAND). `closest_approach` measures any set of timed
tracks, planned or flown, on one time base, so plan and flight are judged by the same ruler.

Positions are in one local metric frame (the grid frame in metres: row axis, column axis, up).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

# Vertical rates the timeline assumes (ArduCopter's WPNAV_SPEED_UP 2.5 m/s; a gentle 1.5 m/s descent).
CLIMB_RATE_M_S = 2.5
LAND_RATE_M_S = 1.5


@dataclass(frozen=True)
class FlightModel:
    speed_m_s: float
    acceptance_m: float
    climb_rate_m_s: float = CLIMB_RATE_M_S
    land_rate_m_s: float = LAND_RATE_M_S


def planned_track(launch_m: np.ndarray, waypoints_m: np.ndarray, altitude_m: float, end: str,
                  model: FlightModel) -> np.ndarray:
    """(n, 4) array of (t, row_m, col_m, up_m) corners of one drone's planned flight; linear in between."""
    here = np.array([launch_m[0], launch_m[1], 0.0])
    t = 0.0
    corners = [(t, *here)]

    def go(target: np.ndarray, speed: float, radius: float) -> None:
        nonlocal here, t
        gap = target - here
        dist = float(np.linalg.norm(gap))
        travel = max(dist - radius, 0.0)
        if travel <= 0.0:
            return
        here = here + gap * (travel / dist)
        t += travel / speed
        corners.append((t, *here))

    go(np.array([launch_m[0], launch_m[1], altitude_m]), model.climb_rate_m_s, 0.0)
    for waypoint in np.asarray(waypoints_m, dtype=float).reshape(-1, 2):
        go(np.array([waypoint[0], waypoint[1], altitude_m]), model.speed_m_s, model.acceptance_m)
    if end == "rtl":
        go(np.array([launch_m[0], launch_m[1], here[2]]), model.speed_m_s, 0.0)
    go(np.array([here[0], here[1], 0.0]), model.land_rate_m_s, 0.0)
    return np.array(corners, dtype=float)


def closest_approach(tracks: dict[int, np.ndarray], step_s: float = 0.02) -> dict[str, Any]:
    """Closest approach between any two drones, horizontally and in 3-D.

    tracks[id] = (n, 4) array of t, row_m, col_m, up_m (increasing t; any common metric frame and
    clock). Each pair is compared while both were recorded, at every recorded time of either and
    every `step_s` in between, positions interpolated linearly. `at_s`: when the 3-D minimum
    happened, in seconds from the earliest start of any track."""
    best = {"horizontal": (np.inf, [], 0.0), "3d": (np.inf, [], 0.0)}
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
            horizontal = np.hypot(gap[:, 0], gap[:, 1])
            for name, dist in (("horizontal", horizontal), ("3d", np.hypot(horizontal, gap[:, 2]))):
                at = int(np.argmin(dist))
                if dist[at] < best[name][0]:
                    best[name] = (float(dist[at]), [a, b], float(times[at]) - origin)
    if not np.isfinite(best["horizontal"][0]):
        return {"horizontal": None, "3d": None, "pair_horizontal": [], "pair_3d": [], "at_s": None}
    return {"horizontal": round(best["horizontal"][0], 3), "3d": round(best["3d"][0], 3),
            "pair_horizontal": best["horizontal"][1], "pair_3d": best["3d"][1], "at_s": round(best["3d"][2], 2)}
