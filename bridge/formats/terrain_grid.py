"""ArduPilot's terrain grid: where each height of the MAVLink terrain protocol lies on the ground.

Shared by both ends of the protocol: the ground station (session/terrain.py, which answers TERRAIN_REQUEST with
TERRAIN_DATA) and the mock autopilot (sim/mock_terrain.py, which asks and looks its ground up as ArduPilot does).
Owns the layout and the position arithmetic it rests on, from ArduPilot's libraries/AP_Terrain (AP_Terrain.h,
TerrainGCS.cpp, TerrainUtil.cpp) and AP_Math's Location:
- Grids start from whole degrees. TerrainUtil.cpp calculate_grid_info (grid_info here): a position's offset
  (north, east) in metres from the degree corner (floor of lat and lon) is Location::get_distance_NE; it is cut
  into grids of 28 x 32 points (north x east, TERRAIN_GRID_BLOCK_SIZE_X/Y) placed every 24 x 28 points
  (TERRAIN_GRID_BLOCK_SPACING_X/Y: neighbours overlap by one row), so point (i, j) of grid (gx, gy) is the
  ground at north (24 gx + i) * spacing, east (28 gy + j) * spacing from the degree corner; the grid's corner
  sent in TERRAIN_REQUEST is the degree corner moved by Location::offset (offset_e7 here).
- TerrainGCS.cpp handle_terrain_data: bit b of the mask is the 4 x 4 block whose first point is
  i0 = (b / 8) * 4 north, j0 = (b % 8) * 4 east (TERRAIN_GRID_BLOCK_MUL_Y = 8 blocks east), and
  data[4 x + y] is height[i0 + x][j0 + y]: x counts north, y east. Heights are int16 metres.
- AP_Math Location::get_distance_NE: north = dlat * LOCATION_SCALING_FACTOR, east = dlon *
  LOCATION_SCALING_FACTOR * cos(mean latitude of the two positions), in 1e-7 degrees; grid_points inverts
  exactly that, so each height is the ground where the vehicle will look it up.
  MAVProxy, QGroundControl and ArduPilot's own terrain file generator (terraingen's terrain_gen.py)
  instead step from the grid's corner by great-circle or flat offsets; they agree with this to metres
  near the degree corner and drift apart by tens of metres across a degree (the gap terraingen's
  slice_graph.py is there to show).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

BLOCK_SIDE = 4              # TERRAIN_GRID_MAVLINK_SIZE: one TERRAIN_DATA is 4 x 4 heights
BLOCKS_NORTH, BLOCKS_EAST = 7, 8  # TERRAIN_GRID_BLOCK_MUL_X / _Y: a grid is 7 x 8 blocks
MASK_BITS = BLOCKS_NORTH * BLOCKS_EAST  # 56
ALL_BLOCKS = (1 << MASK_BITS) - 1  # a grid's bitmap when every block is loaded
GRID_POINTS_NORTH = BLOCKS_NORTH * BLOCK_SIDE  # 28: TERRAIN_GRID_BLOCK_SIZE_X
GRID_POINTS_EAST = BLOCKS_EAST * BLOCK_SIDE    # 32: TERRAIN_GRID_BLOCK_SIZE_Y
GRID_STEP_NORTH = (BLOCKS_NORTH - 1) * BLOCK_SIDE  # 24 points: TERRAIN_GRID_BLOCK_SPACING_X
GRID_STEP_EAST = (BLOCKS_EAST - 1) * BLOCK_SIDE    # 28 points: TERRAIN_GRID_BLOCK_SPACING_Y
LOCATION_SCALING_FACTOR = 0.011131884502145034  # AP_Math: metres per 1e-7 degree of latitude
LOCATION_SCALING_FACTOR_INV = 89.83204953368922  # AP_Math: 1e-7 degrees of latitude per metre
E7 = 10_000_000
INT16 = (-32768, 32767)
# Within one block, point k of TERRAIN_DATA's data is x = k // 4 north, y = k % 4 east.
CELL_NORTH = np.repeat(np.arange(BLOCK_SIDE), BLOCK_SIDE)
CELL_EAST = np.tile(np.arange(BLOCK_SIDE), BLOCK_SIDE)


def longitude_scale(lat_e7: np.ndarray | float) -> np.ndarray:
    """AP_Math longitude_scale: cos(latitude), never below 0.01."""
    return np.maximum(np.cos(np.radians(np.asarray(lat_e7, dtype=float) * 1e-7)), 0.01)


def grid_points(lat_e7: int, lon_e7: int, spacing: int, bits: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(lat, lon) in degrees, shape (len(bits), 16), of the heights TERRAIN_DATA carries for each bit of
    the grid whose south-west corner is (lat_e7, lon_e7): point k of a block in the order of its data."""
    ref_lat, ref_lon = (lat_e7 // E7) * E7, (lon_e7 // E7) * E7  # the degree corner (floor, as C's rounding there)
    corner_north = (lat_e7 - ref_lat) * LOCATION_SCALING_FACTOR
    corner_east = (lon_e7 - ref_lon) * LOCATION_SCALING_FACTOR * float(longitude_scale((lat_e7 + ref_lat) / 2))
    grid_north = round(corner_north / (GRID_STEP_NORTH * spacing))  # which grid of the degree this is
    grid_east = round(corner_east / (GRID_STEP_EAST * spacing))
    bit = np.asarray(bits, dtype=np.int64)[:, None]
    north_m = (grid_north * GRID_STEP_NORTH + (bit // BLOCKS_EAST) * BLOCK_SIDE + CELL_NORTH) * float(spacing)
    east_m = (grid_east * GRID_STEP_EAST + (bit % BLOCKS_EAST) * BLOCK_SIDE + CELL_EAST) * float(spacing)
    lat = ref_lat + north_m / LOCATION_SCALING_FACTOR
    lon = ref_lon + east_m / (LOCATION_SCALING_FACTOR * longitude_scale((ref_lat + lat) / 2))
    return lat / E7, (lon / E7 + 180.0) % 360.0 - 180.0


def mask_bits(mask: int) -> list[int]:
    """The blocks a TERRAIN_REQUEST's mask asks for, lowest bit first."""
    return [bit for bit in range(MASK_BITS) if mask >> bit & 1]


def block_bit(idx_north: int, idx_east: int) -> int:
    """The mask bit of the block that holds point (idx_north, idx_east) of a grid (TerrainUtil.cpp grid_bitnum)."""
    return (idx_north // BLOCK_SIDE) * BLOCKS_EAST + idx_east // BLOCK_SIDE


def offset_e7(lat_e7: int, lon_e7: int, north_m: float, east_m: float) -> tuple[int, int]:
    """AP_Math Location::offset: a position moved north_m, east_m (each step cut toward zero, as C's casts)."""
    dlat = int(north_m * LOCATION_SCALING_FACTOR_INV)
    dlon = int(east_m * LOCATION_SCALING_FACTOR_INV / float(longitude_scale(lat_e7 + int(dlat / 2))))
    lon = (lon_e7 + dlon + 180 * E7) % (360 * E7) - 180 * E7
    return max(min(lat_e7 + dlat, 90 * E7), -90 * E7), lon


def offset_bearing_e7(lat_e7: int, lon_e7: int, bearing_deg: float, distance_m: float) -> tuple[int, int]:
    """AP_Math Location::offset_bearing: a position moved distance_m along a bearing (degrees from north)."""
    bearing = math.radians(bearing_deg)
    return offset_e7(lat_e7, lon_e7, math.cos(bearing) * distance_m, math.sin(bearing) * distance_m)


@dataclass(frozen=True)
class GridInfo:
    """Where a position falls in ArduPilot's terrain grids (TerrainUtil.cpp struct grid_info)."""

    grid_lat_e7: int   # the grid's south-west corner, as TERRAIN_REQUEST / TERRAIN_DATA name the grid
    grid_lon_e7: int
    idx_north: int     # the grid point south-west of the position: 0..23 north (idx_x)
    idx_east: int      # 0..27 east (idx_y)
    frac_north: float  # where the position lies in that square, 0..1 (frac_x, frac_y)
    frac_east: float


def grid_info(lat_e7: int, lon_e7: int, spacing: int) -> GridInfo:
    """TerrainUtil.cpp calculate_grid_info: the grid a position (1e-7 degrees) is looked up in, and the square."""
    ref_lat, ref_lon = (lat_e7 // E7) * E7, (lon_e7 // E7) * E7  # the degree corner (floor)
    north = (lat_e7 - ref_lat) * LOCATION_SCALING_FACTOR  # Location::get_distance_NE from the corner
    east = (lon_e7 - ref_lon) * LOCATION_SCALING_FACTOR * float(longitude_scale((ref_lat + lat_e7) / 2))
    idx_north, idx_east = int(north / spacing), int(east / spacing)
    grid_north, grid_east = idx_north // GRID_STEP_NORTH, idx_east // GRID_STEP_EAST
    corner = offset_e7(ref_lat, ref_lon, grid_north * GRID_STEP_NORTH * float(spacing),
                       grid_east * GRID_STEP_EAST * float(spacing))
    return GridInfo(corner[0], corner[1], idx_north % GRID_STEP_NORTH, idx_east % GRID_STEP_EAST,
                    (north - idx_north * spacing) / spacing, (east - idx_east * spacing) / spacing)


def served_heights(lat: np.ndarray, lon: np.ndarray, spacing: int,
                   height_amsl: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """The ground ArduPilot flies over at each point (degrees) when its ground station serves it `height_amsl`
    at TERRAIN_SPACING `spacing`: the four grid points around it (as calculate_grid_info places them), each
    height rounded to whole metres as TERRAIN_DATA carries it, bilinear between them (AP_Terrain height_amsl).
    NaN where the ground has no height at one of the four. Vectorised: a plan looks up every metre of its tracks."""
    lat_e7 = np.asarray(lat, dtype=float) * E7
    lon_e7 = np.asarray(lon, dtype=float) * E7
    ref_lat, ref_lon = np.floor(lat_e7 / E7) * E7, np.floor(lon_e7 / E7) * E7  # the degree corner
    north = (lat_e7 - ref_lat) * LOCATION_SCALING_FACTOR
    east = (lon_e7 - ref_lon) * LOCATION_SCALING_FACTOR * longitude_scale((ref_lat + lat_e7) / 2)
    i, j = np.floor(north / spacing), np.floor(east / spacing)
    frac_north, frac_east = north / spacing - i, east / spacing - j
    corners = []
    for di, dj in ((0, 0), (1, 0), (0, 1), (1, 1)):
        point_lat = ref_lat + (i + di) * spacing / LOCATION_SCALING_FACTOR
        point_lon = ref_lon + (j + dj) * spacing / (LOCATION_SCALING_FACTOR * longitude_scale((ref_lat + point_lat) / 2))
        corners.append(np.rint(height_amsl(point_lat / E7, point_lon / E7)))
    south_west, north_west, south_east, north_east = corners
    west = (1.0 - frac_north) * south_west + frac_north * north_west
    east_side = (1.0 - frac_north) * south_east + frac_north * north_east
    return (1.0 - frac_east) * west + frac_east * east_side
