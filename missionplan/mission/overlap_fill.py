"""Overlap fill: short detours that give the reachable target points the planner's route left short the photos
the overlaps imply (plan --overlap-fill).

The grid planner counts a target done once one footprint holds it, so where a street ends, turns or is cut by
a zone's border a point can be seen by fewer photos than the front overlap implies (photo_overlap: a short,
reachable point; its *deficit* is the photos it lacks). Photos are a trigger distance apart along the track
(one per cell at the default 8/9 front overlap), and a photo sees a point when it is centred in the point's
*window*: the footprint-sized square around it (`half` cells each way). So a point lacking d photos gets
them from any d more photo positions inside its window. Two kinds of detour give them:

- a **stub**: from a cell P of a drone's path inside the window, straight out along a row or column for L
  cells that are all outside the clearance band (clearance.flight_map) and back to P. Each of its cells
  inside the window and off the cells flown already is photographed twice, out and back (a photo where one
  was taken adds no new view, so a stub over flown cells counts for nothing). For each short point, largest
  deficit first, of the stubs that give it some of what it lacks, the one with the least cost per photo it
  gives all the short points around it: 2 L moves plus `turn_cells`, what the reversal at its end costs in
  moves' time (a multicopter brakes to a stop there). The photos it adds count for every short point
  around it, so a later point may need none.
- a **run**, for a point whose window no path enters: a straight run of 2 * half + 1 open cells across the
  window (either axis, any offset across it), the one whose nearest cell is the fewest moves from a drone's
  path (breadth-first over the open cells from every path cell at once), flown out of the path there,
  end to end and back.

Either joins the drone with the shortest path among those passing its start, as a detour out of the path
and back to it, so the plan's order and end stay as they were (as clearance.photograph_band's detours).
Where every detour turns back is kept as a waypoint by the corrector (`FilledPaths.anchor`), which would
otherwise cut the detour off: its shortcuts keep a target's one photo, not the overlaps. It may still cut a
stub's way back to the path, which is cheaper to fly; from the third round on, where the detours leave the
path is kept too, so what is still short then is flown out and back whole.

The caller (planning/field_plan.py) measures the missions' photos, fills, re-makes the flight plans and
measures again, for a few rounds: photos fall where the trigger distance puts them along the corrected
legs, not exactly at cells, and what counts is where the missions take them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage  # type: ignore[import-untyped]

from .clearance import insert_detours, padded_paths, steps_toward, way_to_source

UNREACHED = np.iinfo(np.int64).max // 4  # a cell no path reaches: never the nearest
DIRECTIONS = ((-1, 0), (0, 1), (1, 0), (0, -1))
Cell = tuple[int, int]


@dataclass(frozen=True)
class Detour:
    """Cells flown out of a path cell `start` and back to it (`cells` ends at `start`); `ends`: where it turns
    back (a stub's far end, a run's two ends)."""

    start: Cell
    cells: tuple[Cell, ...]
    ends: tuple[Cell, ...]


@dataclass
class FilledPaths:
    """fill_paths' answer: the drones' grid paths with the detours flown (the others hovering at their end),
    the grid moves added, the stubs and runs flown and how many short points no detour serves."""

    paths: np.ndarray
    moves_added: int
    stubs: int
    runs: int
    unserved: int
    ends: list[Cell]
    starts: list[Cell]

    def anchor(self, keep: np.ndarray, starts: bool) -> None:
        """Mark where every detour turns back in `keep` (a bool grid), and with `starts` where it leaves the path:
        the corrector keeps them as waypoints."""
        for r, c in self.ends + (self.starts if starts else []):
            keep[r, c] = True


def choose_stubs(points: np.ndarray, deficits: np.ndarray, on_path: np.ndarray, open_cells: np.ndarray, half: int,
                 turn_cells: float) -> tuple[list[Detour], np.ndarray]:
    """Stubs (module docstring) for the short `points` ((m, 2)) lacking `deficits` photos, largest deficit
    first: (the stubs, each point's deficit they leave: > 0 where no stub out of a path cell in its window
    gives it enough)."""
    need = np.zeros(open_cells.shape, dtype=np.int64)
    need[points[:, 0], points[:, 1]] = deficits
    flown = on_path.copy()  # the cells photographed already: a stub's photos count only off them
    stubs: list[Detour] = []
    for index in np.argsort(-deficits, kind="stable"):
        r, c = (int(v) for v in points[index])
        while need[r, c] > 0:
            best = _best_stub((r, c), need, on_path, flown, open_cells, half, turn_cells)
            if best is None:
                break
            (pr, pc), (dr, dc), length = best
            out = [(pr + k * dr, pc + k * dc) for k in range(1, length + 1)]
            stubs.append(Detour((pr, pc), tuple(out + out[-2::-1] + [(pr, pc)]), (out[-1],)))
            for qr, qc in out:  # a new cell: two photos (out and back) for each short point whose window holds it
                if flown[qr, qc]:
                    continue
                flown[qr, qc] = True
                box = need[max(qr - half, 0):qr + half + 1, max(qc - half, 0):qc + half + 1]
                np.maximum(box - 2, 0, out=box, where=box > 0)
    return stubs, need[points[:, 0], points[:, 1]]


def _best_stub(point: Cell, need: np.ndarray, on_path: np.ndarray, flown: np.ndarray, open_cells: np.ndarray,
               half: int, turn_cells: float) -> tuple[Cell, Cell, int] | None:
    """The stub (start, direction, length) out of a path cell in `point`'s window that gives `point` some of
    the photos it lacks at the least cost per photo it gives all the short points (`need` > 0) around it.
    Only its cells off `flown` count: photos where photos were taken already add no new view."""
    rows, cols = open_cells.shape
    r, c = point
    longest = 2 * half
    best: tuple[float, Cell, Cell, int] | None = None
    r0, c0 = max(r - half, 0), max(c - half, 0)
    for pr, pc in np.argwhere(on_path[r0:r + half + 1, c0:c + half + 1]) + (r0, c0):
        for dr, dc in DIRECTIONS:
            steps = np.arange(1, longest + 1)
            ray = np.column_stack([pr + steps * dr, pc + steps * dc])
            inside_map = ((ray >= 0) & (ray < (rows, cols))).all(axis=1)
            ok = np.zeros(longest, dtype=bool)
            ok[inside_map] = open_cells[ray[inside_map, 0], ray[inside_map, 1]]
            length = longest if ok.all() else int(np.argmin(ok))  # the open cells before the first closed one
            if not length:
                continue
            ray = ray[:length]
            lo = np.maximum(ray.min(axis=0) - half, 0)
            hi = ray.max(axis=0) + half + 1
            near = np.argwhere(need[lo[0]:hi[0], lo[1]:hi[1]] > 0) + lo  # the short points the ray may serve
            lacking = need[near[:, 0], near[:, 1]]
            seen = (np.abs(ray[:, None, :] - near[None, :, :]) <= half).all(axis=2)  # (length, points)
            seen &= ~flown[ray[:, 0], ray[:, 1]][:, None]
            photos = 2 * np.cumsum(seen, axis=0)
            gain = np.minimum(photos, lacking).sum(axis=1)
            mine = np.flatnonzero((near == point).all(axis=1))
            if not len(mine):  # the ray leads away from the point's window
                continue
            own = photos[:, mine[0]]
            cost = np.where(own > 0, (2 * steps[:length] + turn_cells) / np.maximum(gain, 1), np.inf)
            k = int(np.argmin(cost))
            if np.isfinite(cost[k]) and (best is None or cost[k] < best[0]):
                best = (float(cost[k]), (int(pr), int(pc)), (dr, dc), k + 1)
    return None if best is None else best[1:]


def run_access(dist: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """For the run of 2 * half + 1 cells centred on each cell, along the columns (index 0) and along the rows
    (index 1): the fewest moves from a path to its nearest cell, and whether the whole run is open and reached
    (dist >= 0) inside the map. (2, rows, cols) each."""
    size = 2 * half + 1
    cost = np.where(dist >= 0, dist, UNREACHED)
    access = np.empty((2,) + dist.shape, dtype=np.int64)
    for axis in (0, 1):
        access[axis] = ndimage.minimum_filter1d(cost, size, axis=axis, mode="constant", cval=UNREACHED)
        worst = ndimage.maximum_filter1d(cost, size, axis=axis, mode="constant", cval=UNREACHED)
        access[axis][worst >= UNREACHED] = UNREACHED
    return access, access < UNREACHED


def choose_runs(points: np.ndarray, dist: np.ndarray, nxt: np.ndarray, half: int) -> tuple[list[Detour], int]:
    """Runs (module docstring) for the short `points` ((m, 2)) in order, each out of the path cell nearest
    it and back (`dist`, `nxt`: clearance.steps_toward from the path cells): (the runs, how many points no
    open run serves). A point a run chosen before crosses end to end takes none."""
    access, fits = run_access(dist, half)
    rows, cols = dist.shape
    runs: list[Detour] = []
    flown: dict[tuple[int, int], np.ndarray] = {}  # (axis, line): the cells along it the runs cover
    unserved = 0

    def crossed(r: int, c: int) -> bool:
        for (axis, line), along in flown.items():
            across, at = (r, c) if axis == 1 else (c, r)
            lo, hi = at - half, at + half
            if abs(across - line) <= half and lo >= 0 and hi < len(along) and along[lo:hi + 1].all():
                return True
        return False

    for r, c in np.asarray(points, dtype=np.int64).reshape(-1, 2):
        r, c = int(r), int(c)
        if crossed(r, c):
            continue
        best: tuple[int, int, int] | None = None  # access, axis, line
        for axis in (0, 1):
            for offset in range(-half, half + 1):
                line = (r + offset) if axis == 1 else (c + offset)
                centre = (line, c) if axis == 1 else (r, line)
                if 0 <= centre[0] < rows and 0 <= centre[1] < cols and fits[axis][centre]:
                    if best is None or access[axis][centre] < best[0]:
                        best = (int(access[axis][centre]), axis, line)
        if best is None:
            unserved += 1
            continue
        _, axis, line = best
        at = c if axis == 1 else r
        cells = [(line, k) for k in range(at - half, at + half + 1)] if axis == 1 else \
            [(k, line) for k in range(at - half, at + half + 1)]
        entry = min(range(len(cells)), key=lambda k: dist[cells[k]])
        back = way_to_source(nxt, cells[entry])  # from the run's entry cell back to the path
        # entry -> one end -> the other end -> entry: the whole run flown, then back to the path
        along = cells[entry::-1] + cells[1:] + cells[-2:entry - 1 if entry else None:-1]
        runs.append(Detour(back[-1], tuple(back[-2::-1] + along[1:] + back[1:]), (cells[0], cells[-1])))
        line_cells = flown.setdefault((axis, line), np.zeros(cols if axis == 1 else rows, dtype=bool))
        line_cells[at - half:at + half + 1] = True
    return runs, unserved


def fill_paths(paths: np.ndarray, open_cells: np.ndarray, points: np.ndarray, deficits: np.ndarray, half: int,
               turn_cells: float) -> FilledPaths:
    """The drones' grid paths (K, T+1, 2) with detours (module docstring) for the short `points` ((m, 2) grid
    cells) lacking `deficits` photos; `open_cells`: where a drone may fly (the planner's flight map)."""
    tracks = [list(map(tuple, p.tolist())) for p in paths]
    on_path = np.zeros(open_cells.shape, dtype=bool)
    for track in tracks:
        on_path[tuple(np.asarray(track).T)] = True
    points = np.asarray(points, dtype=np.int64).reshape(-1, 2)
    stubs, left = choose_stubs(points, np.asarray(deficits, dtype=np.int64), on_path, open_cells, half, turn_cells)
    runs: list[Detour] = []
    unserved = 0
    if (left > 0).any():
        dist, nxt = steps_toward(open_cells, on_path)
        runs, unserved = choose_runs(points[left > 0], dist, nxt, half)
    where: dict[Cell, dict[int, int]] = {}  # path cell -> {drone: its first index there}
    for k, track in enumerate(tracks):
        for i, cell in reversed(list(enumerate(track))):  # the first index last, so it stays
            where.setdefault(cell, {})[k] = i
    lengths = [len(t) for t in tracks]
    detours: dict[tuple[int, int], list[Cell]] = {}
    for detour in stubs + runs:
        k, i = min(where[detour.start].items(), key=lambda ki: lengths[ki[0]])
        detours.setdefault((k, i), []).extend(detour.cells)
        lengths[k] += len(detour.cells)
    return FilledPaths(padded_paths(insert_detours(tracks, detours), paths.dtype), sum(len(d.cells) for d in stubs + runs), len(stubs), len(runs), unserved,
                       [end for d in stubs + runs for end in d.ends], [d.start for d in stubs + runs])
