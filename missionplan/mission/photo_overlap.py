"""Overlaps as measured: front and side overlap and photos per target point, from where the photos are.

The plan asks for overlaps (the front overlap sets the trigger distance, a camera's side overlap the lane
spacing); this module measures what photo positions give, whether they are the plan's (plan_folder) or
the flight's reported ones (the judge), so a report says what was achieved, not what the rule promised.

The footprint is the planner's: an axis-aligned square of side S in the grid's axes (north-up on an
unrotated grid: geo/camera.py, flight_report.coverage), centred on the photo. Positions are (n, 2) grid
metres (row axis, column axis), as flight.plan_report.to_grid_m gives them.

- Strips: a strip is a run of photos along one straight leg. Where the caller has no leg ids, a new
  strip starts at a photo of another run (a drone's sortie or flight) or where the heading from the
  previous photo turns by more than MAX_TURN_DEG from the step before. A step too short to have a
  heading (two photos at one corner) keeps the heading before it.
- Front overlap: each pair of consecutive photos of one strip, 1 - spacing / S, at least 0.
- Side overlap: for each photo, the nearest photo of another strip that runs alongside (within
  PARALLEL_DEG of this strip's direction), lies mostly across this strip's direction (more across than
  along) and no farther than S: 1 - its distance across / S (lanes a footprint apart touch: 0). A crossing street's photos are not side
  neighbours; a photo with no such neighbour has no side overlap (a single strip has none at all).
- Photos per target point: the target points are grid cells' centres; how many footprints hold each
  (its Chebyshev distance to the photo at most S / 2, to a micrometre), and the share of the points seen
  at all that only one strip's photos see.
- What the asked overlaps imply: floor(1 / (1 - front)) photos of a point on one strip, times
  floor(1 / (1 - side)) where strips neighbour side by side (a point seen by photos of more than one strip
  running the same way: east-west, or north-south, in the grid's axes; a street crossing is not that); a
  point seen by fewer photos is short.
- Reachable or bounded (given the flyable cells: not an obstacle, inside the map): the photos that can
  see a point are centred in the footprint-sized window around it (within half a footprint, 4 cells
  of a 9-cell footprint, each way). A point is reachable when some straight row or column run of
  flyable cells crosses that window end to end (9 cells along it): one strip flown there gives it the
  count the front overlap implies. Otherwise it is bounded: a photo cannot be centred where the window
  leaves the map ("map edge") or inside the obstacles that close it ("obstacles": a dead end, a corner
  between buildings), so fewer photos are what the geometry allows. `met` is then judged on the
  reachable points, every one of them (the least, not a percentile); the bounded ones are reported
  beside them. Without the flyable cells every point counts, and the 5th percentile decides `met`
  (the points at a strip's ends or a zone's edge see fewer photos than the middle of a lane).

Pure numpy and scipy's cKDTree (side neighbours), a difference array over the cells (photos per point),
cumulative sums over the flyable mask (reachable runs): a 20-drone city plan (50 000 photos, 500 000
target cells) is measured in well under a second (bench/overlap_bench.py).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree  # type: ignore[import-untyped]

MAX_TURN_DEG = 20.0  # a heading change above this between consecutive photos starts a new strip
PARALLEL_DEG = 30.0  # a side neighbour's strip runs within this of the photo's own strip
PERCENTILE = 5.0  # the low figure reported beside the median: 95 % of the values are at least this
CONTAIN_TOLERANCE_M = 1e-6  # a point on a footprint's edge is inside it (a micrometre of float round trip)
SHORT_STEP = 0.25  # a step shorter than this share of the median step has no heading of its own
IMPLIED_EPS = 1e-9
NEIGHBOURS_BEYOND_OWN = 16  # nearest photos asked for past those of a photo's own strip within a footprint  # floor(1 / (1 - 8/9)) is 9, though the division gives 8.999999999999998


def low(values: np.ndarray) -> float:
    """The PERCENTILE-th percentile of `values`, as one of them (never interpolated above what was seen)."""
    return float(np.percentile(values, PERCENTILE, method="lower"))


@dataclass(frozen=True)
class OverlapSpread:
    """Measured overlaps (fractions 0..1): their median, their 5th percentile and how many pairs were measured."""

    median: float
    p5: float
    pairs: int

    @classmethod
    def of(cls, values: np.ndarray) -> OverlapSpread | None:
        """The spread of `values`, or None for no value."""
        return cls(float(np.median(values)), low(values), int(len(values))) if len(values) else None

    def to_json(self) -> dict[str, Any]:
        return {"median": self.median, "p5": self.p5, "pairs": self.pairs}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> OverlapSpread:
        return cls(float(doc["median"]), float(doc["p5"]), int(doc["pairs"]))


BOUNDED_BY = ("obstacles", "map edge")  # why a bounded point's window holds no straight run: its reason's names


@dataclass(frozen=True)
class PointClass:
    """Photos per point of one class of target points: how many points, the median, 5th percentile and
    least of their photos, and how many are seen by fewer photos than implied for them."""

    points: int
    median: float
    p5: int
    least: int
    short: int

    @classmethod
    def of(cls, counts: np.ndarray, wanted: np.ndarray | None) -> PointClass:
        if not len(counts):
            return cls(0, 0.0, 0, 0, 0)
        short = int((counts < wanted).sum()) if wanted is not None else 0
        return cls(int(len(counts)), float(np.median(counts)), int(low(counts)), int(counts.min()), short)

    def to_json(self) -> dict[str, Any]:
        return {"points": self.points, "median": self.median, "p5": self.p5, "min": self.least, "short": self.short}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PointClass:
        return cls(int(doc["points"]), float(doc["median"]), int(doc["p5"]), int(doc["min"]), int(doc["short"]))


@dataclass(frozen=True)
class ReachSplit:
    """Photos per point of the reachable target points and of the bounded ones (module docstring), and
    how many bounded points each reason bounds (BOUNDED_BY: obstacles close the window, or the map's edge)."""

    reachable: PointClass
    bounded: PointClass
    bounded_by: tuple[int, ...]  # per BOUNDED_BY reason

    def to_json(self) -> dict[str, Any]:
        return {"reachable": self.reachable.to_json(),
                "bounded": {**self.bounded.to_json(), "by": dict(zip(BOUNDED_BY, self.bounded_by))}}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ReachSplit:
        by = doc["bounded"]["by"]
        return cls(PointClass.from_json(doc["reachable"]), PointClass.from_json(doc["bounded"]),
                   tuple(int(by[name]) for name in BOUNDED_BY))

    def summary(self) -> str:
        """`reachable points 11 median, 9 p5, 9 least (0 fewer); bounded points 5 median, 2 p5 (120: 90 obstacles, 30 map edge)`."""
        r, b = self.reachable, self.bounded
        text = f"reachable points {r.median:g} median, {r.p5} p5, {r.least} least ({r.short} of {r.points} fewer)"
        if b.points:
            reasons = ", ".join(f"{n} {name}" for name, n in zip(BOUNDED_BY, self.bounded_by) if n)
            text += f"; bounded points {b.median:g} median, {b.p5} p5 ({b.points}: {reasons})"
        return text


@dataclass(frozen=True)
class OverlapMeasure:
    """Front and side overlap and photos per target point, measured from photo positions, next to what was asked.

    `front` / `side` are None when nothing could be measured (no two photos on one strip; no strip
    alongside another). `asked_front` / `asked_side` are the fractions the plan asked (None: not asked).
    `implied_one_strip` / `implied_neighbouring` are the photos per point the asked overlaps imply on
    one strip and where strips neighbour (None without an asked front overlap); `short` counts the
    target points seen by fewer photos than implied for them. `reach`: the reachable and bounded points
    apart (None when the flyable cells were not given). `met` says whether every reachable point reaches
    the implied count, or without `reach` whether the 5th percentile of photos per point does (None
    when nothing is implied or no point is there to judge)."""

    footprint_m: float
    photos: int
    strips: int
    front: OverlapSpread | None
    side: OverlapSpread | None
    asked_front: float | None
    asked_side: float | None
    points: int
    per_point_median: float
    per_point_p5: int
    per_point_min: int
    single_strip_share: float | None  # of the points seen at all, those only one strip's photos see
    implied_one_strip: int | None
    implied_neighbouring: int | None
    short: int
    met: bool | None
    reach: ReachSplit | None = None

    def to_json(self) -> dict[str, Any]:
        reach = {} if self.reach is None else {"reach": self.reach.to_json()}
        return {**reach, "footprint_m": self.footprint_m, "photos": self.photos, "strips": self.strips,
                "front": None if self.front is None else self.front.to_json(),
                "side": None if self.side is None else self.side.to_json(),
                "asked_front": self.asked_front, "asked_side": self.asked_side,
                "photos_per_point": {"points": self.points, "median": self.per_point_median, "p5": self.per_point_p5,
                                     "min": self.per_point_min,
                                     "implied_one_strip": self.implied_one_strip,
                                     "implied_neighbouring": self.implied_neighbouring,
                                     "short": self.short, "met": self.met},
                "single_strip_share": self.single_strip_share}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> OverlapMeasure:
        per = doc["photos_per_point"]
        front, side = doc.get("front"), doc.get("side")
        return cls(float(doc["footprint_m"]), int(doc["photos"]), int(doc["strips"]),
                   None if front is None else OverlapSpread.from_json(front),
                   None if side is None else OverlapSpread.from_json(side),
                   doc.get("asked_front"), doc.get("asked_side"), int(per["points"]), float(per["median"]),
                   int(per["p5"]), int(per["min"]), doc.get("single_strip_share"), per.get("implied_one_strip"),
                   per.get("implied_neighbouring"), int(per["short"]), per.get("met"),
                   None if doc.get("reach") is None else ReachSplit.from_json(doc["reach"]))

    def summary(self) -> str:
        """One line for a person: `front overlap 89 % median, 88 % p5 (asked 89 %); side overlap ...;
        photos per target point 12 median, 9 p5 (9 implied)`."""
        def pct(value: float) -> str:
            return f"{100.0 * value:.0f} %"

        def overlap(name: str, spread: OverlapSpread | None, asked: float | None) -> str:
            wanted = f" (asked {pct(asked)})" if asked is not None else " (not asked)"
            if spread is None:
                return f"{name} overlap not measured ({'one strip' if name == 'side' else 'no strip of two photos'})" \
                       + (wanted if asked is not None else "")
            return f"{name} overlap {pct(spread.median)} median, {pct(spread.p5)} p5{wanted}"

        implied = ""
        if self.implied_one_strip is not None:
            implied = f" ({self.implied_one_strip}" + (
                f", {self.implied_neighbouring} where strips neighbour" if self.implied_neighbouring
                != self.implied_one_strip else "") + " implied" + (
                f"; {self.short} of {self.points} points fewer" if self.short else "") + ")"
        per_point = (f"photos per target point {self.per_point_median:g} median, {self.per_point_p5} p5, "
                     f"{self.per_point_min} least{implied}")
        parts = [overlap("front", self.front, self.asked_front), overlap("side", self.side, self.asked_side), per_point]
        return "; ".join(parts + ([] if self.reach is None else [self.reach.summary()]))


# ------------------------------------------------------------------------------------------- strips
def strips_of(centres: np.ndarray, runs: np.ndarray, max_turn_deg: float = MAX_TURN_DEG) -> np.ndarray:
    """(n,) strip id of each photo (0, 1, ... in order): a new strip at another run's photo or where the
    heading turns by more than `max_turn_deg` (see the module docstring). Photos are in the order taken."""
    n = len(centres)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    steps = np.diff(centres, axis=0)
    same_run = runs[1:] == runs[:-1]
    length = np.hypot(steps[:, 0], steps[:, 1])
    moving = length[same_run & (length > 0)]
    short = SHORT_STEP * float(np.median(moving)) if len(moving) else 0.0
    # A step too short for a heading keeps the one before it (forward fill of the last step that has one).
    has_heading = same_run & (length > short)
    last = np.maximum.accumulate(np.where(has_heading, np.arange(len(steps)), -1))
    heading = np.arctan2(steps[:, 1], steps[:, 0])
    filled = np.where(last >= 0, heading[np.maximum(last, 0)], np.nan)
    turn = np.abs(np.angle(np.exp(1j * (filled[1:] - filled[:-1]))))  # wrapped to [0, pi]
    # Photo k + 1 starts a strip when it is another run's, or its step turns from the step before it
    # (both steps in its run, and it has a heading of its own).
    turns = np.zeros(len(steps), dtype=bool)
    turns[1:] = same_run[1:] & same_run[:-1] & has_heading[1:] & (turn > math.radians(max_turn_deg))
    new_strip = np.concatenate([[True], ~same_run | turns])
    return np.cumsum(new_strip) - 1


def strip_directions(centres: np.ndarray, runs: np.ndarray, strips: np.ndarray) -> np.ndarray:
    """(number of strips, 2) unit direction of each strip: its first photo to its last, or for a strip
    of one photo the step into it (from its run's photo before) or else out of it; NaN when none."""
    count = int(strips.max()) + 1 if len(strips) else 0
    index = np.arange(len(strips))
    first = np.full(count, len(strips))
    np.minimum.at(first, strips, index)
    last = np.full(count, -1)
    np.maximum.at(last, strips, index)
    vector = centres[last] - centres[first]
    alone = first == last
    before = np.clip(first - 1, 0, None)
    after = np.clip(first + 1, None, len(strips) - 1)
    into = alone & (first > 0) & (runs[before] == runs[first])
    vector[into] = centres[first[into]] - centres[before[into]]
    out_of = alone & ~into & (first + 1 < len(strips)) & (runs[after] == runs[first])
    vector[out_of] = centres[after[out_of]] - centres[first[out_of]]
    length = np.hypot(vector[:, 0], vector[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where((length > 0)[:, None], vector / length[:, None], np.nan)


# ------------------------------------------------------------------------------------------- overlaps
def front_overlaps(centres: np.ndarray, strips: np.ndarray, footprint_m: float) -> np.ndarray:
    """1 - spacing / S of each pair of consecutive photos of one strip (at least 0)."""
    same = strips[1:] == strips[:-1]
    spacing = np.hypot(*np.diff(centres, axis=0)[same].T)
    overlaps: np.ndarray = np.maximum(1.0 - spacing / footprint_m, 0.0)
    return overlaps


def side_overlaps(centres: np.ndarray, strips: np.ndarray, directions: np.ndarray, footprint_m: float) -> np.ndarray:
    """Per photo that has one, 1 - distance across / S to its nearest side neighbour (module docstring).

    Each photo's nearest photos come from a KD-tree, nearest first, enough of them to get past its own
    strip's (about 2 S / spacing lie within S); the few photos whose every candidate was ruled out while
    more photos lie within S are asked again with all of them."""
    n = len(centres)
    if n < 2:
        return np.zeros(0)
    reach = footprint_m + CONTAIN_TOLERANCE_M  # lanes exactly a footprint apart touch: side overlap 0, measured
    tree = cKDTree(centres)
    same = strips[1:] == strips[:-1]
    spacing = np.hypot(*np.diff(centres, axis=0)[same].T)
    spacing = spacing[spacing > 0]
    own = math.ceil(2.0 * footprint_m / float(np.median(spacing))) + 1 if len(spacing) else 1  # itself included
    k = min(n, own + NEIGHBOURS_BEYOND_OWN)
    _, other = tree.query(centres, k=k, distance_upper_bound=reach)
    other = other.reshape(n, -1)
    across, valid = _side_candidates(centres, strips, directions, np.arange(n)[:, None], other, reach)
    has = valid.any(axis=1)
    first = np.argmax(valid, axis=1)  # nearest first: the first valid candidate is the nearest
    side = np.full(n, np.nan)
    side[has] = 1.0 - across[has, first[has]] / footprint_m
    # Every candidate ruled out and the k-th still within reach: more photos may lie there.
    for i in np.flatnonzero(~has & (other[:, -1] < n)):  # rare: a photo crowded by its own strip's photos
        near = np.asarray(tree.query_ball_point(centres[i], reach), dtype=np.int64)
        near = near[np.argsort(np.hypot(*(centres[near] - centres[i]).T), kind="stable")][None, :]
        far, ok = _side_candidates(centres, strips, directions, np.array([[i]]), near, reach)
        if ok.any():
            side[i] = 1.0 - far[0, np.argmax(ok[0])] / footprint_m
    overlaps: np.ndarray = np.maximum(side[~np.isnan(side)], 0.0)
    return overlaps


def _side_candidates(centres: np.ndarray, strips: np.ndarray, directions: np.ndarray, mine: np.ndarray,
                     other: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(how far across photo `mine`'s strip each photo `other` lies, whether it is a side neighbour: another
    strip running within PARALLEL_DEG of it, more across than along it, within `reach` across). `mine`
    (n, 1) and `other` (n, k) photo indexes; an index past the last photo (the KD-tree's "none") is none."""
    n = len(centres)
    found = other < n
    other = np.where(found, other, 0)
    dir_row, dir_col = (directions[strips[mine], j] for j in (0, 1))  # (n, 1): this photo's strip direction
    off_row = centres[other, 0] - centres[mine, 0]
    off_col = centres[other, 1] - centres[mine, 1]
    along = np.abs(off_row * dir_row + off_col * dir_col)
    across = np.abs(off_row * dir_col - off_col * dir_row)
    theirs = strips[other]
    parallel = np.abs(dir_row * directions[theirs, 0] + dir_col * directions[theirs, 1])
    with np.errstate(invalid="ignore"):  # NaN directions compare False: no side neighbour
        valid = (found & (theirs != strips[mine]) & (parallel >= math.cos(math.radians(PARALLEL_DEG)))
                 & (across > along) & (across <= reach))
    return across, valid


# ------------------------------------------------------------------------------------------- per point
def photos_per_point(centres: np.ndarray, strips: np.ndarray, cells: np.ndarray, cell_m: float,
                     footprint_m: float, across: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(photos holding each point, whether every photo holding it is of one strip) for the centres of
    `cells` ((m, 2) integer cells; a cell's centre is cell * cell_m metres, as the grid frame puts it).

    Each footprint holds a rectangle of cells: one pass over the photos adds it to a difference array
    over the cells' bounding box, and two cumulative sums give every cell's count. The same with each
    photo weighted by its strip id s and by s squared gives their sum and sum of squares at each cell:
    the photos holding a cell are all of one strip when count * sum(s^2) == sum(s)^2 (no spread).

    `across` ((n,) bool, optional): each photo's strip runs across the grid's rows (east-west) rather than
    down them. Then "one strip" is asked of each of the two kinds apart: a point at a crossing, seen by one
    east-west and one north-south strip, is on one strip of each, not where strips neighbour side by side."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    m = len(cells)
    if not len(centres) or not m:
        return np.zeros(m, dtype=np.int64), np.zeros(m, dtype=bool)
    low_cell, high_cell = cells.min(axis=0), cells.max(axis=0)
    shape = high_cell - low_cell + 1
    half = footprint_m / 2.0 + CONTAIN_TOLERANCE_M
    # The cells whose centre lies within half a footprint of each photo, clipped to the box.
    first = np.maximum(np.ceil((centres - half) / cell_m).astype(np.int64), low_cell) - low_cell
    last = np.minimum(np.floor((centres + half) / cell_m).astype(np.int64), high_cell) - low_cell
    hit = (first <= last).all(axis=1)
    first, last = first[hit], last[hit]
    strip = strips[hit].astype(np.int64)
    padded = (int(shape[0]) + 1, int(shape[1]) + 1)
    corners = [(first[:, 0], first[:, 1], 1), (first[:, 0], last[:, 1] + 1, -1),
               (last[:, 0] + 1, first[:, 1], -1), (last[:, 0] + 1, last[:, 1] + 1, 1)]
    flat = np.concatenate([r * padded[1] + c for r, c, _ in corners])
    sign = np.concatenate([np.full(len(first), v, dtype=np.int64) for _, _, v in corners])
    at = (cells - low_cell)
    kinds = np.zeros(len(strip), dtype=bool) if across is None else np.asarray(across, dtype=bool)[hit]
    counts = np.zeros(m, dtype=np.int64)
    one_strip = np.ones(m, dtype=bool)  # in every kind, the photos holding the point are of one strip
    for kind in (False, True):
        chosen = kinds == kind
        if not chosen.any():
            continue
        sums = []
        for weight in (np.ones_like(strip), strip, strip * strip):
            weights = np.where(chosen, weight, 0)
            grid = np.bincount(flat, weights=sign * np.tile(weights, 4), minlength=padded[0] * padded[1])
            grid = np.rint(grid).astype(np.int64).reshape(padded).cumsum(axis=0).cumsum(axis=1)
            sums.append(grid[at[:, 0], at[:, 1]])
        count, total, squares = sums
        counts += count
        one_strip &= count * squares == total * total
    return counts, (counts > 0) & one_strip


def window_half_cells(footprint_m: float, cell_m: float) -> int:
    """How many cells each way from a point a photo that sees it may be centred: half a footprint, to
    the containment tolerance photos_per_point uses (4 for the planner's 9-cell footprint)."""
    return int(math.floor((footprint_m / 2.0 + CONTAIN_TOLERANCE_M) / cell_m))


def reachable_windows(flyable: np.ndarray, half: int) -> np.ndarray:
    """(rows, cols) bool: whether a straight row or column run of flyable cells crosses the window of
    `half` cells each way around each cell end to end (2 * half + 1 cells along it); outside the
    map is not flyable. Two cumulative sums per direction: one finds the runs centred on each cell,
    the other whether any lies across the window."""
    n = 2 * half + 1
    padded = np.pad(np.asarray(flyable, dtype=np.int32), half)  # outside the map: not flyable
    rows, cols = np.asarray(flyable).shape
    found = np.zeros((rows, cols), dtype=bool)
    for along in (1, 0):  # runs along a row (crossing the window's columns), then along a column
        ends = np.cumsum(padded, axis=along, dtype=np.int32)
        ends = np.concatenate([np.zeros_like(ends.take([0], axis=along)), ends], axis=along)
        width = ends.shape[along]
        runs = (ends.take(np.arange(n, width), axis=along) - ends.take(np.arange(0, width - n), axis=along)) == n
        across = 1 - along  # any such run among the window's rows (for a row run) or columns
        seen = np.cumsum(runs, axis=across, dtype=np.int32)
        seen = np.concatenate([np.zeros_like(seen.take([0], axis=across)), seen], axis=across)
        width = seen.shape[across]
        found |= (seen.take(np.arange(n, width), axis=across) - seen.take(np.arange(0, width - n), axis=across)) > 0
    return found


def classify_points(flyable: np.ndarray, cells: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """(reachable, at the map's edge) for each of `cells` ((m, 2) inside `flyable`'s shape): reachable
    as reachable_windows says; at the map's edge when its window leaves the map (a bounded point's
    reason is then "map edge", else "obstacles")."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    shape = np.asarray(np.shape(flyable))
    reachable = reachable_windows(flyable, half)[cells[:, 0], cells[:, 1]]
    edge: np.ndarray = np.asarray(((cells - half < 0) | (cells + half >= shape)).any(axis=1))
    return reachable, edge


def implied_photos(front: float | None, side: float | None) -> tuple[int | None, int | None]:
    """Photos per point the asked overlaps imply: (on one strip, where strips neighbour)."""
    if front is None:
        return None, None
    one = math.floor(1.0 / (1.0 - front) + IMPLIED_EPS) if front < 1.0 else None
    if one is None:
        return None, None
    across = math.floor(1.0 / (1.0 - side) + IMPLIED_EPS) if side is not None and side < 1.0 else 1
    return one, one * across


def measure_overlap(centres: np.ndarray, runs: np.ndarray, footprint_m: float, cells: np.ndarray, cell_m: float,
                    strips: np.ndarray | None = None, asked_front: float | None = None,
                    asked_side: float | None = None, flyable: np.ndarray | None = None) -> OverlapMeasure:
    """The overlaps and photos per target point of photos at `centres` ((n, 2) grid metres, in the order
    taken), `runs` ((n,) a drone's flight or sortie: consecutive photos of one run may share a strip),
    footprint side `footprint_m`; the target points are the centres of `cells` ((m, 2) integer grid cells
    of side `cell_m`). `strips`: each photo's leg id where the caller has them (else derived: strips_of).
    `asked_front` / `asked_side`: the fractions asked (None: not asked). `flyable`: the grid's (rows,
    cols) cells a photo may be centred on (not an obstacle), which splits the points into reachable
    and bounded ones (module docstring); None: every point counts alike."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    runs = np.asarray(runs).reshape(-1)
    if len(runs) != len(centres):
        raise ValueError(f"{len(runs)} run ids for {len(centres)} photos")
    if not footprint_m > 0 or not cell_m > 0:
        raise ValueError(f"footprint {footprint_m!r} m, cell {cell_m!r} m: both must be positive")
    if strips is None:
        strips = strips_of(centres, runs)
    else:
        # The caller's leg ids, renumbered 0.. in order of appearance, a new id wherever the run changes.
        strips = np.asarray(strips).reshape(-1)
        change = np.concatenate([[True], (strips[1:] != strips[:-1]) | (runs[1:] != runs[:-1])])[:len(strips)]
        strips = np.cumsum(change) - 1
    directions = strip_directions(centres, runs, strips)
    front = front_overlaps(centres, strips, footprint_m)
    side = side_overlaps(centres, strips, directions, footprint_m)
    counts, single, wanted = _counts_wanted(centres, strips, directions, cells, cell_m, footprint_m, asked_front,
                                            asked_side)
    seen = counts > 0
    one, neighbouring = implied_photos(asked_front, asked_side)
    short = 0
    met = None
    if wanted is not None:
        short = int((counts < wanted).sum())
        met = bool(low(counts - wanted) >= 0)
    reach = None
    if flyable is not None:
        reachable, edge = classify_points(flyable, cells, window_half_cells(footprint_m, cell_m))
        bounded = ~reachable
        reach = ReachSplit(PointClass.of(counts[reachable], None if wanted is None else wanted[reachable]),
                           PointClass.of(counts[bounded], None if wanted is None else wanted[bounded]),
                           (int((bounded & ~edge).sum()), int((bounded & edge).sum())))
        if wanted is not None:  # every reachable point, none left to a percentile
            met = None if not reachable.any() else reach.reachable.short == 0
    return OverlapMeasure(
        footprint_m=float(footprint_m), photos=int(len(centres)), strips=int(strips.max()) + 1 if len(strips) else 0,
        front=OverlapSpread.of(front), side=OverlapSpread.of(side), asked_front=asked_front, asked_side=asked_side,
        points=int(len(cells)), per_point_median=float(np.median(counts)) if len(cells) else 0.0,
        per_point_p5=int(low(counts)) if len(cells) else 0, per_point_min=int(counts.min()) if len(cells) else 0,
        single_strip_share=float(single[seen].mean()) if seen.any() else None,
        implied_one_strip=one, implied_neighbouring=neighbouring, short=short, met=met, reach=reach)


def _counts_wanted(centres: np.ndarray, strips: np.ndarray, directions: np.ndarray, cells: np.ndarray, cell_m: float,
                   footprint_m: float, asked_front: float | None,
                   asked_side: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(photos per point, whether one strip sees it, the photos implied for it: None when nothing is implied)."""
    # Side by side only: a crossing street's strip sees a point from another direction, which no side overlap
    # was asked of (a strip's kind: its direction nearer the grid's columns, east-west, or its rows).
    strip_across = np.abs(directions[:, 1]) > np.abs(directions[:, 0]) if len(directions) else np.zeros(0, bool)
    counts, single = photos_per_point(centres, strips, cells, cell_m, footprint_m,
                                      across=strip_across[strips] if len(strips) else None)
    one, neighbouring = implied_photos(asked_front, asked_side)
    if one is None or neighbouring is None or not len(cells):
        return counts, single, None
    return counts, single, np.where(single | (counts == 0), one, neighbouring)


def reachable_deficits(centres: np.ndarray, runs: np.ndarray, footprint_m: float, cells: np.ndarray, cell_m: float,
                       asked_front: float | None, asked_side: float | None, flyable: np.ndarray) -> np.ndarray:
    """(m,) for each of `cells`: the photos it lacks of those implied for it when it is a reachable point, else 0;
    measured as measure_overlap measures (its arguments). All 0 when nothing is implied."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    runs = np.asarray(runs).reshape(-1)
    strips = strips_of(centres, runs)
    directions = strip_directions(centres, runs, strips)
    counts, _, wanted = _counts_wanted(centres, strips, directions, cells, cell_m, footprint_m, asked_front,
                                       asked_side)
    if wanted is None:
        return np.zeros(len(cells), dtype=np.int64)
    reachable, _ = classify_points(flyable, cells, window_half_cells(footprint_m, cell_m))
    return np.where(reachable, np.maximum(wanted - counts, 0), 0)
