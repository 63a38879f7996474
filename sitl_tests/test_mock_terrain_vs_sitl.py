"""Differential test of the terrain protocol: real ArduCopter SITL (no terrain files) and the ArduPilot mock given
the same ground (bridge/sim/mock_terrain.py), at the same home with the same terrain-frame mission, each served by
the ground station's own code (session.terrain.wait_terrain_loaded through a VehicleSession, a TerrainServer that
records every TERRAIN_REQUEST) until loaded: they must send the same terrain message kinds, ask first for the same
grid, ask for the same grids with the same spacing among their first requests, and need requests and blocks in the
same order of magnitude. What each took is printed (`pytest -s`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    to_wire,
)
from missionplan.bridge.link.connection import Link
from missionplan.bridge.session.terrain import TerrainServer, TerrainStatus, wait_terrain_loaded
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import MissionClient, Timeouts
from missionplan.testing.arducopter import ArduCopter, sitl_or_skip
from missionplan.testing.dem_files import M_PER_DEG, hill

pytestmark = pytest.mark.sitl  # starts a real autopilot

HOME = (44.4056, 8.9463)  # Genoa: the home test_terrain_protocol.py knows SITL's first grid for
LOAD_S = 120.0  # a fresh SITL needs its position first (35-40 s of its clock), then about 2 s per grid
FIRST_GRIDS = 6  # a fresh home's own grid and those around it (SITL: pending 336 = 6 x 56 at a fresh home)


def ground(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return hill(lat, lon, centre=(HOME[0], HOME[1] + 600.0 / (M_PER_DEG * math.cos(math.radians(HOME[0])))),
                peak_m=50.0, base_m=120.0, radius_m=500.0)


class HillGround:
    def height_amsl(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return ground(lat, lon)


def mission() -> Mission:
    """Take off, then 30 m above the terrain over the hill and back (1.2 km east), home."""
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=20.0)]
    for east in (50.0, 1200.0, 50.0):
        lon = HOME[1] + east / (M_PER_DEG * math.cos(math.radians(HOME[0])))
        items.append(MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_TERRAIN_ALT, x=HOME[0], y=lon, z=30.0))
    items.append(MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION))
    home_amsl = float(ground(np.array([HOME[0]]), np.array([HOME[1]]))[0])
    return Mission(items, home=(HOME[0], HOME[1], home_amsl))


class RecordingServer(TerrainServer):
    """A TerrainServer that keeps each TERRAIN_REQUEST it answers: (lat, lon, spacing, mask)."""

    def __init__(self) -> None:
        super().__init__(ground)
        self.asked: list[tuple[int, int, int, int]] = []

    def answer(self, via: Any, msg: Any) -> int:
        if msg.get_type() == "TERRAIN_REQUEST":
            self.asked.append((int(msg.lat), int(msg.lon), int(msg.grid_spacing), int(msg.mask)))
        return super().answer(via, msg)


@dataclass
class Served:
    """What one vehicle asked for and said until its terrain was loaded."""

    status: TerrainStatus
    asked: list[tuple[int, int, int, int]]
    kinds: set[str] = field(default_factory=set)  # the terrain messages it sent

    def grids(self, count: int) -> list[tuple[int, int, int]]:
        """The first `count` distinct grids asked for (corner and spacing), in order."""
        return list(dict.fromkeys((lat, lon, spacing) for lat, lon, spacing, _ in self.asked))[:count]

    @property
    def blocks(self) -> int:
        return self.status.served.blocks_sent if self.status.served is not None else 0


def serve(url: str, sysid: int) -> Served:
    """Upload the mission to the vehicle at `url` and serve its terrain until it has it."""
    with Link(url) as link:
        session = VehicleSession.open(link, sysid, 30.0, Timeouts())
        try:
            MissionClient(link, session.backend.vehicle, Timeouts()).upload(0, to_wire(mission(), Flavour.ARDUPILOT))
            server = RecordingServer()
            points = [(item.x, item.y) for item in mission().items if item.command == CMD_NAV_WAYPOINT]
            seen: set[str] = set()
            original = session.take

            def take(msg: Any) -> None:
                if msg.get_type().startswith("TERRAIN_"):
                    seen.add(msg.get_type())
                original(msg)

            session.take = take  # type: ignore[method-assign]  # every message of the wait passes here first
            status = wait_terrain_loaded(session, server, time.monotonic() + LOAD_S, points)
        finally:
            session.close()
    return Served(status, server.asked, seen)


def test_the_mock_asks_for_the_terrain_as_arducopter_sitl_does() -> None:
    sitl_or_skip()
    home_amsl = mission().home[2]
    with ArduCopter(sysid=1, home=(HOME[0], HOME[1], round(home_amsl, 1), 0.0)) as sitl:
        real = serve(sitl.url, 1)
    with MockAutopilot("tcpin:127.0.0.1:0", homes={1: (HOME[0], HOME[1], 0.0)}, speedup=10.0, gps_fix_after=35.0,
                       streams_until_asked=True, ground=HillGround()).start() as mock:
        mocked = serve(mock.client_url, 1)
    for who, run in (("SITL", real), ("mock", mocked)):
        print(f"\n{who}: {len(run.asked)} TERRAIN_REQUESTs, {run.blocks} blocks, {run.status.loaded} loaded; "
              f"kinds {sorted(run.kinds)}; first grids {run.grids(FIRST_GRIDS)}\n  {run.status.line()}")
    assert real.status.loaded_ok, real.status.line()
    assert mocked.status.loaded_ok, mocked.status.line()
    assert {"TERRAIN_REQUEST", "TERRAIN_REPORT"} <= real.kinds
    assert mocked.kinds == real.kinds
    assert mocked.asked[0][:3] == real.asked[0][:3]  # its own grid first, whole (all 56 blocks asked)
    assert mocked.asked[0][3] == real.asked[0][3] == (1 << 56) - 1
    assert set(mocked.grids(FIRST_GRIDS)) == set(real.grids(FIRST_GRIDS))
    assert {spacing for _, _, spacing, _ in mocked.asked} == {spacing for _, _, spacing, _ in real.asked} == {100}
    for name, mine, theirs in (("requests", len(mocked.asked), len(real.asked)), ("blocks", mocked.blocks, real.blocks),
                               ("loaded", mocked.status.loaded or 0, real.status.loaded or 0)):
        assert theirs / 10 <= mine <= theirs * 10, f"{name}: mock {mine}, SITL {theirs}"
