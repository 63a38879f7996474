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
- Photos per target point: how many footprints hold the point (its Chebyshev distance to the photo at
  most S / 2, to a micrometre); and the share of the points seen at all that only one strip's photos see.
- What the asked overlaps imply: floor(1 / (1 - front)) photos of a point on one strip, times
  floor(1 / (1 - side)) where strips neighbour (a point seen by photos of more than one strip); a
  point seen by fewer photos is short. The points at a strip's ends or a zone's edge are seen by fewer
  photos than the middle of a lane: that is why the 5th percentile, not the least, decides `met`.

Pure numpy and scipy's cKDTree: a 20-drone city plan (50 000 photos, 500 000 target cells) is measured
in well under a second (bench/overlap_bench.py).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

MAX_TURN_DEG = 20.0  # a heading change above this between consecutive photos starts a new strip
PARALLEL_DEG = 30.0  # a side neighbour's strip runs within this of the photo's own strip
PERCENTILE = 5.0  # the low figure reported beside the median: 95 % of the values are at least this
CONTAIN_TOLERANCE_M = 1e-6  # a point on a footprint's edge is inside it (a micrometre of float round trip)
SHORT_STEP = 0.25  # a step shorter than this share of the median step has no heading of its own
IMPLIED_EPS = 1e-9  # floor(1 / (1 - 8/9)) is 9, though the division gives 8.999999999999998


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


@dataclass(frozen=True)
class OverlapMeasure:
    """Front and side overlap and photos per target point, measured from photo positions, next to what was asked.

    `front` / `side` are None when nothing could be measured (no two photos on one strip; no strip
    alongside another). `asked_front` / `asked_side` are the fractions the plan asked (None: not asked).
    `implied_one_strip` / `implied_neighbouring` are the photos per point the asked overlaps imply on
    one strip and where strips neighbour (None without an asked front overlap); `short` counts the
    target points seen by fewer photos than implied for them; `met` says whether the 5th percentile
    of photos per point reaches the implied count (None when nothing is implied or no point)."""

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

    def to_json(self) -> dict[str, Any]:
        return {"footprint_m": self.footprint_m, "photos": self.photos, "strips": self.strips,
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
                   per.get("implied_neighbouring"), int(per["short"]), per.get("met"))

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
        return "; ".join([overlap("front", self.front, self.asked_front),
                          overlap("side", self.side, self.asked_side), per_point])


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
    return np.maximum(1.0 - spacing / footprint_m, 0.0)


def side_overlaps(centres: np.ndarray, strips: np.ndarray, directions: np.ndarray, footprint_m: float) -> np.ndarray:
    """Per photo that has one, 1 - distance across / S to its nearest side neighbour (module docstring)."""
    if len(centres) < 2:
        return np.zeros(0)
    reach = footprint_m + CONTAIN_TOLERANCE_M  # lanes exactly a footprint apart touch: side overlap 0, measured
    pairs = cKDTree(centres).query_pairs(reach, output_type="ndarray")
    if not len(pairs):
        return np.zeros(0)
    mine = np.concatenate([pairs[:, 0], pairs[:, 1]])  # each pair seen from both photos
    other = np.concatenate([pairs[:, 1], pairs[:, 0]])
    along_dir = directions[strips[mine]]
    offset = centres[other] - centres[mine]
    along = np.abs((offset * along_dir).sum(axis=1))
    across = np.abs(offset[:, 0] * along_dir[:, 1] - offset[:, 1] * along_dir[:, 0])
    parallel = np.abs((along_dir * directions[strips[other]]).sum(axis=1))
    with np.errstate(invalid="ignore"):  # NaN directions compare False: no side neighbour
        keep = ((strips[mine] != strips[other]) & (parallel >= math.cos(math.radians(PARALLEL_DEG)))
                & (across > along) & (across <= reach))
    mine, across, distance = mine[keep], across[keep], np.hypot(*offset[keep].T)
    if not len(mine):
        return np.zeros(0)
    order = np.lexsort((distance, mine))  # per photo, its nearest neighbour first
    _, first = np.unique(mine[order], return_index=True)
    return np.maximum(1.0 - across[order][first] / footprint_m, 0.0)


# ------------------------------------------------------------------------------------------- per point
def photos_per_point(centres: np.ndarray, strips: np.ndarray, points: np.ndarray,
                     footprint_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(photos holding each point, whether every photo holding it is of one strip) for (m, 2) points."""
    half = footprint_m / 2.0 + CONTAIN_TOLERANCE_M
    if not len(centres) or not len(points):
        return np.zeros(len(points), dtype=np.int64), np.zeros(len(points), dtype=bool)
    tree = cKDTree(centres)
    counts = np.asarray(tree.query_ball_point(points, half, p=np.inf, return_length=True), dtype=np.int64)
    # The photos of the nearest photo's strip alone: a third coordinate puts each strip 2 S from every
    # other, so a footprint-sized box round (point, that strip) holds only that strip's photos.
    _, nearest = tree.query(points, p=np.inf)
    apart = 2.0 * footprint_m
    by_strip = cKDTree(np.column_stack([centres, strips * apart]))
    own = np.column_stack([points, strips[nearest] * apart])
    same = np.asarray(by_strip.query_ball_point(own, half, p=np.inf, return_length=True), dtype=np.int64)
    return counts, (counts > 0) & (same == counts)


def implied_photos(front: float | None, side: float | None) -> tuple[int | None, int | None]:
    """Photos per point the asked overlaps imply: (on one strip, where strips neighbour)."""
    if front is None:
        return None, None
    one = math.floor(1.0 / (1.0 - front) + IMPLIED_EPS) if front < 1.0 else None
    if one is None:
        return None, None
    across = math.floor(1.0 / (1.0 - side) + IMPLIED_EPS) if side is not None and side < 1.0 else 1
    return one, one * across


def measure_overlap(centres: np.ndarray, runs: np.ndarray, footprint_m: float, points: np.ndarray,
                    strips: np.ndarray | None = None, asked_front: float | None = None,
                    asked_side: float | None = None) -> OverlapMeasure:
    """The overlaps and photos per target point of photos at `centres` ((n, 2) grid metres, in the order
    taken), `runs` ((n,) a drone's flight or sortie: consecutive photos of one run may share a strip),
    footprint side `footprint_m`, target `points` ((m, 2) grid metres). `strips`: each photo's leg id
    where the caller has them (else derived: strips_of). `asked_front` / `asked_side`: the fractions asked."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    runs = np.asarray(runs).reshape(-1)
    if len(runs) != len(centres):
        raise ValueError(f"{len(runs)} run ids for {len(centres)} photos")
    if not footprint_m > 0:
        raise ValueError(f"footprint {footprint_m!r} m: must be positive")
    if strips is None:
        strips = strips_of(centres, runs)
    else:
        # The caller's leg ids, renumbered 0.. in order of appearance, a new id wherever the run changes.
        strips = np.asarray(strips).reshape(-1)
        change = np.concatenate([[True], (strips[1:] != strips[:-1]) | (runs[1:] != runs[:-1])])
        strips = np.cumsum(change) - 1
    directions = strip_directions(centres, runs, strips)
    front = front_overlaps(centres, strips, footprint_m)
    side = side_overlaps(centres, strips, directions, footprint_m)
    counts, single = photos_per_point(centres, strips, points, footprint_m)
    seen = counts > 0
    one, neighbouring = implied_photos(asked_front, asked_side)
    short = 0
    met = None
    if one is not None and neighbouring is not None and len(points):
        wanted = np.where(single | ~seen, one, neighbouring)
        short = int((counts < wanted).sum())
        met = bool(low(counts - wanted) >= 0)
    return OverlapMeasure(
        footprint_m=float(footprint_m), photos=int(len(centres)), strips=int(strips.max()) + 1 if len(strips) else 0,
        front=OverlapSpread.of(front), side=OverlapSpread.of(side), asked_front=asked_front, asked_side=asked_side,
        points=int(len(points)), per_point_median=float(np.median(counts)) if len(points) else 0.0,
        per_point_p5=int(low(counts)) if len(points) else 0, per_point_min=int(counts.min()) if len(points) else 0,
        single_strip_share=float(single[seen].mean()) if seen.any() else None,
        implied_one_strip=one, implied_neighbouring=neighbouring, short=short, met=met)
