"""Live re-tasking against the mock autopilot: missionplan.bridge.transfer.retask.replace_mission_in_flight on a vehicle
that flies its survey, and the mock's own answer to a mission replaced in flight, as ArduCopter SITL and PX4
SIH answered it (docs/live-retasking.md; sitl_tests/test_retask_sitl.py runs the same on them).

The vehicle flies take-off, A1..A12, RTL; flying to A6 its mission becomes take-off, A1..A5, B1..B3,
RTL (or, renumbered, take-off, B1..B3, RTL) and it must continue at B1 (resume_seq) and reach B1..B3
without landing, disarming or going back to its first item. Every wait is bounded by a message or a
deadline; nothing sleeps.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any

import pytest

from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, WireItem, to_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import MissionClient, Timeouts
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED
from missionplan.bridge.transfer.retask import RetaskError, replace_mission_in_flight
from missionplan.bridge.transfer.uploader import PymavlinkBackend

pytestmark = pytest.mark.flight  # flies mock autopilots: `pytest -m "not flight"` leaves it out

HOME = (45.0, 7.0, 200.0)
EARTH_RADIUS = 6_378_137.0
OWN = [(20.0, 0.0), (80.0, 0.0), (80.0, 20.0), (20.0, 20.0), (20.0, 40.0), (80.0, 40.0), (80.0, 60.0), (20.0, 60.0),
       (20.0, 80.0), (80.0, 80.0), (80.0, 100.0), (20.0, 100.0)]
LOST = [(20.0, -40.0), (80.0, -40.0), (80.0, -60.0)]
RETASK_AT = 5  # A6: the waypoint flown to when the mission is replaced
SPEEDUP = 25.0  # with OWN's legs after A6: a re-task delayed two wall seconds still finds it flying
WAIT_S = 10.0  # wall seconds for any one thing the mock does (it flies a minute in about two and a half seconds)


def _point(north: float, east: float) -> tuple[float, float]:
    return (HOME[0] + math.degrees(north / EARTH_RADIUS),
            HOME[1] + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(HOME[0])))))


def _waypoints(points: list[tuple[float, float]]) -> list[MissionItem]:
    return [MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=_point(n, e)[0],
                        y=_point(n, e)[1], z=20.0) for n, e in points]


def survey() -> Mission:
    return Mission([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0],
                                y=HOME[1], z=20.0),
                    *_waypoints(OWN),
                    MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)], home=HOME)


def retasked(renumbered: bool = False, speed: bool = False) -> Mission:
    """The flown part (none when renumbered), B1..B3, RTL; `speed`: a DO_CHANGE_SPEED before B1, as fly's
    re-plans begin (take-off, speed, survey), to resume at."""
    kept = survey().items[:1 if renumbered else 1 + RETASK_AT]
    change = [MissionItem(mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, param1=1.0, param2=5.0,
                          param3=-1.0)] if speed else []
    rtl = MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)
    return Mission([*kept, *change, *_waypoints(LOST), rtl], home=HOME)


@dataclass
class Watched:
    """What the vehicle sent while a test listened, kept in order."""

    sysid: int
    reached: list[int] = field(default_factory=list)
    currents: list[int] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    armed: list[bool] = field(default_factory=list)
    lowest_m: float = math.inf  # the lowest relative altitude heard
    positions: int = 0
    accepted_at: int | None = None  # len(reached) at the vehicle's last accepting MISSION_ACK

    def reached_since_accepted(self) -> list[int]:
        """The items reached once the new mission was on board: before it, the vehicle flies on with its old
        one (PX4 during the whole upload, ArduPilot until GUIDED), whose seqs may be the new B's."""
        return self.reached[self.accepted_at or 0:]

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid:
            return
        kind = msg.get_type()
        if kind == "MISSION_ITEM_REACHED":
            self.reached.append(int(msg.seq))
        elif kind == "MISSION_CURRENT":
            self.currents.append(int(msg.seq))
        elif kind == "STATUSTEXT":
            self.texts.append(str(msg.text).rstrip("\x00"))
        elif kind == "HEARTBEAT" and msg.type != 6:
            self.armed.append(bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED))
        elif kind == "GLOBAL_POSITION_INT":
            self.positions += 1
            self.lowest_m = min(self.lowest_m, msg.relative_alt / 1000.0)
        elif (kind == "MISSION_ACK" and msg.type == mavlink.MAV_MISSION_ACCEPTED
              and msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION):
            self.accepted_at = len(self.reached)

    def clear(self) -> None:
        self.reached, self.currents, self.texts, self.armed = [], [], [], []
        self.lowest_m, self.positions, self.accepted_at = math.inf, 0, None


@dataclass
class Flying:
    mock: MockAutopilot
    link: Link
    backend: PymavlinkBackend
    flavour: Flavour
    watched: Watched

    def listen(self, done: Any, seconds: float = WAIT_S) -> bool:
        """Read (into `watched`) until done() or `seconds`; whether done."""
        deadline = time.monotonic() + seconds
        while not done():
            msg = self.link.recv(deadline)
            if msg is None:
                return False
            self.watched.take(msg)
        return True

    def command(self, command: int, *params: float) -> int | None:
        return self.link.command_long(1, command, list(params), time.monotonic() + 5.0, other=self.watched.take)

    def wire(self, mission: Mission) -> list[WireItem]:
        return to_wire(mission, self.flavour)

    @property
    def first(self) -> int:
        return 1 if self.flavour is Flavour.ARDUPILOT else 0  # ArduPilot's seq 0 is home

    def seq_of(self, index: int) -> int:
        """The wire seq of Mission.items[index]."""
        return index + self.first


@contextmanager
def flying(flavour: Flavour) -> Iterator[Flying]:
    """A mock vehicle flying the survey, mid-way to A6 (it has reached A5)."""
    with MockAutopilot(homes={1: HOME}, flavour=flavour, speedup=SPEEDUP, request_interval=0.05).start() as mock:
        with Link(mock.client_url) as link:
            backend = PymavlinkBackend("", 1, link=link, timeouts=Timeouts(item_timeout=0.3, retries=10))
            f = Flying(mock, link, backend, flavour, Watched(1))
            backend.upload(0, f.wire(survey()))
            if flavour is Flavour.ARDUPILOT:
                assert f.command(mavlink.MAV_CMD_DO_SET_MODE, 1, ARDUPILOT_GUIDED) == 0
            assert f.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
            assert f.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == 0
            a5 = f.seq_of(RETASK_AT)  # A5 is Mission.items[5]
            assert f.listen(lambda: a5 in f.watched.reached), f.watched
            f.watched.clear()
            yield f


class _Seen:
    """The link as a mission client uses it, each message also kept in `watched` (the client drops what it
    does not need, such as the STATUSTEXT ArduPilot sends during the upload)."""

    def __init__(self, f: Flying) -> None:
        self.f = f

    def recv(self, deadline: float) -> Any | None:
        msg = self.f.link.recv(deadline)
        if msg is not None:
            self.f.watched.take(msg)
        return msg

    def __getattr__(self, name: str) -> Any:
        return getattr(self.f.link, name)


def upload_watched(f: Flying, items: list[WireItem]) -> None:
    MissionClient(_Seen(f), f.backend.vehicle, f.backend.client.timeouts).upload(0, items)


def _b_seqs(f: Flying, renumbered: bool = False, speed: bool = False) -> list[int]:
    first_b = f.seq_of(1 if renumbered else 1 + RETASK_AT) + int(speed)
    return [first_b + k for k in range(len(LOST))]


@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4], ids=["ardupilot", "px4"])
@pytest.mark.parametrize("renumbered, speed", [(False, False), (True, False), (True, True)],
                         ids=["same-numbers", "renumbered", "fly-replan"])
def test_the_vehicle_continues_at_resume_seq_and_reaches_the_new_waypoints(flavour: Flavour, renumbered: bool,
                                                                           speed: bool) -> None:
    with flying(flavour) as f:
        b = _b_seqs(f, renumbered, speed)
        resume = b[0] - int(speed)  # fly's re-plans resume at the DO_CHANGE_SPEED before the survey
        report = replace_mission_in_flight(f.backend, f.link, 1, flavour, f.wire(retasked(renumbered, speed)),
                                           resume, time.monotonic() + WAIT_S, observe=f.watched.take)
        assert report.confirmed, report.summary()
        assert report.accepted and report.read_back and resume <= report.continued_at <= b[0], report
        assert report.mode == ("AUTO" if flavour is Flavour.ARDUPILOT else "MISSION"), report
        assert f.watched.positions > 0  # what came during the re-task was handed on, not dropped
        assert f.watched.accepted_at is not None, f.watched  # the upload's final ACK was handed on too
        assert f.listen(lambda: b[-1] in f.watched.reached_since_accepted()), f.watched
        w = f.watched
        assert [seq for seq in w.reached_since_accepted() if seq in b] == b, w.reached  # B1, B2, B3 in order
        assert min(w.currents) >= resume, w.currents  # never back to an earlier item (take-off, seq 0/1)
        assert all(w.armed) and w.lowest_m > 15.0, (w.armed, w.lowest_m)  # stayed armed and up


def test_ardupilot_is_paused_in_guided_for_the_upload() -> None:
    with flying(Flavour.ARDUPILOT) as f:
        modes: list[int] = []
        f.watched.take = _also(f.watched.take, lambda m: m.get_type() == "HEARTBEAT" and modes.append(m.custom_mode))
        b = _b_seqs(f)
        report = replace_mission_in_flight(f.backend, f.link, 1, Flavour.ARDUPILOT, f.wire(retasked()), b[0],
                                           time.monotonic() + WAIT_S, observe=f.watched.take)
        assert report.confirmed, report.summary()
        assert 4 in modes and modes[-1] == 3, modes  # GUIDED, then AUTO again


def _also(first: Any, second: Any) -> Any:
    def both(msg: Any) -> None:
        first(msg)
        second(msg)
    return both


def test_an_upload_in_auto_alone_keeps_ardupilot_at_its_item_and_sends_px4_to_the_flagged_one() -> None:
    """What each autopilot does with the upload itself, no MISSION_SET_CURRENT (measured on SITL / SIH)."""
    with flying(Flavour.ARDUPILOT) as f:
        upload_watched(f, f.wire(retasked()))  # B1 now sits at the item it flies to
        assert f.listen(lambda: "Auto mission changed, restarted command" in f.watched.texts), f.watched
        b = _b_seqs(f)
        assert f.listen(lambda: b[0] in f.watched.reached), f.watched
        assert min(f.watched.currents) == b[0], f.watched.currents
    with flying(Flavour.ARDUPILOT) as f:
        upload_watched(f, f.wire(retasked(renumbered=True)))  # its item is past the new end
        assert f.listen(lambda: "Auto mission changed but failed to restart command" in f.watched.texts)
        a6 = f.seq_of(1 + RETASK_AT)
        assert f.listen(lambda: a6 in f.watched.reached), f.watched  # it finished the item it flew...
        assert f.mock.vehicle(1).flight.state.mission_done  # ...and the mission was over: it holds there
    with flying(Flavour.PX4) as f:
        upload_watched(f, f.wire(retasked()))  # to_wire flags seq 0 current: PX4 goes back to it
        assert f.listen(lambda: 0 in f.watched.currents), f.watched.currents
    with flying(Flavour.PX4) as f:
        b = _b_seqs(f, renumbered=True)
        flagged = [replace(it, current=int(it.seq == b[0])) for it in f.wire(retasked(renumbered=True))]
        upload_watched(f, flagged)
        assert f.listen(lambda: b[0] in f.watched.reached), f.watched
        assert min(f.watched.currents) == b[0], f.watched.currents


@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4], ids=["ardupilot", "px4"])
def test_a_vehicle_not_flying_its_mission_is_not_touched(flavour: Flavour) -> None:
    with flying(flavour) as f:
        assert f.command(20) == 0  # RTL: a failsafe's, or the pilot's choice
        vehicle = f.mock.vehicle(1)
        uploads = vehicle.uploads_completed
        with pytest.raises(RetaskError, match="not flying its mission") as caught:
            replace_mission_in_flight(f.backend, f.link, 1, flavour, f.wire(retasked()), _b_seqs(f)[0],
                                      time.monotonic() + WAIT_S)
        assert vehicle.uploads_completed == uploads and vehicle.flight.state.mode == "RTL"
        assert not caught.value.report.accepted


def test_a_refused_mission_raises_and_px4_flies_on_with_its_old_one() -> None:
    with flying(Flavour.PX4) as f:
        bad = f.wire(retasked())
        bad[3] = replace(bad[3], frame=mavlink.MAV_FRAME_LOCAL_NED)  # PX4 refuses it (UNSUPPORTED_FRAME)
        with pytest.raises(RetaskError, match="flies on with its previous mission"):
            replace_mission_in_flight(f.backend, f.link, 1, Flavour.PX4, bad, _b_seqs(f)[0], time.monotonic() + WAIT_S)
        a6 = f.seq_of(1 + RETASK_AT)
        assert f.listen(lambda: a6 in f.watched.reached), f.watched  # the old mission, flown on


def test_a_fence_goes_up_before_the_mission() -> None:
    with flying(Flavour.ARDUPILOT) as f:
        corners = [_point(-100, -100), _point(-100, 100), _point(150, 100), _point(150, -100)]
        fence = [WireItem(k, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 0, 1, 4.0,
                          0, 0, 0, round(lat * 1e7), round(lon * 1e7), 0.0, mavlink.MAV_MISSION_TYPE_FENCE)
                 for k, (lat, lon) in enumerate(corners)]
        b = _b_seqs(f)
        report = replace_mission_in_flight(f.backend, f.link, 1, Flavour.ARDUPILOT, f.wire(retasked()), b[0],
                                           time.monotonic() + WAIT_S, fence=fence)
        assert report.confirmed, report.summary()
        assert len(f.mock.vehicle(1).mission(1)) == 4


@pytest.mark.parametrize("resume", [0, 99])
def test_a_resume_seq_that_cannot_be_flown_is_refused_before_anything_is_sent(resume: int) -> None:
    with flying(Flavour.ARDUPILOT) as f:
        uploads = f.mock.vehicle(1).uploads_completed
        with pytest.raises(ValueError, match="resume_seq"):  # ArduPilot's seq 0 is its home
            replace_mission_in_flight(f.backend, f.link, 1, Flavour.ARDUPILOT, f.wire(retasked()), resume,
                                      time.monotonic() + WAIT_S)
        assert f.mock.vehicle(1).uploads_completed == uploads
