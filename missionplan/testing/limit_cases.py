"""Out-of-range mission, rally and fence items, uploaded raw (no file, none of our own checks), and what real
ArduCopter SITL and PX4 SIH answered to each: the cases that sitl_tests/test_mock_limits_vs_autopilots.py
uploads to the real autopilots and to the mock, and that tests/test_limits.py holds the mock to in every run.

What they answered (ArduCopter 4.7-dev SITL, PX4 v1.15.4 SIH), and what the mock now answers alike:
- ArduCopter refuses an altitude of 1e38 m, -1e9 m, 83,000 m or NaN with MAV_MISSION_INVALID_PARAM7 (its
  Location keeps 24-bit centimetres: LOCATION_ALT_MAX_M) and takes 82,999 m; a latitude of 91 degrees is
  INVALID_PARAM5_X; a NaN param1 of a waypoint or an infinite one INVALID_PARAM1 (param4, yaw, may be NaN); a
  DO_JUMP past the last item, or to -5, MAV_MISSION_ERROR; a DO_JUMP to itself repeating for ever it takes
  (stores, and flown, hovers over its takeoff point: formats.item_checks.check_jumps); a rally point at 1e38 m
  INVALID_PARAM7; a fence vertex at latitude 91 ERROR once its last point came; a hold time of 1e6 s it
  stores as 16,960 s (a uint16). An item without a position keeps no altitude:
  an RTL at 1e38 m is taken.
- PX4 takes all of these at upload and stores them as sent (float32), a DO_JUMP's repeat -1 as 65535.
So our files' readers refuse them first (formats.item_checks, limits): the vehicle is no safeguard.
"""

from __future__ import annotations

import math
from dataclasses import astuple, replace
from typing import Any

from missionplan.bridge.formats.mission_items import MissionType, WireItem
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import MissionTransferError, Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.loopback import wait_until
from missionplan.testing.plans import same_answer, wire_item as w

HOME = (45.4643, 9.1895, 120.0)
LAT, LON = 454643000, 91895000
ACCEPTED, ERROR = mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_ERROR
PARAM1, PARAM5, PARAM7 = (mavlink.MAV_MISSION_INVALID_PARAM1, mavlink.MAV_MISSION_INVALID_PARAM5_X,
                          mavlink.MAV_MISSION_INVALID_PARAM7)


def _mission(*extra: WireItem, home: bool = True) -> tuple[int, list[WireItem]]:
    """A mission of a takeoff and `extra` (ArduPilot: after its home item 0), renumbered from 0."""
    items = ([w(0, 0, 16, x=LAT, y=LON, z=120.0)] if home else []) + [w(0, 3, 22, x=LAT, y=LON, z=10.0)]
    items += list(extra)
    return MissionType.MISSION, [replace(it, seq=seq, current=int(seq == 0)) for seq, it in enumerate(items)]


def cases(home: bool) -> dict[str, tuple[int, list[WireItem]]]:
    """Out-of-range items by name: (mission_type, the items of the upload)."""
    jump = 2 if home else 1  # the DO_JUMP's own seq
    return {
        "waypoint at 1e38 m": _mission(w(0, 3, 16, x=LAT + 100, y=LON, z=1e38), home=home),
        "waypoint at -1e9 m": _mission(w(0, 3, 16, x=LAT + 100, y=LON, z=-1e9), home=home),
        "waypoint at 83,000 m": _mission(w(0, 3, 16, x=LAT + 100, y=LON, z=83_000.0), home=home),
        "waypoint at 82,999 m": _mission(w(0, 3, 16, x=LAT + 100, y=LON, z=82_999.0), home=home),
        "waypoint at NaN m": _mission(w(0, 3, 16, x=LAT + 100, y=LON, z=math.nan), home=home),
        "waypoint at latitude 91": _mission(w(0, 3, 16, x=910_000_000, y=LON, z=30.0), home=home),
        "waypoint hold NaN": _mission(w(0, 3, 16, p1=math.nan, x=LAT + 100, y=LON, z=30.0), home=home),
        "waypoint hold inf": _mission(w(0, 3, 16, p1=math.inf, x=LAT + 100, y=LON, z=30.0), home=home),
        "waypoint hold 1e6 s": _mission(w(0, 3, 16, p1=1e6, x=LAT + 100, y=LON, z=30.0), home=home),
        "RTL at 1e38 m": _mission(w(0, 2, 20, z=1e38), home=home),
        "DO_JUMP to itself for ever": _mission(w(0, 2, 177, p1=jump, p2=-1), home=home),
        "DO_JUMP to item 99": _mission(w(0, 2, 177, p1=99, p2=1), home=home),
        "rally point at 1e38 m": (MissionType.RALLY, [w(0, 3, 5100, x=LAT, y=LON, z=1e38, mission_type=2)]),
        "fence vertex at latitude 91": (MissionType.FENCE, [
            w(i, 0, 5001, p1=3, x=910_000_000 if i == 0 else LAT + i * 1000, y=LON + i * 1000, mission_type=1)
            for i in range(3)]),
    }


EXPECTED_ARDUCOPTER = {
    "waypoint at 1e38 m": PARAM7, "waypoint at -1e9 m": PARAM7, "waypoint at 83,000 m": PARAM7,
    "waypoint at 82,999 m": ACCEPTED, "waypoint at NaN m": PARAM7, "waypoint at latitude 91": PARAM5,
    "waypoint hold NaN": PARAM1, "waypoint hold inf": PARAM1, "waypoint hold 1e6 s": ACCEPTED,
    "RTL at 1e38 m": ACCEPTED, "DO_JUMP to itself for ever": ACCEPTED, "DO_JUMP to item 99": ERROR,
    "rally point at 1e38 m": PARAM7, "fence vertex at latitude 91": ERROR,
}
EXPECTED_PX4 = dict.fromkeys(EXPECTED_ARDUCOPTER, ACCEPTED)


def session(url: str, sysid: int, home: bool) -> dict[str, tuple[int | None, Any]]:
    """Each case uploaded in turn: (MISSION_ACK result, the stored last item when accepted)."""
    out: dict[str, tuple[int, Any]] = {}
    before: dict[int, Any] = {}  # per list type, the last item the previous accepted case left stored
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(item_timeout=1.0, retries=3), connect_timeout=30) as backend:
        for name, (mission_type, items) in cases(home).items():
            try:
                backend.upload(mission_type, items)
            except MissionTransferError as err:  # the refusal's result (ERROR after the last item included)
                out[name] = (None if err.result is None else int(err.result), None)  # None: no answer at all
                continue
            # PX4 SIH can still serve the previous list just after its ACCEPTED (measured: about 1 upload
            # in 100; read again 0.5 s later it holds the new one), and no two cases store the same item:
            # read until the list is no longer the previous one, or say what was read after 2 s.
            def stored() -> Any:
                last = astuple(backend.download(mission_type)[-1])
                return last if not same_answer((ACCEPTED, last), before.get(mission_type)) else None
            last = wait_until(stored, 2.0) or astuple(backend.download(mission_type)[-1])
            out[name] = before[mission_type] = (ACCEPTED, last)
    return out


def drift(real: dict[str, tuple[int, Any]], mocked: dict[str, tuple[int, Any]], who: str) -> list[str]:
    """Every case where the two answered or stored differently, one line each."""
    return [f"{name}: {who} {real[name]!r}, mock {mocked.get(name)!r}" for name in real
            if not same_answer(real[name], mocked.get(name))]


def mock_answers(flavour: str, home: tuple[float, float, float], sysid: int) -> dict[str, tuple[int, Any]]:
    """What a fresh mock of `flavour` answers and stores for each case; its server thread must serve on."""
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[sysid], flavour=flavour, homes={sysid: home}) as mock:
        found = session(mock.client_url, sysid, home=flavour == "ardupilot")
        assert mock.vehicle(sysid).handler_errors == 0 and mock.serving
    return found
