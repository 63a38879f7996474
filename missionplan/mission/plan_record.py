"""The plan as data: `PlanRecord`, what a plan folder's report.json holds, and the one way it is written and read.

Every writer (`plan`, `replan`, `demo`: plan_folder) builds a PlanRecord and writes it with
`write_plan_record`; every reader (fly, the judge, the survey ledger, status, replan, the live re-task, the
benches) reads it with `read_plan_record`. No other module opens report.json for reading
(tests/test_layers.py holds to that), and none reads it by string key: the blocks are typed
(plan_blocks: drones, the safety promise, coverage, inputs, settings; geo.georeference.Georeference: where
the grid lies and how it is photographed).

A plan is written in the oldest schema version that holds it, so a missionplan that cannot fly a plan
refuses it in one line instead of flying it wrongly, and one that can reads it:
* version 1, with no version key (as every earlier missionplan wrote it): a plan over flat ground, byte for
  byte what missionplan wrote before the record existed: the same keys in the same order, numbers as
  computed, `json.dumps(indent=1)`;
* version 2, `"schema_version": 2` first: a plan over a DEM (georeference.terrain: its heights are above the
  ground, its missions follow the terrain);
* version 3: a plan asked for by camera, GSD or overlaps (georeference.camera: the capture's numbers and rules,
  open-ground lanes possibly closer than a footprint), with an overlap fill's detours (`overlap_fill`), with
  roof targets (`roofs`, 'r' grid cells) or a
  MAVLink camera's capture (settings.mission.capture) or an oblique gimbal (settings.mission.gimbal_pitch_deg),
  over flat ground or a DEM.
SCHEMA_VERSION is the newest this missionplan writes and reads; a report.json of a version it does not know
fails in one line naming the file and the version.

Keys of version 1, in order (the optional ones are left out when None): map, uavs, policy, zones,
zones_balanced, zone_sizes, seed, success, failure, metrics, targets (reachable target cells U), unreachable
(count) and unreachable_cells, floor (U / (9 A)), steps, deadlocks_broken, lane_drones, decisions, timing,
launch, paths (per drone, one [row, col] per step, start and hovers included), grid (one string per row:
'#' obstacle, '.' target, 'o' free non-target); then for a georeferenced plan zone_shares (when re-balanced
for sorties), drones, separation and clearance (the safety promise), settings, drone_ids, survey (a
re-plan's pointer), basemap, credit, georeference; then coverage, roofs (with `plan --targets roofs|all`:
mission/roof_targets.py; the grid's roof target cells are 'r'), overlap_fill (mission/overlap_fill.py), improve
(plan --improve: mission/plan_improvement.py; readers that do not know it fly the plan as any other), tours (a
whole fleet's block tours: mission/plan_tours.py; the same for readers that do not know it), inputs (an area
plan's files), files and files_sha256.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.base.atomic import write_text_atomic
from missionplan.bridge.formats.gimbal import NADIR_PITCH_DEG
from missionplan.geo.errors import GeoError
from missionplan.geo.georeference import Georeference

from ..maps.gridmap import Cell, MapError
from .plan_blocks import (ClearancePromise, CoverageSummary, Decisions, DronePlan, InputFile, OverlapFill,
                          PlanMetrics, PlanSettings, SafetyPromise, SeparationPromise, SurveyPointer, Timing, cells_json, cells_of)
from .plan_improvement import PlanImprovement
from .plan_tours import TourPlan
from .roof_targets import RoofTargets

REPORT_NAME = "report.json"
SCHEMA_VERSION = 3  # the newest format this missionplan writes and reads
TERRAIN_VERSION = 2  # the first that holds a plan over a DEM
CAPTURE_VERSION = 3  # the first that holds a camera block (georeference.camera)


class PlanRecordError(MapError):
    """A report.json that cannot be read as a plan record; the one-line message names the file."""


class SchemaVersionError(ValueError):
    """A report.json object of a schema version this missionplan does not read (newer, or not a version)."""

    def __init__(self, version: Any) -> None:
        super().__init__(f"schema version {version!r}")
        self.version = version


def schema_version(doc: Mapping[str, Any]) -> int:
    """The schema version of a report.json object (1 without the key); SchemaVersionError for one not read here."""
    version = doc.get("schema_version", 1)
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= SCHEMA_VERSION:
        raise SchemaVersionError(version)
    return version


@dataclass(frozen=True)
class PlanRecord:
    """A plan, as report.json holds it: the grid plan, and for a georeferenced plan what each drone flies,
    the safety promise, the settings and the georeference; the coverage and the files written."""

    map: str
    uavs: int
    policy: str
    zones: str
    zones_balanced: bool
    zone_sizes: tuple[int, ...]
    seed: int
    success: bool
    failure: str | None
    metrics: PlanMetrics
    targets: int  # reachable target cells
    unreachable: int
    unreachable_cells: tuple[Cell, ...]
    floor: float  # targets / (9 * uavs): the fewest moves per drone that could photograph them
    steps: int
    deadlocks_broken: int
    lane_drones: int
    decisions: Decisions
    timing: Timing
    launch: tuple[Cell, ...]  # each drone's launch cell, in drone order
    paths: tuple[tuple[Cell, ...], ...]  # each drone's cell at every step, the start included
    grid: tuple[str, ...]  # one string per row: '#' obstacle, '.' target, 'o' free non-target
    zone_shares: tuple[float, ...] | None = None  # each zone's share when re-balanced (for sorties, or by --improve)
    drones: tuple[DronePlan, ...] | None = None  # None: no missions (no georeference, or the plan failed)
    promise: SafetyPromise | None = None  # report.json separation and clearance
    settings: PlanSettings | None = None
    drone_ids: tuple[int, ...] | None = None  # each drone's system id, when not 1, 2, ...
    survey: SurveyPointer | None = None  # a re-plan's survey
    basemap: str | None = None
    credit: str | None = None  # the map data's credit line
    georeference: Georeference | None = None
    coverage: CoverageSummary | None = None
    inputs: tuple[InputFile, ...] | None = None  # the files an area plan read
    files: tuple[str, ...] | None = None  # every file the plan wrote, report.json included
    files_sha256: Mapping[str, str] | None = None  # each file's but report.json's
    roofs: RoofTargets | None = None  # the target classes, cell rule and clearance over roofs (--targets roofs|all)
    overlap_fill: OverlapFill | None = None  # what the overlap fill added (plan --overlap-fill)
    improve: PlanImprovement | None = None  # what the anytime improvement tried and kept (plan --improve)
    tours: TourPlan | None = None  # a whole fleet's block tours: solver, grid, moves, CPU time

    # ---- what readers ask ------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.grid), len(self.grid[0]))

    @property
    def separation(self) -> SeparationPromise | None:
        return self.promise.separation if self.promise is not None else None

    @property
    def clearance(self) -> ClearancePromise | None:
        return self.promise.clearance if self.promise is not None else None

    @property
    def version(self) -> int:
        """The schema version this record is written in: the oldest that holds it (module docstring)."""
        georef = self.georeference
        camera = georef is not None and georef.capture is not None
        mission = self.settings.mission if self.settings is not None else None
        capture_mode = mission is not None and (mission.capture != "relay" or mission.gimbal_pitch_deg != NADIR_PITCH_DEG)
        if camera or self.roofs is not None or capture_mode or self.overlap_fill is not None:
            return CAPTURE_VERSION
        return TERRAIN_VERSION if georef is not None and georef.terrain is not None else 1

    @property
    def sorties(self) -> int:
        """The most battery sorties any drone flies (1 without drones)."""
        return max((len(d.sorties) or 1 for d in self.drones or ()), default=1)

    # ---- report.json ----------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The object report.json holds (see the module docstring for its keys); version 1 writes no version."""
        doc: dict[str, Any] = {} if self.version == 1 else {"schema_version": self.version}
        doc |= {
            "map": self.map, "uavs": self.uavs, "policy": self.policy, "zones": self.zones,
            "zones_balanced": self.zones_balanced, "zone_sizes": list(self.zone_sizes), "seed": self.seed,
            "success": self.success, "failure": self.failure, "metrics": self.metrics.to_json(),
            "targets": self.targets, "unreachable": self.unreachable,
            "unreachable_cells": cells_json(self.unreachable_cells), "floor": self.floor, "steps": self.steps,
            "deadlocks_broken": self.deadlocks_broken, "lane_drones": self.lane_drones,
            "decisions": self.decisions.to_json(), "timing": self.timing.to_json(), "launch": cells_json(self.launch),
            "paths": [cells_json(path) for path in self.paths], "grid": list(self.grid)}
        if self.zone_shares is not None:
            doc["zone_shares"] = list(self.zone_shares)
        if self.drones is not None:
            doc["drones"] = [d.to_json() for d in self.drones]
        if self.promise is not None:
            doc["separation"] = self.promise.separation.to_json()
            doc["clearance"] = self.promise.clearance.to_json()
        if self.settings is not None:
            doc["settings"] = self.settings.to_json()
        if self.drone_ids is not None:
            doc["drone_ids"] = list(self.drone_ids)
        if self.survey is not None:
            doc["survey"] = self.survey.to_json()
        if self.basemap is not None:
            doc["basemap"] = self.basemap
        if self.credit is not None:
            doc["credit"] = self.credit
        if self.georeference is not None:
            doc["georeference"] = self.georeference.to_json()
        if self.coverage is not None:
            doc["coverage"] = self.coverage.to_json()
        if self.roofs is not None:
            doc["roofs"] = self.roofs.to_json()
        if self.overlap_fill is not None:
            doc["overlap_fill"] = self.overlap_fill.to_json()
        if self.improve is not None:
            doc["improve"] = self.improve.to_json()
        if self.tours is not None:
            doc["tours"] = self.tours.to_json()
        if self.inputs is not None:
            doc["inputs"] = [i.to_json() for i in self.inputs]
        if self.files is not None:
            doc["files"] = list(self.files)
        if self.files_sha256 is not None:
            doc["files_sha256"] = dict(self.files_sha256)
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PlanRecord:
        """The record of a report.json object, of this schema version or an earlier one. SchemaVersionError for
        a newer or unknown version; KeyError / TypeError / ValueError for what is no plan."""
        schema_version(doc)  # one this missionplan reads
        grid = tuple(doc["grid"])
        if not grid or not all(isinstance(row, str) for row in grid):
            raise ValueError("grid is not a list of rows")
        separation, clearance, georef = doc.get("separation"), doc.get("clearance"), doc.get("georeference")
        return cls(
            map=doc["map"], uavs=doc["uavs"], policy=doc["policy"], zones=doc["zones"],
            zones_balanced=doc["zones_balanced"], zone_sizes=tuple(doc["zone_sizes"]), seed=doc["seed"],
            success=doc["success"], failure=doc.get("failure"), metrics=PlanMetrics.from_json(doc["metrics"]),
            targets=doc["targets"], unreachable=doc["unreachable"],
            unreachable_cells=cells_of(doc.get("unreachable_cells") or []), floor=doc["floor"], steps=doc["steps"],
            deadlocks_broken=doc["deadlocks_broken"], lane_drones=doc.get("lane_drones", 0),
            decisions=Decisions.from_json(doc["decisions"]), timing=Timing.from_json(doc["timing"]),
            launch=cells_of(doc["launch"]), paths=tuple(cells_of(path) for path in doc["paths"]), grid=grid,
            zone_shares=_optional_tuple(doc.get("zone_shares")),
            drones=tuple(DronePlan.from_json(d) for d in doc["drones"]) if doc.get("drones") is not None else None,
            promise=SafetyPromise(SeparationPromise.from_json(separation), ClearancePromise.from_json(clearance or {}))
            if separation is not None else None,
            settings=PlanSettings.from_json(doc["settings"]) if doc.get("settings") is not None else None,
            drone_ids=_optional_tuple(doc.get("drone_ids")),
            survey=SurveyPointer.from_json(doc["survey"]) if doc.get("survey") is not None else None,
            basemap=doc.get("basemap"), credit=doc.get("credit"),
            georeference=Georeference.from_json(georef, len(grid), len(grid[0])) if georef is not None else None,
            coverage=CoverageSummary.from_json(doc["coverage"]) if doc.get("coverage") is not None else None,
            roofs=RoofTargets.from_json(doc["roofs"]) if doc.get("roofs") is not None else None,
            overlap_fill=OverlapFill.from_json(doc["overlap_fill"]) if doc.get("overlap_fill") is not None else None,
            improve=PlanImprovement.from_json(doc["improve"]) if doc.get("improve") is not None else None,
            tours=TourPlan.from_json(doc["tours"]) if doc.get("tours") is not None else None,
            inputs=tuple(InputFile.from_json(i) for i in doc["inputs"]) if doc.get("inputs") is not None else None,
            files=_optional_tuple(doc.get("files")),
            files_sha256=dict(doc["files_sha256"]) if doc.get("files_sha256") is not None else None)


def _optional_tuple(values: Any) -> tuple[Any, ...] | None:
    return tuple(values) if values is not None else None


# ------------------------------------------------------------------------------------------- on disk
def report_path(folder: str | os.PathLike[str]) -> Path:
    """The report.json of a plan folder."""
    return Path(folder) / REPORT_NAME


def write_plan_record(record: PlanRecord, path: str | os.PathLike[str]) -> None:
    """Write `record` as report.json at `path`, atomically (a temporary file renamed into place)."""
    write_text_atomic(Path(path), json.dumps(record.to_json(), indent=1) + "\n")


def read_plan_record(folder: str | os.PathLike[str]) -> PlanRecord:
    """The plan record of a plan folder (its report.json). PlanRecordError, one line naming the folder or the
    file: no report.json, not readable, not a plan report, or written by a newer missionplan."""
    path = report_path(folder)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise PlanRecordError(f"{folder}: no {REPORT_NAME} (not a plan folder: `missionplan plan --out` makes "
                              "one)") from None
    except (OSError, ValueError) as err:
        raise PlanRecordError(f"{path}: cannot be read ({err})") from None
    if not isinstance(doc, dict) or "grid" not in doc:
        raise PlanRecordError(f"{path}: not a missionplan plan report")
    try:
        return PlanRecord.from_json(doc)
    except SchemaVersionError as err:
        if isinstance(err.version, int) and not isinstance(err.version, bool) and err.version > SCHEMA_VERSION:
            raise PlanRecordError(f"{path}: schema version {err.version}, and this missionplan reads up to version "
                                  f"{SCHEMA_VERSION}: a newer missionplan wrote it (update missionplan to read it)"
                                  ) from None
        raise PlanRecordError(f"{path}: schema version {err.version!r} is not a version (a whole number from 1; this "
                              f"missionplan reads up to version {SCHEMA_VERSION})") from None
    except (KeyError, TypeError, ValueError, IndexError, GeoError) as err:
        what = f"no {err.args[0]!r}" if isinstance(err, KeyError) else str(err)
        raise PlanRecordError(f"{path}: not a missionplan plan report ({what})") from None


def listed_files(folder: str | os.PathLike[str]) -> tuple[list[str], dict[str, str]]:
    """What the report.json in `folder` says `plan` wrote there, of any version and whole or not: the file
    names (a report written before `files` existed: its drones' mission files and tracks.geojson) and each
    one's sha256 (empty before checksums were recorded). Nothing when there is none or it is unreadable."""
    try:
        doc: Any = json.loads(report_path(folder).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return [], {}
    if not isinstance(doc, dict):
        return [], {}
    sums = doc.get("files_sha256")
    sha256 = ({k: v for k, v in sums.items() if isinstance(k, str) and isinstance(v, str)}
              if isinstance(sums, dict) else {})
    files = doc.get("files")
    if isinstance(files, list):
        return [name for name in files if isinstance(name, str)], sha256
    names = []
    for drone in doc.get("drones") or []:  # reports written before `files` existed
        if isinstance(drone, dict) and isinstance(drone.get("id"), int):
            names += [f"uav{drone['id']}.plan", f"uav{drone['id']}.waypoints"]
    return names + (["tracks.geojson"] if names else []), sha256
