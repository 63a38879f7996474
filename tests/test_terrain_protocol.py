"""The MAVLink terrain protocol, ground station side (missionplan.bridge.session.terrain), without SITL.

The vehicle here is written from ArduPilot's AP_Terrain (TerrainUtil.cpp calculate_grid_info, TerrainGCS.cpp
handle_terrain_data and send_terrain_report, AP_Terrain.cpp height_amsl, AP_Math's Location), independently of
the module under test: its grid corner for SITL's home is the one ArduCopter SITL asked for, so the TERRAIN_DATA
we send is checked where the vehicle will read it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.connection import VehicleInfo, command_long, mavlink
from missionplan.bridge.link.readiness import Vehicle
from missionplan.bridge.link.params import terrain_settings
from missionplan.bridge.session.terrain import TERRAIN_REPORTED, TerrainServer, check_terrain, wait_terrain_loaded
from missionplan.bridge.session.vehicle_session import VehicleSession

LSF = 0.011131884502145034  # AP_Math LOCATION_SCALING_FACTOR: metres per 1e-7 degree
LSF_INV = 89.83204953368922
E7 = 10_000_000
SPACING = 100
HOME_E7 = (444_056_000, 89_463_000)  # Genoa
SITL_CORNER = (443_880_744, 89_121_236)  # the grid ArduCopter SITL asked for first at that home (observed)
VEHICLE = 7


# ------------------------------------------------------------------ ArduPilot, as its source says
def longitude_scale(lat_e7: float) -> float:
    return max(math.cos(math.radians(lat_e7 * 1e-7)), 0.01)


def distance_ne(lat1: int, lon1: int, lat2: float, lon2: float) -> tuple[float, float]:
    """Location::get_distance_NE: metres north and east from the first position to the second."""
    return (lat2 - lat1) * LSF, (lon2 - lon1) * LSF * longitude_scale((lat1 + lat2) / 2)


def offset(lat: int, lon: int, north: float, east: float) -> tuple[int, int]:
    """Location::offset (offset_latlng)."""
    dlat = int(north * LSF_INV)
    return lat + dlat, lon + int(east * LSF_INV / longitude_scale(lat + dlat / 2))


def grid_info(lat: int, lon: int, spacing: int) -> tuple[tuple[int, int], int, int, float, float]:
    """calculate_grid_info: (the grid's corner, idx_x, idx_y, frac_x, frac_y); x is north."""
    ref_lat, ref_lon = lat // E7 * E7, lon // E7 * E7
    north, east = distance_ne(ref_lat, ref_lon, lat, lon)
    ix, iy = int(north / spacing), int(east / spacing)
    corner = offset(ref_lat, ref_lon, ix // 24 * 24 * spacing, iy // 28 * 28 * spacing)
    return corner, ix % 24, iy % 28, (north - ix * spacing) / spacing, (east - iy * spacing) / spacing


def degree_offsets(lat_deg: np.ndarray, lon_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """North and east metres from the whole-degree corner, the vehicle's own measure of a position."""
    lat, lon = np.asarray(lat_deg) * E7, np.asarray(lon_deg) * E7
    ref_lat, ref_lon = np.floor(lat / E7) * E7, np.floor(lon / E7) * E7
    scale = np.maximum(np.cos(np.radians((ref_lat + lat) / 2 * 1e-7)), 0.01)
    return (lat - ref_lat) * LSF, (lon - ref_lon) * LSF * scale


def tilted_plane(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """1 m up per 10 m east and 2 cm per metre north of the degree corner: a height per grid point that
    tells east from north."""
    north, east = degree_offsets(lat, lon)
    return 100.0 + 0.1 * east + 0.02 * north


class FakeArduPilot:
    """A link to one ArduPilot vehicle's terrain code: what we send is parsed and acted on as AP_Terrain does;
    every recv() with nothing queued is one run of its terrain stream (TERRAIN_REPORT, then a TERRAIN_REQUEST
    for the first grid it lacks). Our side's link: `mav`, `recv`, `command_long`."""

    url = "fake:terrain"

    def __init__(self, home: tuple[int, int] = HOME_E7, spacing: int = SPACING) -> None:
        self.home, self.spacing = home, spacing
        self.mav = mavlink.MAVLink(self, srcSystem=255, srcComponent=190)  # our side writes into write()
        self.vehicle = mavlink.MAVLink(None, srcSystem=VEHICLE, srcComponent=1)
        self.parser = mavlink.MAVLink(None)
        self.queue: deque[Any] = deque()
        self.grids: dict[tuple[int, int], tuple[np.ndarray, int]] = {}
        self.streams: set[int] = set()
        self.received: list[Any] = []
        self.rested = False
        self.ack_rtt_s: dict[int, float] = {}
        self.want(home)

    def want(self, point: tuple[int, int]) -> None:
        corner = grid_info(*point, self.spacing)[0]
        self.grids.setdefault(corner, (np.zeros((28, 32), np.int16), 0))

    # what we send
    def write(self, buf: bytes) -> None:
        for msg in self.parser.parse_buffer(buf) or []:
            self.received.append(msg)
            kind = msg.get_type()
            if kind == "COMMAND_LONG":
                self.streams.add(int(msg.param1))
                self.emit(self.vehicle.command_ack_encode(msg.command, mavlink.MAV_RESULT_ACCEPTED))
            elif kind == "TERRAIN_CHECK":
                self.want((msg.lat, msg.lon))
                self.emit(self.report((msg.lat, msg.lon)))
            elif kind == "TERRAIN_DATA" and (msg.lat, msg.lon) in self.grids and msg.grid_spacing == self.spacing:
                heights, bitmap = self.grids[(msg.lat, msg.lon)]
                x0, y0 = msg.gridbit // 8 * 4, msg.gridbit % 8 * 4  # handle_terrain_data
                heights[x0:x0 + 4, y0:y0 + 4] = np.asarray(msg.data, np.int16).reshape(4, 4)
                self.grids[(msg.lat, msg.lon)] = (heights, bitmap | 1 << msg.gridbit)

    def emit(self, msg: Any) -> None:
        self.queue.append(self.parser.parse_buffer(msg.pack(self.vehicle))[0])

    # the vehicle's side
    def height(self, point: tuple[int, int]) -> float | None:
        """height_amsl: bilinear between the four grid points around it, None without all four."""
        corner, ix, iy, fx, fy = grid_info(*point, self.spacing)
        if corner not in self.grids:
            return None
        heights, bitmap = self.grids[corner]
        if any(not bitmap >> (y // 4 + 8 * (x // 4)) & 1 for x in (ix, ix + 1) for y in (iy, iy + 1)):
            return None
        h = heights.astype(float)
        return ((1 - fy) * ((1 - fx) * h[ix, iy] + fx * h[ix + 1, iy])
                + fy * ((1 - fx) * h[ix, iy + 1] + fx * h[ix + 1, iy + 1]))

    def report(self, point: tuple[int, int]) -> Any:
        here, home = self.height(point), self.height(self.home)
        ok = here is not None and home is not None
        loaded = sum(bin(bitmap).count("1") for _, bitmap in self.grids.values())
        return self.vehicle.terrain_report_encode(point[0], point[1], self.spacing if ok else 0,
                                                  here if ok else 0.0, 0.0, 56 * len(self.grids) - loaded, loaded)

    def recv(self, deadline: float) -> Any | None:
        """The next message; with nothing queued, None once (a read that ends a listen), then a stream run."""
        if not self.queue:
            if self.rested or mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST not in self.streams:
                self.rested = False
                return None
            self.rested = True
            self.emit(self.report(self.home))
            for corner, (_, bitmap) in self.grids.items():
                if bitmap != (1 << 56) - 1:
                    self.emit(self.vehicle.terrain_request_encode(*corner, self.spacing, ((1 << 56) - 1) & ~bitmap))
                    break
        return self.queue.popleft()

    def command_long(self, *args: Any, **kwargs: Any) -> int | None:
        return command_long(self, *args, **kwargs)

    def signing_hint(self, sysid: int) -> str:
        return ""

    def sent(self, kind: str) -> list[Any]:
        return [m for m in self.received if m.get_type() == kind]


def request(corner: tuple[int, int], mask: int, spacing: int = SPACING) -> Any:
    """A TERRAIN_REQUEST as it arrives from the vehicle (parsed off the wire, its sender in the header)."""
    vehicle = mavlink.MAVLink(None, srcSystem=VEHICLE, srcComponent=1)
    return mavlink.MAVLink(None).parse_buffer(vehicle.terrain_request_encode(*corner, spacing, mask).pack(vehicle))[0]


def session_on(link: FakeArduPilot) -> VehicleSession:
    info = VehicleInfo(VEHICLE, 1, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR,
                       Flavour.ARDUPILOT, False)
    return VehicleSession(backend=None, vehicle=Vehicle(link, info))  # type: ignore[arg-type]


# ------------------------------------------------------------------ the layout
def test_the_grid_corner_of_this_vehicle_model_is_the_one_sitl_asked_for():
    assert grid_info(*HOME_E7, SPACING)[0] == SITL_CORNER


def test_each_height_is_the_ground_where_ardupilot_reads_it():
    link = FakeArduPilot()
    server = TerrainServer(tilted_plane)
    assert server.answer(link, request(SITL_CORNER, (1 << 56) - 1)) == 56
    data = link.sent("TERRAIN_DATA")
    assert [m.gridbit for m in data] == list(range(56))
    assert all((m.lat, m.lon, m.grid_spacing) == (*SITL_CORNER, SPACING) for m in data)
    # The grid's point (i, j) lies (24 gx + i) * spacing north and (28 gy + j) * spacing east of the degree corner.
    north0, east0 = distance_ne(SITL_CORNER[0] // E7 * E7, SITL_CORNER[1] // E7 * E7, *SITL_CORNER)
    gx, gy = round(north0 / (24 * SPACING)), round(east0 / (28 * SPACING))
    for m in data:
        i0, j0 = m.gridbit // 8 * 4, m.gridbit % 8 * 4  # 8 blocks east, then the next row north
        for k, height in enumerate(m.data):
            i, j = i0 + k // 4, j0 + k % 4  # data[4 x + y]: x north, y east
            expected = 100 + 0.1 * (28 * gy + j) * SPACING + 0.02 * (24 * gx + i) * SPACING
            assert height == round(expected), (m.gridbit, k)
    # Read back as the vehicle reads: the plane anywhere in the grid, within the int16 rounding.
    rng = np.random.default_rng(3)
    heights, bitmap = link.grids[SITL_CORNER]
    assert bitmap == (1 << 56) - 1
    for _ in range(200):
        north, east = rng.uniform(0, 23.9 * SPACING), rng.uniform(0, 27.9 * SPACING)  # points this grid serves
        point = offset(*SITL_CORNER, north, east)
        truth = float(tilted_plane(np.array([point[0] / E7]), np.array([point[1] / E7]))[0])
        assert link.height(point) == pytest.approx(truth, abs=0.51)


def test_only_the_blocks_the_mask_asks_for_are_sent():
    link = FakeArduPilot()
    server = TerrainServer(tilted_plane)
    assert server.answer(link, request(SITL_CORNER, 1 << 0 | 1 << 9 | 1 << 55)) == 3
    assert [m.gridbit for m in link.sent("TERRAIN_DATA")] == [0, 9, 55]
    assert server.answer(link, request(SITL_CORNER, 0)) == 0
    served = server.served()
    assert (served.requests, served.blocks_sent) == (2, 3)
    assert served.bytes_sent == sum(len(m.get_msgbuf()) for m in link.sent("TERRAIN_DATA"))


def test_all_heights_of_a_request_are_asked_for_in_one_call():
    calls: list[int] = []

    def ground(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        calls.append(lat.size)
        return tilted_plane(lat, lon)

    TerrainServer(ground).answer(FakeArduPilot(), request(SITL_CORNER, (1 << 20) - 1))
    assert calls == [20 * 16]


def test_blocks_without_ground_are_not_sent_but_counted_with_where():
    corner_east = degree_offsets(np.array([SITL_CORNER[0] / E7]), np.array([SITL_CORNER[1] / E7]))[1][0]

    def half_known(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """The plane up to 1550 m east of the grid's corner, nothing beyond."""
        return np.where(degree_offsets(lat, lon)[1] > corner_east + 1550.0, np.nan, tilted_plane(lat, lon))

    link = FakeArduPilot()
    server = TerrainServer(half_known)
    sent = server.answer(link, request(SITL_CORNER, (1 << 56) - 1))
    # Block columns 0..3 end 1500 m east of the corner: all in; column 4 starts at 1600 m: out, in all 7 rows.
    assert sent == 7 * 4
    assert sorted({m.gridbit % 8 for m in link.sent("TERRAIN_DATA")}) == [0, 1, 2, 3]
    again = server.answer(link, request(SITL_CORNER, (1 << 56) - 1))
    served = server.served()
    assert again == sent and served.blocks_without_ground == 7 * 4  # the same blocks, counted once
    lat, lon = served.no_ground_at
    assert served.missing_line() == f"no ground in the DEM for 28 terrain blocks (the first at {lat:.5f}, {lon:.5f})"
    assert math.isnan(half_known(np.array([lat]), np.array([lon]))[0])


# ------------------------------------------------------------------ the session
def test_the_session_answers_terrain_requests_in_any_wait_once_it_serves_terrain():
    link = FakeArduPilot()
    session = session_on(link)
    link.emit(link.vehicle.terrain_request_encode(*SITL_CORNER, SPACING, 0b111))
    session.listen(time.monotonic() + 0.05)
    assert link.sent("TERRAIN_DATA") == []  # no server: nothing answers
    session.serve_terrain(TerrainServer(tilted_plane))
    link.emit(link.vehicle.terrain_request_encode(*SITL_CORNER, SPACING, 0b111))
    session.wait_ready(time.monotonic() + 0.05)  # a readiness wait reads the vehicle: the request is answered
    assert [m.gridbit for m in link.sent("TERRAIN_DATA")] == [0, 1, 2]
    assert session.terrain_server is not None and session.terrain_server.served().requests == 1


def test_wait_terrain_loaded_serves_until_the_vehicle_has_its_ground_and_the_points():
    link = FakeArduPilot()
    session = session_on(link)
    far = offset(*HOME_E7, 4000.0, 3000.0)  # another grid than home's
    points = [(HOME_E7[0] / E7, HOME_E7[1] / E7), (far[0] / E7, far[1] / E7)]
    status = wait_terrain_loaded(session, TerrainServer(tilted_plane), time.monotonic() + 10.0, points)
    assert status.loaded_ok, status.line()
    assert {mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST, mavlink.MAVLINK_MSG_ID_TERRAIN_REPORT} <= link.streams
    assert status.pending == 0 and status.loaded == 56 * len(link.grids) and len(link.grids) >= 2
    for point in status.points:
        truth = float(tilted_plane(np.array([point.lat]), np.array([point.lon]))[0])
        assert point.height == pytest.approx(truth, abs=0.51)
    assert status.line().startswith("terrain loaded after ")
    # the server stays: a later request (the vehicle moved) is answered
    link.emit(link.vehicle.terrain_request_encode(*far, SPACING, 1))
    session.listen(time.monotonic() + 0.05)
    assert link.sent("TERRAIN_DATA")[-1].gridbit == 0
    # and a check of points already loaded answers at once
    again = check_terrain(session, points, time.monotonic() + 5.0)
    assert [p.height for p in again.points] == [p.height for p in status.points]


def test_wait_terrain_loaded_is_bounded_and_says_what_is_missing():
    def no_ground_north(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return np.where(lat > HOME_E7[0] / E7 + 0.01, np.nan, tilted_plane(lat, lon))

    link = FakeArduPilot()
    north = offset(*HOME_E7, 5000.0, 0.0)
    started = time.monotonic()
    status = wait_terrain_loaded(session_on(link), TerrainServer(no_ground_north), time.monotonic() + 0.5,
                                 [(north[0] / E7, north[1] / E7)])
    assert time.monotonic() - started < 2.0
    assert not status.loaded_ok and status.pending and status.pending > 0
    line = status.line()
    assert line.startswith("terrain not loaded after 0.5 s: ")
    assert f"1 of 1 points without ground (the first at {north[0] / E7:.5f}, {north[1] / E7:.5f})" in line
    assert "no ground in the DEM for " in line and "\n" not in line


# ------------------------------------------------------------------ parameters
def test_terrain_settings_for_an_ardupilot_multirotor_only():
    copter = VehicleInfo(1, 1, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR, Flavour.ARDUPILOT,
                         False)
    px4 = VehicleInfo(1, 1, mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_TYPE_QUADROTOR, Flavour.PX4, False)
    settings = {s.name: s.value for s in terrain_settings(copter)}
    assert settings == {"TERRAIN_ENABLE": 1.0, "TERRAIN_OPTIONS": 0.0, "WPNAV_RFND_USE": 0.0}
    assert {s.name: s.value for s in terrain_settings(copter, use_rangefinder=True)}["WPNAV_RFND_USE"] == 1.0
    assert terrain_settings(px4) == []
    assert terrain_settings(copter)[0].describe(old=0.0) == (
        "TERRAIN_ENABLE = 1 (was 0): keep a terrain database, filled from the ground station's DEM")
    assert "TERRAIN_SPACING" in TERRAIN_REPORTED  # kept as the vehicle has it, and said
