"""Photos recovered from PX4 SIH's own log (a ULog), and the mock's PX4 log transfer compared with it.

PX4 keeps a ULog when its logger runs (SDLOG_MODE 0, PX4's default: from arming to disarming; the
other tests turn it off), with one camera_capture message per photo: what CAMERA_IMAGE_CAPTURED
reported. One session (`session`), run against PX4 SIH v1.15.4 (TRIG_MODE 4 at boot) and against the
mock's SITL-like PX4 flavour with its logging on: list the logs of a fresh vehicle; upload a short
survey (take-off to 10 m, a photo every 2 m on a 30 m leg north and back, RTL); arm (retried while
PX4 is not ready) and list while armed; fly it; after landing ask for one photo report again by index
(MAV_CMD_REQUEST_MESSAGE, SIH only), list, recover the photos with
missionplan.bridge.transfer.onboard_log.recover_photos (timed), and probe the transfer's edges; arm and disarm once more
and list again.

Required: the log's photos equal the CAMERA_IMAGE_CAPTURED reports received (image_index, lat / lon
to the unit of 1e-7 degree, altitudes to the millimetre); PX4 refuses the report by index; and the
mock answers the log protocol as PX4 does (sizes and times aside). The measured download is printed
(`pytest -s`) for docs/flight-faults.md.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from test_photo_recovery_sitl import PAST_THE_END, _raw_data, _raw_list, _Tee

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, MissionType, to_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.transfer.onboard_log import LOG_DATA_LEN, recover_photos
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.formats.px4_rules import px4_millimetres
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.px4_sih import PX4, px4_or_skip

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

HOME = (45.4641, 9.1891, 120.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
READY_TIMEOUT_S = 120.0
FLIGHT_TIMEOUT_S = 240.0
BOOT_PARAMS = {"SDLOG_MODE": 0.0, "TRIG_MODE": 4.0, "TRIG_INTERFACE": 3.0}


def _mission() -> Mission:
    north = HOME[0] + 30.0 / M_PER_DEG_LAT
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=10.0),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=2.0),
             MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=north, y=HOME[1],
                         z=10.0),
             MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=10.0),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0),
             MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)]
    return Mission(items, home=HOME)


def _until_accepted(tee: _Tee, sysid: int, command: int, params: list[float], timeout: float) -> None:
    """A command retried while the vehicle refuses it (PX4: arming before it is ready, a mission start
    right after an upload), each refusal followed by a second of listening."""
    deadline = time.monotonic() + timeout
    since = len(tee.kept)
    while time.monotonic() < deadline:
        result = tee.link.command_long(sysid, command, params, deadline, other=tee.kept.append)
        if result == mavlink.MAV_RESULT_ACCEPTED:
            return
        tee.collect(1.0)
    said = sorted({str(m.text) for m in tee.kept[since:] if m.get_type() == "STATUSTEXT"})
    raise AssertionError(f"vehicle {sysid} did not accept command {command} within {timeout:g} s; it said {said}")


def _armed(msg: Any) -> bool:
    return bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def _disarmed(kept: list[Any]) -> bool:
    """The autopilot's latest HEARTBEAT says disarmed (PX4 sends many other messages, and other
    components' heartbeats, between two of its own)."""
    for msg in reversed(kept):
        if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == AUTOPILOT_COMPONENT_ID:
            return not _armed(msg)
    return False


def session(url: str, sysid: int, keep: Path) -> dict[str, Any]:
    rec: dict[str, Any] = {}
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        tee = _Tee(backend.link, sysid)
        rec["fresh"] = _raw_list(tee, sysid)
        backend.upload(MissionType.MISSION, to_wire(_mission(), Flavour.PX4))
        _until_accepted(tee, sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], READY_TIMEOUT_S)
        rec["armed"] = _raw_list(tee, sysid)
        _until_accepted(tee, sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], 10.0)
        deadline = time.monotonic() + FLIGHT_TIMEOUT_S
        while not _disarmed(tee.kept):
            assert time.monotonic() < deadline, "the vehicle did not land and disarm in time"
            tee.collect(0.5)
        landed_at = time.time()
        rec["reports"] = {int(m.image_index): m for m in tee.kept
                          if m.get_type() == "CAMERA_IMAGE_CAPTURED" and int(m.capture_result) == 1}  # 1: captured
        tee.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                  mavlink.MAVLINK_MSG_ID_CAMERA_IMAGE_CAPTURED, 3, 0, 0, 0, 0, 0)
        answer = [m for m in tee.collect(1.5) if m.get_type() in ("COMMAND_ACK", "CAMERA_IMAGE_CAPTURED")]
        rec["report 3 asked again"] = [(m.get_type(), int(getattr(m, "result", -1))) for m in answer]
        rec["landed"] = _raw_list(tee, sysid)
        started = time.monotonic()
        rec["photos"] = recover_photos(tee, sysid, "px4", time.monotonic() + 180.0, since_utc=landed_at - 600,
                                       save_dir=keep)
        rec["download_s"] = time.monotonic() - started
        rec["log_size"] = max(rec["landed"]["sizes"])
        newest = rec["photos"][0].log_id if rec["photos"] else 0
        rec["listed again"] = _raw_list(tee, sysid)  # PX4 serves data only after a listing
        rec["short request"] = _raw_data(tee, sysid, newest, 0, 2 * LOG_DATA_LEN + 20)
        rec["past the end"] = _raw_data(tee, sysid, newest, PAST_THE_END, LOG_DATA_LEN)
        rec["no such log"] = _raw_data(tee, sysid, newest + 7, 0, LOG_DATA_LEN)
        tee.mav.log_request_end_send(sysid, AUTOPILOT_COMPONENT_ID)
        rec["landed_at"] = landed_at
        # After a landing PX4 refuses to arm until its checks pass again: once over 30 s in a full CI run.
        _until_accepted(tee, sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], READY_TIMEOUT_S)
        tee.link.command_long(sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0.0], time.monotonic() + 5.0)
        tee.collect(1.0)
        rec["armed once more"] = _raw_list(tee, sysid)
        rec["logger says"] = [re.sub(r"\d", "#", str(m.text)) for m in tee.kept
                              if m.get_type() == "STATUSTEXT" and str(m.text).startswith("[logger]")]
    return rec


@pytest.fixture(scope="module")
def px4_session(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    px4_or_skip()
    with PX4(home=HOME, params=BOOT_PARAMS) as vehicle:
        rec = session(vehicle.gcs_url, vehicle.sysid, tmp_path_factory.mktemp("px4-log"))
        rec["ulg files"] = [(p.name, p.stat().st_size) for p in vehicle.log_files()]
        yield rec


def test_after_landing_the_ulog_photos_equal_the_camera_image_captured(px4_session: dict[str, Any]) -> None:
    rec = px4_session
    reports, photos = rec["reports"], rec["photos"]
    print(f"\nPX4 SIH: log of {rec['log_size']} bytes, {len(photos)} photos, downloaded and read in "
          f"{rec['download_s']:.2f} s on loopback; logs {rec['ulg files']}")
    assert len(reports) >= 15  # a photo every 2 m over 60 m
    assert [p.img_idx for p in photos] == sorted(reports) == list(range(len(reports)))
    for p in photos:
        m = reports[p.img_idx]
        assert (p.lat_e7, p.lon_e7) == (int(m.lat), int(m.lon)), (p, m)
        assert px4_millimetres(p.alt_amsl) == int(m.alt) and px4_millimetres(p.alt_rel) == int(m.relative_alt)
        assert p.utc_s == pytest.approx(int(m.time_utc) / 1e6, abs=1e-6)
    # No report is sent again on request: PX4 refuses MAV_CMD_REQUEST_MESSAGE for it.
    assert rec["report 3 asked again"] == [("COMMAND_ACK", mavlink.MAV_RESULT_DENIED)]


def _protocol(rec: dict[str, Any]) -> dict[str, Any]:
    # Just after arming, PX4 SIH lists the log it is opening or not yet (0 or 1 logs: a race with its
    # logger), and its logger's "[logger] ./log/DATE/TIME.ulg" comes within or before the listing:
    # compared apart (test below), as are the texts' digits (dates, times).
    keys = ("fresh", "landed", "listed again", "armed once more")
    out: dict[str, Any] = {k: (rec[k]["entries"], [(sev, re.sub(r"\d", "#", text)) for sev, text in rec[k]["texts"]
                                                    if not text.startswith("[logger]")])
                           for k in keys}
    out["armed"] = rec["armed"]["entries"] in ([(0, 0, 0)], [(0, 1, 0)])
    out["logger says"] = sorted(set(rec["logger says"]))
    for k in ("short request", "past the end", "no such log"):
        out[k] = rec[k]
    out["photo messages"] = sorted({p.message for p in rec["photos"]})
    return out


@pytest.mark.flight
def test_the_mock_answers_the_log_protocol_as_px4_does(px4_session: dict[str, Any], tmp_path: Path) -> None:
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[1], flavour="px4", homes={1: HOME}, sitl_like=True,
                       speedup=5.0) as mock:
        mock.configure_camera(1)
        mock.vehicle(1).logs.logging = True  # SDLOG_MODE 0
        mocked = session(mock.client_url, 1, tmp_path)
    want, got = _protocol(px4_session), _protocol(mocked)
    drift = [f"{k}: PX4 {want[k]!r}, mock {got[k]!r}" for k in want if want[k] != got[k]]
    assert drift == [], "the mock's log transfer drifted from PX4's:\n" + "\n".join(drift)
    for rec in (px4_session, mocked):
        assert rec["log_size"] > 0 and abs(rec["landed"]["times"][-1] - rec["landed_at"]) < 120
    assert len(mocked["photos"]) == len(mocked["reports"])
