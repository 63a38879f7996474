"""Roof targets: which cells a plan photographs, and what a photo of a roof is worth.

`plan --targets` picks the classes of target cells (TARGET_CLASSES):

* `streets` (the default): the open ground; the roofs of buildings low enough to overfly are free cells
  that need no photo (geo/area.py's rule since the first area plans);
* `roofs`: those roofs, and the street cells become free (flown over, not photographed);
* `all`: both.

A building is low enough to overfly when its height is under the flight height less the safety margin
(geo/area.py); taller ones, and those of unknown height, are obstacles whatever is asked.

A nadir photo taken at height H sees a square of side S on the ground, but only S * (H - h) / H on a roof
h metres up: the camera is closer. The grid's 9-cell footprint must hold on every roof photographed, so
with roof targets the cell is sized at the highest of them (`roof_cell_m`), which is conservative
everywhere lower. The ground sample distance scales the same way (`gsd_at`): a roof is photographed
finer than the ground, so a GSD asked at the ground holds on every roof.
"""

from __future__ import annotations

import math

from missionplan.base.naming import Named

from .camera import cell_of_footprint, footprint_side_m
from .errors import GeoError

STREETS, ROOFS, ALL = "streets", "roofs", "all"
TARGET_CLASSES = (STREETS, ROOFS, ALL)
DEFAULT_TARGETS = STREETS


def check_targets(targets: str) -> str:
    """`targets` when it is one of TARGET_CLASSES, else GeoError naming it."""
    if targets not in TARGET_CLASSES:
        raise GeoError(Named("{targets} {0}: choose {1}", targets, ", ".join(TARGET_CLASSES)))
    return targets


def photographs_roofs(targets: str) -> bool:
    """Whether the roofs low enough to overfly are targets."""
    return check_targets(targets) in (ROOFS, ALL)


def photographs_streets(targets: str) -> bool:
    """Whether the street (open ground) cells are targets."""
    return check_targets(targets) in (STREETS, ALL)


def footprint_at(footprint_ground_m: float, altitude_m: float, height_m: float) -> float:
    """The side of a nadir photo's footprint on a surface `height_m` up, for a photo taken `altitude_m` up
    whose footprint on the ground is `footprint_ground_m`: S * (H - h) / H."""
    if not (math.isfinite(height_m) and 0.0 <= height_m < altitude_m):
        raise GeoError(f"a surface {height_m:g} m up is not under the flight height {altitude_m:g} m")
    return footprint_ground_m * (altitude_m - height_m) / altitude_m


def gsd_at(gsd_ground_cm: float, altitude_m: float, height_m: float) -> float:
    """The ground sample distance (cm per pixel) on a surface `height_m` up: gsd_ground * (H - h) / H."""
    return footprint_at(gsd_ground_cm, altitude_m, height_m)


def roof_cell_m(altitude_m: float, fov_deg: float, highest_roof_m: float) -> float:
    """The grid cell when roofs up to `highest_roof_m` are photographed from `altitude_m`: the footprint at
    that roof / 9 (the footprint at the ground / 9 when the highest roof is the ground)."""
    return cell_of_footprint(footprint_at(footprint_side_m(altitude_m, fov_deg), altitude_m, highest_roof_m))


def cell_rule(cell_m: float, highest_roof_m: float | None) -> str:
    """How the cell was sized, as the plan's printout and report.json say it."""
    if highest_roof_m is None:
        return f"cell {cell_m:.2f} m: the footprint at the ground / 9"
    return f"cell {cell_m:.2f} m: the footprint at the highest roof ({highest_roof_m:g} m) / 9"
