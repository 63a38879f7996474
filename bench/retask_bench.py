"""Live re-tasking measured: how ArduCopter SITL and PX4 SIH take a mission replaced while they fly it.

Run by hand: `.venv/bin/python bench/retask_bench.py [--autopilots arducopter,px4] [--strategies
a,b/short] [--write-doc docs/live-retasking.md]` (about 30 minutes: PX4 SIH runs in real time, about 3
minutes a row). Needs ../shared/sitl/arducopter and ../shared/px4/bin/px4. Under each row, on stderr, what
the vehicle said and did around the change (its timeline). sitl_tests/test_retask_sitl.py uses the harness
(start_flying, judge).

Each row is one fresh vehicle (a free instance, killed afterwards; one at a time): it flies a survey
(take-off to 20 m, the eight waypoints A1..A8 of a 60 x 60 m lawnmower north of home, RTL) in AUTO /
mission mode. Mid-leg from A5 to A6 (flying north, 15 m past A5) its mission is replaced. The new mission
keeps the items already flown and puts, at the item it flies to (resume_seq = that seq), three new
waypoints B1..B3 (a lost drone's, west of it and behind it) and the RTL: the same item count, so the
partial write can carry the change too. `/short`: the new mission is take-off, B1..B3, RTL (flown items
dropped, as fly's re-plans are), so B1 (resume_seq) gets another seq than the item flown, which is past
the new mission's end. Strategies:

- `upload-only`: the whole new mission uploaded in AUTO (MISSION_COUNT + items), items as
  missionplan.bridge.formats.mission_items.to_wire makes them (`current` = 1 on seq 0), and nothing more: what the
  autopilot does with the upload alone;
- `full`: the same, then MISSION_SET_CURRENT resume_seq (strategy a);
- `full-cmd`: the same, then MAV_CMD_DO_SET_MISSION_CURRENT (224) instead of the message;
- `full-flag` (PX4): the whole new mission with `current` = 1 on resume_seq instead, then
  MISSION_SET_CURRENT;
- `partial`: MISSION_WRITE_PARTIAL_LIST of the changed items (first changed seq to the end), answered as
  asked, then MISSION_SET_CURRENT (strategy b);
- `abort`: an upload that stops after its first 3 items (a link lost halfway), until the vehicle gives it
  up;
- `pause-guided`, `pause-brake` (ArduCopter), `pause-hold` (PX4): that mode first, the full replace,
  MISSION_SET_CURRENT, then AUTO / mission mode again (strategy c); `pause-guided-noset`: without
  MISSION_SET_CURRENT;
- `product`: missionplan.bridge.transfer.retask.replace_mission_in_flight, what the product does (timed from its call).

Columns: `ack` the upload's answer (MISSION_ACK result; `none`: no answer within 3 s); `heading path`
where the vehicle flew from the upload's start until B1 (or the end of the watch), as what its velocity
pointed at (within 30 degrees, the nearest in direction), each for at least 1.5 vehicle seconds: A6 (its
target when re-tasked), B1 (the new one), TO (the take-off point, home: where a mission restarted from its
first item goes), `stop` (under 1 m/s), `turn` (none of them); `seq path` MISSION_CURRENT
from the upload's start until B1 was reached; `upload s` from MISSION_COUNT (WRITE_PARTIAL_LIST) to the
final ACK, wall seconds, and `veh` the vehicle's; `to B1 s` from the upload's start until the vehicle
headed for B1 for good (the start of the run of samples pointing at B1 that took it there), vehicle
seconds; `min m/s` its lowest horizontal speed in between; `reached` the B waypoints it reported reached
(MISSION_ITEM_REACHED) where it was (within 10 m), of 3; `armed` whether it stayed armed and above 5 m
until B1 (or the end); `holds` what a read-back after the strategy found: `new`, `old`, or `mixed N:a+b`
(N items, a only the new mission's, b only the old one's); `says` its STATUSTEXT from the upload's start
on, each once. ArduCopter SITL runs at --speedup 10, PX4 SIH in real time; vehicle seconds are its own
clock (GLOBAL_POSITION_INT time_boot_ms, 10 per vehicle second).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "sitl_tests"))

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, VehicleInfo, mavlink  # noqa: E402
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, WireItem, to_wire  # noqa: E402
from missionplan.bridge.transfer.protocol import RESULT_TEXT, MissionTransferError, Timeouts  # noqa: E402
from missionplan.bridge.link.readiness import (ARDUPILOT_AUTO, ARDUPILOT_GUIDED, PX4_AUTO_MAIN, PX4_LOITER_SUB,  # noqa: E402
                                               PX4_MISSION_SUB, Vehicle, mode_params, request_streams, stream_rates)
from missionplan.bridge.transfer.retask import RetaskError, replace_mission_in_flight  # noqa: E402
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan  # noqa: E402

import doctable  # noqa: E402  (bench/doctable.py: --write-doc)

EARTH_RADIUS = 6_378_137.0
ALT_M = 20.0
# The survey (metres north, east of home): four 60 m legs north and south, 20 m apart.
OWN = [(20.0, 0.0), (80.0, 0.0), (80.0, 20.0), (20.0, 20.0), (20.0, 40.0), (80.0, 40.0), (80.0, 60.0), (20.0, 60.0)]
# The lost drone's waypoints given to the survivor: west of it, and behind it as it flies north to A6.
LOST = [(20.0, -40.0), (80.0, -40.0), (80.0, -60.0)]
RETASK_AT = 5          # index in OWN of the waypoint flown to when the mission is replaced (A6)
PAST_PREVIOUS_M = 15.0  # ...once this far past the one before (A5): mid-leg, at speed
ARDUCOPTER_SPEEDUP = 10
HEADING_SPEED = 1.0    # m/s toward a target...
HEADING_COS = math.cos(math.radians(30))  # ...and within 30 degrees of it: "moving toward it"
SEGMENT_S = 1.5        # a heading-path segment lasts this long (vehicle s) to count: not a turn sweeping past
POSITION_HZ = 10.0     # GLOBAL_POSITION_INT per vehicle second
AFTER_S = {Flavour.ARDUPILOT: 200.0, Flavour.PX4: 150.0}  # vehicle s to wait for B1..B3 after the retask
FLY_TO_RETASK_S = 300.0  # wall s from boot until mid-survey, at most
PARTIAL_WAIT_S = 3.0
ABORT_AFTER = 3  # items answered before an aborted upload goes silent
SAYS_CHARS = 110  # of the vehicle's STATUSTEXT in the table
NEAR_M = 5.0  # the heading path ends this close to B1
REACHED_M = 10.0  # a B item reported reached counts when the vehicle is this close to it
ARDUPILOT_BRAKE = 17  # ArduCopter's custom_mode number (its own, not a MAVLink enum)
RESULT_NAMES = {k: v.split("(MAV_MISSION_")[-1].rstrip(")") if "(MAV_MISSION_" in v else v
                for k, v in RESULT_TEXT.items()}
RESULT_NAMES[0] = "ACCEPTED"
RESULT_NAMES[15] = "CANCELLED"  # OPERATION_CANCELLED, short for the table
STRATEGIES = {
    Flavour.ARDUPILOT: ("upload-only", "upload-only/short", "full", "full/short", "full-cmd", "partial",
                        "abort/short", "pause-guided", "pause-guided/short", "pause-guided-noset/short", "pause-brake",
                        "product/short"),
    Flavour.PX4: ("upload-only", "full", "full-flag", "full-flag/short", "partial", "abort/short", "pause-hold",
                  "product/short"),
}


# ------------------------------------------------------------------------------ the missions
def offset(home: tuple[float, float], north: float, east: float) -> tuple[float, float]:
    lat = home[0] + math.degrees(north / EARTH_RADIUS)
    lon = home[1] + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(home[0]))))
    return lat, lon


def local(home: tuple[float, float], lat: float, lon: float) -> tuple[float, float]:
    north = math.radians(lat - home[0]) * EARTH_RADIUS
    east = math.radians(lon - home[1]) * EARTH_RADIUS * math.cos(math.radians(home[0]))
    return north, east


def waypoint(home: tuple[float, float], north: float, east: float) -> MissionItem:
    lat, lon = offset(home, north, east)
    return MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=ALT_M)


def survey(home: tuple[float, float, float]) -> Mission:
    """Take-off, A1..A8, RTL."""
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=home[0], y=home[1],
                         z=ALT_M)]
    items += [waypoint(home[:2], n, e) for n, e in OWN]
    items.append(MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION))
    return Mission(items, home=home)


def retasked(home: tuple[float, float, float], short: bool = False, speed: float | None = None) -> Mission:
    """The flown part (take-off, A1..A5), then B1..B3 from the item it was flying to on, then RTL;
    `short`: without A1..A5 (take-off, B1..B3, RTL), so B1 gets another seq than the item flown;
    `speed`: a DO_CHANGE_SPEED to it before B1 (as fly's re-plans begin), the item to resume at."""
    items = survey(home).items[:1 if short else 1 + RETASK_AT]
    if speed is not None:
        items.append(MissionItem(mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, param1=1.0, param2=speed,
                                 param3=-1.0))
    items += [waypoint(home[:2], n, e) for n, e in LOST]
    items.append(MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION))
    return Mission(items, home=home)


def resume_seq(flavour: Flavour, short: bool = False) -> int:
    """The wire seq after home (ArduPilot), take-off and (not short) A1..A5: B1, or the DO_CHANGE_SPEED
    before it."""
    return (1 if flavour is Flavour.ARDUPILOT else 0) + 1 + (0 if short else RETASK_AT)


def flown_seq(flavour: Flavour) -> int:
    """The wire seq of A6 in the survey: the item flown to when the mission is replaced."""
    return resume_seq(flavour)


# ------------------------------------------------------------------------------ watching the vehicle
@dataclass
class Observer:
    """Every message of the vehicle, kept with our monotonic time of arrival."""

    sysid: int
    positions: list[tuple[float, float, float, float, float, float, float]] = field(default_factory=list)
    currents: list[tuple[float, int]] = field(default_factory=list)  # wall, seq
    reached: list[tuple[float, int]] = field(default_factory=list)
    texts: list[tuple[float, str]] = field(default_factory=list)
    beats: list[tuple[float, bool, int]] = field(default_factory=list)  # wall, armed, custom_mode
    acks: list[tuple[float, str, int]] = field(default_factory=list)  # wall, type, result
    requests: list[tuple[float, str, int]] = field(default_factory=list)  # wall, type, seq
    also: Callable[[Any], None] | None = None

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid:
            return
        now = time.monotonic()
        kind = msg.get_type()
        if kind == "GLOBAL_POSITION_INT":
            self.positions.append((now, msg.time_boot_ms / 1000.0, msg.lat / 1e7, msg.lon / 1e7,
                                   msg.relative_alt / 1000.0, msg.vx / 100.0, msg.vy / 100.0))
        elif kind == "MISSION_CURRENT":
            self.currents.append((now, int(msg.seq)))
        elif kind == "MISSION_ITEM_REACHED":
            self.reached.append((now, int(msg.seq)))
        elif kind == "STATUSTEXT":
            self.texts.append((now, str(msg.text).rstrip("\x00").strip()))
        elif kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS:
            self.beats.append((now, bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED), int(msg.custom_mode)))
        elif kind in ("MISSION_ACK", "COMMAND_ACK"):
            self.acks.append((now, kind, int(msg.type if kind == "MISSION_ACK" else msg.result)))
        elif kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            self.requests.append((now, kind, int(msg.seq)))
        if self.also is not None:
            self.also(msg)

    def vehicle_s(self, wall: float) -> float:
        """The vehicle's clock (s since boot) at our monotonic time `wall`, from its positions."""
        p = np.array([(w, b) for w, b, *_ in self.positions])
        if len(p) < 2:
            return float("nan")
        return float(np.interp(wall, p[:, 0], p[:, 1], left=np.nan, right=p[-1, 1] + (wall - p[-1, 0]) *
                               (p[-1, 1] - p[0, 1]) / max(p[-1, 0] - p[0, 0], 1e-9)))


class ObservedLink:
    """A Link whose every received message also goes to the observer (protocol code drops what it
    does not need: the positions during an upload would be lost)."""

    def __init__(self, link: Link, observer: Observer) -> None:
        self._link = link
        self._observer = observer

    def recv(self, deadline: float) -> Any | None:
        msg = self._link.recv(deadline)
        if msg is not None:
            self._observer.take(msg)
        return msg

    def command_long(self, sysid: int, command: int, params: list[float], deadline: float,
                     other: Callable[[Any], Any] | None = None, done: Callable[[], bool] | None = None,
                     tries: int = 5, wait_s: float = 0.5) -> int | None:
        from missionplan.bridge.link.connection import command_long

        return command_long(self, sysid, command, params, deadline, other, done, tries, wait_s)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._link, name)


def listen(link: Any, until: float) -> None:
    while link.recv(until) is not None:
        pass


def listen_for(link: Any, done: Callable[[], bool], until: float) -> bool:
    while not done():
        if time.monotonic() >= until:
            return False
        link.recv(min(until, time.monotonic() + 0.2))
    return True


# ------------------------------------------------------------------------------ one vehicle, flying
@dataclass
class Flight:
    """One vehicle flying the survey, up to mid-leg A5 -> A6, observed."""

    flavour: Flavour
    link: ObservedLink
    backend: PymavlinkBackend
    observer: Observer
    home: tuple[float, float, float]
    old: list[WireItem]
    new: list[WireItem]
    resume: int
    speedup: float
    b1: int = -1  # the wire seq of B1 (-1: resume)

    def __post_init__(self) -> None:
        if self.b1 < 0:
            self.b1 = self.resume

    @property
    def sysid(self) -> int:
        return self.backend.vehicle.sysid

    @property
    def info(self) -> VehicleInfo:
        return self.backend.vehicle


def start_flying(link: Link, sysid: int, flavour: Flavour, home: tuple[float, float, float], speedup: float,
                 short: bool = False, say: Callable[[str], None] = print, speed: float | None = None) -> Flight:
    """Streams, readiness, upload, arm, start; returns once the vehicle flies mid-leg to A6."""
    observer = Observer(sysid)
    seen = ObservedLink(link, observer)
    backend = PymavlinkBackend("", sysid, link=seen, timeouts=Timeouts(item_timeout=0.5, retries=10),
                               connect_timeout=60.0)
    deadline = time.monotonic() + FLY_TO_RETASK_S
    rates = {**stream_rates(POSITION_HZ, flavour), 33: POSITION_HZ}
    refused = request_streams(seen, sysid, rates, deadline)
    if refused:
        say(f"streams refused: {refused}")
    vehicle = Vehicle(seen, backend.vehicle)
    missing = vehicle.wait_ready(deadline)
    if missing:
        raise RuntimeError(f"not ready: {missing}; {vehicle.state.reasons()}")
    old_mission = survey(home)
    upload_plan(backend, [old_mission], verify=True)
    old, new = to_wire(old_mission, flavour), to_wire(retasked(home, short, speed), flavour)
    if flavour is Flavour.ARDUPILOT:
        seen.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
    armed, why = vehicle.arm(deadline)
    if not armed:
        raise RuntimeError(why)
    started_until = time.monotonic() + (30.0 if flavour is Flavour.PX4 else 5.0)
    while True:
        result = seen.command_long(sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], deadline)
        if result == mavlink.MAV_RESULT_ACCEPTED or time.monotonic() > started_until:
            break
        listen(seen, time.monotonic() + 0.5)
    if result != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError(f"MISSION_START refused ({result}): {vehicle.state.reasons()}")
    resume = resume_seq(flavour, short)
    flight = Flight(flavour, seen, backend, observer, home, old, new, resume, speedup,
                    b1=resume + (1 if speed is not None else 0))
    a5, a6_seq = offset(home[:2], *OWN[RETASK_AT - 1]), flown_seq(flavour)
    mid_leg = lambda: (observer.currents and observer.currents[-1][1] == a6_seq  # noqa: E731
                       and observer.positions
                       and _distance(observer.positions[-1][2:4], a5) >= PAST_PREVIOUS_M)
    if not listen_for(seen, mid_leg, deadline):
        raise RuntimeError(f"never got mid-leg to A6: currents {observer.currents[-3:]}")
    return flight


def _distance(p: tuple[float, float] | Any, q: tuple[float, float]) -> float:
    dn = math.radians(q[0] - p[0]) * EARTH_RADIUS
    de = math.radians(q[1] - p[1]) * EARTH_RADIUS * math.cos(math.radians(p[0]))
    return math.hypot(dn, de)


# ------------------------------------------------------------------------------ the strategies
@dataclass
class Outcome:
    """What one strategy's commands got back (the vehicle's behaviour is read from the Observer)."""

    ack: str = ""
    upload_wall: tuple[float, float] = (0.0, 0.0)  # our monotonic start and end of the transfer
    note: str = ""


def _mode(flight: Flight, name: str, deadline: float) -> int | None:
    f = flight
    if f.flavour is Flavour.ARDUPILOT:
        custom = {"AUTO": ARDUPILOT_AUTO, "GUIDED": ARDUPILOT_GUIDED, "BRAKE": ARDUPILOT_BRAKE}[name]
        return f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(custom), deadline)
    sub = {"MISSION": PX4_MISSION_SUB, "HOLD": PX4_LOITER_SUB}[name]
    return f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(PX4_AUTO_MAIN, sub), deadline)


def _upload(flight: Flight, items: list[WireItem], out: Outcome) -> bool:
    start = time.monotonic()
    try:
        flight.backend.upload(0, items)
        out.ack = "ACCEPTED"
        ok = True
    except MissionTransferError as err:
        out.ack = RESULT_NAMES.get(err.result, "none") if err.result is not None else "none"
        out.note = str(err)
        ok = False
    out.upload_wall = (start, time.monotonic())
    return ok


def _set_current(flight: Flight, out: Outcome, how: str = "message") -> None:
    f = flight
    if how == "command":
        result = f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, [float(f.resume)],
                                     time.monotonic() + 5.0)
        out.note += f" DO_SET_MISSION_CURRENT result {result}"
        return
    try:
        f.backend.set_current(f.resume)
    except MissionTransferError as err:
        out.note += f" set_current: {err}"


def full(flight: Flight, how: str = "message", flag_resume: bool = False) -> Outcome:
    """The whole new mission in AUTO, then the current item set (how: "message", "command" or "none")."""
    out = Outcome()
    items = flight.new
    if flag_resume:
        items = [replace(it, current=int(it.seq == flight.resume)) for it in items]
    if _upload(flight, items, out) and how != "none":
        _set_current(flight, out, how)
    return out


def partial(flight: Flight) -> Outcome:
    """MISSION_WRITE_PARTIAL_LIST of the changed items, answered item by item as asked."""
    f, out = flight, Outcome()
    first = next(k for k, (a, b) in enumerate(zip(f.old, f.new)) if a != b)
    last = len(f.new) - 1
    mav = f.link.mav
    start = time.monotonic()
    mav.mission_write_partial_list_send(f.sysid, AUTOPILOT_COMPONENT_ID, first, last, mavlink.MAV_MISSION_TYPE_MISSION)
    until = start + PARTIAL_WAIT_S
    answer = "none"
    while (msg := f.link.recv(until)) is not None:
        if msg.get_srcSystem() != f.sysid:
            continue
        kind = msg.get_type()
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and first <= int(msg.seq) <= last:
            mav.mission_item_int_send(f.sysid, AUTOPILOT_COMPONENT_ID, **f.new[int(msg.seq)].fields())
            until = time.monotonic() + PARTIAL_WAIT_S
        elif kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mavlink.MAV_MISSION_TYPE_MISSION:
            answer = RESULT_NAMES.get(int(msg.type), str(msg.type))
            break
    out.upload_wall = (start, time.monotonic())
    out.ack = answer
    out.note = f"items {first}..{last}"
    if answer == "ACCEPTED":
        _set_current(f, out)
    return out


def abort(flight: Flight) -> Outcome:
    """An upload that stops halfway (a link lost): MISSION_COUNT, the first ABORT_AFTER items as asked,
    then silence until the vehicle gives the transfer up (ArduPilot after 8 vehicle s, PX4 after 5 s)."""
    f, out = flight, Outcome()
    mav = f.link.mav
    start = time.monotonic()
    mav.mission_count_send(f.sysid, AUTOPILOT_COMPONENT_ID, len(f.new), mavlink.MAV_MISSION_TYPE_MISSION)
    until = start + 8.0 / f.speedup + 5.0
    answer = "none"
    while (msg := f.link.recv(until)) is not None:
        if msg.get_srcSystem() != f.sysid:
            continue
        kind = msg.get_type()
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and int(msg.seq) < ABORT_AFTER:
            mav.mission_item_int_send(f.sysid, AUTOPILOT_COMPONENT_ID, **f.new[int(msg.seq)].fields())
        elif kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mavlink.MAV_MISSION_TYPE_MISSION:
            answer = RESULT_NAMES.get(int(msg.type), str(msg.type))
            break
    out.upload_wall = (start, time.monotonic())
    out.ack = answer
    out.note = f"answered items 0..{ABORT_AFTER - 1} of {len(f.new)}"
    return out


def paused(flight: Flight, mode: str, set_current: bool = True) -> Outcome:
    """`mode` first, the full replace, the current item set (unless not set_current), AUTO / mission mode."""
    f = flight
    deadline = time.monotonic() + 10.0
    result = _mode(f, mode, deadline)
    out = Outcome(note=f"{mode} result {result}")
    if _upload(f, f.new, out) and set_current:
        _set_current(f, out)
    back = _mode(f, "AUTO" if f.flavour is Flavour.ARDUPILOT else "MISSION", deadline)
    out.note += f"; back result {back}"
    # the upload's start counts from the pause: it is part of the strategy
    return out


def product(flight: Flight) -> Outcome:
    """missionplan.bridge.transfer.retask.replace_mission_in_flight; timed from its call (its HEARTBEAT wait and mode
    change included), its upload seconds its own."""
    f = flight
    start = time.monotonic()
    try:
        report = replace_mission_in_flight(f.backend, f.link, f.sysid, f.flavour, f.new, f.resume, start + 30.0)
    except RetaskError as err:
        report = err.report
    out = Outcome(ack="ACCEPTED" if report.accepted else "refused", note=report.summary())
    out.upload_wall = (start, start + report.upload_s)
    return out


def run_strategy(flight: Flight, name: str) -> Outcome:
    if name == "upload-only":
        return full(flight, how="none")
    if name == "full":
        return full(flight)
    if name == "full-cmd":
        return full(flight, how="command")
    if name == "full-flag":
        return full(flight, flag_resume=True)
    if name == "partial":
        return partial(flight)
    if name == "abort":
        return abort(flight)
    if name.startswith("pause-"):
        mode, _, noset = name.split("-", 1)[1].partition("-")
        return paused(flight, mode.upper(), set_current=noset != "noset")
    if name == "product":
        return product(flight)
    raise ValueError(name)


# ------------------------------------------------------------------------------ judging what it did
@dataclass
class Row:
    autopilot: str
    strategy: str
    ack: str
    heading_path: str
    seq_path: str
    upload_wall_s: float
    upload_vehicle_s: float
    to_b1_s: float | None
    min_speed: float
    reached: int
    armed_airborne: bool
    holds: str
    says: str
    note: str = ""


def targets(flight: Flight) -> dict[str, tuple[float, float]]:
    """What the vehicle may head for: its target when re-tasked (A6), the new one (B1), the take-off
    point (TO, home: where a mission restarted from its first item goes)."""
    home = flight.home[:2]
    return {"A6": offset(home, *OWN[RETASK_AT]), "B1": offset(home, *LOST[0]), "TO": home}


def heading_of(sample: tuple[float, ...], named: dict[str, tuple[float, float]]) -> str:
    """Which target the velocity of one position sample points at: 'stop' under HEADING_SPEED, 'turn'
    when none is within 45 degrees."""
    _, _, lat, lon, _, vn, ve = sample
    speed = math.hypot(vn, ve)
    if speed < HEADING_SPEED:
        return "stop"
    best, best_cos = "turn", HEADING_COS
    for name, (tlat, tlon) in named.items():
        dn, de = local((lat, lon), tlat, tlon)
        dist = math.hypot(dn, de)
        if dist < 2.0:
            continue
        cos = (vn * dn + ve * de) / (speed * dist)
        if cos > best_cos:
            best, best_cos = name, cos
    return best


def heading_path(flight: Flight, samples: list[tuple[float, ...]]) -> str:
    """The targets headed for in turn, each for at least SEGMENT_S of the vehicle's time."""
    named = targets(flight)
    labels = [(s[1], heading_of(s, named)) for s in samples]
    path: list[str] = []
    run_label: str | None = None
    run_start = 0.0
    for t, label in labels + [(math.inf, None)]:
        if label == run_label:
            continue
        if run_label is not None and (t - run_start >= SEGMENT_S or (t == math.inf and not path)):
            if not path or path[-1] != run_label:
                path.append(run_label)
        run_label, run_start = label, t
    return ">".join(path)


def _position_at(obs: Observer, wall: float) -> tuple[float, float]:
    """The vehicle's latitude and longitude at our time `wall` (the nearest sample)."""
    nearest = min(obs.positions, key=lambda p: abs(p[0] - wall))
    return nearest[2], nearest[3]


def holds(flight: Flight, got: list[WireItem]) -> str:
    """What the vehicle holds, read back after the strategy: `new`, `old`, or `mixed N:a+b` (N items;
    a of them only the new mission's, b only the old one's: ArduPilot writes items as they come)."""
    first = 1 if flight.flavour is Flavour.ARDUPILOT else 0  # ArduPilot's home (seq 0) is not compared

    def key(items: list[WireItem], seq: int) -> tuple[int, int, int] | None:
        return (items[seq].command, items[seq].x, items[seq].y) if seq < len(items) else None

    body = [it for it in got if it.seq >= first]
    if [key(got, it.seq) for it in body] == [key(flight.new, k) for k in range(first, len(flight.new))]:
        return "new"
    if [key(got, it.seq) for it in body] == [key(flight.old, k) for k in range(first, len(flight.old))]:
        return "old"
    mine = [(key(got, it.seq) == key(flight.new, it.seq), key(got, it.seq) == key(flight.old, it.seq)) for it in body]
    return f"mixed {len(got)}:{sum(n and not o for n, o in mine)}+{sum(o and not n for n, o in mine)}"


def judge(flight: Flight, name: str, out: Outcome, until_reached: float, held: str = "") -> Row:
    obs, f = flight.observer, flight
    start_wall = out.upload_wall[0]
    b_seqs = [f.b1 + k for k in range(len(LOST))]
    b1 = offset(f.home[:2], *LOST[0])
    b_points = {seq: offset(f.home[:2], *LOST[k]) for k, seq in enumerate(b_seqs)}
    # A B item reported reached where the vehicle is (not an old item of the same seq: a refused change)
    hits = [(t, seq) for t, seq in obs.reached if t >= start_wall and seq in b_points
            and _distance(_position_at(obs, t), b_points[seq]) <= REACHED_M]
    reached = sorted({seq for _, seq in hits})
    first_b1 = min((t for t, seq in hits if seq == b_seqs[0]), default=until_reached)
    after = [p for p in obs.positions if p[0] >= start_wall]
    near_b1 = next((p[0] for p in after if _distance(p[2:4], b1) < NEAR_M), until_reached)
    window = [p for p in after if p[0] <= min(first_b1, near_b1)]
    # Moving toward B1: the start of the last run of samples headed for it (of all targets, B1 the nearest
    # in direction) before it got there; a turn does not break a run, another target or a stop does.
    heading_t = None
    named = targets(f)
    for p in window:
        label = heading_of(p, named)
        if label == "B1":
            heading_t = p[1] if heading_t is None else heading_t
        elif label != "turn":
            heading_t = None
    if min(first_b1, near_b1) >= until_reached:
        heading_t = None  # it never got to B1
    start_vehicle = obs.vehicle_s(start_wall)
    end_vehicle = obs.vehicle_s(out.upload_wall[1])
    until_heading = [p for p in window if heading_t is None or p[1] <= heading_t]
    min_speed = min((math.hypot(p[5], p[6]) for p in until_heading), default=float("nan"))
    seqs: list[int] = []
    for t, seq in obs.currents:
        if start_wall <= t <= first_b1 and (not seqs or seqs[-1] != seq):
            seqs.append(seq)
    beats = [b for b in obs.beats if b[0] >= start_wall]
    airborne = all(p[4] > 5.0 for p in after if p[0] <= first_b1) and all(armed for _, armed, _ in beats
                                                                          if _ <= first_b1)
    says = [text for t, text in obs.texts if t >= start_wall and t <= first_b1]
    return Row(autopilot="ArduCopter" if f.flavour is Flavour.ARDUPILOT else "PX4", strategy=name, ack=out.ack,
               heading_path=heading_path(f, window), seq_path=">".join(map(str, seqs)),
               upload_wall_s=out.upload_wall[1] - out.upload_wall[0], upload_vehicle_s=end_vehicle - start_vehicle,
               to_b1_s=None if heading_t is None else heading_t - start_vehicle, min_speed=min_speed,
               reached=len(reached), armed_airborne=airborne, holds=held,
               says="; ".join(dict.fromkeys(says))[:SAYS_CHARS],
               note=out.note)


def timeline(flight: Flight, out: Outcome) -> str:
    """What the vehicle said and did from just before the upload on, vehicle seconds from its start
    (printed on stderr under each row)."""
    obs = flight.observer
    t0 = out.upload_wall[0]
    v0 = obs.vehicle_s(t0)
    events: list[tuple[float, str]] = []
    for name, stream in (("current", obs.currents), ("reached", obs.reached)):
        last = None
        for t, seq in stream:  # each change once (ArduPilot streams MISSION_CURRENT, PX4 repeats its reports)
            if seq != last:
                events.append((t, f"{name} {seq}"))
            last = seq
    events += [(t, f"says {text!r}") for t, text in obs.texts]
    events += [(t, f"{kind} {result}") for t, kind, result in obs.acks]
    events += [(t, f"{kind} {seq}") for t, kind, seq in obs.requests]
    modes: list[tuple[float, str]] = []
    for t, armed, mode in obs.beats:
        text = f"heartbeat {'armed' if armed else 'DISARMED'} mode {mode}"
        if not modes or modes[-1][1] != text:
            modes.append((t, text))
    events += modes
    named = targets(flight)
    last = None
    for p in obs.positions:
        label = heading_of(p, named)
        if label != last:
            events.append((p[0], f"heading {label} ({math.hypot(p[5], p[6]):.1f} m/s, {p[4]:.1f} m up)"))
            last = label
    lines = []
    for t, text in sorted(events):
        if t >= t0 - 1.0 / flight.speedup and (obs.vehicle_s(t) - v0) < 40:
            lines.append(f"      {obs.vehicle_s(t) - v0:+7.2f} {text}")
    return "\n".join(lines)


# ------------------------------------------------------------------------------ running
def fly_one(flavour: Flavour, row_name: str, say: Callable[[str], None]) -> Row:
    """A fresh vehicle, flown to mid-leg, re-tasked by strategy `name`, watched until B1..B3."""
    if flavour is Flavour.ARDUPILOT:
        from arducopter import ArduCopter

        vehicle: Any = ArduCopter(sysid=1, speedup=ARDUCOPTER_SPEEDUP)
        vehicle.start()
        home, url, speedup = vehicle.home[:3], vehicle.url, float(ARDUCOPTER_SPEEDUP)
    else:
        from px4_sih import PX4

        vehicle = PX4()
        vehicle.start()
        home, url, speedup = vehicle.home, vehicle.gcs_url, 1.0
    try:
        with Link(url) as link:
            name, _, scenario = row_name.partition("/")
            flight = start_flying(link, vehicle.sysid, flavour, home, speedup, scenario == "short", say)
            out = run_strategy(flight, name)
            b_last = flight.b1 + len(LOST) - 1
            until = time.monotonic() + AFTER_S[flavour] / speedup
            since = out.upload_wall[0]
            listen_for(flight.link, lambda: any(seq == b_last and t >= since for t, seq in flight.observer.reached)
                       or (flight.observer.beats and not flight.observer.beats[-1][1]), until)
            try:
                held = holds(flight, flight.backend.download(0))
            except MissionTransferError as err:
                held = f"? ({err})"
            row = judge(flight, row_name, out, time.monotonic(), held)
            row.note += "\n" + timeline(flight, out)
            return row
    finally:
        vehicle.stop()


HEADER = (f"{'autopilot':<10} {'strategy':<24} {'ack':<9} {'heading path':<28} {'seq path':<14} "
          f"{'upload s':>8} {'veh':>5} {'to B1 s':>7} {'min m/s':>7} {'reached':>7} {'armed':<5} {'holds':<12} says")


def line(row: Row) -> str:
    to_b1 = "-" if row.to_b1_s is None else f"{row.to_b1_s:.1f}"
    return (f"{row.autopilot:<10} {row.strategy:<24} {row.ack:<9} {row.heading_path[:28]:<28} "
            f"{row.seq_path[:14]:<14} {row.upload_wall_s:8.3f} {row.upload_vehicle_s:5.1f} {to_b1:>7} "
            f"{row.min_speed:7.1f} {row.reached:>5}/3 {'yes' if row.armed_airborne else 'NO':<5} {row.holds:<12} "
            f"{row.says}")


def main() -> None:
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # killed: still stop the simulator (finally)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilots", default="arducopter,px4", help="arducopter, px4 (comma-separated)")
    parser.add_argument("--strategies", default="", help="only these (comma-separated; default: all of each)")
    doctable.add_option(parser)
    args = parser.parse_args()
    flavours = {"arducopter": Flavour.ARDUPILOT, "px4": Flavour.PX4}
    wanted = [flavours[name.strip()] for name in args.autopilots.split(",") if name.strip()]
    only = {s.strip() for s in args.strategies.split(",") if s.strip()}
    with doctable.Recorder(args.write_doc, __file__):
        print(HEADER)
        print("-" * len(HEADER))
        for flavour in wanted:
            for name in STRATEGIES[flavour]:
                if only and name not in only:
                    continue
                row = fly_one(flavour, name, lambda text: print(text, file=sys.stderr))
                print(line(row), flush=True)
                print(f"    {row.note}", file=sys.stderr, flush=True)  # the timeline: stderr, not the table


if __name__ == "__main__":
    main()
