"""The mock autopilot's onboard log: an ArduPilot DataFlash log of its flights, served over MAVLink.

Owns, for one mock vehicle:
- DataFlashWriter: the bytes of a DataFlash (.BIN) log as ArduPilot writes them: every message is
  0xA3 0x95 TYPE then its fields packed little-endian; a FMT message (type 128) describes each type
  before its first use. The CAM format is ArduPilot's (AP_Camera's LogStructure.h:
  "QBHIHLLeeeccC", TimeUS,I,Img,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,R,P,Y; Lat / Lng in 1e-7
  degrees, altitudes in cm, R / P in centidegrees, Y in centidegrees 0..36000), so pymavlink's
  DFReader reads it as it reads a real log;
- OnboardLogs: the vehicle's log store and its side of MAVLink's log transfer, as ArduCopter SITL does
  it (AP_Logger_MAVLinkLogTransfer.cpp; sitl_tests/test_photo_recovery_sitl.py compares the two):
  a new log when the vehicle arms and none is open, one CAM per photo, the open log closed by a
  reboot and by the first read of a download (ArduPilot's get_log_data stops logging), ids 1..N oldest
  first; LOG_REQUEST_LIST answered with one LOG_ENTRY per log (one with id 0 and num_logs 0 when
  there is none), LOG_REQUEST_DATA with LOG_DATA chunks of 90 bytes (the last one shorter, zero
  padded, or count 0 at the end), at most LOG_CHUNKS_PER_TICK per loop tick, a request for a log that
  does not exist cancelling the transfer unanswered, a request while a transfer runs dropped; and
  nothing while armed but one STATUSTEXT "Disarm for log download" per arming.
  The PX4 flavour keeps no log: PX4 SIH as the tests run it has its logger off (SDLOG_MODE -1), and
  its log handler then lists none (one LOG_ENTRY with id 0, num_logs 0).

Logs survive a reboot (they are on the vehicle's SD card); everything runs on the mock's loop thread.
"""

from __future__ import annotations

import math
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..link.connection import mavlink
from ..formats.mission_items import Flavour

HEAD = b"\xa3\x95"
FMT_TYPE = 128  # DataFlash's own numbering, not MAVLink's
LOG_DATA_LEN = 90  # MAVLINK_MSG_LOG_DATA_FIELD_DATA_LEN of the C headers: pymavlink has no constant for it
# SITL sends up to 40 LOG_DATA per call of its log sender ("assume USB speeds in SITL").
LOG_CHUNKS_PER_TICK = 40
DISARM_TEXT = "Disarm for log download"
GPS_EPOCH_UNIX = 315_964_800  # 1980-01-06 00:00:00 UTC
GPS_LEAP_SECONDS = 18  # GPS time runs ahead of UTC by this much (since 2017)
ULOG_MAGIC = b"ULog\x01\x12\x35"
ULOG_TOPIC = "camera_capture"
ULOG_CAPTURE_ID = 0
# PX4 v1.15.4's camera_capture, as its ULog defines it (read from a SIH log).
ULOG_CAPTURE_FORMAT = ("uint64_t timestamp;uint64_t timestamp_utc;double lat;double lon;uint32_t seq;float alt;"
                       "float ground_distance;float[4] q;int8_t result;uint8_t[3] _padding0;")

# DataFlash field codes -> struct codes (pymavlink DFReader.FORMAT_TO_STRUCT, the ones used here).
_STRUCT = {"B": "B", "H": "H", "I": "I", "Q": "Q", "L": "i", "e": "i", "c": "h", "C": "H", "n": "4s",
           "N": "16s", "Z": "64s", "b": "b", "h": "h", "i": "i", "f": "f", "d": "d", "q": "q", "M": "B"}


@dataclass(frozen=True)
class LogFormat:
    """One DataFlash message type: its number, name, field codes and column names."""

    type: int
    name: str
    format: str
    columns: str

    @property
    def struct(self) -> struct.Struct:
        return struct.Struct("<" + "".join(_STRUCT[c] for c in self.format))

    @property
    def length(self) -> int:
        return 3 + self.struct.size  # header and type byte included, as FMT's Length says


# The types the mock writes, with the numbers and formats of ArduCopter 4.7-dev SITL's log: FMT itself
# (the log's first message, describing itself), MSG (text: the firmware version at the start of a
# log) and CAM (a real log holds some 190 types; a reader finds these by name).
FMT = LogFormat(FMT_TYPE, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
MSG = LogFormat(59, "MSG", "QZ", "TimeUS,Message")
CAM = LogFormat(81, "CAM", "QBHIHLLeeeccC", "TimeUS,I,Img,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,R,P,Y")


class DataFlashWriter:
    """Appends DataFlash messages to a bytearray, each type's FMT before its first message."""

    def __init__(self) -> None:
        self.data = bytearray()
        self._described: set[int] = set()
        self.describe(FMT)

    def describe(self, fmt: LogFormat) -> None:
        if fmt.type in self._described:
            return
        self._described.add(fmt.type)
        self.data += HEAD + bytes([FMT_TYPE]) + FMT.struct.pack(
            fmt.type, fmt.length, fmt.name.encode(), fmt.format.encode(), fmt.columns.encode())

    def write(self, fmt: LogFormat, *values: Any) -> None:
        self.describe(fmt)
        self.data += HEAD + bytes([fmt.type]) + fmt.struct.pack(*values)


def gps_week_ms(unix_s: float) -> tuple[int, int]:
    """(GPS week, milliseconds into it) of a UTC time in seconds since 1970, as ArduPilot logs them."""
    gps_ms = int(round((unix_s - GPS_EPOCH_UNIX + GPS_LEAP_SECONDS) * 1000))
    return gps_ms // 604_800_000, gps_ms % 604_800_000


class UlogWriter:
    """The bytes of a PX4 ULog holding camera_capture messages, as PX4 v1.15.4 writes them: the header
    (magic, version 1, start time), the flag bits, the topic's format (v1.15.4's camera_capture), its
    subscription, then one data message per capture (trailing padding not logged, as PX4 does)."""

    def __init__(self, start_us: int) -> None:
        self.data = bytearray(ULOG_MAGIC + b"\x01" + struct.pack("<Q", start_us))
        self._message("B", bytes(40))  # no compatible / incompatible flags, no appended data
        self._message("F", f"{ULOG_TOPIC}:{ULOG_CAPTURE_FORMAT}".encode())
        self._message("A", struct.pack("<BH", 0, ULOG_CAPTURE_ID) + ULOG_TOPIC.encode())

    def _message(self, kind: str, body: bytes) -> None:
        self.data += struct.pack("<HB", len(body), ord(kind)) + body

    def capture(self, time_us: int, utc_us: int, lat: float, lon: float, seq: int, alt: float, ground_distance: float,
                q: tuple[float, float, float, float], result: int = 1) -> None:
        self._message("D", struct.pack("<HQQddIff4fb", ULOG_CAPTURE_ID, time_us, utc_us, lat, lon, seq, alt,
                                       ground_distance, *q, result))


@dataclass
class _Log:
    writer: DataFlashWriter | UlogWriter
    mtime: int  # UTC seconds of the last write (the file's mtime, which both autopilots report as time_utc)


@dataclass
class _Transfer:
    log_id: int
    offset: int
    remaining: int
    peer: tuple[int, int]


@dataclass
class OnboardLogs:
    """One vehicle's logs and its side of the log protocol. `mav` is the vehicle's pymavlink encoder;
    `say` sends a STATUSTEXT (text, severity); `wall` is the vehicle's UTC clock (its GPS time).
    `logging`: whether the vehicle logs at all (ArduPilot: yes; PX4: SDLOG_MODE >= 0, which the tests'
    PX4 SIH does not have; set it before the vehicle arms)."""

    flavour: Flavour
    mav: Any
    say: Callable[[str, int], None]
    wall: Callable[[], float] = time.time
    logging: bool | None = None
    logs: list[_Log] = field(default_factory=list)
    open_log: _Log | None = None
    transfer: _Transfer | None = None
    listing: list[int] = field(default_factory=list)  # ids still to send in a LOG_ENTRY
    _last_listed: int = 0  # the listing's last id: every LOG_ENTRY of it says so (last_log_num)
    _listed: bool = False  # PX4 serves data only after a listing (its LogListHelper), until LOG_REQUEST_END
    _warned_armed: bool = False
    photos_logged: int = 0

    def __post_init__(self) -> None:
        if self.logging is None:
            self.logging = self.flavour is Flavour.ARDUPILOT

    @property
    def px4(self) -> bool:
        return self.flavour is Flavour.PX4

    @property
    def first_id(self) -> int:
        return 0 if self.px4 else 1  # PX4 numbers its LOG_ENTRY rows from 0, ArduPilot from 1

    # -- writing
    def on_boot(self) -> None:
        """A (re)boot closes the open log; the logs themselves stay."""
        self.open_log = None
        self.transfer = None
        self.listing = []
        self._listed = False

    def on_armed(self, version: str, time_us: int) -> None:
        """The vehicle is armed: ArduPilot opens a new log unless one is open (LOG_DISARMED 0: it
        logs only while armed), starting with its firmware version; PX4 (SDLOG_MODE 0: from arming to
        disarming) a new one at every arming."""
        if not self.logging or (self.open_log is not None and not self.px4):
            return
        writer: DataFlashWriter | UlogWriter
        if self.px4:
            writer = UlogWriter(time_us)
            # PX4's logger names the file it opens (INFO, with a tab at the end), dated by UTC
            self.say(time.strftime("[logger] ./log/%Y-%m-%d/%H_%M_%S.ulg\t", time.gmtime(self.wall())),
                     mavlink.MAV_SEVERITY_INFO)
        else:
            writer = DataFlashWriter()
            writer.write(MSG, time_us, version.encode())
        self.open_log = _Log(writer, int(self.wall()))
        self.logs.append(self.open_log)

    def log_photo(self, img_idx: int, lat: float, lon: float, alt_amsl_m: float, alt_rel_m: float,
                  roll_deg: float, pitch_deg: float, yaw_deg: float, time_us: int) -> None:
        """One photo in the open log. ArduPilot: a CAM message, as AP_Camera writes it at the trigger (no
        feedback pin): where the vehicle was (centimetre altitudes, centidegree attitude), its time since
        boot and the GPS time; positions in 1e-7 degrees, rounded as CAMERA_FEEDBACK's. PX4: a
        camera_capture message (degrees as doubles, metres, the attitude as a quaternion, UTC in
        microseconds, result 1)."""
        log = self.open_log
        if log is None:
            return
        if isinstance(log.writer, UlogWriter):
            half = math.radians(yaw_deg) / 2  # level flight: the yaw alone (roll, pitch 0 in the mock)
            log.writer.capture(time_us, int(self.wall() * 1e6), lat, lon, img_idx, alt_amsl_m,
                               alt_rel_m, (math.cos(half), 0.0, 0.0, math.sin(half)))
        else:
            week, week_ms = gps_week_ms(self.wall())
            alt_cm = int(round(alt_amsl_m * 100))
            log.writer.write(CAM, time_us, 0, img_idx % 65536, week_ms, week, int(round(lat * 1e7)),
                             int(round(lon * 1e7)), alt_cm,
                             int(round(alt_rel_m * 100)), alt_cm, int(round(roll_deg * 100)),
                             int(round(pitch_deg * 100)), int(round(yaw_deg * 100)) % 36000)
        log.mtime = int(self.wall())
        self.photos_logged += 1

    # -- the log protocol
    def handle(self, msg: Any, peer: tuple[int, int], armed: bool) -> None:
        kind = msg.get_type()
        if armed and not self.px4:
            if not self._warned_armed:  # ArduPilot says it once per arming and answers nothing
                self._warned_armed = True
                self.say(DISARM_TEXT, mavlink.MAV_SEVERITY_ERROR)
            return
        self._warned_armed = False
        if kind == "LOG_REQUEST_LIST":
            self._on_list(int(msg.start), int(msg.end), peer)
        elif kind == "LOG_REQUEST_DATA":
            self._on_data(int(msg.id), int(msg.ofs), int(msg.count), peer)
        elif kind == "LOG_REQUEST_END":
            self.transfer = None
            self.listing = []
            self._listed = False

    def _on_list(self, start: int, end: int, peer: tuple[int, int]) -> None:
        if self.transfer is not None and not self.px4:
            return  # ArduPilot: "Log download in progress" to another channel; ours is the one
        self.transfer = None  # PX4: a listing stops the data being sent
        self._listed = True
        count = len(self.logs)
        if count == 0:
            self.listing, self._last_listed = [0], 0
        elif self.px4:  # both ends clamped to the last log (mavlink_log_handler.cpp)
            self._last_listed = min(end, count - 1)
            self.listing = list(range(min(start, count - 1), self._last_listed + 1))
        else:
            self._last_listed = min(end, count)
            self.listing = list(range(max(start, 1), self._last_listed + 1))

    def _on_data(self, log_id: int, ofs: int, count: int, peer: tuple[int, int]) -> None:
        if self.px4:
            if not self._listed or not 0 <= log_id < len(self.logs):
                return  # PX4 serves only a log of its listing; another request replaces the running one
        else:
            if self.transfer is not None:
                return  # a request while sending is dropped (MAVProxy streams them while filling gaps)
            if not 1 <= log_id <= len(self.logs):
                return  # a log that does not exist: the transfer is cancelled, nothing is said
            self.open_log = None  # get_log_data's first read stops logging: the next arming opens a new log
        size = len(self.logs[log_id - self.first_id].writer.data)
        self.listing = []
        self.transfer = _Transfer(log_id, ofs, min(max(size - ofs, 0), count), peer)

    def tick(self) -> None:
        """Send what the protocol owes: LOG_ENTRY rows, then LOG_DATA chunks."""
        if self.listing:
            log_id = self.listing.pop(0)
            count = len(self.logs)
            if count == 0:
                self.mav.log_entry_send(0, 0, 0, 0, 0)
            else:
                log = self.logs[log_id - self.first_id]
                mtime = int(self.wall()) if log is self.open_log and not self.px4 else log.mtime
                self.mav.log_entry_send(log_id, count, self._last_listed, mtime, len(log.writer.data))
            return
        for _ in range(LOG_CHUNKS_PER_TICK):
            t = self.transfer
            if t is None:
                return
            data = self.logs[t.log_id - self.first_id].writer.data
            chunk = bytes(data[t.offset:t.offset + min(t.remaining, LOG_DATA_LEN)])
            self.mav.log_data_send(t.log_id, t.offset, len(chunk), chunk.ljust(LOG_DATA_LEN, b"\0"))
            t.offset += len(chunk)
            t.remaining -= len(chunk)
            if len(chunk) < LOG_DATA_LEN or t.remaining == 0:
                self.transfer = None
