"""Coverage honesty: what a plan covers of ALL the targets, and warnings when that is much less.

The planner covers the reachable targets (those 4-connected through free cells to a launch
cell), and exit 0 means exactly that: every reachable target is covered. Targets walled in
by obstacles (courtyards, pockets, often buildings of unknown height counted as obstacles)
are left out. This module puts both numbers side by side in report.json (`coverage`) and
says, with counts and the likely cause, when more than 5 % of the targets are unreachable
and when a drone gets under a fifth of the mean share (its launch point in a pocket).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import ndimage

from missionplan.geo.heights import LEVEL_HEIGHT_M

from ..grid.world import reachable_targets
from ..maps.gridmap import Cell, GridMap
from .clearance import clearance_band
from .plan_blocks import CoverageSummary, SmallShare

UNREACHABLE_WARN_FRACTION = 0.05  # warn when more than this share of all targets is unreachable
SMALL_SHARE_FRACTION = 0.2  # warn about a drone whose share is under this fraction of the mean

# Why a target cell is unreachable, as plan.png, plan.html and the GIS files name it.
UNKNOWN_HEIGHT = "unknown-height buildings"
CLEARANCE_BAND = "clearance band"
POCKET = "pocket"
CAUSE_REASONS = {
    UNKNOWN_HEIGHT: "cut off only by buildings of unknown height, counted as obstacles "
                    "(--unknown-building-height M overflies them)",
    CLEARANCE_BAND: "closer than --clearance to an obstacle and out of every photo taken outside that band",
    POCKET: "walled in by obstacles, tall buildings, the clearance margin or the area edge; "
            "a launch point inside would reach them",
}
POCKET_REASON = ("lie in pockets walled in by obstacles, tall buildings, the clearance margin or the area edge "
                 "(courtyards, closed blocks); a launch point inside a pocket would reach it")


def _pct(part: int, whole: int) -> float:
    return round(100.0 * part / whole, 2) if whole else 100.0


def _launch_pockets(gmap: GridMap, starts: list[Cell]) -> tuple[list[int], list[bool]]:
    """Per drone: target cells in the free region (4-connected) its launch cell lies in, and whether
    no other drone launches in that region."""
    labels, _ = ndimage.label(gmap.free)  # 4-connectivity, as the drones move
    counts = np.bincount(labels[gmap.target], minlength=labels.max() + 1)
    regions = [int(labels[cell]) for cell in starts]
    return [int(counts[r]) for r in regions], [regions.count(r) == 1 for r in regions]


def coverage_report(gmap: GridMap, starts: list[Cell], reachable_targets_count: int, unreachable: int,
                    coverage_pct: float, zone_sizes: list[int], unknown_buildings: int | None = None,
                    total_buildings: int | None = None, assumed_height_m: float | None = None,
                    if_overflown: Callable[[], GridMap] | None = None,
                    launch_labels: list[str] | None = None, unreachable_mask: np.ndarray | None = None,
                    clearance_m: float = 0.0, causes: dict[str, np.ndarray] | None = None) -> CoverageSummary:
    """The `coverage` block of report.json: both coverage numbers, counts, causes, warnings.

    `coverage_pct` is the plan's coverage of the reachable targets; `zone_sizes` the targets
    given to each drone. The unknown-height arguments come with an `--osm` area plan:
    `if_overflown` builds the grid with those buildings crossed, to count what they cut off.
    `launch_labels` names each drone's launch point in warnings (default: its grid cell).
    `unreachable_mask` (the report's unreachable cells) and `clearance_m` let the warning name a
    third cause: targets inside the `--clearance` band that no photo taken outside it sees.
    `causes`: unreachable_causes' masks when the caller has them (else computed here when needed).
    """
    total = reachable_targets_count + unreachable
    covered = int(round(coverage_pct * reachable_targets_count / 100.0))
    reachable_pct, all_pct = round(float(coverage_pct), 2), _pct(covered, total)
    unreachable_pct = _pct(unreachable, total) if total else 0.0
    by_unknown_height: int | None = None
    by_clearance: int | None = None
    small_shares: list[SmallShare] = []
    warnings: list[str] = []
    if total and unreachable > UNREACHABLE_WARN_FRACTION * total:
        if causes is None:
            crossed = if_overflown() if if_overflown is not None else None
            causes = unreachable_causes(gmap, starts, unreachable_mask, clearance_m, crossed)
        reasons: list[str] = []
        cut = causes.get(UNKNOWN_HEIGHT)
        if if_overflown is not None or cut is not None:
            by_unknown_height = int(cut.sum()) if cut is not None else 0
        if cut is not None and cut.any():
            reasons.append(f"{int(cut.sum())} of them are cut off only by the {unknown_buildings} of "
                           f"{total_buildings} buildings of unknown height (no height, building:height or "
                           f"building:levels), counted as obstacles: if those are low enough to overfly, give "
                           f"--unknown-building-height M (or tag building:levels, {LEVEL_HEIGHT_M:g} m a level)")
        in_band = causes.get(CLEARANCE_BAND)
        if in_band is not None:
            by_clearance = int(in_band.sum())
            if in_band.any():
                reasons.append(f"{int(in_band.sum())} of them lie within --clearance {clearance_m:g} m of an obstacle "
                               f"and out of every photo taken outside it (narrow streets, courtyards); a smaller "
                               f"--clearance reaches them")
        explained = sum(int(mask.sum()) for name, mask in causes.items() if name != POCKET)
        if not reasons:
            reasons.append(f"they {POCKET_REASON}")
        elif explained < unreachable:
            reasons.append(f"the other {unreachable - explained} {POCKET_REASON}")
        warnings.append(f"{unreachable} of {total} target cells ({unreachable_pct:.1f} %) are unreachable: "
                        f"the plan covers {reachable_pct:.1f} % of the reachable targets but "
                        f"{all_pct:.1f} % of all; {'; '.join(reasons)}")
    if zone_sizes:
        mean = sum(zone_sizes) / len(zone_sizes)
        pockets, alone = _launch_pockets(gmap, starts)
        for k, size in enumerate(zone_sizes):
            # Walled in alone with less than a fair share: it flies short however the zones fall.
            in_pocket = alone[k] and len(starts) > 1 and pockets[k] < mean
            if size >= SMALL_SHARE_FRACTION * mean and not in_pocket:
                continue
            uav = k + 1
            small_shares.append(SmallShare(uav, int(size), round(mean, 1), pockets[k]))
            if pockets[k] < SMALL_SHARE_FRACTION * mean or in_pocket:
                where = launch_labels[k] if launch_labels else f"cell {tuple(starts[k])}"
                why = (f"its launch point {where} is in a pocket of {pockets[k]} target cells walled off "
                       f"from the rest; move it into the open street")
            else:
                why = "its zone came out small; another launch point spreads the work better"
            share = "under a fifth of" if size < SMALL_SHARE_FRACTION * mean else "less than"
            warnings.append(f"uav{uav} gets {size} target cells, {share} the mean share ({mean:.0f}): {why}")
    return CoverageSummary(reachable_pct, all_pct, covered, reachable_targets_count, total, unreachable, unreachable_pct,
                           unknown_buildings, assumed_height_m, by_unknown_height, by_clearance, tuple(small_shares),
                           tuple(warnings))


def unreachable_causes(gmap: GridMap, starts: list[Cell], unreachable_mask: np.ndarray | None,
                       clearance_m: float = 0.0, crossed: GridMap | None = None) -> dict[str, np.ndarray]:
    """Each unreachable target cell's cause, as masks that do not overlap: cut off only by buildings of
    unknown height (`crossed`: the grid with them overflown), in the clearance band though the drones get
    near it, else a pocket. Without `unreachable_mask` every unreachable target counts."""
    if unreachable_mask is None:
        unreachable_mask = gmap.target & ~reachable_targets(gmap, starts)
    left = unreachable_mask.copy()
    causes: dict[str, np.ndarray] = {}
    if crossed is not None:
        causes[UNKNOWN_HEIGHT] = _cut_off_by(gmap, starts, crossed) & left
        left &= ~causes[UNKNOWN_HEIGHT]
    cell_m = gmap.cell_m or 0.0
    if clearance_m > 0 and cell_m > 0:
        band = clearance_band(gmap.obstacle, clearance_m / cell_m)
        # pocket cells are pockets whatever the margin: only band targets the drones can get near count
        causes[CLEARANCE_BAND] = left & band & reachable_targets(gmap, starts)
        left &= ~causes[CLEARANCE_BAND]
    causes[POCKET] = left
    return causes


def _cut_off_by(gmap: GridMap, starts: list[Cell], crossed: GridMap) -> np.ndarray:
    """Targets of `gmap` unreachable from `starts` that become reachable on the `crossed` grid (a mask)."""
    if crossed.shape != gmap.shape:
        return np.zeros(gmap.shape, dtype=bool)  # another grid (cannot happen for the same area and camera): no claim
    before = reachable_targets(gmap, starts)
    after = reachable_targets(crossed, starts)
    return gmap.target & ~before & after
