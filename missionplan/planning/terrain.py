"""The ground under a plan over a DEM (`plan --dem`): read around the grid, checked, recorded and copied.

`plan_terrain` reads the crew's DEM around the grid (geo.dem.read_ground) and refuses, in one line naming
the point, a DEM that leaves any cell a drone may fly over, or a launch point, without ground. The window
read reaches DEM_MARGIN_M beyond the grid where the DEM does: ArduPilot asks its ground station for the
terrain grids around where it flies (28 x 32 points at TERRAIN_SPACING, 100 m by default, aligned to whole
degrees): the grids holding the 9 points 0.7 grid (1.96 km north, 2.24 km east) around its position, each
reaching up to a whole grid (2.7 km north, 3.1 km east) beyond such a point, so up to 5.4 km beyond its track
(measured on ArduCopter SITL: with 3.5 km read it asked for blocks 3.7 km beyond, and arms only once it has
every block it asked for), and `fly` serves them from the plan folder's copy
(geo.dem_copy), which is the ground every later step (fly, the mock, the judge, a re-plan: `folder_terrain`)
measures against. `terrain_record` is what report.json says of it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from missionplan.geo.dem import Ground, read_ground
from missionplan.geo.dem_copy import read_ground_copy
from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import TerrainRecord

from ..maps.gridmap import GridMap
from ..mission.plan_record import PlanRecord

DEM_MARGIN_M = 5_500.0  # around the grid: the terrain grids ArduPilot asks for (see the module docstring)


def plan_terrain(dem: Sequence[Path], frame: GridFrame, gmap: GridMap, starts: Sequence[tuple[int, int]]) -> Ground:
    """The ground of the DEM files `dem` under the grid; GeoError, one line, where a drone could fly over no
    ground (a cell that is not an obstacle) or a launch point has none."""
    return checked_ground(read_ground(dem, frame.latlon_box(), margin_m=DEM_MARGIN_M), frame, gmap, starts)


def reach_m(ground: Ground, frame: GridFrame, step_m: float = 250.0) -> float:
    """How far beyond the grid, up to DEM_MARGIN_M, the ground has a height all round: the widest box around the
    grid (steps of step_m) whose corners and edge midpoints all have one. ArduPilot arms only once it has every
    terrain block it asked for, up to about 5.4 km beyond its track: a DEM that ends sooner keeps it on the ground."""
    min_lat, min_lon, max_lat, max_lon = frame.latlon_box()
    mid_lat, mid_lon = (min_lat + max_lat) / 2, (min_lon + max_lon) / 2
    reached = 0.0
    for margin in np.arange(step_m, DEM_MARGIN_M + step_m / 2, step_m):
        dlat = margin / 111_320.0
        dlon = dlat / max(np.cos(np.radians(mid_lat)), 0.01)
        lat = np.array([min_lat - dlat, min_lat - dlat, max_lat + dlat, max_lat + dlat, mid_lat, mid_lat,
                        min_lat - dlat, max_lat + dlat])
        lon = np.array([min_lon - dlon, max_lon + dlon, min_lon - dlon, max_lon + dlon, min_lon - dlon,
                        max_lon + dlon, mid_lon, mid_lon])
        if np.isnan(ground.height_amsl(lat, lon)).any():
            break
        reached = float(margin)
    return reached


def folder_terrain(folder: Path, record: PlanRecord) -> Ground | None:
    """The ground a plan folder was planned over (its copy, geo.dem_copy), as far as it reaches: what a re-plan
    after landing and a re-task in flight plan over; None for a plan taken as flat."""
    georef = record.georeference
    if georef is None or georef.terrain is None:
        return None
    return read_ground_copy(folder, georef.terrain, georef.frame, margin_m=DEM_MARGIN_M)


def checked_ground(ground: Ground, frame: GridFrame, gmap: GridMap, starts: Sequence[tuple[int, int]]) -> Ground:
    """`ground`, or GeoError (one line) naming the first cell a drone may fly over (not an obstacle) or the first
    launch point where it has no height."""
    rows, cols = np.nonzero(~gmap.obstacle)
    lat, lon = frame.cell_to_latlon(rows, cols)
    ground.heights(lat, lon, "the area")
    for k, (row, col) in enumerate(starts):
        lat, lon = frame.cell_to_latlon(np.array([row]), np.array([col]))
        ground.heights(lat, lon, f"uav{k + 1}'s launch point")
    return ground


def terrain_record(ground: Ground, files: Sequence[str], frame: GridFrame, gmap: GridMap,
                   spacing_m: int | None = None) -> TerrainRecord:
    """report.json's georeference.terrain: the copies written, the DEM files, the ground's range under the
    cells a drone may fly over, and ArduPilot's TERRAIN_SPACING the plan needs (flightplan.FlightPlans)."""
    rows, cols = np.nonzero(~gmap.obstacle)
    heights = ground.height_amsl(*frame.cell_to_latlon(rows, cols))
    return TerrainRecord(tuple(files), ground.sources, ground.crs, round(ground.resolution_m, 2),
                         round(float(np.nanmin(heights)), 2), round(float(np.nanmax(heights)), 2), spacing_m)
