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

The last columns are what extending every strip past both its ends would give: photos added along the
strip's direction a trigger distance apart, up to half a footprint (4 cells), while they stay over
cells outside the plan's clearance band (missionplan/mission/clearance.flight_map). That is a measure
of photo positions only, not a flown track: the photos added, the reachable points still short, their
5th percentile, and the extra flight time at the plan's speed if each added metre were flown out and
back (twice the extension, turns not counted) spread over the fleet, against the plan's makespan.

*gap fill* estimates the other way: only where points are short, a straight run of 9 open cells through each
short point's window (the one nearest a planned photo; a run whose line crosses a later point's window serves it
too), flown out from the nearest planned photo and back. Its columns: the runs, the short points no open run can
serve, and the extra flight time spread over the fleet against the makespan (access counted straight, turns not:
an estimate, not a flown plan).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from missionplan.mission.clearance import flight_map
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


def extended(centres: np.ndarray, strips: np.ndarray, directions: np.ndarray, cell_m: float, trigger_m: float,
             open_cells: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The photos with each strip of two photos or more carried on past both its ends, a trigger distance
    apart, up to `half` cells, while over `open_cells`: (centres, strips, photos added)."""
    added, added_strips = [], []
    first, last = strip_bounds(strips)
    steps = int(round(half * cell_m / trigger_m))
    for s, (a, b) in enumerate(zip(first, last)):
        if a == b or not np.isfinite(directions[s]).all():
            continue
        for end, sign in ((b, 1.0), (a, -1.0)):
            for k in range(1, steps + 1):
                point = centres[end] + sign * directions[s] * k * trigger_m
                cell = np.rint(point / cell_m).astype(int)
                if not ((0 <= cell).all() and (cell < open_cells.shape).all() and open_cells[cell[0], cell[1]]):
                    break
                added.append(point)
                added_strips.append(s)
    if not added:
        return centres, strips, 0
    return np.vstack([centres, added]), np.concatenate([strips, added_strips]), len(added)


def grid_path_counts(paths: np.ndarray, cells: np.ndarray, cell_m: float, footprint_m: float) -> np.ndarray:
    """Photos per target point with a photo at every cell of each drone's grid path (hovers dropped)."""
    points = [drop_hovers(path).astype(float) * cell_m for path in paths]
    centres = np.vstack(points)
    runs = np.concatenate([np.full(len(p), k) for k, p in enumerate(points)])
    counts, _ = photos_per_point(centres, strips_of(centres, runs), cells, cell_m, footprint_m)
    return counts


def gap_fill(short_cells: np.ndarray, open_cells: np.ndarray, photo_cells: np.ndarray,
             half: int) -> tuple[int, int, float]:
    """A gap-fill estimate: for each short point in turn (not yet served), the straight run of 2 * half + 1 open
    cells through its window (either axis, any offset) nearest to a planned photo; a strip flown along it gives
    the point the implied count, and every short point whose window a run's line then crosses end to end is
    served. (runs, points no open run serves, cells flown: each run's new cells plus its access from the nearest
    planned photo and back, straight: a lower bound on the flown way).
    """
    from scipy.spatial import cKDTree  # type: ignore[import-untyped]

    tree = cKDTree(photo_cells)
    rows, cols = open_cells.shape
    lines: dict[tuple[int, int], set[int]] = {}  # (axis, line index): the cells along it a run flies
    runs, unserved, flown = 0, 0, 0.0

    def crossed(r: int, c: int) -> bool:
        for (axis, line), along in lines.items():
            across, at = (r, c) if axis == 0 else (c, r)
            if abs(across - line) <= half and all(a in along for a in range(at - half, at + half + 1)):
                return True
        return False

    for r, c in short_cells:
        if crossed(r, c):
            continue
        best: tuple[float, int, int, int] | None = None  # access, axis, line, centre along it
        for axis in (0, 1):
            for offset in range(-half, half + 1):
                line, at = (r + offset, c) if axis == 0 else (c + offset, r)
                lo, hi = at - half, at + half
                size_line, size_along = (rows, cols) if axis == 0 else (cols, rows)
                if not (0 <= line < size_line and lo >= 0 and hi < size_along):
                    continue
                cells_run = open_cells[line, lo:hi + 1] if axis == 0 else open_cells[lo:hi + 1, line]
                if not cells_run.all():
                    continue
                centre = (line, at) if axis == 0 else (at, line)
                access = float(tree.query(centre)[0])
                if best is None or access < best[0]:
                    best = (access, axis, line, at)
        if best is None:
            unserved += 1
            continue
        access, axis, line, at = best
        along = lines.setdefault((axis, line), set())
        new = set(range(at - half, at + half + 1)) - along
        along |= new
        runs += 1
        flown += 2 * access + len(new)
    return runs, unserved, flown


def row(name: str, uavs: int) -> str:
    ground = shipped_ground(name, uavs)
    gmap, frame, settings, safety = ground.gmap, ground.frame, ground.settings, ground.safety
    assert frame is not None and settings is not None and safety is not None
    field = plan_field(gmap, uavs, frame, settings, safety, policy=make_policy(DEFAULT_POLICY, None), lanes=True)
    plans = field.plans
    assert plans is not None
    cell_m, footprint_m, trigger_m = frame.cell_m, plans.settings.footprint_m, plans.settings.trigger_distance_m
    targets = gmap.target.copy()
    if len(field.result.unreachable):
        targets[tuple(np.asarray(field.result.unreachable).T)] = False
    cells = np.argwhere(targets)
    centres, runs = plans.photo_centres(frame)
    strips = strips_of(centres, runs)
    directions = strip_directions(centres, runs, strips)
    implied, _ = implied_photos(plans.settings.overlap, None)
    half = window_half_cells(footprint_m, cell_m)
    counts, _ = photos_per_point(centres, strips, cells, cell_m, footprint_m)
    reachable, edge = classify_points(~gmap.obstacle, cells, half)
    short = reachable & (counts < implied)
    on_grid = grid_path_counts(field.result.run.paths, cells, cell_m, footprint_m)
    grid_short = int((reachable & (on_grid < implied)).sum())
    causes = causes_of(short, cells * cell_m, centres, runs, strips, directions, footprint_m)
    open_cells = ~flight_map(gmap, safety.clearance_m, uavs)[0].obstacle
    more, more_strips, added = extended(centres, strips, directions, cell_m, trigger_m, open_cells, half)
    after, _ = photos_per_point(more, more_strips, cells, cell_m, footprint_m)
    makespan = max(d.flight_s for d in plans.drone_plans())
    extra_s = 2 * added * trigger_m / plans.settings.speed_m_s / uavs
    bounded = ~reachable
    gap_runs, gap_unserved, gap_cells = gap_fill(cells[short], open_cells, centres / cell_m, half)
    gap_s = gap_cells * cell_m / plans.settings.speed_m_s / uavs
    return (f"{name:<11} {uavs:>4} {int(reachable.sum()):>6} {int(short.sum()):>5} {low(counts[reachable]):>3} "
            f"{grid_short:>5} "
            f"{int((bounded & ~edge).sum()):>5} {int((bounded & edge).sum()):>5} {low(counts[bounded]):>3} "
            + " ".join(f"{c:>5}" for c in causes)
            + f" {added:>6} {int((reachable & (after < implied)).sum()):>5} {low(after[reachable]):>3} "
            f"{makespan:>7.0f} {100 * extra_s / makespan:>5.0f} "
            f"{gap_runs:>5} {gap_unserved:>5} {100 * gap_s / makespan:>5.0f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default="leonardo:5,old-town:4,river-city:3,grid-city:2",
                        help="NAME:UAVS pairs, comma-separated")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        print(f"{'map':<11} {'uavs':>4} {'reachable points':>22} {'bounded':>15} "
              f"{'short reachable, put down to':>23} {'strips carried on 4 cells':>25} {'':>7} {'':>5} "
              f"{'gap fill':>17}")
        print(f"{'':<11} {'':>4} {'all':>6} {'short':>5} {'p5':>3} {'grid':>5} {'obst':>5} {'edge':>5} {'p5':>3} "
              + " ".join(f"{c.split()[0][:5]:>5}" for c in CAUSES)
              + f" {'photos':>6} {'short':>5} {'p5':>3} {'span s':>7} {'+%':>5} {'runs':>5} {'none':>5} {'+%':>5}")
        for pair in args.maps.split(","):
            name, uavs = pair.split(":")
            print(row(name, int(uavs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
