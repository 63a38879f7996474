"""One mission-protocol session for a PX4 vehicle, recorded field by field (real PX4 SIH or the mock),
and how two records differ (drift).

Used by the differential test (sitl_tests/test_mock_vs_px4.py), which runs it against real PX4 SIH and
against the mock's PX4 flavour and compares the two records, and by tests/test_mock_as_autopilots.py,
which shows the comparison catches a mock that drifted. The session, in this order (the first upload
after start matters: PX4 asks for it with the legacy MISSION_REQUEST):
- the request type of the first and of the second upload after start;
- whether MISSION_REQUEST_LIST addressed to component 0 (broadcast) is answered;
- one single-item upload per frame (0, 1, 2, 3, 5, 6, 10, 11) and per command of a list (what we
  write, what QGroundControl writes, and commands PX4 does not know): the final MISSION_ACK of each;
- a rejected upload (one bad frame in the middle) leaves the previous mission; a count of 0 clears;
- a mission with every kind of item our files hold plus odd values, a fence (polygon and circle)
  and rally points; downloaded field by field, with the `current` flag.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import astuple, replace
from typing import Any

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink
from missionplan.bridge.formats.mission_items import MissionType, WireItem
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend, read_back_differences
from missionplan.testing.plans import next_message, same_answer, wire_item as w

HOME = (45.4641, 9.1891, 120.0)
LAT, LON = 454641000, 91891000

FRAMES = (0, 1, 2, 3, 5, 6, 10, 11)
# 16 WAYPOINT, 17 LOITER_UNLIM, 19 LOITER_TIME, 20 RTL, 21 LAND, 22 TAKEOFF, 31 LOITER_TO_ALT, 82 SPLINE_WAYPOINT,
# 93 NAV_DELAY, 112 CONDITION_DELAY, 115 CONDITION_YAW, 177 DO_JUMP, 178 DO_CHANGE_SPEED, 183 DO_SET_SERVO,
# 189 DO_LAND_START, 195 DO_SET_ROI_LOCATION, 201 DO_SET_ROI, 203 DO_DIGICAM_CONTROL, 205 DO_MOUNT_CONTROL,
# 206 DO_SET_CAM_TRIGG_DIST, 214 DO_SET_CAM_TRIGG_INTERVAL, 1000 DO_GIMBAL_MANAGER_PITCHYAW, 2000 / 2001
# IMAGE_START / STOP_CAPTURE, 3000 DO_VTOL_TRANSITION, 5100 RALLY_POINT (not a mission item), 31000 USER_1, 999
COMMANDS = (16, 17, 19, 20, 21, 22, 31, 82, 93, 112, 115, 177, 178, 183, 189, 195, 201, 203, 205, 206, 214, 1000,
            2000, 2001, 3000, 5100, 31000, 999)


# Every item kind our plans hold (PX4 has no home item: seq 0 is the take-off), plus odd values.
MISSION = [
    w(0, 3, 22, p4=7.0, x=LAT, y=LON, z=12.345678),
    w(1, 2, 178, p1=1.0, p2=4.5, p3=-1.0, p4=7.0),
    w(2, 2, 206, p1=2.25, p2=3.0, p3=1.0, p4=5.0),
    w(3, 3, 16, p1=1.7, p2=0.0595, p3=0.5, p4=45.0, x=LAT + 123, y=LON - 77, z=12.345678),
    w(4, 6, 16, p2=0.25, x=LAT + 223, y=LON - 77, z=30.1),
    w(5, 0, 16, p1=2.9, x=LAT + 300, y=LON, z=150.123),
    w(6, 2, 178, p2=3.0, p3=-1.0),
    w(7, 2, 206),
    w(8, 5, 16, x=LAT + 310, y=LON + 5, z=140.5),
    w(9, 3, 21, p2=1.0, p4=45.0, x=LAT + 333, y=LON + 44, z=0.0),
    w(10, 2, 177, p1=2.0, p2=3.0),
    w(11, 2, 20),
]
FENCE = [w(i, 0, 5001, p1=4.0, x=LAT - 1000 + (i // 2) * 3000, y=LON - 1000 + (i % 2 ^ i // 2) * 3000 + i,
           mission_type=1) for i in range(4)] + [w(4, 0, 5004, p1=25.5, x=LAT + 500, y=LON + 500, mission_type=1)]
RALLY = [w(0, 3, 5100, x=LAT + 2000, y=LON + 3000, z=15.7, mission_type=2),
         w(1, 0, 5100, x=LAT - 2000, y=LON + 3000, z=135.5, mission_type=2)]


def raw_upload(link: Link, sysid: int, items: list[WireItem], mission_type: int = 0) -> tuple[str | None, int | None]:
    """Upload item by item as asked; (type of the first request, final MISSION_ACK type or None)."""
    is_ack = lambda m: m.get_type() == "MISSION_ACK" and m.mission_type == mission_type  # noqa: E731
    is_request = lambda m: m.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT")  # noqa: E731
    link.mav.mission_count_send(sysid, AUTOPILOT_COMPONENT_ID, len(items), mission_type)
    first = next_message(link, sysid, lambda m: is_request(m) or is_ack(m))
    if first is None or is_ack(first):
        return None, None if first is None else int(first.type)
    msg = first
    for _ in range(3 * len(items) + 5):  # answer what is asked until the final ack (bounded)
        if msg is None:
            return first.get_type(), None
        if is_ack(msg):
            return first.get_type(), int(msg.type)
        link.mav.mission_item_int_send(sysid, AUTOPILOT_COMPONENT_ID, **items[int(msg.seq)].fields())
        msg = next_message(link, sysid, lambda m: is_request(m) or is_ack(m), 3.0)
    return first.get_type(), None


def _list_answered(link: Link, sysid: int, component: int) -> bool:
    """Whether MISSION_REQUEST_LIST to this component draws a MISSION_COUNT (the download is then
    closed with an ACK: PX4 refuses uploads with ERROR while a download is open)."""
    link.mav.mission_request_list_send(sysid, component, 0)
    answered = next_message(link, sysid, lambda m: m.get_type() == "MISSION_COUNT", 2.0) is not None
    link.mav.mission_ack_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_MISSION_ACCEPTED, MissionType.MISSION)
    return answered


SETTLE_TRIES = 5


def _upload_until_held(backend: PymavlinkBackend, items: list[WireItem]) -> None:
    """Upload `items` until it reads back held (by the product's read-back rule) both at once and
    after the vehicle's next MISSION_CURRENT (sent at 1 Hz or on a change of item): up to SETTLE_TRIES.

    PX4 v1.15 can lose an accepted upload that follows other uploads within moments: its navigator,
    still catching up with an earlier mission, publishes that mission's state with a new current index
    (MissionBase::setMissionIndex), and the MAVLink mission manager adopts any mission topic whose id
    differs from its own (check_active_mission), so the vehicle then holds the earlier mission again.
    The single-item uploads above are 64 uploads in a row."""
    sysid = backend.vehicle.sysid
    for _ in range(SETTLE_TRIES):
        backend.upload(MissionType.MISSION, items)
        if read_back_differences(backend, MissionType.MISSION, items):
            continue
        next_message(backend.link, sysid, lambda m: m.get_type() == "MISSION_CURRENT", 3.0)
        if not read_back_differences(backend, MissionType.MISSION, items):
            return
    raise AssertionError(f"vehicle {sysid} did not keep a {len(items)}-item mission in {SETTLE_TRIES} uploads")


def _single(seq_item: WireItem) -> list[WireItem]:
    return [replace(seq_item, seq=0, current=1)]


def session(url: str, sysid: int) -> dict[str, Any]:
    """The record of one session against the vehicle `sysid` at `url` (see the module doc)."""
    out: dict[str, Any] = {}
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=20) as backend:
        link = backend.link
        out["home known"] = wait_home(link, sysid, 30.0) is not None  # PX4 is up: its mission store too
        good = [w(0, 3, 22, x=LAT, y=LON, z=10.0), w(1, 3, 16, x=LAT + 50, y=LON, z=10.0)]
        out["first request"], out["first ack"] = raw_upload(link, sysid, good)
        out["second request"], out["second ack"] = raw_upload(link, sysid, good)
        out["list answered, by target component"] = {c: _list_answered(link, sysid, c) for c in (0, 1, 2)}
        wp = w(0, 3, 16, x=LAT + 60, y=LON, z=10.0)
        out["frames"] = {f: raw_upload(link, sysid, _single(replace(wp, frame=f)))[1] for f in FRAMES}
        for frame in (3, 2):
            out[f"commands in frame {frame}"] = {c: raw_upload(link, sysid, _single(replace(wp, command=c, frame=frame)))[1]
                                                 for c in COMMANDS}
        # A rejected upload keeps the previous mission: first make sure that mission is `good`.
        _upload_until_held(backend, good)
        bad = good + [w(2, 1, 16, x=1, y=2, z=3.0), w(3, 3, 16, x=LAT, y=LON + 50, z=10.0)]
        out["bad upload ack"] = raw_upload(link, sysid, bad)[1]
        out["after bad upload"] = [astuple(it) for it in backend.download(MissionType.MISSION)]
        out["count 0 ack"] = raw_upload(link, sysid, [])[1]
        out["after count 0"] = len(backend.download(MissionType.MISSION))
        for mtype, items in ((MissionType.MISSION, MISSION), (MissionType.FENCE, FENCE), (MissionType.RALLY, RALLY)):
            backend.upload(mtype, items)
        out["mission"] = [astuple(it) for it in backend.download(MissionType.MISSION)]
        out["fence"] = [astuple(it) for it in backend.download(MissionType.FENCE)]
        out["rally"] = [astuple(it) for it in backend.download(MissionType.RALLY)]
    return out


# A mission whose first waypoint is 2.2 km north of HOME, and a fence that leaves HOME out.
FAR = [w(0, 3, 22, x=LAT + 200_000, y=LON, z=10.0), w(1, 3, 16, x=LAT + 200_500, y=LON, z=10.0), w(2, 2, 20)]
NEAR = [w(0, 3, 22, x=LAT, y=LON, z=10.0), w(1, 3, 16, x=LAT + 500, y=LON, z=10.0), w(2, 2, 20)]  # 55 m
AWAY_FENCE = [w(i, 0, 5001, p1=4.0, x=LAT + 1000 + (i // 2) * 2000, y=LON + (i % 2 ^ i // 2) * 2000, mission_type=1)
              for i in range(4)]


def wait_home(link: Link, sysid: int, seconds: float) -> Any:
    """The vehicle's HOME_POSITION (asked for with MAV_CMD_REQUEST_MESSAGE every second), or None."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                   mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
        msg = next_message(link, sysid, lambda m: m.get_type() == "HOME_POSITION", 1.0)
        if msg is not None:
            return msg
    return None


def wait_ready(link: Link, sysid: int, seconds: float) -> bool:
    """Until SYS_STATUS says the pre-arm checks pass ("Ready for takeoff!"). Before that PX4 answers
    MISSION_START with DENIED and "Mission start denied! No valid mission" even for a valid mission."""
    deadline = time.monotonic() + seconds
    while (msg := link.recv(deadline)) is not None:
        if (msg.get_srcSystem() == sysid and msg.get_type() == "SYS_STATUS"
                and msg.onboard_control_sensors_health & mavlink.MAV_SYS_STATUS_PREARM_CHECK):
            return True
    return False


# STATUSTEXT is best effort on PX4: a line is queued through uORB and can come a second or more after
# the answer it belongs to, or be lost when the log queue overflows (a loaded machine, a burst of
# health messages). The session so waits for the line it is about (bounded), asks again when it
# never came (bounded), and keeps only lines on its subject, not the health chatter around them.
TEXT_WAIT_S = 3.0
TEXT_TRIES = 3


def _texts(link: Link, sysid: int, seconds: float) -> list[str]:
    out = []
    deadline = time.monotonic() + seconds
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == sysid and msg.get_type() == "STATUSTEXT":
            out.append(str(msg.text).rstrip("\t\x00 "))
    return out


def _text_about(link: Link, sysid: int, about: str) -> list[str]:
    """The first STATUSTEXT line from `sysid` containing `about` within TEXT_WAIT_S, as a list ([] if none)."""
    deadline = time.monotonic() + TEXT_WAIT_S
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == sysid and msg.get_type() == "STATUSTEXT" and about in (text := str(msg.text)):
            return [text.rstrip("\t\x00 ")]
    return []


def _fence_texts(backend: PymavlinkBackend, fence: list[WireItem]) -> list[str]:
    """What PX4 says of an uploaded fence (its geofence checks the fence when it loads it): the
    upload is repeated up to TEXT_TRIES times while no geofence line comes."""
    texts: list[str] = []
    for _ in range(TEXT_TRIES):
        backend.upload(MissionType.FENCE, fence)
        if texts := _text_about(backend.link, backend.vehicle.sysid, "eofence"):
            break
    return texts


def _start(link: Link, sysid: int, ready_s: float) -> tuple[int | None, list[str]]:
    """MISSION_START, repeated while the vehicle is not ready yet (TEMPORARILY_REJECTED) up to ready_s,
    and up to TEXT_TRIES times while a refusal comes without its reason: (the final MAV_RESULT, the
    STATUSTEXT lines about the mission that came with it)."""
    deadline = time.monotonic() + ready_s
    tries = 0
    while True:
        texts: list[str] = []
        link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
        until = time.monotonic() + 2.0
        result = None
        while (msg := link.recv(until)) is not None:
            if msg.get_srcSystem() != sysid:
                continue
            if msg.get_type() == "STATUSTEXT":
                texts.append(str(msg.text).rstrip("\t\x00 "))
            elif msg.get_type() == "COMMAND_ACK" and int(msg.command) == mavlink.MAV_CMD_MISSION_START:
                result = int(msg.result)
                break
        texts = [t for t in texts if "ission" in t]
        if result is not None and not texts:
            texts = _text_about(link, sysid, "ission")
        tries += result == mavlink.MAV_RESULT_DENIED
        if result == mavlink.MAV_RESULT_DENIED and not texts and tries < TEXT_TRIES:
            continue  # refused, its reason lost or late: ask again
        if result != mavlink.MAV_RESULT_TEMPORARILY_REJECTED or time.monotonic() > deadline:
            return result, texts
        _texts(link, sysid, 2.0)  # not ready yet: listen, then ask again


def start_session(url: str, sysid: int, ready_s: float = 90.0) -> dict[str, Any]:
    """Once PX4 is ready: the start of a mission whose first waypoint is 2.2 km away (refused, and
    why), and what PX4 says of a fence without the vehicle's home. Nothing is started."""
    out: dict[str, Any] = {}
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=20) as backend:
        link = backend.link
        out["home known"] = wait_home(link, sysid, ready_s) is not None
        out["ready"] = wait_ready(link, sysid, ready_s)
        backend.upload(MissionType.MISSION, FAR)
        _texts(link, sysid, 3.0)  # PX4 SIH drops STATUSTEXT in its first seconds: let it settle
        out["far: start"] = _start(link, sysid, ready_s)
        out["fence upload texts"] = _fence_texts(backend, AWAY_FENCE)
        # (With that fence PX4 still starts a near mission - it arms and flies, unfenced - measured by
        # hand: docs/px4-missions.md. The mock does not fly by itself, so it is not part of the session.)
    return out


def drift(real: dict[str, Any], mocked: dict[str, Any]) -> list[str]:
    """Every difference between two session records, one line each (stored lists field by field)."""
    out = []
    for key in real:
        if key in ("mission", "fence", "rally", "after bad upload"):
            for seq, (r, m) in enumerate(zip(real[key], mocked[key])):
                for name, a, b in zip(WireItem.__dataclass_fields__, r, m):
                    if not same_answer(a, b):
                        out.append(f"{key} item {seq} {name}: PX4 {a!r}, mock {b!r}")
            if len(real[key]) != len(mocked[key]):
                out.append(f"{key}: PX4 holds {len(real[key])} items, mock {len(mocked[key])}")
        elif isinstance(real[key], dict) and isinstance(mocked.get(key), dict):
            out += [f"{key} {k}: PX4 {real[key][k]!r}, mock {mocked[key].get(k)!r}"
                    for k in real[key] if not same_answer(real[key][k], mocked[key].get(k))]
        elif not same_answer(real[key], mocked.get(key)):
            out.append(f"{key}: PX4 {real[key]!r}, mock {mocked.get(key)!r}")
    return out


def mock_record(run: Callable[[str, int], dict[str, Any]]) -> dict[str, Any]:
    """`run` (session or start_session) against a fresh mock of PX4's flavour, system id 11 at HOME."""
    from missionplan.bridge.sim.mock import MockAutopilot

    with MockAutopilot("udpin:127.0.0.1:0", sysids=[11], flavour="px4", homes={11: HOME}) as mock:
        return run(mock.client_url, 11)


if __name__ == "__main__":  # by hand: python -m missionplan.testing.px4_mission_session URL SYSID
    import json
    import sys

    print(json.dumps(session(sys.argv[1], int(sys.argv[2])), indent=1, default=str))
