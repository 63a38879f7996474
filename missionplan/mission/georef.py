"""Georeferenced inputs for `missionplan plan`: an area file, or a shipped map's own georeference.

Turns what the user gave (AreaRequest: the files, launch points, altitude, camera, rotation) into what the
planner needs (a GridMap and its GridFrame) and into the mission settings (altitude, footprint, speed,
overlap, end action). Checks every value first, so bad input fails with one line before any output folder
exists; the errors name each setting by what it means (missionplan.base.naming), for the front end to
spell. Records each file read (report.json `inputs`: `input_entry`) and makes the one warning line naming
what the files left out: buildings not read or repaired, buildings in the area without a height
(`inputs_warning`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import shapely

from missionplan.base.naming import Named, Setting
from missionplan.bridge.formats.gimbal import GIMBAL_PITCH_RANGE, NADIR_PITCH_DEG
from missionplan.bridge.limits import ANGLE_DEG, check_range
from missionplan.geo.area import build_grid_map
from missionplan.geo.camera import Camera
from missionplan.geo.capture import MAX_SPEED_M_S
from missionplan.geo.errors import GeoError
from missionplan.geo.frame import GridFrame
from missionplan.geo.heights import HEIGHT_FIELDS
from missionplan.geo.roofs import DEFAULT_TARGETS, check_targets
from missionplan.geo.readers import read_area_file, read_building_file, read_obstacle_file, split_layer
from missionplan.geo.sources import Building, Omission, SourceFile

from ..maps.gridmap import GridMap
from .drone_missions import DEFAULT_OVERLAP, DEFAULT_SPEED_M_S, MissionSettings
from .plan_blocks import BuildingsRead, InputFile

WARNING_NAMES = 3  # files' omissions named in the warning line before "and N more"
SPEED_WHAT = "a waypoint speed ArduCopter and PX4 fly"  # both top out at MAX_SPEED_M_S


@dataclass(frozen=True)
class AreaRequest:
    """What an area plan is drawn from, as the user gave it: the area file, the launch points (LAT,LON text,
    one per drone), the flight altitude above them (metres), the camera (a field of view in degrees, or a
    sensor's width and height and a focal length in mm), the grid's rotation (degrees clockwise from north),
    the obstacle / no-fly files, the building file with the field holding each one's height, and the height
    given to buildings that have none."""

    area: Path
    launch: tuple[str, ...]
    altitude: float | None
    fov: float | None = None
    sensor_width: float | None = None
    sensor_height: float | None = None
    focal_length: float | None = None
    rotation: float = 0.0
    obstacles: tuple[Path, ...] = ()
    osm: Path | None = None
    height_field: str | None = None
    unknown_building_height: float | None = None
    targets: str = DEFAULT_TARGETS  # which cells are photographed: streets, roofs or all (geo/roofs.py)


def parse_latlon(text: str) -> tuple[float, float]:
    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        raise GeoError(Named("{launch} {0}: expected LAT,LON in degrees, e.g. 45.0701,7.6573", text)) from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise GeoError(Named("{launch} {0}: latitude must be in [-90, 90] and longitude in [-180, 180]", text))
    return lat, lon


def _camera(request: AreaRequest) -> Camera:
    sensor = (request.sensor_width, request.sensor_height, request.focal_length)
    if request.fov is not None and any(v is not None for v in sensor):
        raise GeoError(Named("give either {fov} or {sensor_width}/{sensor_height}/{focal_length}, not both"))
    if request.fov is not None:
        return Camera(fov_deg=request.fov)
    if all(v is not None for v in sensor):
        return Camera.from_sensor(*sensor)
    raise GeoError(Named("the camera is needed: {fov} DEG, or {sensor_width} MM {sensor_height} MM {focal_length} MM"))


@dataclass
class UnknownHeights:
    """Buildings of unknown height in `--osm` and what counting them as obstacles costs.

    `if_overflown` builds the same grid with those buildings overflown (called only when the
    plan leaves many targets unreachable, to tell how many of them these buildings cut off).
    """

    buildings: int  # footprints in the area without height or building:levels
    total: int  # all footprints in the area
    assumed_m: float | None  # --unknown-building-height, when given
    if_overflown: Callable[[], GridMap] | None


@dataclass
class AreaSources:
    """What an `--area` grid was drawn from, in lon/lat: the area, the building footprints in it (with
    the heights the plan used) and the no-fly polygons (the plan's map layers draw them); each file read
    (report.json `inputs`) and the one warning naming what they left out."""

    area: Any  # shapely (Multi)Polygon
    buildings: list[Building] = field(default_factory=list)
    no_fly: list[Any] = field(default_factory=list)
    inputs: list[InputFile] = field(default_factory=list)  # input_entry of each file: area, obstacles, buildings
    warnings: list[str] = field(default_factory=list)  # inputs_warning's line, when it has one
    highest_roof_m: float | None = None  # the highest roof target, which sized the cell (None: roofs are no targets)


def load_area(request: AreaRequest) -> tuple[GridMap, GridFrame]:
    """The grid of `--area` with its obstacles, buildings and launch points."""
    gmap, frame, _, _ = load_area_checked(request)
    return gmap, frame


def load_area_checked(request: AreaRequest) -> tuple[GridMap, GridFrame, UnknownHeights, AreaSources]:
    """`load_area`, plus the buildings of unknown height and the grid without them as obstacles, and
    what the grid was drawn from."""
    if request.altitude is None:
        raise GeoError(Named("{altitude} is required with {area}"))
    if not request.launch:
        raise GeoError(Named("{area} needs at least one {launch} LAT,LON (one per drone)"))
    assumed = request.unknown_building_height
    if assumed is not None:
        if request.osm is None:
            raise GeoError(Named("{unknown_building_height} needs {osm} (the buildings it applies to)"))
        if not (math.isfinite(assumed) and assumed >= 0):
            raise GeoError(Named("{unknown_building_height} {0}: must be a height in metres, 0 or more", assumed))
    check_range(request.rotation, Setting("rotation"), *ANGLE_DEG, unit=" degrees", what="a grid angle", error=GeoError)
    check_targets(request.targets)
    camera = _camera(request)
    area, area_source = read_area_file(request.area)
    # Obstacle and no-fly files are obstacles whatever their height; OSM buildings may be overflown.
    obstacle_files = [read_obstacle_file(path) for path in request.obstacles]
    no_fly = [polygon for polygons, _ in obstacle_files for polygon in polygons]
    height_field = request.height_field
    if height_field is not None and request.osm is None:
        raise GeoError(Named("{height_field} needs {osm} (the buildings whose height it holds)"))
    buildings, building_source = (read_building_file(request.osm, height_field) if request.osm is not None
                                  else ([], None))
    # Counted in the area only: an OSM extract of a whole city is mostly buildings nowhere near it.
    inside = shapely.intersects(area, [b.geometry for b in buildings]) if buildings else []
    unknown = sum(1 for b, within in zip(buildings, inside) if within and b.height_m is None)
    in_area = int(sum(inside))
    in_area_buildings = [b for b, within in zip(buildings, inside) if within]
    inputs = [input_entry("area", area_source)] + [input_entry("obstacles", source) for _, source in obstacle_files]
    if building_source is not None:
        inputs.append(input_entry("buildings", building_source, in_area_buildings, assumed, height_field))
    if assumed is not None:
        buildings = [b if b.height_m is not None else dataclasses.replace(b, height_m=assumed) for b in buildings]
    launch = [parse_latlon(text) for text in request.launch]
    area_path = split_layer(request.area)[0]

    def build(blds: list[Building]) -> tuple[GridMap, GridFrame, float | None]:
        raster, frame = build_grid_map(area_path.stem, area, [], blds, no_fly, launch, request.altitude,
                                       camera.fov_deg, rotation_deg=request.rotation, area_file=str(request.area),
                                       targets=request.targets)
        return GridMap(raster.name, raster.obstacle, raster.target, raster.launch, georef=raster.georef,
                       roof=raster.roof), frame, raster.highest_roof_m

    gmap, frame, highest_roof = build(buildings)
    if building_source is not None and building_source.reader == "pyosmium":
        gmap.meta["credit"] = "Buildings: OpenStreetMap data © OpenStreetMap contributors (ODbL)"  # wherever shown

    def overflown() -> GridMap:
        # Height 0 m: below any flight altitude, so each such footprint is a roof the drones cross.
        return build([b if b.height_m is not None else dataclasses.replace(b, height_m=0.0) for b in buildings])[0]

    warning = inputs_warning(inputs)
    return gmap, frame, UnknownHeights(unknown, in_area, assumed,
                                       overflown if unknown and assumed is None else None), \
        AreaSources(area, [b for b, within in zip(buildings, inside) if within], no_fly, inputs,
                    [warning] if warning else [], highest_roof)


def input_entry(role: str, source: SourceFile, in_area: list[Building] | None = None,
                assumed_height_m: float | None = None, height_field: str | None = None) -> InputFile:
    """report.json's record of one file read: how it was read, what it left out (named) and, for the
    buildings, how many lie in the area and which of those have no height (`role`: area, obstacles,
    buildings). Repairs of buildings are listed for those in the area only."""
    repaired = tuple(source.repaired)
    buildings = None
    if in_area is not None:
        repaired = tuple(Omission(b.ref, b.repaired) for b in in_area if b.repaired)
        buildings = BuildingsRead(len(in_area), tuple(b.ref for b in in_area if b.height_m is None), assumed_height_m,
                                  height_field)
    return InputFile(role, source.path, source.format, source.reader, source.layer, source.crs, source.reprojected,
                     source.features, tuple(source.dropped), repaired, tuple(source.notes), buildings)


def _some(items: list[str]) -> str:
    """The first few of a list, then 'and N more'."""
    shown = ", ".join(items[:WARNING_NAMES])
    return shown + (f" and {len(items) - WARNING_NAMES} more" if len(items) > WARNING_NAMES else "")


def inputs_warning(inputs: list[InputFile]) -> str | None:
    """ONE line naming, file by file, what was not read, what was repaired and which buildings in the area
    have no height (unless --unknown-building-height gave them one); None when there is nothing to say.
    The full lists are in report.json `inputs`."""
    sentences = []
    for entry in inputs:
        layer = f":{entry.layer}" if entry.layer else ""
        what = "buildings" if entry.role == "buildings" else "polygons"
        for omitted, done in ((entry.dropped, "not read"), (entry.repaired, "repaired")):
            if omitted:
                named = _some([f"{item.ref} ({item.cause})" for item in omitted])
                count = len(omitted)
                sentences.append(f"{entry.path}{layer}: {count} {what if count > 1 else what[:-1]} {done}: {named}")
        buildings = entry.buildings
        if buildings is not None and buildings.unknown_height and buildings.unknown_height_assumed_m is None:
            unknown = list(buildings.unknown_height)
            sentences.append(f"{entry.path}{layer}: {len(unknown)} of the {buildings.in_area} buildings "
                             f"in the area have no height ({', '.join(HEIGHT_FIELDS[:2])} or building:levels), so "
                             f"they are obstacles: {_some(unknown)} (--unknown-building-height M gives them one)")
    if not sentences:
        return None
    return ". ".join(sentences) + ". All are listed in report.json under inputs."


def shipped_frame(gmap: GridMap) -> GridFrame | None:
    """The frame of a map that carries a georeference (`origin_lat` / `origin_lon`: the shipped maps do), else None."""
    return gmap.georef.frame if gmap.georef is not None else None


def mission_settings(gmap: GridMap, *, speed: float = DEFAULT_SPEED_M_S, overlap: float = DEFAULT_OVERLAP,
                     end: str = "rtl", altitude_step: float = 0.0, altitude: float | None = None,
                     autopilot: str = "ardupilot", capture: str = "relay",
                     transit_speed: float | None = None, gimbal_pitch: float = NADIR_PITCH_DEG) -> MissionSettings:
    """Altitude and footprint from the map's georeference (9 cells a side; `altitude` where the map has none),
    speed, overlap, end action, altitude step, autopilot, capture mode and the ways out and home's speed
    (`transit_speed`, None: the speed) as `plan` takes them; the defaults are `plan`'s."""
    check_range(speed, Setting("speed"), 0.0, MAX_SPEED_M_S, unit=" m/s", low_open=True, what=SPEED_WHAT, error=GeoError)
    if transit_speed is not None:
        check_range(transit_speed, Setting("transit_speed"), 0.0, MAX_SPEED_M_S, unit=" m/s", low_open=True,
                    what=SPEED_WHAT, error=GeoError)
    check_range(overlap, Setting("overlap"), 0.0, 1.0, high_open=True, what="a fraction", error=GeoError)
    # Layers go up from the altitude, never below it.
    check_range(altitude_step, Setting("altitude_step"), 0.0, 5_000.0, unit=" m", error=GeoError)
    check_range(gimbal_pitch, Setting("gimbal_pitch"), *GIMBAL_PITCH_RANGE, unit=" degrees",
                what="a gimbal pitch (-90 straight down)", error=GeoError)
    georef = gmap.georef
    if georef is None:
        raise GeoError(f"map {gmap.name}: no georeference (origin_lat, origin_lon) in its metadata")
    flight_altitude = float(georef.altitude_m if georef.altitude_m is not None else altitude or 0.0)
    if not flight_altitude > 0:
        raise GeoError(f"map {gmap.name}: no flight altitude (altitude_m) in its metadata")
    return MissionSettings(altitude_m=flight_altitude, footprint_m=georef.footprint_m, speed_m_s=speed,
                           overlap=overlap, end=end, altitude_step_m=altitude_step, autopilot=autopilot,
                           capture=capture, transit_speed_m_s=None if transit_speed == speed else transit_speed,
                           gimbal_pitch_deg=gimbal_pitch)
