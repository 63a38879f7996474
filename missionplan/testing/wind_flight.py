"""A short AUTO mission flown in wind over a raw MAVLink link, recorded leg by leg: the same flight against real
ArduCopter SITL and against the ArduPilot-flavoured mock (sitl_tests/test_wind_sitl.py, bench/wind_bench.py).

The mission (wind_mission): take-off to ALT_M, a hold above home (hover current), then legs of LEG_M to the
north, east, south (into, across and with a wind from the north), and RTL (west, across it). The record
(FlightRecord): per leg its time (MISSION_ITEM_REACHED to MISSION_ITEM_REACHED, on the vehicle's clock:
GLOBAL_POSITION_INT time_boot_ms), its ground speed along the leg over its middle half, its largest
cross-track error, its mean SYS_STATUS current; the hover current; the battery used (BATTERY_STATUS
current_consumed when sent, else the current integrated); the STATUSTEXTs; the track. A GPS glitch can be set
at a leg and cleared some simulated seconds later (SIM_GPS1_GLTCH_X / _Y, degrees, as SITL takes them).
Every wait is bounded.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from missionplan.bridge.formats.mission_items import CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT
from missionplan.bridge.formats.mission_items import MissionType, WireItem
from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink, wait_vehicle
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.bridge.sim.gps_glitch import glitch_params
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.arducopter import wait_mission_ready

ALT_M = 20.0
LEG_M = 150.0
HOVER_HOLD_S = 6.0
EARTH_RADIUS = 6_378_137.0
# (north, east) of each waypoint after the hover, metres from home: legs north, east, south; RTL flies west.
LEGS = ((LEG_M, 0.0), (LEG_M, LEG_M), (0.0, LEG_M))
LEG_NAMES = ("north", "east", "south", "home (west)")
LAST_SEQ = 3 + len(LEGS)  # the RTL item
ARM_RETRY_S = 1.0
# Streams asked for, and their intervals in the vehicle's seconds (SIMSTATE: SITL's true position).
STREAMS = {mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.2, mavlink.MAVLINK_MSG_ID_SYS_STATUS: 0.5,
           mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
           mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 0.2, mavlink.MAVLINK_MSG_ID_SIMSTATE: 0.2}


@dataclass
class Leg:
    name: str
    time_s: float
    ground_speed: float  # along the leg, mean over its middle half, m/s
    cross_track_m: float  # largest distance off the straight leg, metres
    current_a: float  # mean SYS_STATUS current over the leg, amperes


@dataclass
class FlightRecord:
    legs: list[Leg]
    hover_current_a: float
    consumed_mah: float  # BATTERY_STATUS current_consumed at landing (the mock: the current integrated)
    flight_s: float  # MISSION_START to the RTL item reached (as it disarms), vehicle clock
    texts: list[tuple[float, str, int]] = field(default_factory=list)
    track: list[tuple[float, float, float, float]] = field(default_factory=list)  # t, north, east, alt
    reached: dict[int, float] = field(default_factory=dict)  # seq -> vehicle time
    truth: list[tuple[float, float, float]] = field(default_factory=list)  # t, north, east (SITL's SIMSTATE)
    gps: list[tuple[float, float, float]] = field(default_factory=list)  # t, north, east (GPS_RAW_INT)

    def table(self) -> str:
        rows = [f"{leg.name:12s} {leg.time_s:6.1f} s {leg.ground_speed:5.2f} m/s xtrack {leg.cross_track_m:5.2f} m "
                f"{leg.current_a:5.1f} A" for leg in self.legs]
        return "\n".join(rows + [f"hover {self.hover_current_a:.1f} A, used {self.consumed_mah:.0f} mAh, "
                                 f"flight {self.flight_s:.1f} s"])


def wind_mission(home: tuple[float, float, float]) -> list[WireItem]:
    """Home, take-off, a hover above home, the three legs, RTL (relative frame, integer lat/lon)."""
    lat0, lon0 = home[0], home[1]

    def at(north: float, east: float) -> tuple[int, int]:
        lat = lat0 + math.degrees(north / EARTH_RADIUS)
        lon = lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0))))
        return int(round(lat * 1e7)), int(round(lon * 1e7))

    def item(seq: int, cmd: int, p1: float = 0.0, xy: tuple[int, int] = (0, 0), z: float = ALT_M,
             frame: int = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) -> WireItem:
        return WireItem(seq, frame, cmd, 1 if seq == 0 else 0, 1, p1, 0.0, 0.0, 0.0, xy[0], xy[1], z,
                        int(MissionType.MISSION))

    items = [item(0, CMD_NAV_WAYPOINT, xy=at(0, 0), z=home[2], frame=mavlink.MAV_FRAME_GLOBAL_INT),
             item(1, CMD_NAV_TAKEOFF, xy=at(0, 0)), item(2, CMD_NAV_WAYPOINT, HOVER_HOLD_S, at(0, 0))]
    items += [item(3 + k, CMD_NAV_WAYPOINT, xy=at(*wp)) for k, wp in enumerate(LEGS)]
    return items + [item(3 + len(LEGS), CMD_NAV_RETURN_TO_LAUNCH, z=0.0)]


class _Recorder:
    """Everything the vehicle sends during the flight, on its own clock."""

    def __init__(self, link: Link, sysid: int, home: tuple[float, float, float]) -> None:
        self.link, self.sysid, self.home = link, sysid, home
        self.t = 0.0
        self.track: list[tuple[float, float, float, float, float, float]] = []  # t, n, e, alt, vn, ve
        self.currents: list[tuple[float, float]] = []
        self.consumed: float | None = None
        self.consumed_first: float | None = None  # SITL counts from boot, across flights
        self.reached: dict[int, float] = {}
        self.texts: list[tuple[float, str, int]] = []
        self.armed_at: float | None = None
        self.disarmed_at: float | None = None
        self.truth: list[tuple[float, float, float]] = []  # t, north, east: SITL's SIMSTATE, GPS_RAW_INT's below
        self.gps: list[tuple[float, float, float]] = []

    def local(self, lat: float, lon: float) -> tuple[float, float]:
        north = math.radians(lat - self.home[0]) * EARTH_RADIUS
        return north, math.radians(lon - self.home[1]) * EARTH_RADIUS * math.cos(math.radians(self.home[0]))

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid:
            return
        kind = msg.get_type()
        if kind == "GLOBAL_POSITION_INT":
            self.t = msg.time_boot_ms / 1000.0
            north, east = self.local(msg.lat / 1e7, msg.lon / 1e7)
            self.track.append((self.t, north, east, msg.relative_alt / 1000.0, msg.vx / 100.0, msg.vy / 100.0))
        elif kind == "SYS_STATUS" and self.armed_at is not None and msg.current_battery >= 0:
            self.currents.append((self.t, msg.current_battery / 100.0))
        elif kind == "BATTERY_STATUS" and msg.current_consumed >= 0:
            self.consumed = float(msg.current_consumed)
            self.consumed_first = self.consumed if self.consumed_first is None else self.consumed_first
        elif kind in ("SIMSTATE", "GPS_RAW_INT") and (msg.lat or msg.get_type() == "SIMSTATE"):
            lon = msg.lng if kind == "SIMSTATE" else msg.lon
            (self.truth if kind == "SIMSTATE" else self.gps).append((self.t, *self.local(msg.lat / 1e7, lon / 1e7)))
        elif kind == "MISSION_ITEM_REACHED":
            self.reached.setdefault(int(msg.seq), self.t)
        elif kind == "STATUSTEXT":
            self.texts.append((self.t, str(msg.text).rstrip("\x00 "), int(msg.severity)))
        if kind == "MISSION_ITEM_REACHED" and int(msg.seq) == LAST_SEQ:  # RTL's: sent as it disarms
            self.disarmed_at = self.t

    def pump(self, until: float) -> None:
        while (msg := self.link.recv(until)) is not None:
            self.take(msg)


def _set_params(client: ParamClient, values: dict[str, float]) -> None:
    for name, value in values.items():
        client.set(name, value)


def _arm(link: Link, rec: _Recorder, deadline: float) -> None:
    """GUIDED and arm, again each ARM_RETRY_S while the vehicle refuses (SITL: its EKF not ready yet)."""
    arm = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
    while time.monotonic() < deadline:
        link.command_long(rec.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
        if link.command_long(rec.sysid, arm, [1.0], deadline, other=rec.take) == mavlink.MAV_RESULT_ACCEPTED:
            return
        rec.pump(min(deadline, time.monotonic() + ARM_RETRY_S))
    raise RuntimeError(f"system {rec.sysid} did not arm in time")


def fly_wind_mission(url: str, sysid: int, home: tuple[float, float, float], wind: tuple[float, float, float],
                     stream_scale: float = 1.0, timeout_s: float = 120.0,
                     glitch: tuple[int, float, float, float] | None = None,
                     params: dict[str, float] | None = None) -> FlightRecord:
    """Fly wind_mission with SIM_WIND_SPD, _DIR, _TURB = wind. stream_scale: the streams' intervals are asked
    in the vehicle's seconds (SITL: simulated; the mock: wall, so pass 1 / its speedup). glitch: (at seq,
    north m, east m, seconds) set SIM_GPS1_GLTCH_X / _Y when item `seq` becomes current, cleared that long after.
    params: more parameters to set first (WPNAV_SPEED ...)."""
    deadline = time.monotonic() + timeout_s
    with Link(url) as link:
        wait_mission_ready(link, sysid, timeout=min(30.0, timeout_s))
        rec = _Recorder(link, sysid, home)
        client = ParamClient(link, wait_vehicle(link, sysid, timeout=10.0))  # once: the mock's heartbeat is slow
        for msgid, interval in STREAMS.items():  # the mock refuses SIMSTATE and BATTERY_STATUS: it has neither
            link.command_long(sysid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [msgid, interval * stream_scale * 1e6],
                              deadline)
        _set_params(client, {**(params or {}), "SIM_WIND_SPD": wind[0], "SIM_WIND_DIR": wind[1],
                             "SIM_WIND_TURB": wind[2]})
        rec.pump(time.monotonic() + 0.3)  # the battery's count before the flight (SITL's runs from boot)
        with PymavlinkBackend(url, sysid, timeouts=Timeouts(), link=_NoClose(link)) as backend:
            backend.upload(MissionType.MISSION, wind_mission(home))
        _arm(link, rec, deadline)
        if link.command_long(sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], deadline, other=rec.take) \
                != mavlink.MAV_RESULT_ACCEPTED:
            raise RuntimeError(f"system {sysid} refused MISSION_START")
        seen = len(rec.track)
        while len(rec.track) == seen and time.monotonic() < deadline:  # the vehicle's clock now
            rec.pump(min(deadline, time.monotonic() + 0.05))
        rec.armed_at = rec.t  # the flight's start (the mock's heartbeat comes once a wall second: too coarse)
        glitch_on: float | None = None
        while rec.disarmed_at is None and time.monotonic() < deadline:
            rec.pump(min(deadline, time.monotonic() + 0.02))
            if glitch is not None and glitch_on is None and glitch[0] - 1 in rec.reached:
                glitch_on = rec.t
                _set_params(client, glitch_params(glitch[1], glitch[2], home[0]))
            elif glitch_on is not None and glitch is not None and rec.t - glitch_on >= glitch[3]:
                _set_params(client, glitch_params(0.0, 0.0, home[0]))
                glitch = None
        if rec.disarmed_at is None:
            raise RuntimeError(f"system {sysid} did not land within {timeout_s:g} s (reached {sorted(rec.reached)})")
        if rec.consumed is not None:  # SITL: its battery's count once the motors stopped
            rec.pump(min(deadline, time.monotonic() + 0.5))
        return _record(rec)


class _NoClose:
    """A view of an open Link that the mission backend may 'close' without closing it."""

    def __init__(self, link: Link) -> None:
        self._link = link

    def __getattr__(self, name: str) -> Any:
        return getattr(self._link, name)

    def close(self) -> None:
        pass


def _mean(values: list[float]) -> float:
    return sum(values) / len(values) if values else float("nan")


def _record(rec: _Recorder) -> FlightRecord:
    points = [(0.0, 0.0), *LEGS, (0.0, 0.0)]
    first = 2  # the hover item: its reach ends the take-off
    legs = []
    for k in range(len(points) - 1):
        start_t = rec.reached.get(first + k, float("nan"))
        end_seq = first + k + 1
        end_t = rec.reached.get(end_seq) if k < len(LEGS) else _home_arrival(rec, start_t)
        end_t = float("nan") if end_t is None else end_t
        (n0, e0), (n1, e1) = points[k], points[k + 1]
        length = math.hypot(n1 - n0, e1 - e0)
        un, ue = (n1 - n0) / length, (e1 - e0) / length
        speeds, xtrack = [], 0.0
        for t, n, e, _, vn, ve in rec.track:
            if not start_t <= t <= end_t:
                continue
            along = (n - n0) * un + (e - e0) * ue
            xtrack = max(xtrack, abs(-(n - n0) * ue + (e - e0) * un))
            if 0.25 * length <= along <= 0.75 * length:
                speeds.append(vn * un + ve * ue)
        current = _mean([a for t, a in rec.currents if start_t <= t <= end_t])
        legs.append(Leg(LEG_NAMES[k], end_t - start_t, _mean(speeds), xtrack, current))
    hover_from, hover_to = rec.reached.get(first - 1, math.nan), rec.reached.get(first, math.nan)
    hover = _mean([a for t, a in rec.currents if hover_from + 1.0 <= t <= hover_to - 0.5])  # reached after the hold
    consumed = rec.consumed - (rec.consumed_first or 0.0) if rec.consumed is not None else _integrated_mah(rec.currents)
    assert rec.armed_at is not None and rec.disarmed_at is not None
    return FlightRecord(legs, hover, consumed, rec.disarmed_at - rec.armed_at, rec.texts,
                        [(t, n, e, a) for t, n, e, a, _, _ in rec.track], dict(rec.reached), rec.truth, rec.gps)


def _home_arrival(rec: _Recorder, start_t: float) -> float | None:
    """RTL's way home: from its start until it is within 2 m of home, still in the air."""
    for t, n, e, alt, _, _ in rec.track:
        if t > start_t and math.hypot(n, e) <= 2.0 and alt > 5.0:
            return t
    return None


def _integrated_mah(currents: list[tuple[float, float]]) -> float:
    return sum(a * (t1 - t0) for (t0, a), (t1, _) in zip(currents, currents[1:])) / 3.6
