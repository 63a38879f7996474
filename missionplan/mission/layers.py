"""A plan's map layers: what plan.html, plan.gpkg, plan.kmz and tracks.geojson draw.

One layer per thing a crew looks at, each a GeoJSON FeatureCollection (RFC 7946: WGS 84 lon/lat,
exterior rings counter-clockwise, holes clockwise), in drawing order:

- `area` the surveyed area; `buildings` the footprints with their heights (the obstacle cells of a
  grid map); `clearance` the band drones keep out of; `zones` each drone's share;
- `roofs` the roof target cells (`plan --targets roofs|all` only: mission/roof_targets.py);
- `unreachable` the target cells no drone reaches, one feature per cause (`cause`, `reason`);
- `fences` each drone's geofence; `paths` each sortie's flown-as-uploaded path, 3-D
  (lon, lat, metres above home; in a plan over a DEM, metres above the ground under it, as the KMZ's
  relativeToGround says); `photos` where each photo is planned; `launch` the launch points.

The flight adds its own layers beside these (missionplan/flight/flight_layers.py). Each feature
carries `layer` (its layer's name) so the one-file tracks.geojson can be split back into layers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import shapely
from shapely.geometry import mapping

from missionplan.bridge.formats.mission_items import (CMD_DO_SET_CAM_TRIGG_DIST, CMD_IMAGE_START_CAPTURE,
                                                      CMD_IMAGE_STOP_CAPTURE, CMD_NAV_LAND, CMD_NAV_RETURN_TO_LAUNCH,
                                                      CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL, MissionItem)
from missionplan.geo.cells import cells_polygons
from missionplan.geo.geojson_layers import rfc7946
from missionplan.geo.frame import GridFrame

from ..grid.planresult import PlanResult
from ..maps.gridmap import GridMap
from .coverage_check import CAUSE_REASONS
from .georef import AreaSources
from .plan_record import PlanRecord

Layers = dict[str, dict[str, Any]]

# matplotlib's tab10, so plan.png, plan.html and the KMZ give a drone the same colour.
UAV_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
               "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")


# Each layer's geometry type, declared in the GeoPackage even when the layer is empty.
LAYER_GEOMETRY = {"area": "MultiPolygon", "buildings": "MultiPolygon", "clearance": "MultiPolygon",
                  "zones": "MultiPolygon", "roofs": "MultiPolygon", "unreachable": "MultiPolygon", "covered": "MultiPolygon",
                  "missed": "MultiPolygon", "fences": "Polygon", "paths": "LineString Z", "photos": "Point Z",
                  "launch": "Point Z", "flown": "LineString Z", "photos_taken": "Point Z"}


def uav_colour(index: int) -> str:
    """The colour of the drone planned `index`-th (0-based)."""
    return UAV_COLOURS[index % len(UAV_COLOURS)]


def feature(layer: str, geometry: dict[str, Any] | None, **properties: Any) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": {"layer": layer, **properties}}


def collection(features: list[dict[str, Any]]) -> dict[str, Any]:
    return {"type": "FeatureCollection", "features": features}


def _polygonal(geom: Any) -> dict[str, Any]:
    """A shapely polygon or multipolygon in RFC 7946 ring order, as GeoJSON, 7 decimals (1 cm)."""
    geom = shapely.set_precision(geom, 1e-7)  # may merge or split parts: orient after it
    parts = [part for part in shapely.get_parts(geom) if isinstance(part, shapely.Polygon) and not part.is_empty]
    return rfc7946(mapping(parts[0] if len(parts) == 1 else shapely.MultiPolygon(parts)))


def cells_geometry(frame: GridFrame, mask: np.ndarray) -> dict[str, Any] | None:
    """The True cells of `mask` as one MultiPolygon (neighbours merged), or None when there are none."""
    polygons = cells_polygons(frame, np.argwhere(mask))
    return mapping(shapely.MultiPolygon(polygons)) if polygons else None


def mission_path(items: list[MissionItem], launch: tuple[float, float],
                 ground: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """(n, 3) lon, lat, metres above home of the path a mission flies: from the launch point up, through
    its waypoints, and home (RTL) or down (LAND). With `ground` (a plan over a DEM), metres above the
    ground under each point: a waypoint's above-sea-level altitude (PX4's, frame 0) less the ground there;
    the terrain frame's (ArduPilot's, 10) as it is."""
    lat0, lon0 = launch
    points = [(lon0, lat0, 0.0)]
    for item in items:
        here = points[-1]
        if item.command == CMD_NAV_TAKEOFF:
            points.append((here[0], here[1], float(item.z)))
        elif item.command == CMD_NAV_WAYPOINT:
            up = float(item.z)
            if ground is not None and item.frame == FRAME_GLOBAL:
                up -= float(ground(np.array([item.x]), np.array([item.y]))[0])
            points.append((float(item.y), float(item.x), up))
        elif item.command == CMD_NAV_RETURN_TO_LAUNCH:
            points += [(lon0, lat0, here[2]), (lon0, lat0, 0.0)]
        elif item.command == CMD_NAV_LAND:
            lon, lat = (float(item.y), float(item.x)) if item.x or item.y else here[:2]
            points += [(lon, lat, here[2]), (lon, lat, 0.0)]
    return np.array(points)


def planned_photos(items: list[MissionItem], trigger_m: float, to_m: Callable[[float, float], np.ndarray],
                   from_takeoff: bool = True) -> np.ndarray:
    """Where a mission's photos are planned, in the metric frame `to_m(lat, lon)` maps into: one wherever
    DO_SET_CAM_TRIGG_DIST says "trigger once now" (over the take-off point, after a waypoint), and one
    every trigger distance along each leg flown with the distance trigger on (not on a way out or home,
    where it is 0). A camera-interval mission (IMAGE_START_CAPTURE ... IMAGE_STOP_CAPTURE): one at the start,
    then one every trigger distance flown, across corners, as at the cruise speed. Counts as
    missions.build_mission counts `photos`; without `from_takeoff`, the photo over the take-off point and
    those on the leg from it are left out (the judge's sortie duties)."""
    points: list[np.ndarray] = []
    distance, previous = 0.0, None
    interval, since_photo = False, 0.0  # capturing by time, and the metres flown since its last photo
    for item in items:
        if item.command == CMD_NAV_TAKEOFF and from_takeoff and (item.x or item.y):
            previous = to_m(item.x, item.y)
        elif item.command == CMD_IMAGE_START_CAPTURE:
            if previous is not None:
                points.append(previous)
            interval, since_photo = True, 0.0
        elif item.command == CMD_IMAGE_STOP_CAPTURE:
            interval = False
        elif item.command == CMD_NAV_WAYPOINT and interval:
            here = to_m(item.x, item.y)
            if previous is not None and trigger_m > 0:
                length = float(np.hypot(*(here - previous)))
                for along in np.arange(trigger_m - since_photo, length + 1e-6, trigger_m):
                    points.append(previous + (here - previous) * (along / max(length, 1e-12)))
                since_photo = (since_photo + length) % trigger_m
            previous = here
        elif item.command == CMD_DO_SET_CAM_TRIGG_DIST:
            if item.param3 > 0 and previous is not None:
                points.append(previous)
            distance = item.param1
        elif item.command == CMD_NAV_WAYPOINT:
            here = to_m(item.x, item.y)
            if distance > 0 and previous is not None and trigger_m > 0:
                length = float(np.hypot(*(here - previous)))
                # photos strictly inside the leg (the waypoint's own comes next); the tolerance absorbs the
                # lat/lon round trip of a leg that is a whole number of trigger distances long
                inside = max(int(np.ceil(length / trigger_m - 1e-6)) - 1, 0)
                for along in trigger_m * np.arange(1, inside + 1):
                    points.append(previous + (here - previous) * (along / length))
            previous = here
    return np.array(points).reshape(-1, 2)


def _round(coords: np.ndarray, digits: tuple[int, ...] = (7, 7, 2)) -> list[list[float]]:
    return [[round(float(v), d) for v, d in zip(row, digits)] for row in coords]


def plan_layers(result: PlanResult, frame: GridFrame, plans: Any, base: GridMap, *,
                band: np.ndarray | None = None, causes: dict[str, np.ndarray] | None = None,
                sources: AreaSources | None = None, launch_labels: list[str] | None = None) -> Layers:
    """The plan's layers (see the module docstring).

    `plans`: flightplan.FlightPlans; `base`: the map as given (buildings, without the clearance band);
    `band`: the clearance band's cells; `causes`: coverage_check.unreachable_causes' masks; `sources`:
    the area and buildings of an `--area` plan (a grid map's area is its grid, its buildings its
    obstacle cells); `launch_labels`: each drone's launch point as the user gave it."""
    layers: Layers = {}
    if sources is not None:
        layers["area"] = collection([feature("area", _polygonal(sources.area), name=base.name)])
        area = sources.area
        layers["buildings"] = collection([  # sources.buildings are those in the area (georef)
            feature("buildings", _polygonal(b.geometry), height_m=b.height_m, known_height=b.height_m is not None)
            for b in sources.buildings] + [
            feature("buildings", _polygonal(p), height_m=None, known_height=False, no_fly=True)
            for p in sources.no_fly if p.intersects(area)])
    else:
        rows, cols = base.shape
        corners = np.array([[-0.5, -0.5], [-0.5, cols - 0.5], [rows - 0.5, cols - 0.5], [rows - 0.5, -0.5]])
        lat, lon = frame.grid_to_latlon(corners[:, 0], corners[:, 1])
        layers["area"] = collection([feature("area", _polygonal(shapely.Polygon(np.column_stack([lon, lat]))),
                                             name=base.name)])
        layers["buildings"] = collection([feature("buildings", cells_geometry(frame, base.obstacle),
                                                  height_m=None, known_height=False, cells=int(base.obstacle.sum()))])
    clearance_m = float(plans.safety.clearance_m) if plans.safety is not None else 0.0
    layers["clearance"] = collection(
        [feature("clearance", cells_geometry(frame, band), clearance_m=clearance_m, cells=int(band.sum()))]
        if band is not None and band.any() else [])
    zone_masks = [(k, result.zones.zone == k) for k in range(len(plans.sorties))]
    layers["zones"] = collection([
        feature("zones", cells_geometry(frame, mask), uav=plans.sorties[k][0].sysid, cells=int(mask.sum()))
        for k, mask in zone_masks if mask.any()])
    if base.roof is not None:  # a plan with roof targets: which target cells are roofs
        layers["roofs"] = collection([feature("roofs", cells_geometry(frame, base.roofs), cells=int(base.roofs.sum()))])
    layers["unreachable"] = collection([
        feature("unreachable", cells_geometry(frame, mask), cause=cause, cells=int(mask.sum()),
                reason=CAUSE_REASONS.get(cause, cause))
        for cause, mask in (causes or {}).items() if mask.any()])
    layers["fences"] = collection([
        feature("fences", _polygonal(shapely.Polygon(fence.latlon[:, ::-1])), uav=plans.sorties[k][0].sysid,
                max_altitude_m=round(float(fence.max_altitude_m), 2))
        for k, fence in enumerate(plans.fences)])

    def grid_m_to_latlon(point_m: np.ndarray) -> tuple[float, float]:
        lat, lon = frame.grid_to_latlon(np.array([point_m[0] / frame.cell_m]), np.array([point_m[1] / frame.cell_m]))
        return float(lat[0]), float(lon[0])

    def to_en(lat: float, lon: float) -> np.ndarray:
        row, col = frame.latlon_to_grid(np.array([lat]), np.array([lon]))
        return np.array([float(np.atleast_1d(row)[0]), float(np.atleast_1d(col)[0])]) * frame.cell_m

    trigger_m = plans.settings.trigger_distance_m
    paths, photos, launch = [], [], []
    for k, missions in enumerate(plans.sorties):
        sysid = missions[0].sysid
        home = grid_m_to_latlon(plans.sortie_routes[k][0][0]) if plans.sortie_routes else \
            grid_m_to_latlon(np.asarray(result.starts[k], dtype=float) * frame.cell_m)
        label = launch_labels[k] if launch_labels and k < len(launch_labels) else f"uav{sysid}"
        launch.append(feature("launch", {"type": "Point", "coordinates": _round(np.array([[home[1], home[0], 0.0]]))[0]},
                              uav=sysid, label=label))
        index = 0
        for j, drone in enumerate(missions):
            items = drone.mission.items
            paths.append(feature("paths", {"type": "LineString",
                                           "coordinates": _round(mission_path(items, home, plans.ground))},
                                 uav=sysid, sortie=j + 1, altitude_m=round(plans.settings.altitude_of(k), 2),
                                 waypoints=drone.waypoints, length_m=round(drone.length_m, 2),
                                 flight_s=round(drone.flight_s, 1), photos=drone.photos))
            points_m = planned_photos(items, trigger_m, to_en)
            altitude = plans.settings.altitude_of(k)
            lat, lon = frame.grid_to_latlon(points_m[:, 0] / frame.cell_m, points_m[:, 1] / frame.cell_m)
            points = np.column_stack([np.atleast_1d(lon), np.atleast_1d(lat), np.full(len(points_m), altitude)])
            for point in _round(points):
                index += 1
                photos.append(feature("photos", {"type": "Point", "coordinates": point},
                                      uav=sysid, sortie=j + 1, index=index))
    layers["paths"] = collection(paths)
    layers["photos"] = collection(photos)
    layers["launch"] = collection(launch)
    return layers


def drone_paths_latlon(layers: Layers) -> list[np.ndarray]:
    """Per drone, in planning order, the (n, 2) lat/lon of its paths layer, every sortie one after another."""
    by_uav: dict[int, list[np.ndarray]] = {}
    for item in layers["paths"]["features"]:
        coords = np.asarray(item["geometry"]["coordinates"], dtype=float)
        by_uav.setdefault(item["properties"]["uav"], []).append(coords[:, 1::-1])
    return [np.vstack(parts) for parts in by_uav.values()]


def layers_from_geojson(doc: dict[str, Any]) -> Layers:
    """tracks.geojson split back into its layers by each feature's `layer`."""
    layers: Layers = {}
    for item in doc.get("features") or []:
        name = (item.get("properties") or {}).get("layer")
        if isinstance(name, str):
            layers.setdefault(name, collection([]))["features"].append(item)
    return layers


def one_collection(layers: Layers) -> dict[str, Any]:
    """Every layer's features in one FeatureCollection (tracks.geojson), in drawing order."""
    return collection([item for layer in layers.values() for item in layer["features"]])


def plan_summary(record: PlanRecord, layers: Layers) -> dict[str, Any]:
    """plan.html's side panel: the plan's figures as its record (report.json) gives them, per drone and in all."""
    metrics, cover = record.metrics, record.coverage
    drones = []
    for k, drone in enumerate(record.drones or ()):
        drones.append({"uav": drone.id, "colour": uav_colour(k), "figures": {
            "altitude": f"{drone.altitude_m:g} m", "waypoints": str(drone.waypoints),
            "length": f"{drone.length_m:.0f} m", "flight": f"{drone.flight_s:.0f} s",
            "photos": str(drone.photos), "sorties": str(len(drone.sorties) or 1)}})
    all_pct = cover.all_pct if cover is not None else metrics.coverage
    figures = {"targets": f"{record.targets} reachable, {record.unreachable} unreachable",
               "coverage": f"{metrics.coverage:.1f} % of reachable, {all_pct:.1f} % of all",
               "makespan": f"{metrics.makespan} moves", "MMN / floor": f"{metrics.mmn / record.floor:.2f}"
               if record.floor else "-"}
    sep = record.separation
    if sep is not None and sep.d3 is not None:
        figures["closest approach"] = f"{sep.d3} m (uav{sep.closest.pair_3d[0]}, uav{sep.closest.pair_3d[1]})"
    clearance = record.clearance
    if clearance is not None and clearance.kept_m is not None:
        figures["clearance kept"] = f"{clearance.kept_m:g} m (asked {clearance.required_m:g} m)"
    if record.credit:
        figures["map data"] = record.credit
    status = "every reachable target covered" if record.success else f"FAILED: {record.failure}"
    return {"kind": "plan", "title": f"{record.map}: {record.uavs} drones, policy {record.policy}",
            "subtitle": status, "drones": drones, "figures": figures,
            "notes": list(cover.warnings) if cover is not None else [],
            "layers": {name: len(layer["features"]) for name, layer in layers.items()}}
