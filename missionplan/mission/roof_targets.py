"""Roof targets in a plan: which classes are photographed, what each class's coverage is, how the cell was
sized, and the vertical clearance kept over every roof the tracks cross (report.json `roofs`).

`plan --targets roofs|all` (geo/roofs.py has the rules) makes the roofs low enough to overfly targets; this
module says what that plan promises:

* the cell rule: the grid cell is the footprint at the highest roof target / 9, so a photo's 9 x 9 cells
  hold on every roof (and hold with room to spare on the ground); the ground sample distance at the
  ground and at that roof (a roof is nearer the camera, so finer);
* coverage per class: the streets' and the roofs' reachable target cells and how many of them the plan's
  photos hold (grid.world's 9 x 9 footprint);
* the vertical clearance: along every leg each drone flies (its smoothed track, the way out and home), the
  flight height less the height of every building the track passes over, target or not; the smallest
  must be at least the margin the roofs were overflown with (the georeference's safety margin).

A plan with the default `--targets streets` has no such block, so it is written as before.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from missionplan.base.naming import Named
from missionplan.geo.camera import footprint_side_m
from missionplan.geo.frame import GridFrame
from missionplan.geo.roofs import ROOFS, STREETS, cell_rule, footprint_at, gsd_at, photographs_roofs, \
    photographs_streets
from missionplan.geo.sources import Building

from ..maps.gridmap import GridMap, MapError

JSON = dict[str, Any]


@dataclass(frozen=True)
class ClassCoverage:
    """One target class (streets or roofs): its reachable target cells and those the plan's photos hold."""

    name: str
    targets: int
    covered: int

    @property
    def pct(self) -> float:
        return round(100.0 * self.covered / self.targets, 2) if self.targets else 100.0

    def to_json(self) -> JSON:
        return {"targets": self.targets, "covered": self.covered, "coverage_pct": self.pct}

    @classmethod
    def from_json(cls, name: str, doc: Mapping[str, Any]) -> ClassCoverage:
        return cls(name, int(doc["targets"]), int(doc["covered"]))


@dataclass(frozen=True)
class VerticalClearance:
    """The flight height less the highest building under each drone's legs: the smallest over the fleet,
    each drone's (None: its legs cross no building), the margin asked, and whether it holds."""

    required_m: float
    kept_m: float | None
    per_drone_m: tuple[float | None, ...]
    roofs_crossed: int  # buildings some leg passes over

    @property
    def kept(self) -> bool:
        return self.kept_m is None or self.kept_m >= self.required_m - 1e-6

    def to_json(self) -> JSON:
        return {"required_m": self.required_m, "kept_m": self.kept_m, "per_drone_m": list(self.per_drone_m),
                "roofs_crossed": self.roofs_crossed, "kept": self.kept}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> VerticalClearance:
        return cls(float(doc["required_m"]), doc.get("kept_m"), tuple(doc.get("per_drone_m") or ()),
                   int(doc.get("roofs_crossed", 0)))


@dataclass(frozen=True)
class RoofTargets:
    """report.json `roofs`: the target classes asked (`--targets`), the cell rule, the GSD at the ground and
    at the highest roof (None: no GSD asked), coverage per class and the vertical clearance over roofs
    (None: no building heights, a `--map` grid)."""

    targets: str
    cell_m: float
    highest_roof_m: float | None  # None: a map's roof layer, whose heights are not known
    rule: str
    footprint_at_ground_m: float | None
    footprint_at_highest_roof_m: float | None
    gsd_cm_at_ground: float | None
    gsd_cm_at_highest_roof: float | None
    by_class: tuple[ClassCoverage, ...]
    vertical: VerticalClearance | None

    def coverage_of(self, name: str) -> ClassCoverage | None:
        return next((c for c in self.by_class if c.name == name), None)

    def to_json(self) -> JSON:
        return {"targets": self.targets, "cell_m": self.cell_m, "highest_roof_m": self.highest_roof_m,
                "cell_rule": self.rule, "footprint_at_ground_m": self.footprint_at_ground_m,
                "footprint_at_highest_roof_m": self.footprint_at_highest_roof_m,
                "gsd_cm_at_ground": self.gsd_cm_at_ground, "gsd_cm_at_highest_roof": self.gsd_cm_at_highest_roof,
                "coverage": {c.name: c.to_json() for c in self.by_class},
                "vertical_clearance": self.vertical.to_json() if self.vertical is not None else None}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> RoofTargets:
        vertical = doc.get("vertical_clearance")
        return cls(doc["targets"], float(doc["cell_m"]), doc.get("highest_roof_m"), doc["cell_rule"],
                   doc.get("footprint_at_ground_m"), doc.get("footprint_at_highest_roof_m"),
                   doc.get("gsd_cm_at_ground"), doc.get("gsd_cm_at_highest_roof"),
                   tuple(ClassCoverage.from_json(name, c) for name, c in (doc.get("coverage") or {}).items()),
                   VerticalClearance.from_json(vertical) if vertical is not None else None)


def select_targets(gmap: GridMap, targets: str) -> GridMap:
    """A map with a roof layer (`--map` with `r` cells) as `--targets` asks: streets drops the roofs from the
    targets (they stay free), roofs drops the streets, all keeps both. MapError for roof targets on a map
    without a roof layer (a grid without building heights cannot tell a roof from a street)."""
    if gmap.roof is None:
        if photographs_roofs(targets):
            raise MapError(Named("{targets} {0}: map {1} has no roof layer (no 'r' cells) and no building heights "
                                 "to find its roofs in; plan the area with {area} and {osm}", targets, gmap.name))
        return gmap
    roof = gmap.roofs
    target = gmap.target & ~roof if photographs_streets(targets) else np.zeros_like(roof)
    if photographs_roofs(targets):
        target = target | roof
    return GridMap(gmap.name, gmap.obstacle, target, gmap.launch, dict(gmap.meta), gmap.georef,
                   roof=roof if photographs_roofs(targets) else None)


def class_coverage(gmap: GridMap, reachable: np.ndarray, covered: np.ndarray, targets: str) -> tuple[ClassCoverage, ...]:
    """Each class asked (streets, roofs), its reachable target cells (`reachable`: a mask) and those `covered`
    (a mask of cells the photos hold)."""
    classes = []
    roof = gmap.roofs
    if photographs_streets(targets):
        streets = reachable & ~roof
        classes.append(ClassCoverage(STREETS, int(streets.sum()), int((streets & covered).sum())))
    if photographs_roofs(targets):
        roofs = reachable & roof
        classes.append(ClassCoverage(ROOFS, int(roofs.sum()), int((roofs & covered).sum())))
    return tuple(classes)


def vertical_clearance(routes: Sequence[Sequence[np.ndarray]], altitudes: Sequence[float], frame: GridFrame,
                       buildings: Sequence[Building], required_m: float) -> VerticalClearance:
    """The vertical clearance kept over the buildings (lon/lat footprints with heights) along each drone's
    legs: `routes` per drone, per sortie, (n, 2) grid metres (row, col) as flightplan.FlightPlans.sortie_routes
    holds them (launch, the smoothed track, the way out and home); `altitudes` each drone's flight height.
    A building of unknown height is an obstacle, never under a leg, and is left out."""
    known = [b for b in buildings if b.height_m is not None]
    shapes = [frame.geometry_to_grid(b.geometry) for b in known]  # x = col, y = row, in cells
    tree = shapely.STRtree(shapes)
    heights = np.array([float(b.height_m or 0.0) for b in known])
    crossed: set[int] = set()
    per_drone: list[float | None] = []
    for legs, altitude in zip(routes, altitudes):
        highest = None
        for route in legs:
            points = np.asarray(route, dtype=float).reshape(-1, 2)[:, ::-1] / frame.cell_m
            if len(points) < 2 or not len(known):
                continue
            hit = tree.query(shapely.LineString(points), predicate="intersects")
            if len(hit):
                crossed.update(int(i) for i in hit)
                tallest = float(heights[hit].max())
                highest = tallest if highest is None else max(highest, tallest)
        per_drone.append(None if highest is None else round(float(altitude) - highest, 2))
    kept = [v for v in per_drone if v is not None]
    return VerticalClearance(float(required_m), min(kept) if kept else None, tuple(per_drone), len(crossed))


def roof_targets_block(gmap: GridMap, targets: str, altitude_m: float | None, highest_roof_m: float | None,
                       by_class: tuple[ClassCoverage, ...], vertical: VerticalClearance | None,
                       gsd_cm_at_ground: float | None = None) -> RoofTargets:
    """report.json `roofs` for a plan of `gmap` flown `altitude_m` up (the lowest drone's height: a layer
    above it sees every roof finer still; None: a grid that is not flown). `gsd_cm_at_ground`: the GSD asked
    (None: not asked)."""
    georef = gmap.georef
    cell_m = float(gmap.cell_m or 0.0)
    camera = georef.camera if georef is not None else None
    at_ground = footprint_side_m(altitude_m, camera.fov_deg) if camera is not None and altitude_m else None
    if highest_roof_m is None or altitude_m is None:
        rule = f"cell {cell_m:.2f} m: as the map gives it (its roofs have no heights)"
        at_roof = gsd_roof = None
    else:
        rule = cell_rule(cell_m, highest_roof_m)
        at_roof = footprint_at(at_ground, altitude_m, highest_roof_m) if at_ground is not None else None
        gsd_roof = gsd_at(gsd_cm_at_ground, altitude_m, highest_roof_m) if gsd_cm_at_ground is not None else None
    return RoofTargets(targets, cell_m, highest_roof_m, rule, _rounded(at_ground), _rounded(at_roof),
                       gsd_cm_at_ground, _rounded(gsd_roof, 3), by_class, vertical)


def _rounded(value: float | None, digits: int = 2) -> float | None:
    return None if value is None else round(float(value), digits)
