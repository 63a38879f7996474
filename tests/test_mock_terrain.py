"""The mock autopilot over a ground (bridge/sim/mock_terrain.py): an ArduPilot mock vehicle given a hill asks the
ground station for its terrain as ArduCopter SITL does, is served by the ground station's own TerrainServer over a
real loopback link, refuses to arm until it has it, and flies terrain-frame items at their height above the terrain
it was sent; over the same hill ArduPilot and PX4 mock vehicles land on the true ground.

"Served ground" here is computed from the server's side: the DEM rounded to whole metres at the grid points the
server sent (formats.terrain_grid, checked against ArduCopter SITL's own grid in test_terrain_protocol.py), and
bilinear between the four around a point, as AP_Terrain reads it.
"""

from __future__ import annotations

import functools
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_DO_CHANGE_SPEED,
    CMD_NAV_LAND,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    to_wire,
)
from missionplan.bridge.formats.terrain_grid import block_bit, grid_info, grid_points
from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle
from missionplan.bridge.link.readiness import mission_mode_params
from missionplan.bridge.session.terrain import TerrainServer
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import MissionClient, Timeouts
from missionplan.cli.app import main
from missionplan.testing.dem_files import M_PER_DEG, hill, write_geotiff

HOME = (45.0700, 7.6800)
HILL_CENTRE = (45.0700, 7.6880)  # 630 m east of home
HEIGHT_M = 25.0  # the terrain-frame waypoints' height above the terrain
SPACING = 100
SPEEDUP = 40.0


class HillGround:
    """The true ground of these tests (geo.dem.Ground's shape): a 50 m hill east of home on a 230 m plain."""

    def height_amsl(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return hill(lat, lon, centre=HILL_CENTRE, peak_m=50.0, base_m=230.0, radius_m=500.0)


GROUND = HillGround()


def east_of_home(metres_east: float, metres_north: float = 0.0) -> tuple[float, float]:
    return (HOME[0] + metres_north / M_PER_DEG,
            HOME[1] + metres_east / (M_PER_DEG * math.cos(math.radians(HOME[0]))))


@functools.lru_cache(maxsize=None)
def _served_block(lat_e7: int, lon_e7: int, bit: int) -> np.ndarray:
    lat, lon = grid_points(lat_e7, lon_e7, SPACING, [bit])
    return np.rint(GROUND.height_amsl(lat[0], lon[0]))  # what TerrainServer sends: whole metres


def served_height(lat: float, lon: float) -> float:
    """The ground the vehicle was sent, at a point: bilinear between the four grid points around it."""
    info = grid_info(round(lat * 1e7), round(lon * 1e7), SPACING)

    def at(i: int, j: int) -> float:
        block = _served_block(info.grid_lat_e7, info.grid_lon_e7, block_bit(i, j))
        return float(block[(i % 4) * 4 + j % 4])

    i, j, fn, fe = info.idx_north, info.idx_east, info.frac_north, info.frac_east
    west = (1 - fn) * at(i, j) + fn * at(i + 1, j)
    east = (1 - fn) * at(i, j + 1) + fn * at(i + 1, j + 1)
    return (1 - fe) * west + fe * east


def command(link: Link, cmd: int, *params: float, sysid: int = 1) -> int:
    p = list(params) + [0.0] * (7 - len(params))
    link.mav.command_long_send(sysid, 1, cmd, 0, *p)
    deadline = time.monotonic() + 3
    while True:
        msg = link.recv(deadline)
        assert msg is not None, f"no COMMAND_ACK for {cmd}"
        if msg.get_type() == "COMMAND_ACK" and msg.command == cmd:
            return int(msg.result)


def ask_terrain_streams(link: Link) -> None:
    for msgid in (mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST, mavlink.MAVLINK_MSG_ID_TERRAIN_REPORT):
        assert command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msgid, 500_000) == mavlink.MAV_RESULT_ACCEPTED


def serve_until_loaded(link: Link, server: TerrainServer, timeout: float = 20.0) -> tuple[Any, list[float]]:
    """Answer the vehicle's TERRAIN_REQUESTs until it reports nothing pending and ground where it is: its last
    TERRAIN_REPORT, and when (wall clock) each request came."""
    asked: list[float] = []
    deadline = time.monotonic() + timeout
    while True:
        msg = link.recv(deadline)
        assert msg is not None, f"terrain not loaded in {timeout} s ({server.served()})"
        if msg.get_type() == "TERRAIN_REQUEST":
            asked.append(time.monotonic())
            server.answer(link, msg)
        elif msg.get_type() == "TERRAIN_REPORT" and msg.pending == 0 and msg.spacing == SPACING:
            return msg, asked


def terrain_mission(*far: tuple[float, float]) -> Mission:
    """Take off to 20 m, then waypoints 25 m above the terrain over the hill and back (then at `far` points,
    metres east and north of home), and home."""
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=20.0),
             MissionItem(CMD_DO_CHANGE_SPEED, FRAME_MISSION, param1=1, param2=10.0)]
    for east, north in ((50.0, 0.0), (1200.0, 0.0), (1200.0, 80.0), (50.0, 80.0), *far):
        lat, lon = east_of_home(east, north)
        items.append(MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_TERRAIN_ALT, x=lat, y=lon, z=HEIGHT_M))
    items.append(MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION))
    return Mission(items, home=(HOME[0], HOME[1], 0.0))


def ardupilot_mock(**options: Any) -> MockAutopilot:
    return MockAutopilot(homes={1: (HOME[0], HOME[1], 0.0)}, speedup=SPEEDUP, request_interval=0.02, ground=GROUND,
                         **options)


def test_a_mock_vehicle_over_a_hill_asks_for_its_terrain_and_reports_what_it_was_sent() -> None:
    server = TerrainServer(GROUND.height_amsl)
    with ardupilot_mock().start() as mock, Link(mock.client_url) as link:
        wait_vehicle(link, 1, timeout=3)
        assert mock.vehicle(1).options.home[2] == pytest.approx(float(GROUND.height_amsl(*HOME)))
        # Nothing is asked for before the ground station asks for the streams (ArduCopter 4.7).
        quiet_until = time.monotonic() + 0.3  # 12 simulated seconds: six request periods
        while (msg := link.recv(quiet_until)) is not None:
            assert msg.get_type() not in ("TERRAIN_REQUEST", "TERRAIN_REPORT")
        ask_terrain_streams(link)
        report, asked = serve_until_loaded(link, server)
        vehicle = mock.vehicle(1)
        # Its own grid and the 8 around it: 6 grids of 56 blocks at this home, as ArduCopter SITL reports a fresh
        # home (pending 336); one grid per 2 s of its clock at most.
        assert report.loaded == 336 and server.served().blocks_sent == 336
        # Six requests, one a grid; a loaded machine may let it ask a grid again (as ArduPilot does, 2 s on) before
        # the answer is in, or send one more that was not read yet.
        assert 6 <= len(asked) <= vehicle.terrain.requests_sent
        assert min(b - a for a, b in zip(asked, asked[1:])) >= 2.0 / SPEEDUP * 0.9
        assert report.terrain_height == pytest.approx(served_height(*HOME), abs=1e-3)
        assert report.current_height == pytest.approx(0.0, abs=1e-3)  # on the ground at home
        # TERRAIN_CHECK anywhere in what it holds: the ground it was sent, within 1 m of the DEM.
        for east in (-500.0, 0.0, 300.0, 630.0, 900.0, 1200.0):
            lat, lon = east_of_home(east, 40.0)
            link.mav.terrain_check_send(round(lat * 1e7), round(lon * 1e7))
            deadline = time.monotonic() + 3
            while True:
                msg = link.recv(deadline)
                assert msg is not None, "no TERRAIN_REPORT for a TERRAIN_CHECK"
                if msg.get_type() == "TERRAIN_REPORT" and (msg.lat, msg.lon) == (round(lat * 1e7), round(lon * 1e7)):
                    break
            assert msg.spacing == SPACING
            assert msg.terrain_height == pytest.approx(served_height(lat, lon), abs=1e-3)
            assert msg.terrain_height == pytest.approx(float(GROUND.height_amsl(lat, lon)), abs=1.0)


def test_it_refuses_to_arm_while_the_terrain_of_a_terrain_frame_mission_is_pending() -> None:
    server = TerrainServer(GROUND.height_amsl)
    with ardupilot_mock().start() as mock, Link(mock.client_url) as link:
        vehicle = wait_vehicle(link, 1, timeout=3)
        # A last waypoint 6 km north: beyond the grids around home, so that arming waits for its grid too.
        wire = to_wire(terrain_mission((0.0, 6000.0)), Flavour.ARDUPILOT)
        MissionClient(link, vehicle, Timeouts(item_timeout=0.2)).upload(0, wire)
        ask_terrain_streams(link)
        texts: list[str] = []
        link.mav.command_long_send(1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        deadline = time.monotonic() + 3
        while (msg := link.recv(deadline)) is not None:
            if msg.get_type() == "STATUSTEXT":
                texts.append(msg.text)
            if msg.get_type() == "COMMAND_ACK" and msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
                assert msg.result == mavlink.MAV_RESULT_FAILED
                break
        assert "PreArm: waiting for terrain data" in texts
        assert not mock.vehicle(1).flight.state.armed
        serve_until_loaded(link, server)
        # Loaded around it; the mission's points (4 around each waypoint, 1 km away, and itself) come after.
        deadline = time.monotonic() + 20
        while (result := command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)) != mavlink.MAV_RESULT_ACCEPTED:
            assert result == mavlink.MAV_RESULT_FAILED and time.monotonic() < deadline
            serve_until_loaded(link, server)
        assert server.served().blocks_sent > 336  # the far waypoint's grids too
        assert mock.vehicle(1).terrain.statistics()[0] == 0


@pytest.mark.flight
@pytest.mark.parametrize("sitl_like", [False, True], ids=["straight-legs", "copter-model"])
def test_a_terrain_frame_mission_is_flown_at_its_height_above_the_terrain_it_was_sent(sitl_like: bool) -> None:
    server = TerrainServer(GROUND.height_amsl)
    samples: list[tuple[float, float, float]] = []  # lat, lon, alt AMSL along the terrain legs
    heights: list[float] = []  # TERRAIN_REPORT's current_height there
    with ardupilot_mock(sitl_like=sitl_like).start() as mock, Link(mock.client_url) as link:
        vehicle = wait_vehicle(link, 1, timeout=3)
        wire = to_wire(terrain_mission(), Flavour.ARDUPILOT)
        MissionClient(link, vehicle, Timeouts(item_timeout=0.2)).upload(0, wire)
        first_wp = next(item.seq for item in wire if item.frame == FRAME_GLOBAL_TERRAIN_ALT)
        ask_terrain_streams(link)
        assert command(link, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                       20_000) == mavlink.MAV_RESULT_ACCEPTED
        deadline = time.monotonic() + 30
        while command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) != mavlink.MAV_RESULT_ACCEPTED:
            assert time.monotonic() < deadline, "never armed"
            serve_until_loaded(link, server)
        assert command(link, mavlink.MAV_CMD_DO_SET_MODE, *mission_mode_params(Flavour.ARDUPILOT)) == mavlink.MAV_RESULT_ACCEPTED
        assert command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED
        current, armed_seen = 0, True
        deadline = time.monotonic() + 30
        while armed_seen:
            msg = link.recv(deadline)
            assert msg is not None, "the flight did not end"
            kind = msg.get_type()
            if kind == "TERRAIN_REQUEST":
                server.answer(link, msg)  # it asks as it moves, as ArduCopter does
            elif kind == "MISSION_CURRENT":
                current = int(msg.seq)
            elif kind == "HEARTBEAT":
                armed_seen = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            elif first_wp < current <= first_wp + 3:  # on the legs between terrain-frame waypoints
                if kind == "GLOBAL_POSITION_INT":
                    samples.append((msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000))
                elif kind == "TERRAIN_REPORT" and msg.spacing:
                    heights.append(msg.current_height)
        state = mock.vehicle(1).flight.state
    assert len(samples) > 50
    errors = [alt - (served_height(lat, lon) + HEIGHT_M) for lat, lon, alt in samples]
    assert max(abs(e) for e in errors) <= 1.0, max(errors, key=abs)
    climbs = [alt for _, _, alt in samples]
    assert max(climbs) - min(climbs) > 30.0  # it did follow the hill (a relative flight would stay level)
    assert heights and all(h == pytest.approx(HEIGHT_M, abs=0.5) for h in heights)
    assert state.on_ground and state.alt == pytest.approx(0.0, abs=0.02)  # RTL: home, on its ground


@pytest.mark.flight
@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4])
def test_it_lands_on_the_true_ground_and_reports_sea_level_altitudes(flavour: Flavour) -> None:
    """A LAND item on the hill's slope: relative altitude ground - home's ground, AMSL the DEM's. PX4's items are
    sea-level altitudes (frame 0), flown as they are; ArduPilot's waypoint is relative here."""
    home_amsl = float(GROUND.height_amsl(*HOME))
    lat, lon = east_of_home(400.0)
    ground_there = float(GROUND.height_amsl(lat, lon))
    frame, z = (FRAME_GLOBAL, ground_there + 30.0) if flavour is Flavour.PX4 else (FRAME_GLOBAL_RELATIVE_ALT, 60.0)
    mission = Mission([MissionItem(CMD_NAV_TAKEOFF, frame, x=HOME[0], y=HOME[1],
                                   z=home_amsl + 20.0 if flavour is Flavour.PX4 else 20.0),
                       MissionItem(CMD_NAV_WAYPOINT, frame, x=lat, y=lon, z=z),
                       MissionItem(CMD_NAV_LAND, frame, x=lat, y=lon, z=0.0)], home=(HOME[0], HOME[1], home_amsl))
    last: Any = None
    with MockAutopilot(homes={1: (HOME[0], HOME[1], 0.0)}, flavour=flavour, speedup=SPEEDUP, request_interval=0.02,
                       ground=GROUND).start() as mock, Link(mock.client_url) as link:
        vehicle = wait_vehicle(link, 1, timeout=3)
        MissionClient(link, vehicle, Timeouts(item_timeout=0.2)).upload(0, to_wire(mission, flavour))
        assert command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
        assert command(link, mavlink.MAV_CMD_DO_SET_MODE, *mission_mode_params(flavour)) == mavlink.MAV_RESULT_ACCEPTED
        assert command(link, mavlink.MAV_CMD_MISSION_START) == mavlink.MAV_RESULT_ACCEPTED
        assert mock.wait_until(lambda m: not m.vehicle(1).flight.state.armed, timeout=20)
        landed_ms = mock.vehicle(1).time_boot_ms(time.monotonic())
        deadline = time.monotonic() + 3
        while last is None or last.time_boot_ms <= landed_ms:
            msg = link.recv(deadline)
            assert msg is not None, "no GLOBAL_POSITION_INT after the landing"
            if msg.get_type() == "GLOBAL_POSITION_INT":
                last = msg
        state = mock.vehicle(1).flight.state
    assert state.on_ground and math.dist((state.lat, state.lon), (lat, lon)) < 1e-6
    assert state.alt == pytest.approx(ground_there - home_amsl, abs=0.02)  # relative: its ground less home's
    assert last.relative_alt / 1000 == pytest.approx(ground_there - home_amsl, abs=0.05)
    assert last.alt / 1000 == pytest.approx(ground_there, abs=0.05)  # sea level: home's plus relative


def test_the_mock_command_gives_every_vehicle_the_ground_of_its_dem(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    dem = write_geotiff(tmp_path / "hill.tif", GROUND.height_amsl, (45.05, 7.66, 45.09, 7.71), 30.0)
    made: list[MockAutopilot] = []
    monkeypatch.setattr(MockAutopilot, "start", lambda self: made.append(self) or self)  # nothing served: its set-up
    assert main(["mock", "--sysid", "1,2", "--listen", "udpin:127.0.0.1:0", "--home", f"{HOME[0]},{HOME[1]},5",
                 "--dem", str(dem), "--duration", "0.01"]) == 0
    out = capsys.readouterr().out
    for sysid, vehicle in made[0].vehicles.items():
        lat, lon, alt = vehicle.options.home
        assert alt == pytest.approx(float(GROUND.height_amsl(lat, lon)), abs=0.5)  # the DEM's, not --home's 5 m
        assert f"system {sysid} starts at {lat:.7f}, {lon:.7f}, {alt:g} m AMSL" in out
        assert vehicle.terrain is not None and vehicle.params["TERRAIN_ENABLE"] == 1.0
    assert f"ground: {dem} (30 m)" in out
    # One line when the DEM does not reach a home, or a vehicle has no home to read it around.
    assert main(["mock", "--sysid", "1", "--listen", "udpin:127.0.0.1:0", "--home", "45.2,7.68", "--dem", str(dem),
                 "--duration", "0.01"]) == 2
    assert main(["mock", "--sysid", "1", "--listen", "udpin:127.0.0.1:0", "--dem", str(dem), "--duration", "0.01"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"missionplan: DEM {dem}: no file covers lat 45.20000") and len(err) == 2
    assert err[1] == "missionplan: --dem needs each vehicle's home (--home or --plan): none for system id 1"
