"""The typed blocks of a plan record (plan_record.PlanRecord): what each drone flies, the safety promise,
the coverage and its warnings, the files read, the settings a plan was made with, the planner's figures.

Each block is a frozen dataclass with `to_json` (the object report.json holds, keys in the order report.json
has always had them, numbers as they were computed) and `from_json` (its inverse; a report.json from an earlier
missionplan may lack a key that came later: its field is then None, or empty). A field that may be left out
of report.json is None when it is; one that report.json writes as null is None too, and the two are told
apart by the block, not by the reader. Nothing here reads or writes a file (plan_record does).

Room for what comes next: a ground model per waypoint (terrain) is a field of SortiePlan / DronePlan, a
camera with a sensor, GSD and capture interval is geo.camera.Camera inside the georeference; each adds a
field to its block and a key to its to_json / from_json, never a loose dict.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.bridge.formats.gimbal import NADIR_PITCH_DEG
from missionplan.geo.sources import Omission

from ..maps.gridmap import Cell
from .drone_missions import MissionSettings
from .photo_overlap import OverlapMeasure
from .safety import SafetySettings

JSON = dict[str, Any]  # an object as report.json holds it


def cells_of(rows: Iterable[Sequence[int]]) -> tuple[Cell, ...]:
    """[[row, col], ...] as report.json holds cells -> a tuple of (row, col)."""
    return tuple((row[0], row[1]) for row in rows)


def cells_json(cells: Iterable[Cell]) -> list[list[int]]:
    return [list(cell) for cell in cells]


# ------------------------------------------------------------------------------------------- the grid planner
@dataclass(frozen=True)
class PlanMetrics:
    """The planner's figures (SPEC section 6): MMN, TE, MNT, MUD, MDU, coverage (TE, MNT, coverage in
    percent), the busiest drone's moves and the hover steps. MUD / MDU are None when no step fell in the
    steady-state window."""

    mmn: float
    te: float
    mnt: float
    mud: float | None
    mdu: float | None
    coverage: float
    makespan: int
    hover_steps: int

    def to_json(self) -> JSON:
        return {"MMN": self.mmn, "TE": self.te, "MNT": self.mnt, "MUD": self.mud, "MDU": self.mdu,
                "coverage": self.coverage, "makespan": self.makespan, "hover_steps": self.hover_steps}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PlanMetrics:
        return cls(doc["MMN"], doc["TE"], doc["MNT"], doc.get("MUD"), doc.get("MDU"), doc["coverage"],
                   doc["makespan"], doc["hover_steps"])


@dataclass(frozen=True)
class Decisions:
    """Drones per step decided by the policy, on a path-finder or a lane sweep, or parked idle."""

    policy: tuple[int, ...]
    pathfinder: tuple[int, ...]
    idle: tuple[int, ...]

    def to_json(self) -> JSON:
        return {"policy": list(self.policy), "pathfinder": list(self.pathfinder), "idle": list(self.idle)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Decisions:
        return cls(tuple(doc["policy"]), tuple(doc["pathfinder"]), tuple(doc["idle"]))


@dataclass(frozen=True)
class Timing:
    """Wall time of the planning, zones and all (the only figures two runs do not share)."""

    zones_s: float
    plan_s: float

    def to_json(self) -> JSON:
        return {"zones_s": self.zones_s, "plan_s": self.plan_s}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Timing:
        return cls(doc["zones_s"], doc["plan_s"])


# ------------------------------------------------------------------------------------------- the drones
@dataclass(frozen=True)
class PathShape:
    """A drone's path before or after the trajectory corrector: waypoints, length (cells), turning (degrees)."""

    waypoints: int
    length_cells: float
    turning_deg: float

    def to_json(self) -> JSON:
        return {"waypoints": self.waypoints, "length_cells": self.length_cells, "turning_deg": self.turning_deg}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PathShape:
        return cls(doc["waypoints"], doc["length_cells"], doc["turning_deg"])


@dataclass(frozen=True)
class SortiePlan:
    """One battery sortie of a drone: its mission file, planned flight time, photos and waypoints."""

    file: str
    flight_s: float
    photos: int
    waypoints: int

    def to_json(self) -> JSON:
        return {"file": self.file, "flight_s": self.flight_s, "photos": self.photos, "waypoints": self.waypoints}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> SortiePlan:
        return cls(doc["file"], doc["flight_s"], doc["photos"], doc["waypoints"])


@dataclass(frozen=True)
class FencePlan:
    """A drone's inclusion geofence: its vertices, ceiling (above home) and how far outside its flight it lies;
    over a DEM, how far the ceiling was raised for the ground's rise above home inside it (mission.geofence)."""

    vertices: int
    max_altitude_m: float
    margin_m: float | None
    ground_rise_m: float | None = None  # None: a plan over flat ground (not written)

    def to_json(self) -> JSON:
        doc: JSON = {"vertices": self.vertices, "max_altitude_m": self.max_altitude_m, "margin_m": self.margin_m}
        if self.ground_rise_m is not None:
            doc["ground_rise_m"] = self.ground_rise_m
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> FencePlan:
        return cls(doc["vertices"], doc["max_altitude_m"], doc.get("margin_m"), doc.get("ground_rise_m"))


@dataclass(frozen=True)
class DronePlan:
    """One drone's plan: totals over its sorties (cells, waypoints, length, flight time, photos, altitude),
    its path's shape before and after smoothing, each sortie, and its geofence (None: none planned)."""

    id: int  # MAVLink system id
    cells: int
    waypoints: int
    length_m: float
    flight_s: float
    photos: int
    altitude_m: float
    before: PathShape
    after: PathShape
    sorties: tuple[SortiePlan, ...]
    geofence: FencePlan | None = None
    # A plan over a DEM: the lowest and highest height above the ground along its waypoint legs as its autopilot
    # flies them (mission.terrain_missions.flown_above_ground); None over flat ground.
    above_ground_m: tuple[float, float] | None = None

    @property
    def planned_sorties(self) -> tuple[SortiePlan, ...]:
        """Its sorties; a report that lists none (an older missionplan's): its one whole flight."""
        return self.sorties or (SortiePlan(f"uav{self.id}.plan", self.flight_s, self.photos, self.waypoints),)

    def sortie(self, j: int) -> SortiePlan | None:
        """Sortie j (1-based), None past its last."""
        return self.planned_sorties[j - 1] if 1 <= j <= len(self.planned_sorties) else None

    def for_sortie(self, j: int) -> DronePlan | None:
        """This drone as sortie j is flown: that sortie's flight time, photos and waypoints (None: no sortie j)."""
        entry = self.sortie(j)
        if entry is None:
            return None
        return replace(self, flight_s=entry.flight_s, photos=entry.photos, waypoints=entry.waypoints)

    def to_json(self) -> JSON:
        doc = {"id": self.id, "cells": self.cells, "waypoints": self.waypoints, "length_m": self.length_m,
               "flight_s": self.flight_s, "photos": self.photos, "altitude_m": self.altitude_m,
               "smoothing": {"before": self.before.to_json(), "after": self.after.to_json()},
               "sorties": [s.to_json() for s in self.sorties]}
        if self.geofence is not None:
            doc["geofence"] = self.geofence.to_json()
        if self.above_ground_m is not None:
            doc["above_ground_m"] = list(self.above_ground_m)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> DronePlan:
        smoothing = doc["smoothing"]
        fence = doc.get("geofence")
        above = doc.get("above_ground_m")
        return cls(doc["id"], doc["cells"], doc["waypoints"], doc["length_m"], doc["flight_s"], doc["photos"],
                   doc["altitude_m"], PathShape.from_json(smoothing["before"]), PathShape.from_json(smoothing["after"]),
                   tuple(SortiePlan.from_json(s) for s in doc.get("sorties") or []),
                   FencePlan.from_json(fence) if fence is not None else None,
                   (float(above[0]), float(above[1])) if above is not None else None)


# ------------------------------------------------------------------------------------------- the safety promise
@dataclass(frozen=True)
class Closest:
    """The closest approach of two drones if all fly as planned (timeline.closest_approach): horizontal and
    3-D metres, the pairs (system ids), when (seconds into the sortie); all None (pairs empty) when no two
    drones fly together."""

    horizontal: float | None
    d3: float | None  # report.json "3d"
    pair_horizontal: tuple[int, ...]
    pair_3d: tuple[int, ...]
    at_s: float | None

    def to_json(self) -> JSON:
        return {"horizontal": self.horizontal, "3d": self.d3, "pair_horizontal": list(self.pair_horizontal),
                "pair_3d": list(self.pair_3d), "at_s": self.at_s}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Closest:
        return cls(doc.get("horizontal"), doc.get("3d"), tuple(doc.get("pair_horizontal") or []),
                   tuple(doc.get("pair_3d") or []), doc.get("at_s"))


@dataclass(frozen=True)
class SeparationPromise:
    """report.json `separation`: the closest approach over every sortie (and the sortie it is in), what the
    timeline assumes, each sortie's own; with safety settings, the minimum asked, how it is kept (the
    altitude layers) and what is guaranteed."""

    closest: Closest
    sortie: int | None
    assumes: str
    sorties: tuple[Closest, ...]
    required_m: float | None = None  # required_m, method, altitude_step_m, guaranteed_m: written when method is set
    method: str | None = None
    altitude_step_m: float | None = None
    guaranteed_m: float | None = None

    @property
    def d3(self) -> float | None:
        """The 3-D distance promised."""
        return self.closest.d3

    def for_sortie(self, j: int) -> SeparationPromise:
        """The promise a flight of sortie j is held to: that sortie's closest approach (self past the last)."""
        if not 1 <= j <= len(self.sorties):
            return self
        return replace(self, closest=self.sorties[j - 1], sortie=j)

    def promising(self, d3: float) -> SeparationPromise:
        """This promise with `d3` metres 3-D promised instead (a live re-task promised less)."""
        return replace(self, closest=replace(self.closest, d3=d3))

    def to_json(self) -> JSON:
        doc = {**self.closest.to_json(), "sortie": self.sortie, "assumes": self.assumes,
               "sorties": [s.to_json() for s in self.sorties]}
        if self.method is not None:
            doc.update({"required_m": self.required_m, "method": self.method, "altitude_step_m": self.altitude_step_m,
                        "guaranteed_m": self.guaranteed_m})
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> SeparationPromise:
        return cls(Closest.from_json(doc), doc.get("sortie"), doc.get("assumes", ""),
                   tuple(Closest.from_json(s) for s in doc.get("sorties") or []), doc.get("required_m"),
                   doc.get("method"), doc.get("altitude_step_m"), doc.get("guaranteed_m"))


@dataclass(frozen=True)
class BandCounts:
    """The clearance band's target cells: how many, photographed from outside it, missed."""

    band_cells: int
    band_targets: int
    band_targets_photographed: int
    band_targets_missed: int

    def to_json(self) -> JSON:
        return {"band_cells": self.band_cells, "band_targets": self.band_targets,
                "band_targets_photographed": self.band_targets_photographed,
                "band_targets_missed": self.band_targets_missed}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> BandCounts:
        return cls(doc["band_cells"], doc["band_targets"], doc["band_targets_photographed"], doc["band_targets_missed"])


@dataclass(frozen=True)
class ClearancePromise:
    """report.json `clearance`: the margin asked, the smallest kept (each drone's), whether it holds, where the
    closest track is; with a clearance band, the grid moves added to photograph it and its target counts."""

    required_m: float | None
    kept_m: float | None
    per_drone_m: tuple[float | None, ...]
    kept: bool
    closest_uav: int | None = None  # closest_uav and closest_at: written when kept_m is known
    closest_at: tuple[float, float] | None = None
    band_moves_added: int | None = None
    band: BandCounts | None = None

    def with_band(self, band: BandCounts) -> ClearancePromise:
        return replace(self, band=band)

    def to_json(self) -> JSON:
        doc: JSON = {"required_m": self.required_m, "kept_m": self.kept_m, "per_drone_m": list(self.per_drone_m),
                     "kept": self.kept}
        if self.closest_at is not None:
            doc.update({"closest_uav": self.closest_uav, "closest_at": list(self.closest_at)})
        if self.band_moves_added is not None:
            doc["band_moves_added"] = self.band_moves_added
        if self.band is not None:
            doc.update(self.band.to_json())
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ClearancePromise:
        at = doc.get("closest_at")
        return cls(doc.get("required_m"), doc.get("kept_m"), tuple(doc.get("per_drone_m") or []),
                   doc.get("kept", True), doc.get("closest_uav"), (at[0], at[1]) if at is not None else None,
                   doc.get("band_moves_added"), BandCounts.from_json(doc) if "band_cells" in doc else None)


@dataclass(frozen=True)
class SafetyPromise:
    """What a georeferenced plan promises the flight: the separation between drones and the clearance from
    obstacles (report.json `separation` and `clearance`)."""

    separation: SeparationPromise
    clearance: ClearancePromise


# ------------------------------------------------------------------------------------------- coverage
@dataclass(frozen=True)
class SmallShare:
    """A drone given under a fair share of the targets (a launch point in a pocket, or a small zone)."""

    uav: int
    targets: int
    mean: float
    launch_pocket_targets: int

    def to_json(self) -> JSON:
        return {"uav": self.uav, "targets": self.targets, "mean": self.mean,
                "launch_pocket_targets": self.launch_pocket_targets}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> SmallShare:
        return cls(doc["uav"], doc["targets"], doc["mean"], doc["launch_pocket_targets"])


@dataclass(frozen=True)
class CoverageSummary:
    """report.json `coverage`: the coverage of the reachable targets and of all, the counts, why targets are
    unreachable (unknown-height buildings, the clearance band; None: not asked), the drones with a small
    share, and the warnings `plan` prints (one line each)."""

    reachable_pct: float
    all_pct: float
    covered: int
    targets_reachable: int
    targets_all: int
    unreachable: int
    unreachable_pct: float
    unknown_height_buildings: int | None
    unknown_building_height_m: float | None
    unreachable_by_unknown_height: int | None
    unreachable_by_clearance: int | None
    small_shares: tuple[SmallShare, ...]
    warnings: tuple[str, ...]
    # The overlaps the planned photos achieve (photo_overlap): recorded for a plan that asks its overlaps
    # (a camera's side overlap); left out, as before, for one that does not.
    overlap: OverlapMeasure | None = None

    def warned_first(self, warnings: Sequence[str]) -> CoverageSummary:
        """These warnings before the block's own (an area's input warnings come first)."""
        return replace(self, warnings=(*warnings, *self.warnings))

    def to_json(self) -> JSON:
        return {"reachable_pct": self.reachable_pct, "all_pct": self.all_pct, "covered": self.covered,
                "targets_reachable": self.targets_reachable, "targets_all": self.targets_all,
                "unreachable": self.unreachable, "unreachable_pct": self.unreachable_pct,
                "unknown_height_buildings": self.unknown_height_buildings,
                "unknown_building_height_m": self.unknown_building_height_m,
                "unreachable_by_unknown_height": self.unreachable_by_unknown_height,
                "unreachable_by_clearance": self.unreachable_by_clearance,
                "small_shares": [s.to_json() for s in self.small_shares], "warnings": list(self.warnings),
                **({} if self.overlap is None else {"overlap": self.overlap.to_json()})}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> CoverageSummary:
        return cls(doc["reachable_pct"], doc["all_pct"], doc["covered"], doc["targets_reachable"], doc["targets_all"],
                   doc["unreachable"], doc["unreachable_pct"], doc.get("unknown_height_buildings"),
                   doc.get("unknown_building_height_m"), doc.get("unreachable_by_unknown_height"),
                   doc.get("unreachable_by_clearance"),
                   tuple(SmallShare.from_json(s) for s in doc.get("small_shares") or []), tuple(doc.get("warnings") or []),
                   OverlapMeasure.from_json(doc["overlap"]) if doc.get("overlap") is not None else None)


# ------------------------------------------------------------------------------------------- the files read
@dataclass(frozen=True)
class BuildingsRead:
    """What a buildings file gave inside the area: how many, which have no height and what was assumed for
    them, the attribute the heights came from (the repairs of those in the area: InputFile.repaired)."""

    in_area: int
    unknown_height: tuple[str, ...]
    unknown_height_assumed_m: float | None
    height_field: str | None


@dataclass(frozen=True)
class InputFile:
    """report.json `inputs`: one file an area plan read (`role`: area, obstacles, buildings), how it was read
    (geo.sources.SourceFile's fields) and what it left out; for the buildings, what lies in the area."""

    role: str
    path: str
    format: str
    reader: str
    layer: str | None
    crs: str
    reprojected: bool
    features: int
    dropped: tuple[Omission, ...]
    repaired: tuple[Omission, ...]  # for the buildings: the repairs of those in the area (buildings.repaired)
    notes: tuple[str, ...]
    buildings: BuildingsRead | None = None

    def to_json(self) -> JSON:
        doc: JSON = {"role": self.role, "path": self.path, "format": self.format, "reader": self.reader,
                     "layer": self.layer, "crs": self.crs, "reprojected": self.reprojected, "features": self.features,
                     "dropped": [o.to_json() for o in self.dropped], "repaired": [o.to_json() for o in self.repaired],
                     "notes": list(self.notes)}
        if self.buildings is not None:
            buildings = self.buildings
            doc.update({"buildings_in_area": buildings.in_area, "unknown_height": list(buildings.unknown_height),
                        "unknown_height_assumed_m": buildings.unknown_height_assumed_m,
                        "height_field": buildings.height_field})
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> InputFile:
        repaired = tuple(Omission.from_json(o) for o in doc.get("repaired") or [])
        buildings = None
        if "buildings_in_area" in doc:
            buildings = BuildingsRead(doc["buildings_in_area"], tuple(doc.get("unknown_height") or []),
                                      doc.get("unknown_height_assumed_m"), doc.get("height_field"))
        return cls(doc["role"], doc["path"], doc["format"], doc["reader"], doc.get("layer"), doc["crs"],
                   doc["reprojected"], doc["features"], tuple(Omission.from_json(o) for o in doc.get("dropped") or []),
                   repaired, tuple(doc.get("notes") or []), buildings)


# ------------------------------------------------------------------------------------------- settings, survey
@dataclass(frozen=True)
class PlanSettings:
    """report.json `settings`: the mission and safety settings and the planning choices a plan was made with,
    which `replan` and the live re-task plan the rest with."""

    mission: MissionSettings
    safety: SafetySettings
    policy: str
    zones: str
    balance_zones: bool
    open_ground: str
    # cells between open-ground lanes; written only when a side overlap made them closer than a footprint
    lane_spacing_cells: int = CELLS_PER_FOOTPRINT
    overlap_fill: bool = False  # written only when on

    def to_json(self) -> JSON:
        # Every field of the two settings, in their order: a field added there is recorded here. The capture
        # mode only when it is not the relay, the transit speed only when it differs from the survey's and the
        # gimbal pitch only when not straight down, so a plan without them is written as before.
        mission = asdict(self.mission)
        if mission.get("capture") == "relay":
            del mission["capture"]
        if mission.get("transit_speed_m_s") is None:  # one speed throughout: written as before
            mission.pop("transit_speed_m_s", None)
        if mission.get("gimbal_pitch_deg") == NADIR_PITCH_DEG:
            del mission["gimbal_pitch_deg"]
        doc: JSON = {"mission": mission, "safety": asdict(self.safety), "policy": self.policy,
                     "zones": self.zones, "balance_zones": self.balance_zones, "open_ground": self.open_ground}
        if self.lane_spacing_cells != CELLS_PER_FOOTPRINT:
            doc["lane_spacing_cells"] = self.lane_spacing_cells
        if self.overlap_fill:
            doc["overlap_fill"] = True
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PlanSettings:
        return cls(MissionSettings(**doc["mission"]), SafetySettings(**doc["safety"]), doc.get("policy", "expert"),
                   doc.get("zones", "geodesic"), doc.get("balance_zones", True), doc.get("open_ground", "lanes"),
                   int(doc.get("lane_spacing_cells", CELLS_PER_FOOTPRINT)), bool(doc.get("overlap_fill", False)))


@dataclass(frozen=True)
class SurveyPointer:
    """report.json `survey` of a re-plan: its survey's root folder and the folder it was re-planned from
    (both relative to the re-plan's), and how many target cells were missing then."""

    root: str
    missing_cells: int | None = None
    from_folder: str | None = None  # report.json "from"

    def to_json(self) -> JSON:
        doc: JSON = {"root": self.root}
        if self.missing_cells is not None:
            doc["missing_cells"] = self.missing_cells
        if self.from_folder is not None:
            doc["from"] = self.from_folder
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> SurveyPointer:
        return cls(doc["root"], doc.get("missing_cells"), doc.get("from"))


@dataclass(frozen=True)
class OverlapFill:
    """report.json `overlap_fill`: what the overlap fill (mission/overlap_fill.py) did over all its rounds. `short_before` / `short_after`: the
    reachable points short of the implied photos before the first round and after the last; `unserved`: of
    the last round's short points, those no detour could serve (the clearance band closes their window)."""

    rounds: int
    stubs: int
    runs: int
    moves_added: int
    short_before: int
    short_after: int
    unserved: int
    makespan_before_s: float  # the busiest drone's flight time, all its sorties, without the fill
    makespan_s: float  # and with it

    def to_json(self) -> JSON:
        return {"rounds": self.rounds, "stubs": self.stubs, "runs": self.runs, "moves_added": self.moves_added,
                "short_before": self.short_before, "short_after": self.short_after, "unserved": self.unserved,
                "makespan_before_s": self.makespan_before_s, "makespan_s": self.makespan_s}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> OverlapFill:
        return cls(int(doc["rounds"]), int(doc["stubs"]), int(doc["runs"]), int(doc["moves_added"]),
                   int(doc["short_before"]), int(doc["short_after"]), int(doc["unserved"]),
                   float(doc["makespan_before_s"]), float(doc["makespan_s"]))

    def summary(self) -> str:
        """`overlap fill: 35 stubs, 0 runs (174 grid moves) in 5 rounds; reachable points short 285 -> 0;
        busiest drone 55 s -> 65 s (+18 %)`."""
        text = (f"overlap fill: {self.stubs} stubs, {self.runs} runs ({self.moves_added:,} grid moves) in "
                f"{self.rounds} round{'s' if self.rounds != 1 else ''}; reachable points short {self.short_before} "
                f"-> {self.short_after}")
        if self.unserved:
            text += f" ({self.unserved} no detour could serve)"
        if self.makespan_before_s > 0:
            text += (f"; busiest drone {self.makespan_before_s:.0f} s -> {self.makespan_s:.0f} s "
                     f"(+{100 * (self.makespan_s / self.makespan_before_s - 1):.0f} %)")
        return text
