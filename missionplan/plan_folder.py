"""Plan a map and write its plan folder: the library call behind `plan`, `replan` and `demo`.

`write_plan_folder(out, ground, options)` plans the ground (missionplan/fieldplan.py: zones, the
drones' paths, the clearance band, flight plans, sorties, separation, geofences) and writes the folder:
report.json, plan.png, one mission per drone (.plan, .waypoints) and the map files (plan.html,
plan.gpkg, plan.kmz, GeoJSON), each written whole or not at all; files of an earlier plan in the same
folder that this plan does not write are removed. It prints nothing: the caller prints the returned
`PlanFolder` (missionplan/plan_display.py).

`PlanGround` is what is planned (the grid, its georeference, the mission and safety settings, the
launch cells: `grid_ground` makes it as `plan` does); `PlanOptions` is how (policy, zones, seed,
basemap). Every input that can be wrong fails with MapError before the folder is made.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np

from missionplan.bridge.atomic import probe_writable
from missionplan.geo.frame import GridFrame

from .grid.zones import DEFAULT_ZONE_METHOD
from .maps.catalog import load_shipped
from .maps.gridmap import GridMap, MapError
from .mission.georef import AreaSources, UnknownHeights, mission_settings, shipped_frame
from .mission.drone_missions import MissionSettings
from .mission.safety import SafetySettings, safety_settings
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
    seed: int = 0
    basemap: str | None = None  # tile server URL drawn under plan.html and flight.html
    progress: bool = False  # a progress bar on stderr while planning
    drone_ids: list[int] | None = None  # system id of each drone, in launch order (default 1, 2, ...)
    survey: dict[str, Any] | None = None  # report.json `survey`: a re-plan's pointer to the survey it continues

    def __post_init__(self) -> None:
        # A basemap URL that is no tile server's fails here, before any area is read or folder made.
        if self.basemap is not None:
            from .mission.webmap import basemap_problem

            if (problem := basemap_problem(self.basemap)) is not None:
                raise MapError(f"--basemap {self.basemap}: {problem}")


@dataclass
class PlanFolder:
    """A written plan folder: its report (as report.json holds it) and every file written."""

    out: Path
    ground: PlanGround
    options: PlanOptions
    report: dict[str, Any]
    written: list[Path] = field(default_factory=list)  # missions and map files, report.json and plan.png aside

    @property
    def success(self) -> bool:
        return bool(self.report["success"])


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


def _cell_mask(shape: tuple[int, int], cells: list[list[int]]) -> np.ndarray:
    """A boolean grid that is True on `cells` ([row, col] pairs from report.json)."""
    mask = np.zeros(shape, dtype=bool)
    if cells:
        rows, cols = np.asarray(cells, dtype=int).T
        mask[rows, cols] = True
    return mask


def _make_folder(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise MapError(f"--out {out}: cannot create folder ({err.strerror})") from None
    try:
        probe_writable(out)
    except OSError as err:
        raise MapError(f"--out {out}: cannot write files there ({err.strerror})") from None


def write_plan_folder(out: Path, ground: PlanGround, options: PlanOptions = PlanOptions()) -> PlanFolder:
    """Plan `ground` and write the plan folder `out` (created if missing); see the module docstring."""
    from .mission.plot import draw_plan  # matplotlib only when a picture is drawn
    from .mission.report import build_report, write_report

    from .fieldplan import plan_field
    from .mission.coverage_check import coverage_report, unreachable_causes
    from .mission.outputs import remove_stale_outputs

    gmap, frame, settings, safety, unknown = ground.gmap, ground.frame, ground.settings, ground.safety, ground.unknown
    if safety is not None:  # a launch point inside the clearance band fails here, before any folder
        from .mission.clearance import flight_map

        flight_map(gmap, safety.clearance_m, ground.uavs)
    policy = make_policy(options.policy, options.weights)
    _make_folder(out)
    # Clearance band, band detours, flight plans, sorties, separation, geofences (missionplan/fieldplan.py).
    field_plan = plan_field(gmap, ground.uavs, frame, settings, safety, balance_zones=options.balance_zones,
                            policy=policy, zone_method=options.zones, seed=options.seed, progress=options.progress,
                            lanes=options.open_ground == "lanes")
    result, plans = field_plan.result, field_plan.plans
    if plans is not None and options.drone_ids is not None:
        plans.relabel(options.drone_ids)
    report = build_report(result, options.seed)
    field_plan.fill_report(report, gmap, frame)
    if settings is not None and safety is not None:  # what `replan` plans the rest of the survey with
        report["settings"] = {"mission": dataclasses.asdict(settings), "safety": dataclasses.asdict(safety),
                              "policy": options.policy, "zones": options.zones,
                              "balance_zones": options.balance_zones, "open_ground": options.open_ground}
    if options.drone_ids is not None:
        report["drone_ids"] = list(options.drone_ids)
    if options.survey is not None:
        report["survey"] = options.survey
    if options.basemap:  # flight.html draws the same tiles
        report["basemap"] = options.basemap
    if gmap.meta.get("credit"):  # the map data's credit, for every picture and page drawn from it
        report["credit"] = gmap.meta["credit"]
    written: list[Path] = []
    sortie_starts = None
    if plans is not None and frame is not None and settings is not None:
        from missionplan.bridge.formats.mission_items import Flavour

        from .mission.flightplan import write_flight_files

        report["georeference"] = {**frame.to_meta(), "altitude_m": settings.altitude_m,
                                  "footprint_m": settings.footprint_m, "trigger_distance_m": settings.trigger_distance_m}
        written = write_flight_files(out, plans, Flavour(settings.autopilot))
        sortie_starts = plans.sortie_starts
    unreachable_mask = _cell_mask(gmap.shape, report["unreachable_cells"])
    clearance_m = float(report.get("clearance", {}).get("required_m") or 0.0)
    # Why each unreachable target is unreachable: the warnings count them, the pictures colour them.
    osm = ground.from_osm
    crossed = unknown.if_overflown() if osm and unknown.if_overflown is not None and unreachable_mask.any() else None
    causes = unreachable_causes(gmap, ground.starts, unreachable_mask, clearance_m, crossed)
    report["coverage"] = coverage_report(
        gmap, ground.starts, report["targets"], report["unreachable"], report["metrics"]["coverage"],
        report["zone_sizes"], unknown_buildings=unknown.buildings if osm else None,
        total_buildings=unknown.total if osm else None, assumed_height_m=unknown.assumed_m,
        if_overflown=unknown.if_overflown, launch_labels=ground.launch_labels, unreachable_mask=unreachable_mask,
        clearance_m=clearance_m, causes=causes)
    if ground.sources is not None:  # each file an --area plan read; its warning (what they left out) first
        report["inputs"] = ground.sources.inputs
        report["coverage"]["warnings"][:0] = ground.sources.warnings
    paths_latlon = None
    if plans is not None and frame is not None:
        from .mission.layers import drone_paths_latlon, plan_layers, plan_summary
        from .mission.mapfiles import write_map_files

        layers = plan_layers(result, frame, plans, gmap, band=field_plan.band, causes=causes, sources=ground.sources,
                             launch_labels=ground.launch_labels)
        written += write_map_files(out, "plan", layers, plan_summary(report, layers), basemap=options.basemap)
        paths_latlon = drone_paths_latlon(layers)
    report["files"] = sorted({p.name for p in written} | {"report.json", "plan.png"})
    remove_stale_outputs(out, keep=report["files"])  # before the new report.json replaces the old list
    write_report(report, out / "report.json")
    draw_plan(result, out / "plan.png", sortie_starts=sortie_starts, frame=frame, paths_latlon=paths_latlon,
              obstacle=gmap.obstacle, band=field_plan.band, unreachable_causes=causes)
    return PlanFolder(out, ground, options, report, written)
