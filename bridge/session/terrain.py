"""The MAVLink terrain protocol on the ground station's side: serve a DEM to an ArduPilot vehicle.

An ArduPilot vehicle with TERRAIN_ENABLE = 1 and no terrain files of its own asks the ground station
for the ground (as Mission Planner, MAVProxy's terrain module and QGroundControl answer it): it sends
TERRAIN_REQUEST (the south-west corner of a grid, its spacing, and a 56-bit mask of the 4 x 4 blocks it
lacks) and the ground station answers one TERRAIN_DATA per bit; TERRAIN_CHECK asks it for its terrain
height at a point and TERRAIN_REPORT tells (its pending and loaded blocks too). Owns:
- TerrainServer: answers TERRAIN_REQUESTs from a height function (metres above sea level, NaN where
  unknown), all the heights of a request in one vectorised call; blocks with no ground are not sent,
  but counted, so the caller can say where the DEM ends; counts requests, blocks and bytes;
- check_terrain / wait_terrain_loaded: TERRAIN_CHECK for a mission's points and the vehicle's
  TERRAIN_REPORTs read back, bounded, with a TerrainStatus that says in one line what is missing;
- TERRAIN_REPORTED / read_terrain_params: the terrain parameters read and reported but left as the vehicle
  has them (the ones terrain flight needs are link.params.terrain_settings: the upload sets them as it sets
  WPNAV_RADIUS).

The layout (which ground each height of a TERRAIN_DATA is, from ArduPilot's libraries/AP_Terrain) is
formats/terrain_grid.py's, shared with the mock autopilot that asks for it. From TerrainGCS.cpp:
- TerrainGCS.cpp send_request: the vehicle asks again for what is still missing, at most every 2 s
  of its own clock, one grid at a time; a loaded vehicle (pre_arm_checks) has no pending block and
  ground at its position and home ("waiting for terrain data" until then). TERRAIN_REPORT's spacing
  is 0 when it has no ground at the point or at home. ArduCopter 4.7 sends TERRAIN_REQUEST and
  TERRAIN_REPORT as two streams (MAV_CMD_SET_MESSAGE_INTERVAL 133 and 136), nothing unless asked.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..formats.terrain_grid import INT16, grid_points, mask_bits
from ..link.connection import mavlink
from ..link.params import ParamClient, read_params
from ..link.readiness import request_streams

HeightFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]

TERRAIN_STREAM_HZ = 2.0  # TERRAIN_REQUEST (the vehicle's 2 s pacing is its own) and TERRAIN_REPORT
TERRAIN_STREAMS = {mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST: "TERRAIN_REQUEST",
                   mavlink.MAVLINK_MSG_ID_TERRAIN_REPORT: "TERRAIN_REPORT"}
CHECK_RESEND_S = 1.0  # a TERRAIN_CHECK not answered (or answered without ground) is sent again this often

# Read and reported, never set: the vehicle's grid spacing decides what it asks for (100 m by default,
# what SRTM-based ground stations serve), and its arming-time terrain offset limit.
TERRAIN_REPORTED = ("TERRAIN_SPACING", "TERRAIN_OFS_MAX")


# ---------------------------------------------------------------------------------------------- sending
def _mav(via: Any) -> Any:
    """The pymavlink sender of a Link, a shared link's VehicleLink, or a VehicleSession (its link)."""
    return via.mav if hasattr(via, "mav") else via.link.mav


def _send_to(mav: Any, packet: Any, sysid: int) -> int:
    """Send a packet of a message that names no target (TERRAIN_DATA, TERRAIN_CHECK) to vehicle sysid:
    the link routes by target_system (link.connection: on a udpin port shared by a fleet, to that
    vehicle's address, not to every vehicle). The attribute is not a field: it is not on the wire.
    Returns the bytes sent."""
    packet.target_system = sysid
    mav.send(packet)
    return len(packet.get_msgbuf())


# ---------------------------------------------------------------------------------------------- server
@dataclass(frozen=True)
class TerrainServed:
    """What a TerrainServer has done so far."""

    requests: int = 0              # TERRAIN_REQUESTs answered
    blocks_sent: int = 0           # TERRAIN_DATA sent (a block asked for twice counts twice)
    bytes_sent: int = 0            # their bytes on the wire (MAVLink 2 framing, signature included)
    blocks_without_ground: int = 0  # distinct blocks asked for that the DEM has no ground for (not sent)
    no_ground_at: tuple[float, float] | None = None  # the first point without ground (lat, lon)

    def missing_line(self) -> str:
        """'' when every block asked for had ground; else where it did not, as a phrase."""
        if not self.blocks_without_ground or self.no_ground_at is None:
            return ""
        lat, lon = self.no_ground_at
        return (f"no ground in the DEM for {self.blocks_without_ground} terrain blocks "
                f"(the first at {lat:.5f}, {lon:.5f})")


class TerrainServer:
    """Answers TERRAIN_REQUESTs from `height_amsl(lat, lon)` (arrays of degrees -> metres above sea level,
    NaN where unknown). One server may answer several vehicles from their threads (fly's followers)."""

    def __init__(self, height_amsl: HeightFunction) -> None:
        self.height_amsl = height_amsl
        self._lock = threading.Lock()
        self._requests = self._blocks = self._bytes = 0
        self._without_ground: set[tuple[int, int, int, int]] = set()  # (lat, lon, spacing, bit)
        self._no_ground_at: tuple[float, float] | None = None

    def answer(self, via: Any, msg: Any) -> int:
        """For a TERRAIN_REQUEST, one TERRAIN_DATA per bit of its mask whose 16 heights are all known, sent
        on `via` (a Link, a VehicleLink or a VehicleSession) to the vehicle that asked; the number sent
        (0 for any other message)."""
        if msg.get_type() != "TERRAIN_REQUEST" or int(msg.grid_spacing) <= 0:
            return 0
        lat_e7, lon_e7, spacing = int(msg.lat), int(msg.lon), int(msg.grid_spacing)
        bits = mask_bits(int(msg.mask))
        if not bits:
            with self._lock:
                self._requests += 1
            return 0
        lat, lon = grid_points(lat_e7, lon_e7, spacing, bits)
        heights = np.asarray(self.height_amsl(lat.ravel(), lon.ravel()), dtype=float).reshape(lat.shape)
        has_ground = np.isfinite(heights).all(axis=1)
        data = np.clip(np.rint(np.where(np.isfinite(heights), heights, 0.0)), *INT16).astype(np.int16)
        mav, sysid = _mav(via), msg.get_srcSystem()
        sent_bytes = 0
        for row in np.flatnonzero(has_ground):
            packet = mav.terrain_data_encode(lat_e7, lon_e7, spacing, bits[row], data[row].tolist())
            sent_bytes += _send_to(mav, packet, sysid)
        sent = int(has_ground.sum())
        with self._lock:
            self._requests += 1
            self._blocks += sent
            self._bytes += sent_bytes
            for row in np.flatnonzero(~has_ground):
                self._without_ground.add((lat_e7, lon_e7, spacing, bits[row]))
                if self._no_ground_at is None:
                    k = int(np.flatnonzero(~np.isfinite(heights[row]))[0])
                    self._no_ground_at = (float(lat[row, k]), float(lon[row, k]))
        return sent

    def served(self) -> TerrainServed:
        with self._lock:
            return TerrainServed(self._requests, self._blocks, self._bytes, len(self._without_ground),
                                 self._no_ground_at)


# ---------------------------------------------------------------------------------------------- reports
@dataclass(frozen=True)
class TerrainReport:
    """One TERRAIN_REPORT: the vehicle's terrain at a point (its own position, or one checked)."""

    lat: float
    lon: float
    spacing: int            # 0: no ground there (or at home) in its database
    terrain_height: float   # metres above sea level at the point (when spacing > 0)
    current_height: float   # the vehicle's height above the terrain under it
    pending: int            # blocks it still waits for (all grids in its cache)
    loaded: int             # blocks it has

    @classmethod
    def of(cls, msg: Any) -> TerrainReport:
        return cls(msg.lat / 1e7, msg.lon / 1e7, int(msg.spacing), float(msg.terrain_height),
                   float(msg.current_height), int(msg.pending), int(msg.loaded))

    @property
    def has_ground(self) -> bool:
        return self.spacing > 0


@dataclass(frozen=True)
class CheckedPoint:
    """A point asked for with TERRAIN_CHECK and the vehicle's latest answer (None: none yet)."""

    lat: float
    lon: float
    report: TerrainReport | None

    @property
    def height(self) -> float | None:
        """The vehicle's terrain height there (m above sea level), None when it has none."""
        return self.report.terrain_height if self.report is not None and self.report.has_ground else None


@dataclass(frozen=True)
class TerrainStatus:
    """What the vehicle says of its terrain: at its position, at the points checked, its blocks."""

    own: TerrainReport | None            # its latest report for its own position
    points: tuple[CheckedPoint, ...]
    pending: int | None                  # blocks pending in its latest report (None: no report heard)
    loaded: int | None
    waited_s: float
    served: TerrainServed | None = None  # what our server sent meanwhile (and before)
    refused_streams: tuple[str, ...] = ()

    @property
    def points_without_ground(self) -> list[CheckedPoint]:
        return [p for p in self.points if p.height is None]

    @property
    def loaded_ok(self) -> bool:
        """No block pending, ground at its position (and home), and a height at every point checked."""
        return (self.pending == 0 and self.own is not None and self.own.has_ground
                and not self.points_without_ground)

    def line(self) -> str:
        """One line for the crew: what is loaded, or what is still missing and why."""
        served = self.served
        if self.loaded_ok:
            assert self.own is not None
            sent = (f" (served {served.requests} requests, {served.blocks_sent} blocks, "
                    f"{served.bytes_sent / 1000:.1f} kB)" if served is not None else "")
            return (f"terrain loaded after {self.waited_s:.1f} s: 0 blocks pending, {self.loaded} loaded; "
                    f"ground {self.own.terrain_height:.1f} m at its position and at all {len(self.points)} "
                    f"points checked{sent}")
        parts = []
        if self.refused_streams:
            parts.append(f"the vehicle refused the streams {', '.join(self.refused_streams)}")
        if self.pending is None:
            parts.append("no TERRAIN_REPORT heard (is TERRAIN_ENABLE 1?)")
        else:
            parts.append(f"{self.pending} blocks pending, {self.loaded} loaded")
        if self.own is not None and not self.own.has_ground:
            parts.append(f"no ground at its position ({self.own.lat:.5f}, {self.own.lon:.5f}) or home")
        missing = self.points_without_ground
        if missing:
            parts.append(f"{len(missing)} of {len(self.points)} points without ground "
                         f"(the first at {missing[0].lat:.5f}, {missing[0].lon:.5f})")
        if served is not None and (where := served.missing_line()):
            parts.append(where)
        return f"terrain not loaded after {self.waited_s:.1f} s: " + "; ".join(parts)


class _TerrainWatch:
    """The vehicle's TERRAIN_REPORTs while we wait: for its own position and for each point checked."""

    def __init__(self, session: Any, points: Sequence[tuple[float, float]]) -> None:
        self.session = session
        self.sysid: int = session.sysid
        self.keys = [(round(lat * 1e7), round(lon * 1e7)) for lat, lon in points]
        self.answers: dict[tuple[int, int], TerrainReport] = {}
        self.checks_sent: dict[tuple[int, int], int] = {}
        self.reports_heard: dict[tuple[int, int], int] = {}
        self.own: TerrainReport | None = None
        self.latest: TerrainReport | None = None
        self.next_check = 0.0

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid or msg.get_type() != "TERRAIN_REPORT":
            return
        report = TerrainReport.of(msg)
        self.latest = report
        key = (int(msg.lat), int(msg.lon))
        if key not in self.keys:
            self.own = report
            return
        # A TERRAIN_CHECK's answer echoes the point exactly (TerrainGCS.cpp); more reports there than checks
        # sent means the vehicle stands on it (home is often a mission point): those are its own too.
        self.answers[key] = report
        self.reports_heard[key] = self.reports_heard.get(key, 0) + 1
        if self.reports_heard[key] > self.checks_sent.get(key, 0):
            self.own = report

    def check(self, which: Callable[[TerrainReport | None], bool]) -> None:
        """TERRAIN_CHECK for the points whose latest answer `which` says to ask again, once a second."""
        now = time.monotonic()
        if now < self.next_check:
            return
        self.next_check = now + CHECK_RESEND_S
        mav = _mav(self.session)
        for key in dict.fromkeys(self.keys):
            if which(self.answers.get(key)):
                _send_to(mav, mav.terrain_check_encode(*key), self.sysid)
                self.checks_sent[key] = self.checks_sent.get(key, 0) + 1

    def run(self, deadline: float, done: Callable[[], bool], ask_again: Callable[[TerrainReport | None], bool]) -> None:
        """Read the vehicle until done() or the deadline; every message goes to the session's `take`
        first (its state, its terrain server's answer to a TERRAIN_REQUEST, its observer)."""
        while not done():
            now = time.monotonic()
            if now >= deadline:
                return
            self.check(ask_again)
            msg = self.session.recv(min(deadline, self.next_check))
            if msg is None:
                continue
            if msg.get_srcSystem() == self.sysid:
                self.session.take(msg)
            self.take(msg)

    def status(self, started: float, served: TerrainServed | None, refused: Sequence[str] = ()) -> TerrainStatus:
        latest = self.latest
        points = tuple(CheckedPoint(lat / 1e7, lon / 1e7, self.answers.get((lat, lon))) for lat, lon in self.keys)
        return TerrainStatus(self.own, points, None if latest is None else latest.pending,
                             None if latest is None else latest.loaded, time.monotonic() - started, served,
                             tuple(refused))


def check_terrain(session: Any, points: Sequence[tuple[float, float]], deadline: float) -> TerrainStatus:
    """TERRAIN_CHECK for each (lat, lon) of `points` (a mission's waypoints) on a VehicleSession, and the
    vehicle's answers, until each point is answered or the deadline; TERRAIN_REQUESTs that arrive
    meanwhile are answered by the session's terrain server, if it has one (VehicleSession.serve_terrain)."""
    started = time.monotonic()
    watch = _TerrainWatch(session, points)
    watch.run(deadline, done=lambda: all(key in watch.answers for key in watch.keys),
              ask_again=lambda report: report is None)
    server = getattr(session, "terrain_server", None)
    return watch.status(started, None if server is None else server.served())


def request_terrain_streams(session: Any, deadline: float, hz: float = TERRAIN_STREAM_HZ) -> list[str]:
    """Ask the vehicle for TERRAIN_REQUEST and TERRAIN_REPORT (ArduPilot sends neither unless asked);
    the names of those it refused."""
    refused = request_streams(session.link, session.sysid, dict.fromkeys(TERRAIN_STREAMS, hz), deadline,
                              other=session.take)
    return [TERRAIN_STREAMS.get(int(name), name) if name.isdigit() else name for name in refused]


def wait_terrain_loaded(session: Any, server: TerrainServer, deadline: float,
                        points: Sequence[tuple[float, float]] = ()) -> TerrainStatus:
    """Serve the vehicle its terrain from `server` until it has it: no block pending, ground at its own
    position and home, and a height at each of `points` (TERRAIN_CHECK, asked again each second until
    it has one). Bounded by the deadline; the status says what is still missing. The server stays the
    session's afterwards, so that the vehicle is answered through the flight (it asks as it moves)."""
    started = time.monotonic()
    session.serve_terrain(server)
    refused = request_terrain_streams(session, deadline)
    watch = _TerrainWatch(session, points)

    def loaded() -> bool:
        latest, own = watch.latest, watch.own
        return (latest is not None and latest.pending == 0 and own is not None and own.has_ground
                and all(watch.answers.get(key) is not None and watch.answers[key].has_ground for key in watch.keys))

    watch.run(deadline, done=loaded, ask_again=lambda report: report is None or not report.has_ground)
    return watch.status(started, server.served(), refused)


# ---------------------------------------------------------------------------------------------- parameters
def read_terrain_params(session: Any) -> dict[str, float]:
    """TERRAIN_REPORTED as the vehicle has them (those it answers for)."""
    return read_params(ParamClient(session.link, session.backend.vehicle), list(TERRAIN_REPORTED))

