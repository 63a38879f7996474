"""Plan a map and write its plan folder: the library call behind `plan`, `replan` and `demo`.

`write_plan_folder(out, ground, options)` plans the ground (missionplan/planning/field_plan.py: zones, the
drones' paths, the clearance band, flight plans, sorties, separation, geofences) and writes the folder:
report.json, plan.png, one mission per drone (.plan, .waypoints) and the map files (plan.html,
plan.gpkg, plan.kmz, GeoJSON). It prints nothing: the caller prints the returned `PlanFolder`
(missionplan/cli/plan_display.py).

The folder is the run's alone and a plan never lands over a flight: `out` is held for the whole run
(missionplan.bridge.folder_lock: a second process gets one line naming this one), and a folder that
holds a flight (a journal, a ledger, fly's record), the root folder or the user's home is refused
before anything is written (`check_out_folder`). Every file is first written into a hidden staging
folder inside `out` (same filesystem), then renamed into place, report.json last, so report.json lists
only files that exist; a write that fails (a full disk, a quota, a read-only mount) removes the staging
folder, and `out` itself when this run made it, leaves the previous plan as it was, and is one MapError
naming the folder, the file and the cause. Files of an earlier plan that this plan does not write are
removed only when they are exactly what that plan wrote (missionplan/mission/outputs.py); changed ones
are kept and listed in `PlanFolder.kept`.

`PlanGround` is what is planned (the grid, its georeference, the mission and safety settings, the
launch cells: `grid_ground` makes it as `plan` does); `PlanOptions` is how (policy, zones, seed,
basemap). Every input that can be wrong fails with MapError before the folder is made.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from missionplan.base.atomic import probe_writable
from missionplan.base.naming import Named
from missionplan.bridge.folder_lock import hold_folder
from missionplan.geo.dem import Ground
from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.geo.capture import CapturePlan
from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import Georeference
from missionplan.geo.roofs import DEFAULT_TARGETS

from ..grid.zones import DEFAULT_ZONE_METHOD
from ..maps.catalog import load_shipped
from ..maps.gridmap import GridMap
from ..mission.georef import AreaSources, UnknownHeights, mission_settings, shipped_frame
from ..mission.drone_missions import MissionSettings
from ..mission.photo_overlap import OverlapMeasure
from ..mission.plan_blocks import PlanSettings, SurveyPointer
from ..mission.plan_record import REPORT_NAME, PlanRecord, report_path, write_plan_record
from ..mission.safety import SafetySettings, safety_settings
from .errors import PlanFolderError
from .pipeline import DEFAULT_POLICY, launch_cells, make_policy

NO_UNKNOWN_HEIGHTS = UnknownHeights(0, 0, None, None)


@dataclass
class PlanGround:
    """What is planned: the grid and, for a georeferenced plan, its frame and settings."""

    gmap: GridMap
    starts: list[tuple[int, int]]  # launch cell of each drone, in drone order
    frame: GridFrame | None = None  # None: a grid without origin (no missions, no map files)
    settings: MissionSettings | None = None
    safety: SafetySettings | None = None
    unknown: UnknownHeights = field(default_factory=lambda: NO_UNKNOWN_HEIGHTS)  # --osm buildings of unknown height
    sources: AreaSources | None = None  # the area and buildings an --area grid was drawn from
    from_osm: bool = False  # drawn from OpenStreetMap buildings (--area with --osm)
    launch_labels: list[str] | None = None  # the launch points as given (--launch LAT,LON), for the pictures
    terrain: Ground | None = None  # the ground under the plan (plan --dem: planning/terrain.py); None: flat
    # The side overlap asked of the camera (a fraction; None: not asked). The planned photos' measured
    # overlaps are set against it, and recorded in report.json's coverage when it is asked.
    side_overlap: float | None = None
    targets: str = DEFAULT_TARGETS  # the classes of target cells: streets, roofs or all (geo/roofs.py)
    gsd_cm_at_ground: float | None = None  # the ground sample distance asked, said at the roofs too (None: not asked)
    capture: CapturePlan | None = None  # the camera, GSD and overlaps asked (report.json georeference.camera)

    @property
    def asked_side_overlap(self) -> float | None:
        """The side overlap asked: side_overlap where set, else the capture's (None: not asked)."""
        if self.side_overlap is not None:
            return self.side_overlap
        return self.capture.side_overlap if self.capture is not None else None

    @property
    def asked_gsd_cm(self) -> float | None:
        """The ground sample distance at the ground: gsd_cm_at_ground where set, else the capture's camera's."""
        if self.gsd_cm_at_ground is not None:
            return self.gsd_cm_at_ground
        return self.capture.gsd_cm if self.capture is not None else None

    @property
    def uavs(self) -> int:
        return len(self.starts)


@dataclass(frozen=True)
class PlanOptions:
    """How to plan; the defaults are `plan`'s."""

    policy: str = DEFAULT_POLICY
    weights: Path | None = None  # network weights for policy nn (None: the shipped ones)
    zones: str = DEFAULT_ZONE_METHOD
    balance_zones: bool = True
    open_ground: str = "lanes"  # or "explore"
    # cells between the lanes open ground is swept in: one footprint (9), or closer for a side overlap
    lane_spacing_cells: int = CELLS_PER_FOOTPRINT
    seed: int = 0
    basemap: str | None = None  # tile server URL drawn under plan.html and flight.html
    progress: bool = False  # a progress bar on stderr while planning
    drone_ids: list[int] | None = None  # system id of each drone, in launch order (default 1, 2, ...)
    survey: SurveyPointer | None = None  # report.json `survey`: a re-plan's pointer to the survey it continues
    overlap_fill: bool = False  # detours where reachable points lack photos (mission/overlap_fill.py)
    improve_s: float | None = None  # seconds of local search on the finished plan (planning/improve.py; None: none)
    improve_rounds: int | None = None  # and at most this many candidate plans (None: as many as the time allows)

    def __post_init__(self) -> None:
        # A basemap URL that is no tile server's fails here, before any area is read or folder made.
        if self.basemap is not None:
            from ..mission.webmap import basemap_problem

            if (problem := basemap_problem(self.basemap)) is not None:
                raise PlanFolderError(Named("{basemap} {0}: {1}", self.basemap, problem))


@dataclass
class PlanFolder:
    """A written plan folder: its plan record (what report.json holds) and every file written."""

    out: Path
    ground: PlanGround
    options: PlanOptions
    record: PlanRecord
    written: list[Path] = field(default_factory=list)  # missions and map files, report.json and plan.png aside
    kept: list[Path] = field(default_factory=list)  # an earlier plan's files, changed since: not removed
    overlap: OverlapMeasure | None = None  # what the planned photos achieve (None: no missions)

    @property
    def success(self) -> bool:
        return bool(self.record.success)


def grid_ground(gmap: GridMap, uavs: int, frame: GridFrame | None, mission: Mapping[str, Any] | None = None,
                safety: Mapping[str, Any] | None = None, **ground: Any) -> PlanGround:
    """`gmap` flown from its first `uavs` launch cells; with a frame, the mission and safety settings as
    `plan` makes them (`mission`: mission_settings' keywords, `safety`: safety_settings'; unset ones take
    plan's defaults). `ground`: PlanGround's other fields."""
    starts = launch_cells(gmap, uavs)
    settings = safety_checked = None
    if frame is not None:
        settings = mission_settings(gmap, **(mission or {}))
        safety_checked = safety_settings(gmap, settings.altitude_m, **(safety or {}))
    return PlanGround(gmap, starts, frame, settings, safety_checked, **ground)


def shipped_ground(name: str, uavs: int) -> PlanGround:
    """A shipped map (or a .map file) from its first `uavs` launch cells, with `plan`'s default settings."""
    gmap = load_shipped(name)
    return grid_ground(gmap, uavs, shipped_frame(gmap))


def _cell_mask(shape: tuple[int, int], cells: Sequence[tuple[int, int]]) -> np.ndarray:
    """A boolean grid that is True on `cells` ((row, col) pairs of the plan record)."""
    mask = np.zeros(shape, dtype=bool)
    if cells:
        rows, cols = np.asarray(cells, dtype=int).T
        mask[rows, cols] = True
    return mask


STAGING_PREFIX = ".plan-staging-"  # the hidden folder inside --out a plan is written into before it is renamed
# What fly writes into a folder it flies (missionplan/flight/: the journal, the judged record, the geotags)
# besides the survey's ledger; any of them, or a file named flight.*, means the folder holds a flight.
FLIGHT_RECORD_FILES = ("missed.geojson",)


def flight_record(out: Path) -> list[str]:
    """The names of the files in `out` that say a flight was flown or judged there: the journal, the ledger
    and flight.json first, then the rest by name (empty when none, or when `out` is no folder)."""
    from ..flight.geotag import GEOTAG_FILES
    from ..flight.journal_db import COUNTER_NAME, JOURNAL_NAME
    from ..flight.ledger import LEDGER_NAME

    first = [JOURNAL_NAME, LEDGER_NAME, "flight.json"]
    names = {*first, f"{JOURNAL_NAME}-wal", COUNTER_NAME, *GEOTAG_FILES, *FLIGHT_RECORD_FILES}
    try:
        found = [p.name for p in out.iterdir() if p.name in names or p.name.startswith("flight.")]
    except OSError:  # no folder yet (or none to read): nothing flown there
        return []
    return sorted(found, key=lambda name: (first.index(name) if name in first else len(first), name))


def _new_folder_like(out: Path) -> Path:
    """A sibling of `out` that does not exist yet: out-2, out-3, ..."""
    k = 2
    while (candidate := out.with_name(f"{out.name}-{k}")).exists():
        k += 1
    return candidate


def check_out_folder(out: Path) -> None:
    """MapError when `out` may not take a plan: the root folder, the user's home, or a folder that holds a
    survey's record: a flight's (its journal, fly's record) or the survey's ledger, which `status` and
    `replan` open too (a plan there would replace the plan that record belongs to: the grid its cells mean,
    the plan its flights were judged against)."""
    where = out.resolve()
    if where == Path(where.anchor):
        raise PlanFolderError(Named("{out} {0}: the root folder is no plan folder (a plan writes and replaces files in "
                             "{out}); give a folder of its own, e.g. {out} {1}", out, where / "survey-1"))
    try:
        home: Path | None = Path.home().resolve()
    except (RuntimeError, KeyError):  # no HOME and no password entry: no home folder to protect
        home = None
    if where == home:
        raise PlanFolderError(Named("{out} {0}: your home folder is no plan folder (a plan writes and replaces files in "
                             "{out}); give a folder of its own, e.g. {out} {1}", out, where / "survey-1"))
    flown = flight_record(out)
    if flown:
        shown = ", ".join(flown[:3]) + (f" and {len(flown) - 3} more" if len(flown) > 3 else "")
        raise PlanFolderError(Named("{out} {0}: holds a survey's record ({1}): a plan here would replace the plan it "
                             "belongs to; plan into a new folder, e.g. {out} {2}", out, shown, _new_folder_like(out)))


def _make_folder(out: Path) -> Path | None:
    """Create `out` if missing and check that it takes files; the outermost folder this made (None: none)."""
    made = next((p for p in reversed([out, *out.parents]) if not p.exists()), None)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise PlanFolderError(Named("{out} {0}: cannot create folder ({1})", out, err.strerror)) from None
    try:
        probe_writable(out)
    except OSError as err:
        _remove_made(out, made)
        raise PlanFolderError(Named("{out} {0}: cannot write files there ({1})", out, err.strerror)) from None
    return made


def _remove_made(out: Path, made: Path | None) -> None:
    """Remove the folders _make_folder made, from `out` up to `made`, each only when empty."""
    if made is None:
        return
    for folder in [out, *out.parents]:
        try:
            folder.rmdir()
        except OSError:
            return  # not empty: something else is in it, which is not ours to remove
        if folder == made:
            return


def write_plan_folder(out: Path, ground: PlanGround, options: PlanOptions = PlanOptions()) -> PlanFolder:
    """Plan `ground` and write the plan folder `out` (created if missing); see the module docstring."""
    out = Path(out)
    if ground.safety is not None:  # a launch point inside the clearance band fails here, before any folder
        from ..mission.clearance import flight_map

        flight_map(ground.gmap, ground.safety.clearance_m, ground.uavs)
    policy = make_policy(options.policy, options.weights)
    check_out_folder(out)
    made = _make_folder(out)
    try:
        with hold_folder(out):
            check_out_folder(out)  # again, held: no fly can have started here since
            return _plan_into(out, ground, options, policy)
    except BaseException:
        _remove_made(out, made)
        raise


def _plan_into(out: Path, ground: PlanGround, options: PlanOptions, policy: Any) -> PlanFolder:
    """Plan, write every file into a staging folder inside `out`, then rename them into place."""
    from ..mission.plot import draw_plan  # matplotlib only when a picture is drawn
    from ..mission.report import build_report

    from .field_plan import plan_field
    from ..mission.coverage_check import coverage_report, unreachable_causes

    gmap, frame, settings, safety, unknown = ground.gmap, ground.frame, ground.settings, ground.safety, ground.unknown
    # Clearance band, band detours, flight plans, sorties, separation, geofences (missionplan/planning/field_plan.py).
    terrain = ground.terrain
    field_plan = plan_field(gmap, ground.uavs, frame, settings, safety, balance_zones=options.balance_zones,
                            ground=terrain.height_amsl if terrain is not None else None,
                            policy=policy, zone_method=options.zones, seed=options.seed, progress=options.progress,
                            lanes=options.open_ground == "lanes", lane_spacing=options.lane_spacing_cells,
                            overlap_fill=options.overlap_fill, side_overlap=ground.asked_side_overlap,
                            improve_s=options.improve_s, improve_rounds=options.improve_rounds)
    result, plans = field_plan.result, field_plan.plans
    if plans is not None and options.drone_ids is not None:
        plans.relabel(options.drone_ids)
    record = field_plan.fill_record(build_report(result, options.seed), gmap, frame)
    if settings is not None and safety is not None:  # what `replan` plans the rest of the survey with
        record = replace(record, settings=PlanSettings(settings, safety, options.policy, options.zones,
                                                       options.balance_zones, options.open_ground,
                                                       options.lane_spacing_cells, options.overlap_fill))
    record = replace(record, drone_ids=None if options.drone_ids is None else tuple(options.drone_ids),
                     survey=options.survey,
                     basemap=options.basemap or None,  # flight.html draws the same tiles
                     # the map data's credit, for every picture and page drawn from it
                     credit=gmap.meta.get("credit") or None)
    staging = _staging_folder(out)
    try:
        written: list[Path] = []
        sortie_starts = None
        if plans is not None and frame is not None and settings is not None:
            from missionplan.bridge.formats.mission_items import Flavour

            from ..mission.flightplan import write_flight_files

            terrain_block = None
            if terrain is not None:  # the ground it was planned over, kept beside it (geo/dem_copy.py)
                from missionplan.geo.dem_copy import write_ground_copy

                from .terrain import terrain_record

                copies = write_ground_copy(terrain, staging)
                written += copies
                terrain_block = terrain_record(terrain, [p.name for p in copies], frame, gmap, plans.terrain_spacing)
            record = replace(record, georeference=Georeference(frame, settings.altitude_m,
                                                               trigger_distance_m=settings.trigger_distance_m,
                                                               terrain=terrain_block, capture=ground.capture))
            written += write_flight_files(staging, plans, Flavour(settings.autopilot))
            sortie_starts = plans.sortie_starts
        unreachable_mask = _cell_mask(gmap.shape, record.unreachable_cells)
        clearance_m = float(record.clearance.required_m or 0.0) if record.clearance is not None else 0.0
        # Why each unreachable target is unreachable: the warnings count them, the pictures colour them.
        osm = ground.from_osm
        crossed = (unknown.if_overflown() if osm and unknown.if_overflown is not None and unreachable_mask.any()
                   else None)
        causes = unreachable_causes(gmap, ground.starts, unreachable_mask, clearance_m, crossed)
        coverage = coverage_report(
            gmap, ground.starts, record.targets, record.unreachable, record.metrics.coverage,
            list(record.zone_sizes), unknown_buildings=unknown.buildings if osm else None,
            total_buildings=unknown.total if osm else None, assumed_height_m=unknown.assumed_m,
            if_overflown=unknown.if_overflown, launch_labels=ground.launch_labels, unreachable_mask=unreachable_mask,
            clearance_m=clearance_m, causes=causes)
        if ground.sources is not None:  # each file an --area plan read; its warning (what they left out) first
            record = replace(record, inputs=tuple(ground.sources.inputs))
            coverage = coverage.warned_first(ground.sources.warnings)
        overlap = None
        if plans is not None and frame is not None:  # measured from where the missions take their photos
            side = ground.asked_side_overlap
            overlap = plans.overlap(frame, np.argwhere(gmap.target & ~unreachable_mask), side,
                                    flyable=~gmap.obstacle)
            if side is not None:
                coverage = replace(coverage, overlap=overlap)
        record = replace(record, coverage=coverage)
        if ground.targets != DEFAULT_TARGETS:
            record = replace(record, roofs=_roof_targets(ground, field_plan, unreachable_mask))
        paths_latlon = None
        if plans is not None and frame is not None:
            from ..mission.layers import drone_paths_latlon, plan_layers, plan_summary
            from ..mission.mapfiles import write_map_files

            layers = plan_layers(result, frame, plans, gmap, band=field_plan.band, causes=causes,
                                 sources=ground.sources, launch_labels=ground.launch_labels)
            written += write_map_files(staging, "plan", layers, plan_summary(record, layers), basemap=options.basemap)
            paths_latlon = drone_paths_latlon(layers)
        draw_plan(result, staging / "plan.png", sortie_starts=sortie_starts, frame=frame, paths_latlon=paths_latlon,
                  obstacle=gmap.obstacle, band=field_plan.band, unreachable_causes=causes,
                  ground=terrain.height_amsl if terrain is not None else None)
        files = sorted({p.name for p in written} | {REPORT_NAME, "plan.png"})
        record = replace(record, files=tuple(files), files_sha256=_sha256_of(staging, files))
        write_plan_record(record, report_path(staging))  # in staging: it goes into place last
        kept = _into_place(staging, out, files)
    except OSError as err:
        raise _write_failed(out, err) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return PlanFolder(out, ground, options, record, [out / p.name for p in written], kept, overlap)


def _roof_targets(ground: PlanGround, field_plan: Any, unreachable: np.ndarray) -> Any:
    """report.json `roofs` (mission/roof_targets.py): coverage per class from the plan's grid paths, the cell
    rule, and the vertical clearance over the buildings along every leg (an --area plan's, which have heights)."""
    from ..mission.clearance import footprint_union
    from ..mission.roof_targets import class_coverage, roof_targets_block, vertical_clearance

    gmap, plans, frame = ground.gmap, field_plan.plans, ground.frame
    covered = footprint_union(field_plan.result.run.paths, gmap.shape)
    by_class = class_coverage(gmap, gmap.target & ~unreachable, covered, ground.targets)
    sources, settings = ground.sources, ground.settings
    vertical = None
    if sources is not None and plans is not None and frame is not None and gmap.georef is not None:
        altitudes = [plans.settings.altitude_of(k) for k in range(len(plans.sortie_routes))]
        vertical = vertical_clearance(plans.sortie_routes, altitudes, frame, sources.buildings,
                                      float(gmap.georef.safety_margin_m or 0.0))
    altitude = settings.altitude_m if settings is not None else None
    return roof_targets_block(gmap, ground.targets, altitude, sources.highest_roof_m if sources is not None else None,
                              by_class, vertical, ground.asked_gsd_cm)


def _staging_folder(out: Path) -> Path:
    try:
        return Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
    except OSError as err:
        raise PlanFolderError(Named("{out} {0}: cannot write files there ({1})", out, err.strerror)) from None


def _sha256_of(staging: Path, names: list[str]) -> dict[str, str]:
    """Each staged file's sha256, report.json aside (a later plan removes a stale file only if it still matches)."""
    from ..mission.outputs import file_sha256

    return {name: file_sha256(staging / name) for name in names if name != "report.json"}


class _Committing(OSError):
    """A staged file that could not be renamed into place: part of the new plan is in the folder."""


def _into_place(staging: Path, out: Path, names: list[str]) -> list[Path]:
    """Rename the staged files into `out`, then remove the earlier plan's stale files (outputs.py) and put
    report.json in place last; the earlier plan's files kept because they changed since it wrote them."""
    from ..mission.outputs import remove_stale_outputs

    try:
        for name in names:
            if name != "report.json":
                os.replace(staging / name, out / name)
        stale = remove_stale_outputs(out, keep=names)  # reads the earlier report.json, still in place
        os.replace(staging / "report.json", out / "report.json")
    except OSError as err:
        raise _Committing(err.errno, err.strerror, err.filename) from None
    return stale.kept


def _write_failed(out: Path, err: OSError) -> PlanFolderError:
    """One line naming the folder, the file and the cause of a failed write."""
    name = Path(err.filename).name if err.filename else "the plan's files"
    cause = err.strerror or str(err)
    if isinstance(err, _Committing):
        return PlanFolderError(Named("{out} {0}: cannot put {1} in place ({2}); the folder holds part of the new plan: plan "
                              "again once the cause is fixed", out, name, cause))
    return PlanFolderError(Named("{out} {0}: cannot write {1} ({2}); nothing of this plan was kept, and the folder's "
                          "earlier files are as they were", out, name, cause))
