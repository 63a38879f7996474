"""The ground under a plan over a DEM (`plan --dem`): read around the grid, checked, recorded and copied.

`plan_terrain` reads the crew's DEM around the grid (geo.dem.read_ground) and refuses, in one line naming
the point, a DEM that leaves any cell a drone may fly over, or a launch point, without ground. The window
read reaches DEM_MARGIN_M beyond the grid where the DEM does: ArduPilot asks its ground station for the
terrain grids around where it flies (28 x 32 points at TERRAIN_SPACING, 100 m by default, aligned to whole
degrees): the grids holding the 9 points 0.7 grid (1.96 km north, 2.24 km east) around its position, each
reaching up to a whole grid (2.7 km north, 3.1 km east) beyond such a point, so up to 5.4 km beyond its track
(measured on ArduCopter SITL: with 3.5 km read it asked for blocks 3.7 km beyond, and arms only once it has
every block it asked for), and `fly` serves them from the plan folder's copy
(geo.dem_copy), which is the ground every later step (fly, the mock, the judge) measures against.
`terrain_record` is what report.json says of it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from missionplan.geo.dem import Ground, read_ground
from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import TerrainRecord

from ..maps.gridmap import GridMap

DEM_MARGIN_M = 5_500.0  # around the grid: the terrain grids ArduPilot asks for (see the module docstring)


def grid_box(frame: GridFrame) -> tuple[float, float, float, float]:
    """(min_lat, min_lon, max_lat, max_lon) of the grid's four outer corners (it may be rotated)."""
    rows = np.array([-0.5, -0.5, frame.rows - 0.5, frame.rows - 0.5])
    cols = np.array([-0.5, frame.cols - 0.5, -0.5, frame.cols - 0.5])
    lat, lon = frame.grid_to_latlon(rows, cols)
    return float(lat.min()), float(lon.min()), float(lat.max()), float(lon.max())


def plan_terrain(dem: Sequence[Path], frame: GridFrame, gmap: GridMap, starts: Sequence[tuple[int, int]]) -> Ground:
    """The ground of the DEM files `dem` under the grid; GeoError, one line, where a drone could fly over no
    ground (a cell that is not an obstacle) or a launch point has none."""
    ground = read_ground(dem, grid_box(frame), margin_m=DEM_MARGIN_M)
    rows, cols = np.nonzero(~gmap.obstacle)
    lat, lon = frame.cell_to_latlon(rows, cols)
    ground.heights(lat, lon, "the area")
    for k, (row, col) in enumerate(starts):
        lat, lon = frame.cell_to_latlon(np.array([row]), np.array([col]))
        ground.heights(lat, lon, f"uav{k + 1}'s launch point")
    return ground


def terrain_record(ground: Ground, files: Sequence[str], frame: GridFrame, gmap: GridMap) -> TerrainRecord:
    """report.json's georeference.terrain: the copies written, the DEM files, and the ground's range under the
    cells a drone may fly over."""
    rows, cols = np.nonzero(~gmap.obstacle)
    heights = ground.height_amsl(*frame.cell_to_latlon(rows, cols))
    return TerrainRecord(tuple(files), ground.sources, ground.crs, round(ground.resolution_m, 2),
                         round(float(np.nanmin(heights)), 2), round(float(np.nanmax(heights)), 2))
