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

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .mission import Flavour

HEAD = b"\xa3\x95"
FMT_TYPE = 128
LOG_DATA_LEN = 90  # MAVLINK_MSG_LOG_DATA_FIELD_DATA_LEN
# SITL sends up to 40 LOG_DATA per call of its log sender ("assume USB speeds in SITL").
LOG_CHUNKS_PER_TICK = 40
MAV_SEVERITY_ERROR = 3
DISARM_TEXT = "Disarm for log download"
GPS_EPOCH_UNIX = 315_964_800  # 1980-01-06 00:00:00 UTC
GPS_LEAP_SECONDS = 18  # GPS time runs ahead of UTC by this much (since 2017)

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


# The types the mock writes, with ArduPilot's numbers and formats (LogStructure.h): FMT itself,
# MSG (text, e.g. the firmware version at the start of a log) and CAM.
FMT = LogFormat(FMT_TYPE, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
MSG = LogFormat(91, "MSG", "QZ", "TimeUS,Message")
CAM = LogFormat(72, "CAM", "QBHIHLLeeeccC", "TimeUS,I,Img,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,R,P,Y")


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


@dataclass
class _Log:
    writer: DataFlashWriter
    mtime: int  # UTC seconds of the last write (the file's mtime, which ArduPilot reports as time_utc)


@dataclass
class _Transfer:
    log_id: int
    offset: int
    remaining: int
    peer: tuple[int, int]


@dataclass
class OnboardLogs:
    """One vehicle's logs and its side of the log protocol. `mav` is the vehicle's pymavlink encoder;
    `say` sends a STATUSTEXT (text, severity); `wall` is the vehicle's UTC clock (its GPS time)."""

    flavour: Flavour
    mav: Any
    say: Callable[[str, int], None]
    wall: Callable[[], float] = time.time
    logs: list[_Log] = field(default_factory=list)
    open_log: _Log | None = None
    transfer: _Transfer | None = None
    listing: list[int] = field(default_factory=list)  # ids still to send in a LOG_ENTRY
    _last_listed: int = 0  # the listing's last id: every LOG_ENTRY of it says so (last_log_num)
    _warned_armed: bool = False
    photos_logged: int = 0

    @property
    def keeps_logs(self) -> bool:
        return self.flavour is Flavour.ARDUPILOT

    # -- writing
    def on_boot(self) -> None:
        """A (re)boot closes the open log; the logs themselves stay."""
        self.open_log = None
        self.transfer = None
        self.listing = []

    def on_armed(self, version: str, time_us: int) -> None:
        """The vehicle is armed: ArduPilot opens a new log unless one is open (LOG_DISARMED 0: it
        logs only while armed), starting with its firmware version."""
        if not self.keeps_logs or self.open_log is not None:
            return
        self.open_log = _Log(DataFlashWriter(), int(self.wall()))
        self.logs.append(self.open_log)
        self.open_log.writer.write(MSG, time_us, version.encode())

    def log_photo(self, img_idx: int, lat_e7: int, lon_e7: int, alt_amsl_m: float, alt_rel_m: float,
                  roll_deg: float, pitch_deg: float, yaw_deg: float, time_us: int) -> None:
        """One CAM message, as AP_Camera writes it at the trigger (no feedback pin): where the vehicle
        was (centimetre altitudes, centidegree attitude), its time since boot and the GPS time."""
        log = self.open_log
        if log is None:
            return
        week, week_ms = gps_week_ms(self.wall())
        alt_cm = int(round(alt_amsl_m * 100))
        log.writer.write(CAM, time_us, 0, img_idx % 65536, week_ms, week, lat_e7, lon_e7, alt_cm,
                         int(round(alt_rel_m * 100)), alt_cm, int(round(roll_deg * 100)),
                         int(round(pitch_deg * 100)), int(round(yaw_deg * 100)) % 36000)
        log.mtime = int(self.wall())
        self.photos_logged += 1

    # -- the log protocol
    def handle(self, msg: Any, peer: tuple[int, int], armed: bool) -> None:
        kind = msg.get_type()
        if armed and self.flavour is Flavour.ARDUPILOT:
            if not self._warned_armed:  # ArduPilot says it once per arming and answers nothing
                self._warned_armed = True
                self.say(DISARM_TEXT, MAV_SEVERITY_ERROR)
            return
        self._warned_armed = False
        if kind == "LOG_REQUEST_LIST":
            self._on_list(int(msg.start), int(msg.end), peer)
        elif kind == "LOG_REQUEST_DATA":
            self._on_data(int(msg.id), int(msg.ofs), int(msg.count), peer)
        elif kind == "LOG_REQUEST_END":
            self.transfer = None
            self.listing = []

    def _on_list(self, start: int, end: int, peer: tuple[int, int]) -> None:
        if self.transfer is not None:
            return  # ArduPilot: "Log download in progress" to another channel; ours is the one
        count = len(self.logs)
        if count == 0:
            self.listing, self._last_listed = [0], 0
        else:
            self._last_listed = min(end, count)
            self.listing = list(range(max(start, 1), self._last_listed + 1))

    def _on_data(self, log_id: int, ofs: int, count: int, peer: tuple[int, int]) -> None:
        if self.transfer is not None:
            return  # a request while sending is dropped (MAVProxy streams them while filling gaps)
        if not 1 <= log_id <= len(self.logs):
            return  # a log that does not exist: the transfer is cancelled, nothing is said
        self.open_log = None  # get_log_data's first read stops logging: the next arming opens a new log
        size = len(self.logs[log_id - 1].writer.data)
        self.transfer = _Transfer(log_id, ofs, min(max(size - ofs, 0), count), peer)

    def tick(self) -> None:
        """Send what the protocol owes: LOG_ENTRY rows, then LOG_DATA chunks."""
        if self.listing:
            log_id = self.listing.pop(0)
            count = len(self.logs)
            if log_id == 0:
                self.mav.log_entry_send(0, 0, 0, 0, 0)
            else:
                log = self.logs[log_id - 1]
                size = len(log.writer.data)
                mtime = int(self.wall()) if log is self.open_log else log.mtime  # the open one: now
                self.mav.log_entry_send(log_id, count, self._last_listed, mtime, size)
            return
        for _ in range(LOG_CHUNKS_PER_TICK):
            t = self.transfer
            if t is None:
                return
            data = self.logs[t.log_id - 1].writer.data
            chunk = bytes(data[t.offset:t.offset + min(t.remaining, LOG_DATA_LEN)])
            self.mav.log_data_send(t.log_id, t.offset, len(chunk), chunk.ljust(LOG_DATA_LEN, b"\0"))
            t.offset += len(chunk)
            t.remaining -= len(chunk)
            if len(chunk) < LOG_DATA_LEN or t.remaining == 0:
                self.transfer = None
