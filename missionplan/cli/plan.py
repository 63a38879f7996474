"""`missionplan maps` (the shipped maps) and `missionplan plan` (plan full coverage of a shipped map, a .map
file or an area drawn to a grid, and write the plan folder: report.json, plan.png, the missions).

plan's numeric options are checked before any file is read (docs/cli.md has the table and the reasons); the
planning is plan_folder.write_plan_folder's, printed as plan_display prints it."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.formats.gimbal import GIMBAL_PITCH_RANGE, NADIR_PITCH_DEG
from missionplan.bridge.limits import SEED_MAX, check_integer, check_range
from missionplan.bridge.terminal_text import printable

from ..grid.lanes import MAX_OBSTACLE_SHARE
from ..grid.zones import DEFAULT_ZONE_METHOD, ZONE_METHODS
from ..maps.catalog import load_shipped, shipped_map_names
from ..maps.gridmap import MapError
from ..mission.drone_missions import DEFAULT_OVERLAP, DEFAULT_SPEED_M_S, END_ACTIONS
from ..mission.georef import AreaRequest
from ..mission.safety import DEFAULT_CLEARANCE_M
from ..mission.separation import DEFAULT_MAX_ALTITUDE_M
from ..mission.sorties import DEFAULT_ENDURANCE_MIN, DEFAULT_RESERVE
from ..planning.pipeline import DEFAULT_POLICY, POLICIES
from .plan_display import EXIT_FAILED, print_plan
from ..planning.plan_folder import NO_UNKNOWN_HEIGHTS, PlanGround, PlanOptions, grid_ground, write_plan_folder
from .parsing import runs

MAX_PLAN_ALTITUDE_M = 5_000.0  # above launch: beyond any survey multirotor's ceiling (the legal one is 120 m)


@dataclass(frozen=True)
class MapsRequest:
    """`maps` takes no arguments."""


@dataclass(frozen=True)
class PlanRequest:
    """`plan`: what to plan (a map, or an area with its launch points, camera and buildings), the missions'
    and the safety settings, the planner's options and the output folder."""

    map: str | None
    area: Path | None
    uavs: int | None
    obstacles: tuple[Path, ...]
    dem: tuple[Path, ...]
    osm: Path | None
    height_field: str | None
    unknown_building_height: float | None
    launch: tuple[str, ...]
    altitude: float | None
    fov: float | None
    sensor_width: float | None
    sensor_height: float | None
    focal_length: float | None
    rotation: float
    speed: float
    overlap: float
    end: str
    altitude_step: float
    min_separation: float | None
    max_altitude: float
    clearance: float | None
    endurance: float
    reserve: float
    autopilot: str
    gimbal_pitch: float
    out: Path
    basemap: str | None
    policy: str
    weights: Path | None
    zones: str
    no_balance: bool
    open_ground: str
    seed: int
    quiet: bool

    def area_request(self) -> AreaRequest:
        """What the area grid is drawn from (with --area)."""
        assert self.area is not None
        return AreaRequest(area=self.area, launch=self.launch, altitude=self.altitude, fov=self.fov,
                          sensor_width=self.sensor_width, sensor_height=self.sensor_height,
                          focal_length=self.focal_length, rotation=self.rotation, obstacles=self.obstacles,
                          osm=self.osm, height_field=self.height_field,
                          unknown_building_height=self.unknown_building_height)


def register(sub: Any) -> None:
    """Add `maps` and `plan`."""
    maps = sub.add_parser("maps", help="list the shipped maps")
    maps.set_defaults(handler=runs(MapsRequest, cmd_maps))
    plan = sub.add_parser("plan", help="plan full coverage of a map and write report.json and plan.png")
    source = plan.add_mutually_exclusive_group(required=True)
    source.add_argument("--map", help="a shipped map name (see `missionplan maps`) or a .map file")
    source.add_argument("--area", type=Path, help="the area to photograph: GeoJSON, KML / KMZ, GeoPackage, Shapefile "
                        "(.shp or .zip), FlatGeobuf, GML or a QGroundControl .plan; FILE:LAYER for one layer of several")
    plan.add_argument("--uavs", type=int,
                      help="number of drones (with --map: the map's first N launch cells; with --area: one per --launch)")
    plan.add_argument("--obstacles", type=Path, action="append", default=[],
                      help="obstacle / no-fly polygons, any --area format (a .plan: its geofence exclusions), repeatable")
    plan.add_argument("--osm", type=Path, help="building footprints: OpenStreetMap .osm / .osm.pbf, or any --area "
                      "format with height, building:height or building:levels (3 m a level)")
    plan.add_argument("--height-field", metavar="NAME",
                      help="the --osm field (or OSM tag) holding each building's height in metres, read before "
                           "height, building:height and building:levels")
    plan.add_argument("--unknown-building-height", type=float, metavar="M",
                      help="height in metres of --osm buildings without height or building:levels "
                           "(default: unknown, so they are obstacles)")
    plan.add_argument("--launch", action="append", default=[], metavar="LAT,LON",
                      help="a launch point, one per drone (with --area; -33.86,151.21 works after a space)")
    plan.add_argument("--altitude", type=float, help="flight height above the launch points, metres (with --area); "
                      "with --dem, above the ground under the drone")
    plan.add_argument("--dem", type=Path, action="append", default=[], metavar="FILE",
                      help="the ground's heights above sea level: a GeoTIFF, SRTM .hgt tiles or any raster GDAL reads, "
                           "or a folder of tiles (repeatable); heights then hold above the ground (docs/terrain.md)")
    plan.add_argument("--fov", type=float, help="camera field of view, degrees")
    plan.add_argument("--sensor-width", type=float, help="sensor width, mm (with --sensor-height and --focal-length)")
    plan.add_argument("--sensor-height", type=float, help="sensor height, mm")
    plan.add_argument("--focal-length", type=float, help="focal length, mm")
    plan.add_argument("--rotation", type=float, default=0.0, help="grid rotation, degrees clockwise from north")
    plan.add_argument("--speed", type=float, default=DEFAULT_SPEED_M_S, help="cruise speed, m/s")
    plan.add_argument("--overlap", type=float, default=DEFAULT_OVERLAP,
                      help="frontal overlap of consecutive photos, 0..1 (sets the camera trigger distance)")
    plan.add_argument("--end", choices=END_ACTIONS, default="rtl", help="after the survey: return to launch or land")
    plan.add_argument("--altitude-step", type=float, default=0.0,
                      help="drone k flies this many metres above drone k-1 (layers go up from --altitude)")
    plan.add_argument("--min-separation", type=float, metavar="M",
                      help="closest two drones may come, 3-D metres, over the whole flight (default: the map's "
                           "min_separation_m, else 5); altitude layers are added when needed")
    plan.add_argument("--max-altitude", type=float, default=DEFAULT_MAX_ALTITUDE_M, metavar="M",
                      help=f"no altitude layer above this (default {DEFAULT_MAX_ALTITUDE_M:g} m)")
    plan.add_argument("--clearance", type=float, metavar="M",
                      help="horizontal margin of the tracks from obstacles (default: the map's clearance_m, "
                           f"else the larger of {DEFAULT_CLEARANCE_M:g} m and one cell)")
    plan.add_argument("--endurance", type=float, default=DEFAULT_ENDURANCE_MIN, metavar="MIN",
                      help=f"usable flight minutes per battery; longer routes fly in sorties (default "
                           f"{DEFAULT_ENDURANCE_MIN:g}; 0: no limit)")
    plan.add_argument("--reserve", type=float, default=DEFAULT_RESERVE, metavar="F",
                      help=f"fraction of the endurance kept for landing (default {DEFAULT_RESERVE:g})")
    plan.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot",
                      help="the vehicles' autopilot: the .plan firmwareType that upload / fly check (default "
                           "ardupilot; px4 writes no .waypoints, see docs/px4-missions.md)")
    plan.add_argument("--gimbal-pitch", type=float, default=NADIR_PITCH_DEG, metavar="DEG",
                      help=f"where every mission points the camera before its first photo, {GIMBAL_PITCH_RANGE[0]:g} "
                           f"(straight down, the default) to {GIMBAL_PITCH_RANGE[1]:g} (level) degrees "
                           "(docs/capture.md, Gimbal)")
    plan.add_argument("--out", required=True, type=Path, help="output folder (created if missing)")
    plan.add_argument("--basemap", metavar="URL",
                      help="plan.html draws map tiles from this tile server (e.g. "
                           "https://tile.openstreetmap.org/{z}/{x}/{y}.png); without it the page needs no network")
    plan.add_argument("--policy", default=DEFAULT_POLICY, choices=POLICIES,
                      help="who decides moves in view of targets: the neural network (nn) or the expert it imitates")
    plan.add_argument("--weights", type=Path, help="network weights for --policy nn (default: the shipped ones)")
    plan.add_argument("--zones", default=DEFAULT_ZONE_METHOD, choices=ZONE_METHODS, help="zone distance")
    plan.add_argument("--no-balance", action="store_true",
                      help="plain Lloyd/Voronoi zones, without equalising their sizes")
    plan.add_argument("--open-ground", choices=("lanes", "explore"), default="lanes",
                      help=f"a drone whose zone lies on open ground (at most {100 * MAX_OBSTACLE_SHARE:g} %% of the box "
                           "around it blocked, e.g. buildings low enough to fly over with a few tall ones) sweeps "
                           "it in footprint-wide lanes, or explores it cell by cell (default lanes)")
    plan.add_argument("--seed", type=int, default=0, help="seed for zones and deadlock breaking")
    plan.add_argument("--quiet", action="store_true", help="no progress bar")
    plan.set_defaults(handler=runs(PlanRequest, cmd_plan))


def cmd_maps(request: MapsRequest) -> int:
    print(f"{'name':<12} {'rows x cols':>11} {'targets':>8} {'launch':>6}  title")
    for name in shipped_map_names():
        gmap = load_shipped(name)
        rows, cols = gmap.shape
        print(f"{printable(name):<12} {f'{rows} x {cols}':>11} {int(gmap.target.sum()):>8} {len(gmap.launch):>6}  "
              f"{printable(gmap.meta.get('title', ''))}")
    return 0


def _plan_ground(request: PlanRequest) -> PlanGround:
    """What `plan` is asked to plan: a shipped map or .map file (--map), or an area drawn to a grid (--area)."""
    from ..mission.georef import load_area_checked, shipped_frame

    if request.area is not None:
        gmap, frame, unknown, sources = load_area_checked(request.area_request())
        uavs = len(gmap.launch) if request.uavs is None else request.uavs
    else:
        if request.uavs is None:
            raise MapError("--uavs is required with --map")
        if request.unknown_building_height is not None:
            raise MapError("--unknown-building-height is for --area with --osm; a map's grid is already drawn")
        assert request.map is not None  # argparse: --map or --area
        gmap = load_shipped(request.map)
        uavs = request.uavs
        frame, unknown, sources = shipped_frame(gmap), NO_UNKNOWN_HEIGHTS, None
    mission = {"speed": request.speed, "overlap": request.overlap, "end": request.end,
               "altitude_step": request.altitude_step, "altitude": request.altitude, "autopilot": request.autopilot,
               "gimbal_pitch": request.gimbal_pitch}
    safety = {"min_separation": request.min_separation, "max_altitude": request.max_altitude,
              "clearance": request.clearance, "endurance": request.endurance, "reserve": request.reserve}
    ground = grid_ground(gmap, uavs, frame, mission, safety, unknown=unknown, sources=sources,
                         from_osm=request.area is not None and request.osm is not None,
                         launch_labels=list(request.launch[:uavs]) if request.area is not None else None)
    if request.dem:
        if frame is None:
            raise MapError(f"--dem needs a plan on the Earth: {printable(gmap.name)} has no origin (use --area, "
                           "or a map with origin_lat / origin_lon)")
        from ..planning.terrain import DEM_MARGIN_M, plan_terrain, reach_m

        ground.terrain = plan_terrain(request.dem, frame, gmap, ground.starts)
        reached = reach_m(ground.terrain, frame)
        if request.autopilot == "ardupilot" and reached < DEM_MARGIN_M:
            print(f"missionplan: warning: the DEM reaches only {reached / 1000:.2f} km beyond the area all round; "
                  f"ArduPilot asks its ground station for terrain up to {DEM_MARGIN_M / 1000:g} km beyond its track "
                  "and arms only once it has it all: `fly` will say where the ground ends (a larger DEM avoids it)",
                  file=sys.stderr)
    return ground


def _check_plan_numbers(request: PlanRequest) -> None:
    """plan's numeric options, each finite and within its range (docs/cli.md has the table and the reasons),
    before any file is read: a `--rotation 1e308` is refused, not stored."""
    def check(name: str, value: float | None, low: float, high: float, unit: str = "", **how: Any) -> None:
        if value is not None:
            check_range(value, name, low, high, unit=unit, error=MapError, **how)

    if request.uavs is not None:  # each drone is a MAVLink vehicle: system ids 1..254
        check_integer(request.uavs, "--uavs", 1, 254, what="a number of drones", error=MapError)
    check("--altitude", request.altitude, 0.0, MAX_PLAN_ALTITUDE_M, " m", low_open=True, what="metres above launch")
    check("--fov", request.fov, 0.0, 180.0, " degrees", low_open=True, high_open=True)
    check("--sensor-width", request.sensor_width, 0.0, 100.0, " mm", low_open=True)
    check("--sensor-height", request.sensor_height, 0.0, 100.0, " mm", low_open=True)
    check("--focal-length", request.focal_length, 0.0, 2_000.0, " mm", low_open=True)
    check("--rotation", request.rotation, -360.0, 360.0, " degrees", what="a grid angle")
    check("--speed", request.speed, 0.0, 100.0, " m/s", low_open=True)
    check("--overlap", request.overlap, 0.0, 1.0, high_open=True, what="a fraction")
    check("--gimbal-pitch", request.gimbal_pitch, *GIMBAL_PITCH_RANGE, " degrees", what="a gimbal pitch (-90 straight down)")
    check("--altitude-step", request.altitude_step, 0.0, MAX_PLAN_ALTITUDE_M, " m")
    check("--min-separation", request.min_separation, 0.0, 1_000.0, " m", low_open=True)
    check("--max-altitude", request.max_altitude, 0.0, MAX_PLAN_ALTITUDE_M, " m", low_open=True)
    check("--clearance", request.clearance, 0.0, 1_000.0, " m")
    check("--endurance", request.endurance, 0.0, 1_440.0, " minutes", what="0 (no limit) or minutes")
    check("--reserve", request.reserve, 0.0, 1.0, high_open=True, what="a fraction")
    check("--unknown-building-height", request.unknown_building_height, 0.0, 1_000.0, " m", what="a height in metres")
    check_integer(request.seed, "--seed", 0, SEED_MAX, error=MapError)


def cmd_plan(request: PlanRequest) -> int:
    _check_plan_numbers(request)
    options = PlanOptions(policy=request.policy, weights=request.weights, zones=request.zones,
                          balance_zones=not request.no_balance, open_ground=request.open_ground, seed=request.seed,
                          basemap=request.basemap, progress=not request.quiet and sys.stderr.isatty())
    folder = write_plan_folder(request.out, _plan_ground(request), options)
    print_plan(folder)
    return 0 if folder.success else EXIT_FAILED
