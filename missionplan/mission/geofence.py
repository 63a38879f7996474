"""Each drone's geofence: an inclusion polygon around its whole flight, and a ceiling.

The polygon is the convex hull of everything the drone flies over in every sortie - its zone's
cells, its launch point (take-off, return, landing) and every waypoint - grown by a margin
(SafetySettings.fence_margin_m), with mitred corners so it keeps the hull's few vertices (an
autopilot stores fence points in scarce memory). A hull of more than MAX_VERTICES points is
replaced by its minimum rotated rectangle (4 points), which contains it. The ceiling is the
drone's altitude plus the same margin, kept at or under --max-altitude when that leaves room.

The fence goes into the drone's .plan files as QGroundControl's geoFence (one inclusion polygon)
with the ceiling as `maxAltitude` (QGroundControl ignores the key; ArduPilot takes its ceiling
from the FENCE_ALT_MAX parameter, PX4 from GF_MAX_VER_DIST): bridge/ uploads the polygon with
the mission. Grid metres (row axis, column axis) in, latitude/longitude out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from missionplan.bridge.formats.mission_items import (CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, Mission,
                                                      MissionItem, MissionType)
from missionplan.geo.frame import GridFrame

MAX_VERTICES = 24


@dataclass
class Fence:
    polygon_m: np.ndarray  # (n, 2) vertices in grid metres (row_m, col_m), not closed
    latlon: np.ndarray  # (n, 2) the same vertices as latitude, longitude
    max_altitude_m: float

    def mission(self) -> Mission:
        """The fence as MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION items (what bridge/ uploads)."""
        # autocontinue 0, as the .plan reader makes fence points and ArduPilot stores them
        items = [MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=float(len(self.latlon)),
                             x=float(lat), y=float(lon), z=0.0, autocontinue=False) for lat, lon in self.latlon]
        return Mission(items=items, mission_type=MissionType.FENCE)


def drone_fence(frame: GridFrame, zone_cells: np.ndarray, points_m: np.ndarray, altitude_m: float,
                margin_m: float, max_altitude_m: float) -> Fence:
    """The fence around `zone_cells` (n, 2 grid cells) and `points_m` (m, 2 grid metres: launch, waypoints)."""
    import shapely

    cell = frame.cell_m
    corners = [np.asarray(points_m, dtype=float).reshape(-1, 2)]
    if len(zone_cells):
        centres = np.asarray(zone_cells, dtype=float) * cell
        for dr in (-0.5, 0.5):
            for dc in (-0.5, 0.5):
                corners.append(centres + np.array([dr, dc]) * cell)
    hull = shapely.MultiPoint(np.vstack(corners)).convex_hull
    if len(shapely.get_coordinates(hull)) - 1 > MAX_VERTICES:
        hull = shapely.minimum_rotated_rectangle(hull)
    grown = hull.buffer(margin_m, quad_segs=2, join_style="mitre", mitre_limit=2.0)
    ring = shapely.get_coordinates(grown.exterior)[:-1]
    lat, lon = frame.grid_to_latlon(ring[:, 0] / cell, ring[:, 1] / cell)
    ceiling = altitude_m + margin_m
    if ceiling > max_altitude_m and max_altitude_m > altitude_m + 1.0:
        ceiling = max_altitude_m
    return Fence(ring, np.column_stack([lat, lon]), round(float(ceiling), 2))
