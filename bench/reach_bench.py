"""Which target points of the shipped maps' plans see fewer photos than the overlaps imply, and why.

    python bench/reach_bench.py [--maps leonardo:5,old-town:4,river-city:3,grid-city:2] [--write-doc FILE]

Each map is planned as `missionplan plan --map NAME --uavs N` plans it (default settings), and its planned
photos are measured as the plan measures them (missionplan/mission/photo_overlap.py, flightplan.photo_centres):
the target points reachable (a straight run of 9 flyable cells crosses the footprint window around
them) and bounded (obstacles or the map's edge close it), the reachable points short of the implied
count and their 5th percentile. Each short reachable point is put down to the first of these that its
window holds: the end of a drone's track (a sortie's first or last photo: where a zone's border or a
sortie's end cuts a street), the end of a straight strip inside a track (a turn: a lane's end, a street
corner, a street end where the drone turns back), a diagonal leg (the corrector's cut across a corner)
or none of them (strips passing along the window's edge). *grid* is how many reachable points would still be short
with a photo at every cell of the drones' grid paths, before the corrector smooths them into waypoint legs: where
the short points come from (the planner's route, which counts a target photographed once one footprint holds it,
or the smoothing).

The last columns are the same plan with the overlap fill (`plan --overlap-fill`,
missionplan/mission/overlap_fill.py): the stubs and runs it flies and in how many rounds, the reachable points
still short and their 5th percentile, the busiest drone's flight time without and with it and the share
added, and the wall time of planning (plan_field: the grid plan, the flight plans, the fill's rounds) without
and with it.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from missionplan.mission.corrector import drop_hovers
from missionplan.mission.photo_overlap import (classify_points, implied_photos, photos_per_point, strip_directions,
                                               strips_of, window_half_cells)
from missionplan.planning.field_plan import plan_field
from missionplan.planning.pipeline import DEFAULT_POLICY, make_policy
from missionplan.planning.plan_folder import shipped_ground

import doctable  # bench/doctable.py: --write-doc

CAUSES = ("track end", "turn", "diagonal", "edge")
AXIS_DEG = 10.0  # a strip within this of a grid axis is straight along it; others are diagonal legs


def low(values: np.ndarray) -> int:
    return int(np.percentile(values, 5, method="lower")) if len(values) else 0


def strip_bounds(strips: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each strip's first and last photo index (photos in order, strips numbered 0.. as they come)."""
    first = np.r_[0, np.flatnonzero(np.diff(strips)) + 1]
    return first, np.r_[first[1:] - 1, len(strips) - 1]


def causes_of(short: np.ndarray, points_m: np.ndarray, centres: np.ndarray, runs: np.ndarray, strips: np.ndarray,
              directions: np.ndarray, footprint_m: float) -> list[int]:
    """How many of the `short` points each of CAUSES explains (the first that holds, in that order)."""
    first, last = strip_bounds(strips)
    is_end = np.zeros(len(strips), dtype=bool)
    is_end[first] = is_end[last] = True
    track_end = np.r_[True, runs[1:] != runs[:-1]] | np.r_[runs[1:] != runs[:-1], True]
    diagonal = ~(np.abs(directions).max(axis=1) > math.cos(math.radians(AXIS_DEG)))
    counts = [0] * len(CAUSES)
    for i in np.flatnonzero(short):
        inside = np.flatnonzero((np.abs(centres - points_m[i]) <= footprint_m / 2 + 1e-6).all(axis=1))
        ends = inside[is_end[inside]]
        if len(ends):
            counts[0 if track_end[ends].any() else 1] += 1
        else:
            counts[2 if diagonal[strips[inside]].any() else 3] += 1
    return counts


def grid_path_counts(paths: np.ndarray, cells: np.ndarray, cell_m: float, footprint_m: float) -> np.ndarray:
    """Photos per target point with a photo at every cell of each drone's grid path (hovers dropped)."""
    points = [drop_hovers(path).astype(float) * cell_m for path in paths]
    centres = np.vstack(points)
    runs = np.concatenate([np.full(len(p), k) for k, p in enumerate(points)])
    counts, _ = photos_per_point(centres, strips_of(centres, runs), cells, cell_m, footprint_m)
    return counts


def row(name: str, uavs: int) -> str:
    ground = shipped_ground(name, uavs)
    gmap, frame, settings, safety = ground.gmap, ground.frame, ground.settings, ground.safety
    assert frame is not None and settings is not None and safety is not None
    policy = make_policy(DEFAULT_POLICY, None)
    started = time.perf_counter()
    field = plan_field(gmap, uavs, frame, settings, safety, policy=policy, lanes=True)
    plan_s = time.perf_counter() - started
    plans = field.plans
    assert plans is not None
    cell_m, footprint_m = frame.cell_m, plans.settings.footprint_m
    targets = gmap.target.copy()
    if len(field.result.unreachable):
        targets[tuple(np.asarray(field.result.unreachable).T)] = False
    cells = np.argwhere(targets)
    centres, runs = plans.photo_centres(frame)
    strips = strips_of(centres, runs)
    directions = strip_directions(centres, runs, strips)
    implied, _ = implied_photos(plans.settings.overlap, None)
    counts, _ = photos_per_point(centres, strips, cells, cell_m, footprint_m)
    reachable, edge = classify_points(~gmap.obstacle, cells, window_half_cells(footprint_m, cell_m))
    short = reachable & (counts < implied)
    on_grid = grid_path_counts(field.result.run.paths, cells, cell_m, footprint_m)
    grid_short = int((reachable & (on_grid < implied)).sum())
    causes = causes_of(short, cells * cell_m, centres, runs, strips, directions, footprint_m)
    bounded = ~reachable
    started = time.perf_counter()
    filled = plan_field(gmap, uavs, frame, settings, safety, policy=policy, lanes=True, overlap_fill=True)
    fill_s = time.perf_counter() - started
    fill = filled.overlap_fill
    assert filled.plans is not None and fill is not None
    more, more_runs = filled.plans.photo_centres(frame)
    after, _ = photos_per_point(more, strips_of(more, more_runs), cells, cell_m, footprint_m)
    return (f"{name:<11} {uavs:>4} {int(reachable.sum()):>6} {int(short.sum()):>5} {low(counts[reachable]):>3} "
            f"{grid_short:>5} "
            f"{int((bounded & ~edge).sum()):>5} {int((bounded & edge).sum()):>5} {low(counts[bounded]):>3} "
            + " ".join(f"{c:>5}" for c in causes)
            + f" {fill.stubs:>5} {fill.runs:>4} {fill.rounds:>6} {int((reachable & (after < implied)).sum()):>5} "
            f"{low(after[reachable]):>3} {fill.makespan_before_s:>6.0f} {fill.makespan_s:>6.0f} "
            f"{100 * (fill.makespan_s / fill.makespan_before_s - 1):>4.0f} {plan_s:>6.1f} {fill_s:>6.1f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default="leonardo:5,old-town:4,river-city:3,grid-city:2",
                        help="NAME:UAVS pairs, comma-separated")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        print(f"{'map':<11} {'uavs':>4} {'reachable points':>22} {'bounded':>15} "
              f"{'short reachable, put down to':>23}  {'with --overlap-fill':>36} {'busiest drone s':>20} "
              f"{'plan s':>13}")
        print(f"{'':<11} {'':>4} {'all':>6} {'short':>5} {'p5':>3} {'grid':>5} {'obst':>5} {'edge':>5} {'p5':>3} "
              + " ".join(f"{c.split()[0][:5]:>5}" for c in CAUSES)
              + f" {'stubs':>5} {'runs':>4} {'rounds':>6} {'short':>5} {'p5':>3} {'before':>6} {'after':>6} {'+%':>4} "
              f"{'before':>6} {'after':>6}")
        for pair in args.maps.split(","):
            name, uavs = pair.split(":")
            print(row(name, int(uavs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
