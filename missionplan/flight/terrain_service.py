"""The plan's ground served to its ArduPilot vehicles, by `fly` (each follower, the whole flight) and `upload`.

A plan over a DEM (report.json's georeference.terrain) gives ArduPilot its waypoints in the terrain frame
(MAV_FRAME_GLOBAL_TERRAIN_ALT: heights above the ground). The vehicle flies them from its own terrain
database, which it fills by asking its ground station (TERRAIN_REQUEST) from its first seconds and as it
moves; it arms only once it has the ground under its mission. So the ground station must answer from the
ground the plan was made over: the plan folder's exact copy (geo.dem_copy), not the crew's DEM, which may
have changed since. PX4 plans carry sea-level altitudes: their vehicles are served nothing.

Owns:
- plan_ground: a plan folder's ground, read around the grid and as far beyond as ArduPilot asks;
- terrain_points: the positions of a mission's terrain-frame items to check (TERRAIN_CHECK), thinned;
- DroneTerrain: one vehicle's terrain server (its own counts) attached to its session from the moment it
  is found, the streams it asks with, the bounded wait until the vehicle reports the ground loaded for its
  waypoints (bridge.session.terrain.wait_terrain_loaded), and the lines a record keeps of it;
- FleetTerrain: the ground a flight serves, one DroneTerrain per ArduPilot vehicle;
- UploadTerrain: `upload`'s serving, on the upload's own link, until the vehicle has the ground, bounded.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.bridge.formats.mission_items import Flavour, WireItem
from missionplan.bridge.link.params import TERRAIN_FRAMES
from missionplan.bridge.link.readiness import Vehicle
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.session.terrain import (TerrainServed, TerrainServer, TerrainStatus, request_terrain_streams,
                                                wait_terrain_loaded)
from missionplan.bridge.transfer.uploader import MissionBackend, PymavlinkBackend
from missionplan.geo.dem import Ground
from missionplan.geo.dem_copy import read_ground_copy

from ..mission.plan_record import PlanRecord

# The copy holds the ground the plan read, the grid and up to planning.terrain.DEM_MARGIN_M (5.5 km) beyond it,
# where ArduPilot asks for its terrain grids (28 x 32 points at TERRAIN_SPACING, aligned to whole degrees):
# it is read whole, with a margin wider than any plan reads.
SERVE_MARGIN_M = 20_000.0
# TERRAIN_CHECK points per vehicle: one a second each until answered, so a long survey's hundreds of
# waypoints are thinned to this many, spread along the mission (the vehicle's own "pending 0" covers the
# grids of every waypoint: AP_Terrain loads them for the mission it holds).
MAX_CHECKED_POINTS = 24
CHECK_CELL_DEG = 1e-3  # about 100 m, ArduPilot's default grid spacing: two points closer than this add nothing
UPLOAD_LOAD_S = 30.0  # how long `upload` serves after the mission is on board (fly serves again before arming)
ASK_S = 5.0  # for the vehicle's answer to our stream requests


def plan_ground(plan_dir: Path, record: PlanRecord) -> Ground | None:
    """The ground of a plan folder made over a DEM (its copy, geo.dem_copy, read whole: around the grid and
    SERVE_MARGIN_M beyond); None for a plan taken over flat ground. GeoError, one line, when the copy is
    missing or unreadable."""
    georef = record.georeference
    if georef is None or georef.terrain is None:
        return None
    return read_ground_copy(plan_dir, georef.terrain, georef.frame, margin_m=SERVE_MARGIN_M)


def terrain_points(wire: Sequence[WireItem]) -> list[tuple[float, float]]:
    """(lat, lon) of the mission's terrain-frame items, one per CHECK_CELL_DEG cell, at most
    MAX_CHECKED_POINTS evenly spread along the mission (its first and last kept)."""
    cells: dict[tuple[int, int], tuple[float, float]] = {}
    for item in wire:
        if item.frame in TERRAIN_FRAMES:
            lat, lon = item.x / 1e7, item.y / 1e7
            cells.setdefault((round(lat / CHECK_CELL_DEG), round(lon / CHECK_CELL_DEG)), (lat, lon))
    points = list(cells.values())
    if len(points) <= MAX_CHECKED_POINTS:
        return points
    keep = np.unique(np.linspace(0, len(points) - 1, MAX_CHECKED_POINTS).round().astype(int))
    return [points[k] for k in keep]


def served_line(served: TerrainServed) -> str:
    """What a vehicle was served, in one line (the record's note at the end of its flight)."""
    line = (f"terrain served: {served.requests} TERRAIN_REQUESTs answered, {served.blocks_sent} blocks sent "
            f"({served.bytes_sent / 1000:.1f} kB)")
    missing = served.missing_line()
    return f"{line}; {missing}" if missing else line


class DroneTerrain:
    """One ArduPilot vehicle's ground: served through its session (every wait that reads the vehicle answers
    its TERRAIN_REQUESTs: readiness, commands, the follower's loop) from `attach` on."""

    def __init__(self, ground: Ground, spacing: int | None = None) -> None:
        self.server = TerrainServer(ground.height_amsl)
        self.spacing = spacing  # the TERRAIN_SPACING the plan checked its heights on (the upload sets it)
        self.status: TerrainStatus | None = None

    def attach(self, session: Any) -> None:
        """Answer the vehicle from now on (ArduPilot asks from its first seconds)."""
        session.serve_terrain(self.server)

    def ask(self, session: Any, deadline: float) -> list[str]:
        """Ask the vehicle for its TERRAIN_REQUEST and TERRAIN_REPORT streams (ArduPilot sends neither unless
        asked), so that it loads while it gets ready; the names of those it refused."""
        return request_terrain_streams(session, deadline)

    def wait_loaded(self, session: Any, deadline: float, wire: Sequence[WireItem]) -> TerrainStatus:
        """Serve until the vehicle reports no block pending and ground at its position, home and the
        mission's waypoints (terrain_points), or the deadline: its status (.loaded_ok, .line())."""
        self.status = wait_terrain_loaded(session, self.server, deadline, terrain_points(wire))
        return self.status

    def served_line(self) -> str:
        return served_line(self.server.served())


@dataclass(frozen=True)
class FleetTerrain:
    """The ground a flight serves to each of its ArduPilot vehicles."""

    ground: Ground
    spacing: int | None = None  # report.json georeference.terrain.spacing_m

    def for_vehicle(self, flavour: Flavour) -> DroneTerrain | None:
        """A vehicle's own server of the ground; None for a PX4 vehicle (its altitudes are above sea level)."""
        return DroneTerrain(self.ground, self.spacing) if flavour is Flavour.ARDUPILOT else None



class UploadTerrain:
    """`upload`: the ground served over the upload's own link to an ArduPilot vehicle, from before the
    parameters and the mission are sent (the vehicle asks again for what a transfer's reads left unanswered)
    until it reports the ground loaded for the mission's waypoints, bounded."""

    def __init__(self, session: VehicleSession, ground: Ground) -> None:
        self.session = session
        self.terrain = DroneTerrain(ground)
        self.terrain.attach(session)

    @classmethod
    def start(cls, backend: MissionBackend, ground: Ground, ask_s: float = ASK_S) -> UploadTerrain | None:
        """Serving begun on the backend's link; None when the vehicle is not ArduPilot, or when the backend
        owns its link (MAVSDK reads every message itself: nothing of ours would see the requests)."""
        if backend.vehicle.flavour is not Flavour.ARDUPILOT or not isinstance(backend, PymavlinkBackend):
            return None
        served = cls(VehicleSession(backend, Vehicle(backend.link, backend.vehicle)), ground)
        served.terrain.ask(served.session, time.monotonic() + ask_s)
        return served

    def finish(self, wire: Sequence[WireItem], seconds: float) -> TerrainStatus:
        """Serve until the vehicle has the ground of `wire`'s waypoints, at most `seconds`."""
        return self.terrain.wait_loaded(self.session, time.monotonic() + seconds, wire)
