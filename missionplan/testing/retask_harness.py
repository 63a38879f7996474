"""The re-task harness: one vehicle flies a small survey, is watched message by message, and what it did
around a mission replaced in flight is judged. bench/retask_bench.py measures every re-task strategy with
it (docs/live-retasking.md, where the columns of a Row are explained); sitl_tests/test_retask_sitl.py and
tests/test_mock_as_autopilots.py hold ArduCopter SITL, PX4 SIH and the mock to what fly's re-plans need
(retask_and_follow, check).

The survey (metres north, east of home): take-off to 20 m, the eight waypoints A1..A8 of a 60 x 60 m
lawnmower north of home, RTL, flown in AUTO / mission mode. start_flying returns once the vehicle flies
mid-leg from A5 to A6 (15 m past A5); the new mission puts three waypoints B1..B3 (a lost drone's, west
of it and behind it) at the item it flies to, or (`short`) is take-off, B1..B3, RTL, renumbered as fly's
re-plans are. The Observer keeps every message of the vehicle with our time of arrival; judge() reads
from it where the vehicle headed, which items it reported reached and where, and whether it stayed armed
and airborne until B1.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    FRAME_GLOBAL,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    WireItem,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.link.connection import Link, VehicleInfo, mavlink
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, Vehicle, mode_params, request_streams, stream_rates
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.retask import RetaskReport, replace_mission_in_flight
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan

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
SAYS_CHARS = 110  # of the vehicle's STATUSTEXT in the table
NEAR_M = 5.0  # the heading path ends this close to B1
REACHED_M = 10.0  # a B item reported reached counts when the vehicle is this close to it


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


@dataclass
class Outcome:
    """What one strategy's commands got back (the vehicle's behaviour is read from the Observer)."""

    ack: str = ""
    upload_wall: tuple[float, float] = (0.0, 0.0)  # our monotonic start and end of the transfer
    note: str = ""


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


# ------------------------------------------------------------------------------ the table's lines
HEADER = (f"{'autopilot':<10} {'strategy':<24} {'ack':<9} {'heading path':<28} {'seq path':<14} "
          f"{'upload s':>8} {'veh':>5} {'to B1 s':>7} {'min m/s':>7} {'reached':>7} {'armed':<5} {'holds':<12} says")


def line(row: Row) -> str:
    to_b1 = "-" if row.to_b1_s is None else f"{row.to_b1_s:.1f}"
    return (f"{row.autopilot:<10} {row.strategy:<24} {row.ack:<9} {row.heading_path[:28]:<28} "
            f"{row.seq_path[:14]:<14} {row.upload_wall_s:8.3f} {row.upload_vehicle_s:5.1f} {to_b1:>7} "
            f"{row.min_speed:7.1f} {row.reached:>5}/3 {'yes' if row.armed_airborne else 'NO':<5} {row.holds:<12} "
            f"{row.says}")


# ------------------------------------------------------------------------------ re-tasking as fly does
RETASK_S = 30.0  # wall seconds for replace_mission_in_flight
SPEED_M_S = 5.0  # the re-plan's DO_CHANGE_SPEED
FENCE_HALF_M = 300.0


def square_fence(home: tuple[float, float, float]) -> list[WireItem]:
    """An inclusion polygon (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION) 2 x FENCE_HALF_M wide around home."""
    h = FENCE_HALF_M
    corners = [offset(home[:2], n, e) for n, e in ((-h, -h), (-h, h), (h, h), (h, -h))]
    return [WireItem(k, FRAME_GLOBAL, CMD_FENCE_POLYGON_VERTEX_INCLUSION, 0, 1, 4.0, 0.0, 0.0, 0.0, round(lat * 1e7),
                     round(lon * 1e7), 0.0, MissionType.FENCE)
            for k, (lat, lon) in enumerate(corners)]


def retask_and_follow(link: Any, sysid: int, flavour: Flavour, home: tuple[float, float, float],
                      speedup: float) -> tuple[RetaskReport, Row, Flight, float]:
    """Fly to mid-leg, replace the mission as fly's re-plans do (renumbered: take-off, DO_CHANGE_SPEED,
    B1..B3, RTL, to continue at the DO_CHANGE_SPEED; a new 600 m square geofence with it), follow until
    B3 is reached or it lands. The fence read back must be the one sent."""
    flight = start_flying(link, sysid, flavour, home, speedup, short=True, say=lambda text: None, speed=SPEED_M_S)
    started = time.monotonic()
    report = replace_mission_in_flight(flight.backend, flight.link, sysid, flavour, flight.new, flight.resume,
                                       started + RETASK_S, fence=square_fence(home))
    b3 = flight.b1 + len(LOST) - 1
    obs = flight.observer
    listen_for(flight.link, lambda: any(seq == b3 and t >= started for t, seq in obs.reached)
               or bool(obs.beats and not obs.beats[-1][1]), time.monotonic() + AFTER_S[flavour] / speedup)
    row = judge(flight, "product", Outcome(ack="ACCEPTED", upload_wall=(started, started + report.upload_s)),
                time.monotonic())
    held = flight.backend.download(MissionType.FENCE)
    assert compare_wire(square_fence(home), held, skip_home=False, flavour=flavour) == [], held
    return report, row, flight, started


def check(report: RetaskReport, row: Row, flight: Flight, started: float) -> None:
    """What must hold on every autopilot, the mock included: the new mission confirmed (read back, continued
    at resume_seq or at B1 it leads to); B1, B2, B3 reached in order, each where the vehicle was; armed and
    above 5 m until B1; MISSION_CURRENT never below resume_seq from the change on."""
    said = f"{report.summary()}\n{row}\n{timeline(flight, Outcome(upload_wall=(0.0, 0.0)))[-3000:]}"
    assert report.confirmed, said
    assert report.continued_at in (flight.resume, flight.b1) and report.read_back, said
    assert row.reached == len(LOST), said  # B1, B2, B3, each where the vehicle was
    assert row.armed_airborne, said  # armed, above 5 m, until B1
    seqs = [int(s) for s in row.seq_path.split(">") if s]
    assert seqs and min(seqs) >= flight.resume, said  # never back to the take-off or item 0/1
    b = [flight.b1 + k for k in range(len(LOST))]
    reached = [seq for t, seq in flight.observer.reached if t >= started and seq in b]
    assert list(dict.fromkeys(reached)) == b, said  # in order (PX4 repeats each report)
