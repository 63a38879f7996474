"""Real ArduCopter SITL (../shared/sitl/arducopter) takes its terrain from us over MAVLink.

With no terrain files in its folder, SITL asks the ground station for the ground (TERRAIN_REQUEST) from its
first seconds. One SITL for the module, on a hill made here (a plain function: a slope and a round hill),
served by missionplan.bridge.session.terrain's TerrainServer through a VehicleSession: the vehicle reports no
block pending and blocks loaded, and the heights it reports (TERRAIN_REPORT) at its home and at points
checked 500 m away (TERRAIN_CHECK) are our ground within 1 m (int16 metres, bilinear between 100 m points).
The requests and bytes it took are printed (`pytest -s`) for the bench and the docs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest

from missionplan.bridge.link.connection import Link
from missionplan.bridge.link.params import ParamClient, terrain_settings
from missionplan.bridge.session.terrain import (TERRAIN_REPORTED, TerrainServer, TerrainStatus, check_terrain,
                                                read_terrain_params, wait_terrain_loaded)
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.testing.arducopter import ArduCopter, sitl_or_skip

pytestmark = pytest.mark.sitl  # starts a real autopilot

HOME_LAT, HOME_LON = 44.4056, 8.9463  # Genoa
M_PER_DEG = 111_320.0
LOAD_S = 90.0  # a fresh SITL needs a position first; then about 2 s of its clock per grid


def local_m(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """North and east metres from home (flat: the hill is 2 km across)."""
    return (lat - HOME_LAT) * M_PER_DEG, (lon - HOME_LON) * M_PER_DEG * math.cos(math.radians(HOME_LAT))


def hill(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """A slope rising 5 m per 100 m east, with a 60 m round hill (1 km wide) 300 m north-east of home."""
    north, east = local_m(np.asarray(lat, float), np.asarray(lon, float))
    r2 = (north - 300.0) ** 2 + (east - 300.0) ** 2
    return 150.0 + 0.05 * east + 60.0 * np.exp(-r2 / (2 * 1000.0 ** 2))


def ground_at(lat: float, lon: float) -> float:
    return float(hill(np.array([lat]), np.array([lon]))[0])


def around_home(distance_m: float) -> list[tuple[float, float]]:
    """Points north, east, south and west of home."""
    dlat = distance_m / M_PER_DEG
    dlon = distance_m / (M_PER_DEG * math.cos(math.radians(HOME_LAT)))
    return [(HOME_LAT + dlat, HOME_LON), (HOME_LAT, HOME_LON + dlon), (HOME_LAT - dlat, HOME_LON),
            (HOME_LAT, HOME_LON - dlon)]


@pytest.fixture(scope="module")
def served() -> Iterator[tuple[VehicleSession, TerrainServer, TerrainStatus, float]]:
    """One SITL on the hill, its terrain served until loaded: (session, server, status, seconds it took)."""
    sitl_or_skip()
    with ArduCopter(sysid=1, home=(HOME_LAT, HOME_LON, round(ground_at(HOME_LAT, HOME_LON), 1), 0.0)) as sitl, \
            Link(sitl.url) as link:
        session = VehicleSession.open(link, 1, 30.0, Timeouts())
        server = TerrainServer(hill)
        started = time.monotonic()
        status = wait_terrain_loaded(session, server, started + LOAD_S, around_home(500.0))
        yield session, server, status, time.monotonic() - started
        session.close()


def test_sitl_loads_the_terrain_we_serve(served):
    session, server, status, took_s = served
    assert status.loaded_ok, status.line()
    assert status.pending == 0 and status.loaded is not None and status.loaded > 0
    done = server.served()
    print(f"\nSITL terrain: {done.requests} TERRAIN_REQUESTs answered, {done.blocks_sent} TERRAIN_DATA, "
          f"{done.bytes_sent} bytes, loaded {status.loaded} blocks in {took_s:.1f} s (speed-up 10)\n"
          f"{status.line()}")
    assert done.blocks_sent >= status.loaded and done.blocks_without_ground == 0


def test_sitl_reports_our_ground_at_home_and_500_m_away(served):
    session, server, status, _ = served
    assert status.own is not None
    assert status.own.terrain_height == pytest.approx(ground_at(status.own.lat, status.own.lon), abs=1.0)
    assert len(status.points) == 4
    for point in status.points:
        assert point.height == pytest.approx(ground_at(point.lat, point.lon), abs=1.0), point
    # Checked again later, farther out (still in the grids around home it loaded), the answers match too.
    far = check_terrain(session, around_home(1200.0), time.monotonic() + 20.0)
    for point in far.points:
        assert point.height == pytest.approx(ground_at(point.lat, point.lon), abs=1.0), point


def test_sitl_has_the_terrain_parameters_we_set_and_report(served):
    session, _, _, _ = served
    client = ParamClient(session.link, session.backend.vehicle)
    for setting in terrain_settings(session.backend.vehicle):
        assert client.set(setting.name, setting.value) == setting.value  # the names exist on ArduCopter 4.7
    reported = read_terrain_params(session)
    assert set(reported) == set(TERRAIN_REPORTED)
    assert reported["TERRAIN_SPACING"] == 100.0
