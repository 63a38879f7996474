"""`missionplan maps` (the shipped maps) and `missionplan plan` (plan full coverage of a shipped map, a .map
file or an area drawn to a grid, and write the plan folder: report.json, plan.png, the missions).

plan's numeric options are checked before any file is read (docs/cli.md has the table and the reasons); the
planning is plan_folder.write_plan_folder's, printed as plan_display prints it. The capture options (a
catalogue camera, a GSD, front / side overlaps, the image size and capture interval: docs/capture.md) become
the plan's CapturePlan (geo/capture.py): the height a GSD gives, the speed the camera keeps up with, the
lane spacing on open ground; a plan asked with none of them is planned and written as before."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from missionplan.bridge.formats.gimbal import GIMBAL_PITCH_RANGE, NADIR_PITCH_DEG
from missionplan.bridge.limits import SEED_MAX, check_integer, check_range
from missionplan.bridge.terminal_text import printable
from missionplan.geo.roofs import DEFAULT_TARGETS, TARGET_CLASSES
from missionplan.geo.camera import CELLS_PER_FOOTPRINT, Camera
from missionplan.geo.camera_catalogue import find as catalogue_camera
from missionplan.geo.capture import (GSD_NEEDS, MAX_SPEED_M_S, CapturePlan, check_height, choose_speed,
                                     choose_transit_speed, height_for_gsd, lane_spacing_cells)

from ..grid.lanes import MAX_OBSTACLE_SHARE
from ..grid.zones import DEFAULT_ZONE_METHOD, ZONE_METHODS
from ..maps.catalog import load_shipped, shipped_map_names
from ..maps.gridmap import MapError
from ..mission.drone_missions import CAPTURE_MODES, DEFAULT_OVERLAP, DEFAULT_SPEED_M_S, END_ACTIONS
from ..mission.georef import SPEED_WHAT, AreaRequest
from ..mission.safety import DEFAULT_CLEARANCE_M
from ..mission.separation import DEFAULT_MAX_ALTITUDE_M
from ..mission.sorties import DEFAULT_ENDURANCE_MIN, DEFAULT_RESERVE
from ..planning.improve import MAX_BUDGET_S
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
    gsd: float | None
    camera: str | None
    fov: float | None
    sensor_width: float | None
    sensor_height: float | None
    focal_length: float | None
    image_width: int | None
    image_height: int | None
    capture_interval: float | None
    rotation: float
    speed: float | None
    overlap: float | None
    front_overlap: float | None
    side_overlap: float | None
    end: str
    altitude_step: float
    min_separation: float | None
    max_altitude: float
    clearance: float | None
    endurance: float
    reserve: float
    autopilot: str
    capture: str
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
    targets: str = DEFAULT_TARGETS
    transit_speed: float | None = None
    overlap_fill: bool | None = None  # None: on for a plan asked by camera, GSD or overlaps (capture_asked)
    improve: float | None = None  # seconds of local search on the finished plan
    improve_rounds: int | None = None

    def area_request(self) -> AreaRequest:
        """What the area grid is drawn from (with --area); a --camera gives the sensor and focal length."""
        assert self.area is not None
        sensor = (self.sensor_width, self.sensor_height, self.focal_length)
        if self.camera is not None:
            row = catalogue_camera(self.camera)
            sensor = (row.sensor_width_mm, row.sensor_height_mm, row.focal_length_mm)
        return AreaRequest(area=self.area, launch=self.launch, altitude=self.altitude, fov=self.fov,
                          sensor_width=sensor[0], sensor_height=sensor[1], focal_length=sensor[2],
                          rotation=self.rotation, obstacles=self.obstacles, osm=self.osm,
                          height_field=self.height_field, unknown_building_height=self.unknown_building_height,
                          targets=self.targets)

    @property
    def capture_asked(self) -> bool:
        """Whether a capture option was given: then the plan records its camera block (schema version 3)."""
        return any(value is not None for value in (self.camera, self.gsd, self.front_overlap, self.side_overlap,
                                                   self.image_width, self.image_height, self.capture_interval))

    @property
    def front(self) -> float:
        """The front overlap, a fraction: --front-overlap PCT, --overlap F, or plan's default (8/9)."""
        if self.front_overlap is not None:
            return self.front_overlap / 100.0
        return self.overlap if self.overlap is not None else DEFAULT_OVERLAP

    @property
    def side(self) -> float | None:
        """The side overlap, a fraction (None: not asked, lanes one footprint apart)."""
        return None if self.side_overlap is None else self.side_overlap / 100.0


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
    plan.add_argument("--targets", choices=TARGET_CLASSES, default=DEFAULT_TARGETS,
                      help="what to photograph: the streets (default), the roofs of the buildings low enough to "
                           "overfly, or all; with roofs the cell is the footprint at the highest roof / 9 "
                           "(docs/capture.md)")
    plan.add_argument("--launch", action="append", default=[], metavar="LAT,LON",
                      help="a launch point, one per drone (with --area; -33.86,151.21 works after a space)")
    height = plan.add_mutually_exclusive_group()
    height.add_argument("--altitude", type=float, help="flight height above the launch points, metres (with --area); "
                        "with --dem, above the ground under the drone")
    height.add_argument("--gsd", type=float, metavar="CM",
                        help="ground sample distance, cm per pixel: the flight height that gives it (with --area and "
                             "a camera whose sensor, image size and focal length are known)")
    plan.add_argument("--dem", type=Path, action="append", default=[], metavar="FILE",
                      help="the ground's heights above sea level: a GeoTIFF, SRTM .hgt tiles or any raster GDAL reads, "
                           "or a folder of tiles (repeatable); heights then hold above the ground (docs/terrain.md)")
    plan.add_argument("--camera", metavar="NAME", help="a survey camera of the catalogue (`missionplan cameras`): "
                      "its sensor, image size, focal length and capture interval")
    plan.add_argument("--fov", type=float, help="camera field of view, degrees")
    plan.add_argument("--sensor-width", type=float, help="sensor width, mm (with --sensor-height and --focal-length)")
    plan.add_argument("--sensor-height", type=float, help="sensor height, mm")
    plan.add_argument("--focal-length", type=float, help="focal length, mm")
    plan.add_argument("--image-width", type=int, metavar="PX", help="image width, pixels (for the GSD)")
    plan.add_argument("--image-height", type=int, metavar="PX", help="image height, pixels (for the GSD)")
    plan.add_argument("--capture-interval", type=float, metavar="S",
                      help="the shortest time between two photos the camera takes, seconds (limits the speed)")
    plan.add_argument("--rotation", type=float, default=0.0, help="grid rotation, degrees clockwise from north")
    plan.add_argument("--speed", type=float,
                      help=f"cruise speed, m/s, at most {MAX_SPEED_M_S:g} (default {DEFAULT_SPEED_M_S:g}, or slower "
                           "when the camera's capture interval asks it)")
    plan.add_argument("--transit-speed", type=float, metavar="M/S",
                      help=f"speed of the ways out to the survey and home from it, camera off, m/s, at most "
                           f"{MAX_SPEED_M_S:g} (default: the survey's speed; with a capture option, the cruise speed "
                           f"{DEFAULT_SPEED_M_S:g} when the survey's is below it)")
    front = plan.add_mutually_exclusive_group()
    front.add_argument("--overlap", type=float,
                       help="frontal overlap of consecutive photos, 0..1 (sets the camera trigger distance; default 8/9)")
    front.add_argument("--front-overlap", type=float, metavar="PCT",
                       help="frontal overlap of consecutive photos, percent (as --overlap)")
    plan.add_argument("--side-overlap", type=float, metavar="PCT",
                      help="overlap of neighbouring lanes on open ground, percent (default: lanes one footprint "
                           "apart)")
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
    plan.add_argument("--capture", choices=CAPTURE_MODES, default="relay",
                      help="how photos are taken: relay, the autopilot's own trigger by distance (default); camera, "
                           "the same for a MAVLink camera whose CAMERA_IMAGE_CAPTURED are the capture records; "
                           "camera-interval, IMAGE_START_CAPTURE every trigger distance / speed seconds "
                           "(docs/capture.md)")
    plan.add_argument("--gimbal-pitch", type=float, default=NADIR_PITCH_DEG, metavar="DEG",
                      help=f"where every mission points the camera before its first photo, {GIMBAL_PITCH_RANGE[0]:g} "
                           f"(straight down, the default) to {GIMBAL_PITCH_RANGE[1]:g} (level) degrees "
                           "(docs/capture.md, Gimbal)")
    plan.add_argument("--overlap-fill", action=argparse.BooleanOptionalAction, default=None,
                      help="short detours where the planned photos leave a reachable target point with fewer "
                           "photos than the overlaps imply (default: on with a camera, GSD or overlap option, off "
                           "otherwise; docs/capture.md, Overlap fill)")
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
    plan.add_argument("--improve", type=float, metavar="SECONDS",
                      help="spend up to SECONDS after planning on local search (zone shares balanced on the drones' "
                           "times, work shifted to a neighbouring zone, other seeds), keeping a candidate only when "
                           "its busiest drone is done sooner: never a worse plan (docs/planner.md, Anytime improvement)")
    plan.add_argument("--improve-rounds", type=int, metavar="N",
                      help="with --improve, at most N candidate plans: the same seed and N give the same plan on "
                           "any machine")
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
        from ..mission.roof_targets import select_targets

        gmap = select_targets(load_shipped(request.map), request.targets)
        uavs = request.uavs
        frame, unknown, sources = shipped_frame(gmap), NO_UNKNOWN_HEIGHTS, None
    mission = {"speed": DEFAULT_SPEED_M_S if request.speed is None else request.speed, "overlap": request.front,
               "end": request.end,
               "altitude_step": request.altitude_step, "altitude": request.altitude, "autopilot": request.autopilot,
               "capture": request.capture, "transit_speed": request.transit_speed,
               "gimbal_pitch": request.gimbal_pitch}
    safety = {"min_separation": request.min_separation, "max_altitude": request.max_altitude,
              "clearance": request.clearance, "endurance": request.endurance, "reserve": request.reserve}
    ground = grid_ground(gmap, uavs, frame, mission, safety, unknown=unknown, sources=sources,
                         from_osm=request.area is not None and request.osm is not None,
                         launch_labels=list(request.launch[:uavs]) if request.area is not None else None,
                         targets=request.targets)
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
    check("--speed", request.speed, 0.0, MAX_SPEED_M_S, " m/s", low_open=True, what=SPEED_WHAT)
    check("--transit-speed", request.transit_speed, 0.0, MAX_SPEED_M_S, " m/s", low_open=True, what=SPEED_WHAT)
    check("--overlap", request.overlap, 0.0, 1.0, high_open=True, what="a fraction")
    check("--gsd", request.gsd, 0.0, 1_000.0, " cm/px", low_open=True)
    check("--front-overlap", request.front_overlap, 0.0, 100.0, " %", high_open=True, what="a percentage")
    check("--side-overlap", request.side_overlap, 0.0, 100.0, " %", high_open=True, what="a percentage")
    check("--capture-interval", request.capture_interval, 0.0, 3_600.0, " s", low_open=True)
    for name, pixels in (("--image-width", request.image_width), ("--image-height", request.image_height)):
        if pixels is not None:
            check_integer(pixels, name, 1, 1_000_000, what="pixels", error=MapError)
    check("--improve", request.improve, 0.0, MAX_BUDGET_S, " s", what="seconds of improvement")
    if request.improve_rounds is not None:
        if request.improve is None:
            raise MapError("--improve-rounds needs --improve SECONDS (the time it may spend)")
        check_integer(request.improve_rounds, "--improve-rounds", 1, 100_000, what="a number of plans", error=MapError)
    check("--gimbal-pitch", request.gimbal_pitch, *GIMBAL_PITCH_RANGE, " degrees", what="a gimbal pitch (-90 straight down)")
    check("--altitude-step", request.altitude_step, 0.0, MAX_PLAN_ALTITUDE_M, " m")
    check("--min-separation", request.min_separation, 0.0, 1_000.0, " m", low_open=True)
    check("--max-altitude", request.max_altitude, 0.0, MAX_PLAN_ALTITUDE_M, " m", low_open=True)
    check("--clearance", request.clearance, 0.0, 1_000.0, " m")
    check("--endurance", request.endurance, 0.0, 1_440.0, " minutes", what="0 (no limit) or minutes")
    check("--reserve", request.reserve, 0.0, 1.0, high_open=True, what="a fraction")
    check("--unknown-building-height", request.unknown_building_height, 0.0, 1_000.0, " m", what="a height in metres")
    check_integer(request.seed, "--seed", 0, SEED_MAX, error=MapError)


def _asked_camera(request: PlanRequest) -> Camera | None:
    """The camera the options describe: a catalogue one (--camera, its interval replaced by --capture-interval),
    a sensor's (--sensor-width/--sensor-height/--focal-length) or a field of view's (--fov), each with the image
    size and capture interval given; None when none is described. MapError for --camera with a description."""
    known = {"image_width_px": request.image_width, "image_height_px": request.image_height,
             "capture_interval_s": request.capture_interval}
    if request.camera is not None:
        described = [name for name, value in (("--fov", request.fov), ("--sensor-width", request.sensor_width),
                                              ("--sensor-height", request.sensor_height),
                                              ("--focal-length", request.focal_length),
                                              ("--image-width", request.image_width),
                                              ("--image-height", request.image_height)) if value is not None]
        if described:
            raise MapError(f"--camera {printable(request.camera)} describes the camera already: give --camera or "
                           f"{described[0]}, not both (--capture-interval may replace its interval)")
        camera = catalogue_camera(request.camera).camera()
        return camera if request.capture_interval is None else replace(camera,
                                                                        capture_interval_s=request.capture_interval)
    sensor = (request.sensor_width, request.sensor_height, request.focal_length)
    if request.fov is None and all(value is not None for value in sensor):
        return Camera.from_sensor(*sensor, **known)  # type: ignore[misc]
    if request.fov is not None:
        return Camera(request.fov, **known)
    return None


def _check_capture(request: PlanRequest) -> None:
    """The capture options' combinations, before any file is read: camera options only with --area (a map's grid
    fixes its footprint and height), a --gsd only from a camera whose GSD is known and under --max-altitude, a
    side overlap that leaves lanes at least a cell apart."""
    if request.area is None:
        given = [name for name, value in (("--camera", request.camera), ("--gsd", request.gsd),
                                          ("--image-width", request.image_width),
                                          ("--image-height", request.image_height)) if value is not None]
        if given:
            raise MapError(f"{given[0]} is for --area: a map's grid was drawn for its own camera and height "
                           "(--front-overlap, --side-overlap and --capture-interval work with --map)")
    lane_spacing_cells(request.side)  # refused here when the lanes would be closer than a cell
    camera = _asked_camera(request)  # --camera with a description of another is refused here
    if request.gsd is None:
        return
    known = camera.to_json() if camera is not None else {}
    missing = [(setting, unit) for key, setting, unit in GSD_NEEDS if known.get(key) is None]
    if missing:
        needs = " ".join(f"--{setting.replace('_', '-')} {unit}" for setting, unit in missing)
        raise MapError(f"--gsd needs the camera's sensor, image size and focal length: give {needs} (or --camera "
                       "NAME: `missionplan cameras` lists them)")
    assert camera is not None
    check_height(camera, request.gsd, height_for_gsd(camera, request.gsd), request.max_altitude)


def _map_camera(ground: PlanGround) -> Camera:
    """A --map plan's camera: the field of view its grid was drawn for (its header's fov_deg, else the one its
    footprint and altitude give)."""
    georef, settings = ground.gmap.georef, ground.settings
    assert settings is not None
    if georef is not None and georef.camera is not None:
        return georef.camera
    return Camera(math.degrees(2.0 * math.atan(settings.footprint_m / (2.0 * settings.altitude_m))))


def _capture_plan(request: PlanRequest, ground: PlanGround) -> CapturePlan:
    """The capture of a plan asked with capture options: the camera, the height and footprint the ground was
    drawn for, the overlaps and the speed (refused in one line when the camera cannot keep up with it)."""
    settings = ground.settings
    if settings is None:
        raise MapError(f"the capture options need a plan on the Earth: {printable(ground.gmap.name)} has no origin "
                       "(use --area, or a map with origin_lat / origin_lon)")
    camera = _asked_camera(request) if request.area is not None else None
    if camera is None:
        camera = _map_camera(ground)
        if request.capture_interval is not None:
            camera = replace(camera, capture_interval_s=request.capture_interval)
    speed, source = choose_speed(camera, settings.trigger_distance_m, request.speed)
    return CapturePlan(camera, settings.altitude_m, settings.footprint_m, request.front, request.side, speed, source,
                       request.gsd, choose_transit_speed(speed, request.transit_speed), request.gimbal_pitch)


def cmd_plan(request: PlanRequest) -> int:
    _check_plan_numbers(request)
    if request.capture_asked:
        _check_capture(request)
    if request.gsd is not None:  # the height that gives the GSD, checked under the ceiling above
        camera = _asked_camera(request)
        assert camera is not None
        request = replace(request, altitude=height_for_gsd(camera, request.gsd))
    ground = _plan_ground(request)
    lane_spacing = CELLS_PER_FOOTPRINT
    if request.capture_asked:
        ground.capture = _capture_plan(request, ground)
        assert ground.settings is not None
        ground.settings = replace(ground.settings, speed_m_s=ground.capture.speed_m_s,
                                  transit_speed_m_s=ground.capture.transit_speed_m_s)
        lane_spacing = ground.capture.lane_spacing_cells
    options = PlanOptions(policy=request.policy, weights=request.weights, zones=request.zones,
                          balance_zones=not request.no_balance, open_ground=request.open_ground,
                          lane_spacing_cells=lane_spacing, seed=request.seed,
                          basemap=request.basemap, progress=not request.quiet and sys.stderr.isatty(),
                          overlap_fill=request.capture_asked if request.overlap_fill is None else request.overlap_fill,
                          improve_s=request.improve, improve_rounds=request.improve_rounds)
    folder = write_plan_folder(request.out, ground, options)
    print_plan(folder)
    return 0 if folder.success else EXIT_FAILED
