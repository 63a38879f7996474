"""Photos recovered from ArduCopter SITL's own log, and the mock's log transfer compared with it.

One session (`session`), run against real ArduCopter SITL and against the mock's SITL-like ArduPilot
flavour: list the logs of a fresh vehicle; configure the camera (CAM1_TYPE = 1 and a reboot); arm and
disarm once (readiness); upload a short survey (take-off to 10 m, a photo every 2 m on a 30 m leg north
and back, RTL) and fly it, asking for the log list while armed; after landing list the logs, recover
the photos with missionplan.bridge.transfer.onboard_log.recover_photos (timed), and probe the transfer's edges (a short
request, a request past the end, a log that does not exist); arm and disarm twice more and list again.

Required: after landing, the log's CAM photos equal the CAMERA_FEEDBACK reports received (img_idx,
lat / lon to 1e-7 degree, altitudes to 1 cm); and the mock answers the log protocol as ArduCopter does,
field by field (sizes and times aside). The measured download (log size, seconds, on loopback) is
printed (`pytest -s`) for docs/flight-faults.md.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, MissionType, to_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.transfer.onboard_log import LOG_DATA_LEN, recover_photos
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.testing.arducopter import ArduCopter, reboot_and_wait, sitl_or_skip

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

SYSID = 5
HOME = (45.4643, 9.1895, 120.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
FLIGHT_TIMEOUT_S = 150.0
READY_TIMEOUT_S = 120.0
PAST_THE_END = 1 << 30  # a byte offset beyond any log here (the listed size is not the end: the log grows)


def _mission() -> Mission:
    north = HOME[0] + 30.0 / M_PER_DEG_LAT
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=10.0),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=2.0),
             MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=north, y=HOME[1],
                         z=10.0),
             MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=10.0),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0),
             MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)]
    return Mission(items, home=HOME)


class _Tee:
    """A link whose every packet from the vehicle is also kept (the log client drops what it does not
    read; the flight's CAMERA_FEEDBACK must not be lost to it)."""

    def __init__(self, link: Any, sysid: int) -> None:
        self.link, self.sysid = link, sysid
        self.kept: list[Any] = []

    @property
    def mav(self) -> Any:
        return self.link.mav

    def recv(self, deadline: float) -> Any | None:
        msg = self.link.recv(deadline)
        if msg is not None and msg.get_srcSystem() == self.sysid:
            self.kept.append(msg)
        return msg

    def signing_hint(self, sysid: int) -> str:
        return self.link.signing_hint(sysid)

    def collect(self, seconds: float) -> list[Any]:
        """What the vehicle sends in the next `seconds` (bounded)."""
        start = len(self.kept)
        until = time.monotonic() + seconds
        while self.recv(until) is not None:
            pass
        return self.kept[start:]


def _raw_list(tee: _Tee, sysid: int, seconds: float = 1.5) -> dict[str, Any]:
    """LOG_REQUEST_LIST and what comes back within `seconds`: the LOG_ENTRY rows and any STATUSTEXT."""
    tee.mav.log_request_list_send(sysid, AUTOPILOT_COMPONENT_ID, 0, 0xFFFF)
    got = tee.collect(seconds)
    entries = [(int(m.id), int(m.num_logs), int(m.last_log_num)) for m in got if m.get_type() == "LOG_ENTRY"]
    sizes = [int(m.size) for m in got if m.get_type() == "LOG_ENTRY"]
    times = [int(m.time_utc) for m in got if m.get_type() == "LOG_ENTRY"]
    texts = [(int(m.severity), str(m.text)) for m in got
             if m.get_type() == "STATUSTEXT" and "log" in str(m.text).lower()]
    return {"entries": entries, "sizes": sizes, "times": times, "texts": texts}


def _raw_data(tee: _Tee, sysid: int, log_id: int, ofs: int, count: int,
              seconds: float = 1.0) -> list[tuple[int, int, int]]:
    """LOG_REQUEST_DATA and the (id, ofs, count) of every LOG_DATA within `seconds`; the padding of a
    short chunk must be zeros (checked here)."""
    tee.mav.log_request_data_send(sysid, AUTOPILOT_COMPONENT_ID, log_id, ofs, count)
    rows = []
    for m in tee.collect(seconds):
        if m.get_type() == "LOG_DATA":
            assert not any(m.data[int(m.count):]), "a short LOG_DATA chunk is padded with zeros"
            rows.append((int(m.id), int(m.ofs), int(m.count)))
    return rows


def _formats(path: Path) -> dict[str, tuple[int, int, str, str]]:
    """The log's FMT of MSG, CAM and TRIG: (type, length, format, columns), as DFReader reads them."""
    from pymavlink import DFReader

    reader = DFReader.DFReader_binary(str(path), zero_time_base=True)
    try:
        return {f.name: (f.type, f.len, f.format, ",".join(f.columns)) for f in reader.formats.values()
                if f.name in ("MSG", "CAM", "TRIG")}
    finally:
        reader.close()


def _arm_until_accepted(link: Any, sysid: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        link.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
        armed = link.command_long(sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], deadline)
        if armed == mavlink.MAV_RESULT_ACCEPTED:
            return
        retry_at = min(deadline, time.monotonic() + 1.0)  # not ready yet: listen, then ask again
        while link.recv(retry_at) is not None:
            pass
    raise AssertionError(f"vehicle {sysid} did not arm within {timeout:g} s")


def _disarm(link: Any, sysid: int) -> None:
    result = link.command_long(sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0.0], time.monotonic() + 5.0)
    assert result == mavlink.MAV_RESULT_ACCEPTED


def _armed(msg: Any) -> bool:
    return bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def _armed_flags(packets: list[Any]) -> list[bool]:
    """The armed flag of each autopilot HEARTBEAT among `packets`, oldest first."""
    return [_armed(m) for m in packets
            if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == AUTOPILOT_COMPONENT_ID]


def _landed(flags: list[bool]) -> bool:
    """Whether these armed flags, oldest first, say armed and then disarmed."""
    return True in flags and False in flags[flags.index(True):]


def session(url: str, sysid: int, configure_camera: Callable[[Any, Any], None], keep: Path) -> dict[str, Any]:
    """The session of the module doc on one vehicle; a record of what it answered. The downloaded log
    is kept in `keep`."""
    rec: dict[str, Any] = {}
    with PymavlinkBackend(url, sysid, timeouts=Timeouts(), connect_timeout=30) as backend:
        link = backend.link
        tee = _Tee(link, sysid)
        rec["fresh"] = _raw_list(tee, sysid)
        configure_camera(link, backend.vehicle)
        _arm_until_accepted(link, sysid, READY_TIMEOUT_S)
        _disarm(link, sysid)
        rec["after one arming"] = _raw_list(tee, sysid)
        backend.upload(MissionType.MISSION, to_wire(_mission(), Flavour.ARDUPILOT))
        armed_from = len(tee.kept)
        _arm_until_accepted(link, sysid, 30.0)
        start = link.command_long(sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], time.monotonic() + 5.0)
        assert start == mavlink.MAV_RESULT_ACCEPTED
        rec["armed"] = _raw_list(tee, sysid)
        rec["armed again"] = _raw_list(tee, sysid)  # ArduPilot warns once per arming
        # Landed: a disarmed HEARTBEAT after an armed one of this flight. Under load the link runs seconds behind,
        # so the last few packets read may still be heartbeats from before the arming.
        deadline = time.monotonic() + FLIGHT_TIMEOUT_S
        while not _landed(_armed_flags(tee.kept[armed_from:])):
            assert time.monotonic() < deadline, "the vehicle did not land and disarm in time"
            tee.collect(0.5)
        landed_at = time.time()
        feedback = {int(m.img_idx): m for m in tee.kept if m.get_type() == "CAMERA_FEEDBACK"}
        rec["feedback"] = feedback
        # What the flight sent, for a failure's message: packets by type, and the armed flag of each heartbeat.
        flown = tee.kept[armed_from:]
        rec["flight packets"] = dict(Counter(m.get_type() for m in flown))
        rec["flight armed"] = "".join("A" if armed else "d" for armed in _armed_flags(flown))
        rec["landed"] = _raw_list(tee, sysid)
        newest = max(e[0] for e in rec["landed"]["entries"])
        started = time.monotonic()
        rec["photos"] = recover_photos(tee, sysid, "ardupilot", time.monotonic() + 60.0, since_utc=landed_at - 600,
                                       save_dir=keep)
        rec["download_s"] = time.monotonic() - started
        rec["log_size"] = rec["landed"]["sizes"][-1]
        rec["short request"] = _raw_data(tee, sysid, newest, 0, 2 * LOG_DATA_LEN + 20)
        rec["past the end"] = _raw_data(tee, sysid, newest, PAST_THE_END, LOG_DATA_LEN)
        rec["no such log"] = _raw_data(tee, sysid, newest + 7, 0, LOG_DATA_LEN)
        tee.mav.log_request_end_send(sysid, AUTOPILOT_COMPONENT_ID)
        rec["landed_at"] = landed_at
        rec["formats"] = _formats(keep / f"log{newest}.BIN")
        for label in ("after a download, armed again", "armed once more"):
            _arm_until_accepted(link, sysid, 30.0)
            _disarm(link, sysid)
            rec[label] = _raw_list(tee, sysid)
    return rec


@pytest.fixture(scope="module")
def arducopter_session(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    sitl_or_skip()

    def configure(link: Any, vehicle: Any) -> None:  # what a team does once: CAM1_TYPE = 1, reboot
        assert ParamClient(link, vehicle).set("CAM1_TYPE", 1.0) == 1.0
        reboot_and_wait(link, SYSID)

    with ArduCopter(sysid=SYSID, home=(*HOME, 0.0)) as vehicle:
        rec = session(vehicle.url, SYSID, configure, tmp_path_factory.mktemp("arducopter-log"))
        rec["log files"] = sorted(p.name for p in (Path(vehicle.workdir) / "logs").glob("*.BIN"))
        yield rec


def test_after_landing_the_logged_photos_equal_the_camera_feedback(arducopter_session: dict[str, Any]) -> None:
    rec = arducopter_session
    feedback, photos = rec["feedback"], rec["photos"]
    print(f"\nArduCopter SITL ({sitl_or_skip().parent.name}): log of {rec['log_size']} bytes, {len(photos)} photos, "
          f"downloaded and read in {rec['download_s']:.2f} s on loopback; logs {rec['log files']}")
    assert len(feedback) >= 15, (rec["flight packets"], rec["flight armed"])  # a photo every 2 m over 60 m
    assert [p.img_idx for p in photos] == sorted(feedback) == list(range(1, len(feedback) + 1))
    for p in photos:
        m = feedback[p.img_idx]
        assert abs(p.lat_e7 - int(m.lat)) <= 1 and abs(p.lon_e7 - int(m.lng)) <= 1, (p, m)
        assert p.alt_amsl == pytest.approx(float(m.alt_msl), abs=0.01)
        assert p.alt_rel == pytest.approx(float(m.alt_rel), abs=0.01)
        assert abs((p.yaw - float(m.yaw) + 180.0) % 360.0 - 180.0) <= 0.02, (p.yaw, m.yaw)  # centidegrees, 0..360
    # CAM's GPSTime is the time of the GPS's latest fix (5 Hz here), CAMERA_FEEDBACK's time_usec the same
    # clock carried on to the photo: the log's UTC is at most one GPS period early.
    late = [int(feedback[p.img_idx].time_usec) / 1e6 - p.utc_s for p in photos if p.utc_s is not None]
    print(f"CAMERA_FEEDBACK time_usec - CAM GPS time: {min(late):.3f} .. {max(late):.3f} s")
    assert len(late) == len(photos) and all(0.0 <= d <= 0.25 for d in late), late
    assert all(p.log_id == max(e[0] for e in rec["landed"]["entries"]) for p in photos)


def _protocol(rec: dict[str, Any]) -> dict[str, Any]:
    """What must be equal between ArduCopter and the mock: the answers, not sizes or times."""
    keys = ("fresh", "after one arming", "armed", "armed again", "landed", "after a download, armed again",
            "armed once more")
    out: dict[str, Any] = {k: (rec[k]["entries"], rec[k]["texts"]) for k in keys}
    out["short request"] = rec["short request"]
    out["past the end"] = rec["past the end"]
    out["no such log"] = rec["no such log"]
    out["photo messages"] = sorted({p.message for p in rec["photos"]})
    out["CAM format"] = rec["formats"].get("CAM")
    return out


@pytest.mark.flight
def test_the_mock_answers_the_log_protocol_as_arducopter_does(arducopter_session: dict[str, Any],
                                                             tmp_path: Path) -> None:
    real = arducopter_session

    with MockAutopilot("udpin:127.0.0.1:0", sysids=[SYSID], flavour="ardupilot", homes={SYSID: HOME},
                       sitl_like=True, speedup=10.0) as mock:
        mocked = session(mock.client_url, SYSID, lambda link, vehicle: mock.configure_camera(SYSID), tmp_path)
    want, got = _protocol(real), _protocol(mocked)
    drift = [f"{k}: ArduCopter {want[k]!r}, mock {got[k]!r}" for k in want if want[k] != got[k]]
    assert drift == [], "the mock's log transfer drifted from ArduCopter:\n" + "\n".join(drift)
    # Sizes and times: a log that grows with the flight, dated by the vehicle's clock (UTC).
    for rec in (real, mocked):
        assert rec["landed"]["sizes"][-1] > 0 and abs(rec["landed"]["times"][-1] - rec["landed_at"]) < 120
    assert len(mocked["photos"]) == len(mocked["feedback"])
