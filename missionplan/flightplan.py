"""Grid plan -> smoothed tracks -> missions -> files (`uavK.plan`, `uavK.waypoints`, `tracks.geojson`).

The last stage of `missionplan plan` when the grid is georeferenced: each drone's cell path
goes through the trajectory corrector, its waypoints are turned into latitude/longitude by
the grid frame, and missions.build_mission makes its MAVLink mission. Drone k's files are
`uavK.*` (K from 1): it is meant for the autopilot with system id K. All files are written
to a temporary name and renamed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bridge.missionfile import PlanFile, write_mission_file
from geo.frame import GridFrame

from .atomic import write_text_atomic
from .corrector import CorrectedPath, correct_path
from .missions import DroneMission, MissionSettings, build_mission
from .pipeline import PlanResult
from .timeline import ASSUMES, FlightModel, closest_approach, planned_track
from .world import FOOTPRINT_RADIUS


@dataclass
class FlightPlans:
    corrected: list[CorrectedPath]
    waypoints_latlon: list[np.ndarray]  # per drone (n, 2): the corrected waypoints as (lat, lon)
    drones: list[DroneMission]
    settings: MissionSettings
    timed: dict[int, np.ndarray]  # sysid -> (n, 4) t, row_m, col_m, up_m of the planned flight (timeline)

    def separation(self) -> dict[str, Any]:
        """report.json's `separation`: the closest approach of two drones if all fly as planned."""
        return {**closest_approach(self.timed), "assumes": ASSUMES}

    def report(self) -> list[dict[str, Any]]:
        """report.json's `drones`: one object per drone."""
        rows = []
        for k, (track, drone) in enumerate(zip(self.corrected, self.drones)):
            rows.append({"id": drone.sysid, "cells": int(track.before["waypoints"]), "waypoints": drone.waypoints,
                         "length_m": round(drone.length_m, 2), "flight_s": round(drone.flight_s, 1),
                         "photos": drone.photos, "altitude_m": round(self.settings.altitude_of(k), 2),
                         "smoothing": {"before": track.before, "after": track.after}})
        return rows


def make_flight_plans(result: PlanResult, frame: GridFrame, settings: MissionSettings) -> FlightPlans:
    """Correct every drone's path and build its mission."""
    gmap, paths = result.gmap, result.run.paths
    corrected, latlons, drones = [], [], []
    timed: dict[int, np.ndarray] = {}
    model = FlightModel(speed_m_s=settings.speed_m_s, acceptance_m=settings.acceptance_m)
    for k in range(paths.shape[0]):
        # A diagonal is credited only with the cells every photo spacing still sees.
        track = correct_path(paths[k], gmap.obstacle, result.world.reachable, footprint_radius=FOOTPRINT_RADIUS,
                             sample_step=max(settings.trigger_distance_m / frame.cell_m, 0.25))
        waypoints = np.asarray(track.waypoints, dtype=float)
        latlon = np.column_stack(frame.grid_to_latlon(waypoints[:, 0], waypoints[:, 1]))
        launch = np.asarray(result.starts[k], dtype=float)
        launch_lat, launch_lon = frame.grid_to_latlon(launch[:1], launch[1:])
        timed[k + 1] = planned_track(launch * frame.cell_m, waypoints * frame.cell_m, settings.altitude_of(k),
                                     settings.end, model)
        drones.append(build_mission(k, (float(launch_lat[0]), float(launch_lon[0])), latlon,
                                    waypoints * frame.cell_m, launch * frame.cell_m, settings,
                                    flight_s=float(timed[k + 1][-1, 0])))
        corrected.append(track)
        latlons.append(latlon)
    return FlightPlans(corrected, latlons, drones, settings, timed)


def _zone_polygons(result: PlanResult, frame: GridFrame) -> list[dict[str, Any]]:
    """Each drone's zone as a GeoJSON (Multi)Polygon, from the union of its cells' squares."""
    import shapely
    from shapely.geometry import mapping

    features = []
    zone = result.zones.zone
    for k in range(len(result.starts)):
        cells = np.argwhere(zone == k)
        if not len(cells):
            continue
        # Cell (i, j) is the square (i +- 0.5, j +- 0.5) in grid coordinates.
        boxes = shapely.box(cells[:, 1] - 0.5, cells[:, 0] - 0.5, cells[:, 1] + 0.5, cells[:, 0] + 0.5)
        merged = shapely.union_all(boxes)

        def to_lonlat(coords: np.ndarray) -> np.ndarray:
            lat, lon = frame.grid_to_latlon(coords[:, 1], coords[:, 0])  # (x, y) = (col, row)
            return np.column_stack([lon, lat])

        geometry = shapely.transform(merged, to_lonlat)
        features.append({"type": "Feature", "geometry": mapping(geometry),
                         "properties": {"kind": "zone", "uav": k + 1, "cells": int(len(cells))}})
    return features


def tracks_geojson(result: PlanResult, frame: GridFrame, plans: FlightPlans) -> dict[str, Any]:
    features = _zone_polygons(result, frame)
    for k, (latlon, drone) in enumerate(zip(plans.waypoints_latlon, plans.drones)):
        features.append({"type": "Feature",
                         "geometry": {"type": "LineString", "coordinates": latlon[:, ::-1].tolist()},
                         "properties": {"kind": "track", "uav": k + 1, "sysid": drone.sysid,
                                        "altitude_m": plans.settings.altitude_of(k), "waypoints": drone.waypoints,
                                        "length_m": round(drone.length_m, 2), "flight_s": round(drone.flight_s, 1),
                                        "photos": drone.photos}})
    return {"type": "FeatureCollection", "features": features}


def write_flight_files(out: Path, result: PlanResult, frame: GridFrame, plans: FlightPlans) -> list[Path]:
    """Write uavK.plan, uavK.waypoints and tracks.geojson into `out`; returns the paths written."""
    written = []
    for drone in plans.drones:
        plan_file = PlanFile(mission=drone.mission, cruise_speed=plans.settings.speed_m_s,
                             hover_speed=plans.settings.speed_m_s)
        for suffix in (".plan", ".waypoints"):
            path = out / f"uav{drone.sysid}{suffix}"
            write_mission_file(path, plan_file)
            written.append(path)
    path = out / "tracks.geojson"
    write_text_atomic(path, json.dumps(tracks_geojson(result, frame, plans)) + "\n")
    written.append(path)
    return written
