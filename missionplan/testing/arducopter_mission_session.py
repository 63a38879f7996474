"""One mission-protocol session for an ArduCopter vehicle, recorded field by field (real ArduCopter SITL
or the ArduPilot-flavoured mock), and how two records differ (drift).

Used by the differential test (sitl_tests/test_mock_vs_arducopter.py), which runs it against real
ArduCopter SITL and against the mock and compares the two records, and by
tests/test_mock_as_autopilots.py, which shows the comparison catches a mock that drifted.

The session: a raw upload that sends an item before it was asked for, finishes, then sends a stray
item after the end (the answers are recorded); a full upload of a mission with every kind of item our
files hold plus odd values (fractional hold time, yaw, pass radius, deprecated frames, DO_* in frame
3, RTL with a position), a fence and rally points; a download of all three lists, field by field;
WPNAV_RADIUS set below its range and read back.
"""

from __future__ import annotations

import time
from dataclasses import astuple
from typing import Any

from missionplan.bridge.formats.mission_items import MissionType, WireItem
from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.plans import next_message, same_answer, wire_item as _w

HOME = (45.4643, 9.1895, 120.0)
LAT, LON = 454643000, 91895000


MISSION = [
    _w(0, 0, 16, x=LAT, y=LON, z=120.0),
    _w(1, 3, 22, p1=5.0, p4=7.0, x=LAT + 100, y=LON + 100, z=12.345678),
    _w(2, 2, 178, p1=1.0, p2=4.5, p3=-1.0, p4=7.0),
    _w(3, 2, 206, p1=2.25, p2=3.0, p3=1.0, p4=5.0),
    _w(4, 3, 16, p1=1.7, p2=0.0595, p3=0.5, p4=45.0, x=LAT + 123, y=LON - 77, z=12.345678),
    _w(5, 6, 16, p2=0.25, x=LAT + 223, y=LON - 77, z=30.1),
    _w(6, 0, 16, p1=2.9, x=LAT + 300, y=LON, z=150.123),
    _w(7, 3, 178, p2=3.0, p3=-1.0),
    _w(8, 2, 206),
    _w(9, 3, 21, p2=1.0, p4=45.0, x=LAT + 333, y=LON + 44, z=0.0),
    _w(10, 3, 20, p1=1.0, x=5, y=6, z=7.0),
    _w(11, 2, 177, p1=2.0, p2=3.0),
]
FENCE = [_w(i, 3, 5001, p1=4.0, x=LAT + (i // 2) * 1000, y=LON + (i % 2 ^ i // 2) * 1000 + i, z=7.0, mission_type=1)
         for i in range(4)] + [_w(4, 0, 5004, p1=25.5, x=LAT + 500, y=LON + 500, z=3.0, mission_type=1)]
RALLY = [_w(0, 3, 5100, p1=1.0, x=LAT + 2000, y=LON + 3000, z=15.7, mission_type=2),
         _w(1, 0, 5100, x=LAT - 2000, y=LON + 3000, z=-2.5, mission_type=2)]


def _out_of_turn_answers(link: Link, sysid: int) -> dict[str, Any]:
    """Raw upload of 3 items with an early item first, then a stray item after the end."""
    mav = link.mav
    items = MISSION[:3]
    is_ack = lambda m: m.get_type() == "MISSION_ACK" and m.mission_type == MissionType.MISSION  # noqa: E731
    is_request = lambda m: m.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT")  # noqa: E731
    mav.mission_count_send(sysid, AUTOPILOT_COMPONENT_ID, len(items), MissionType.MISSION)
    first = next_message(link, sysid, is_request)
    answers: dict[str, Any] = {"request": first.get_type() if first else None}
    mav.mission_item_int_send(sysid, AUTOPILOT_COMPONENT_ID, **items[2].fields())  # not asked for yet
    early = next_message(link, sysid, is_ack, 1.0)
    answers["early item"] = int(early.type) if early else None
    request, final = first, None
    for _ in range(10):  # answer what is asked until the end (bounded)
        if request is None:
            break
        mav.mission_item_int_send(sysid, AUTOPILOT_COMPONENT_ID, **items[int(request.seq)].fields())
        msg = next_message(link, sysid, lambda m: is_request(m) or is_ack(m), 2.5)
        if msg is not None and msg.get_type() == "MISSION_ACK":
            final = int(msg.type)
            break
        request = msg
    answers["final"] = final
    mav.mission_item_int_send(sysid, AUTOPILOT_COMPONENT_ID, **items[2].fields())  # after the end
    stray = next_message(link, sysid, is_ack, 1.0)
    answers["stray item"] = int(stray.type) if stray else None
    return answers


def _home_known(backend: PymavlinkBackend, seconds: float) -> list[WireItem]:
    """The mission, once item 0 holds a real home (SITL needs its GPS fix, ~40 simulated s)."""
    deadline = time.monotonic() + seconds
    while True:
        got = backend.download(MissionType.MISSION)
        if got and (got[0].x, got[0].y) != (0, 0) or time.monotonic() > deadline:
            return got
        ask_again = min(deadline, time.monotonic() + 0.5)  # listen meanwhile, then ask again
        while backend.link.recv(ask_again) is not None:
            pass


def session(url: str, sysid: int) -> dict[str, Any]:
    """The record of one session against the vehicle `sysid` at `url` (see the module doc)."""
    out: dict[str, Any] = {}
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=20) as backend:
        out["answers"] = _out_of_turn_answers(backend.link, sysid)
        for mtype, items in ((MissionType.MISSION, MISSION), (MissionType.FENCE, FENCE), (MissionType.RALLY, RALLY)):
            backend.upload(mtype, items)
        out["invalid_sequence_acks"] = backend.client.invalid_sequence_acks
        out["fence"] = [astuple(it) for it in backend.download(MissionType.FENCE)]
        out["rally"] = [astuple(it) for it in backend.download(MissionType.RALLY)]
        out["mission"] = [astuple(it) for it in _home_known(backend, 60.0)]
        params = ParamClient(backend.link, backend.vehicle)
        out["WPNAV_RADIUS default"] = params.get("WPNAV_RADIUS")
        # below its documented range
        params.link.mav.param_set_send(sysid, AUTOPILOT_COMPONENT_ID, b"WPNAV_RADIUS", 3.0,
                                       mavlink.MAV_PARAM_TYPE_REAL32)
        answer = next_message(backend.link, sysid, lambda m: m.get_type() == "PARAM_VALUE"
                       and str(m.param_id).rstrip("\x00") == "WPNAV_RADIUS", 5.0)  # what it made of it
        out["WPNAV_RADIUS answer to setting 3"] = None if answer is None else float(answer.param_value)
        out["WPNAV_RADIUS after setting 3"] = params.get("WPNAV_RADIUS")
    return out


def drift(real: dict[str, Any], mocked: dict[str, Any]) -> list[str]:
    """Every difference between two sessions, field by field, as one line each."""
    out = []
    for key in real:
        if key in ("mission", "fence", "rally"):
            for seq, (r, m) in enumerate(zip(real[key], mocked[key])):
                for name, a, b in zip(WireItem.__dataclass_fields__, r, m):
                    if key == "mission" and seq == 0 and name in ("x", "y", "z"):
                        # Home is where the EKF puts it: within a few 1e-7 degrees and 0.5 m of --home.
                        if abs(a - b) <= (0.5 if name == "z" else 5):
                            continue
                    if not same_answer(a, b):
                        out.append(f"{key} item {seq} {name}: ArduCopter {a!r}, mock {b!r}")
            if len(real[key]) != len(mocked[key]):
                out.append(f"{key}: ArduCopter holds {len(real[key])} items, mock {len(mocked[key])}")
        elif not same_answer(real[key], mocked[key]):
            out.append(f"{key}: ArduCopter {real[key]!r}, mock {mocked[key]!r}")
    return out


def mock_record(**options: Any) -> dict[str, Any]:
    """The session against a fresh ArduPilot-flavoured mock, system id 7 at HOME (`options` go to
    MockAutopilot)."""
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[7], flavour="ardupilot", homes={7: HOME}, **options) as mock:
        return session(mock.client_url, 7)
