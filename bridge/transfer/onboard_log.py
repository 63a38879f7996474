"""Photos recovered from the vehicle's own log after a flight: MAVLink log transfer and the log reader.

A photo report lost on the link (CAMERA_FEEDBACK, CAMERA_IMAGE_CAPTURED) is gone: neither ArduPilot
nor PX4 sends one again, nor answers a request for it by index. What the vehicle keeps is its log.
This module owns:

- LogClient: the ground-station side of MAVLink's log transfer with one vehicle over a link.connection.Link
  or a link.shared_link.VehicleLink: LOG_REQUEST_LIST -> one LOG_ENTRY per log (re-asked for the
  entries that did not arrive), LOG_REQUEST_DATA -> LOG_DATA in 90-byte chunks (the missing chunks
  asked for again, a gap at a time, once the vehicle has gone quiet), LOG_REQUEST_END. Every wait is
  bounded by the caller's deadline; a vehicle that stops answering is a LogTransferError naming what
  it did not get;
- read_dataflash_photos: the CAM messages (TRIG when a camera with a feedback pin logged no CAM) of an
  ArduPilot DataFlash (.BIN) log, read with pymavlink's DFReader; read_ulog_photos: the camera_capture
  messages of a PX4 ULog;
- recover_photos: the one call: list, choose, download and read, for a vehicle on the ground.

What each autopilot supports (measured on ArduCopter SITL 4.7-dev and PX4 SIH v1.15.4:
docs/flight-faults.md): ArduPilot writes one CAM per photo (Img = CAMERA_FEEDBACK's img_idx, the
same AHRS position) into a log it opens when it arms, and serves logs only while DISARMED (armed, it
answers nothing but one STATUSTEXT "Disarm for log download"). PX4 keeps a ULog from arming to
disarming when its logger runs (SDLOG_MODE 0, its default), with one camera_capture per photo
(read_ulog_photos); it has no re-request of CAMERA_IMAGE_CAPTURED by index.
"""

from __future__ import annotations

import math
import os
import struct
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.base.atomic import atomic_path
from ..errors import BridgeError
from ..link.connection import AUTOPILOT_COMPONENT_ID, mavlink
from ..formats.mission_items import Flavour

ProgressFn = Callable[[int, int], None]  # (bytes received, bytes in all), over every log downloaded

LOG_DATA_LEN = 90  # bytes per LOG_DATA chunk (MAVLINK_MSG_LOG_DATA_FIELD_DATA_LEN)
LIST_WAIT_S = 1.0  # for the first LOG_ENTRY, per try: ArduPilot answers within milliseconds
LIST_TRIES = 4
QUIET_S = 0.5      # no LOG_DATA for this long: the vehicle has finished (or lost) what it was sending
MIN_QUIET_S = 0.05  # the shortest silence taken for that, however fast the chunks came
DATA_TRIES = 6     # requests in a row that bring nothing new before the download fails
COALESCE_CHUNKS = 16  # missing chunks this close together are asked for in one request
WINDOW_BYTES = 512 * LOG_DATA_LEN  # asked for at a time (46 KB: a burst a UDP socket's buffer holds)
DISARM_TEXT = "Disarm for log download"  # ArduPilot's answer, once per arming, to a log request while armed
GPS_EPOCH_UNIX = 315_964_800  # 1980-01-06 00:00:00 UTC
GPS_LEAP_SECONDS = 18  # GPS time runs ahead of UTC by this much (since 2017)
CLOCK_SLACK_S = 5.0  # the vehicle's UTC clock (GPS) against ours: a log or photo dated this much before
                     # the flight's start may still be of the flight


class LogTransferError(BridgeError):
    """The log transfer failed: the vehicle is armed, has no log, or stopped answering."""


@dataclass(frozen=True)
class LogEntry:
    """One LOG_ENTRY: a log the vehicle holds (ArduPilot: ids 1..N, oldest first; PX4: 0..N-1)."""

    id: int
    num_logs: int
    last_log_num: int
    time_utc: int  # seconds since 1970 of its last write (the file's mtime), 0 when unknown
    size: int      # bytes


@dataclass(frozen=True)
class LoggedPhoto:
    """One photo as the vehicle logged it. Angles in degrees, altitudes in metres; None where the log
    has no such field. lat_e7 / lon_e7 are the logged integers (1e-7 degree), which equal the
    CAMERA_FEEDBACK of the same photo."""

    img_idx: int
    lat_e7: int
    lon_e7: int
    alt_amsl: float | None
    alt_rel: float | None
    roll: float | None
    pitch: float | None
    yaw: float | None
    time_boot_s: float    # the vehicle's time since boot when it took the photo
    utc_s: float | None   # the same moment in UTC seconds since 1970, from the logged GPS time (None: no fix)
    log_id: int           # the LOG_ENTRY id of the log it came from
    message: str = "CAM"  # the log message it came from (CAM, or TRIG)

    @property
    def lat(self) -> float:
        return self.lat_e7 / 1e7

    @property
    def lon(self) -> float:
        return self.lon_e7 / 1e7


class LogClient:
    """Log listing and download with one vehicle over a Link or VehicleLink (one thread at a time)."""

    def __init__(self, link: Any, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID) -> None:
        self.link = link
        self.sysid = sysid
        self.compid = compid
        self.armed: bool | None = None  # from its latest HEARTBEAT
        self.said_disarm = False        # it answered "Disarm for log download"
        self.requests = 0               # LOG_REQUEST_DATA sent (the first one and the re-requests)
        # Smoothed seconds between two chunks of a burst, and from a request to its first chunk: a
        # silence of several of those means the burst is over (bounded by QUIET_S, 2 * QUIET_S).
        self._chunk_gap: float | None = None
        self._round_trip: float | None = None

    def _quiet(self) -> float:
        return QUIET_S if self._chunk_gap is None else min(QUIET_S, max(MIN_QUIET_S, 8.0 * self._chunk_gap))

    def _first_wait(self) -> float:
        return 2 * QUIET_S if self._round_trip is None else min(2 * QUIET_S, max(0.1, 4.0 * self._round_trip))

    # -- receiving
    def _recv(self, deadline: float) -> Any | None:
        """The vehicle's next packet (None at the deadline); notes its arming state and refusals."""
        while (msg := self.link.recv(deadline)) is not None:
            if msg.get_srcSystem() != self.sysid:
                continue
            kind = msg.get_type()
            if kind == "HEARTBEAT" and msg.get_srcComponent() == self.compid:
                self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            elif kind == "STATUSTEXT" and DISARM_TEXT in str(msg.text):
                self.said_disarm = True
            return msg
        return None

    def _why_silent(self, what: str) -> LogTransferError:
        if self.said_disarm or self.armed:
            return LogTransferError(f"vehicle {self.sysid} is armed: it sends its logs only when disarmed (after "
                                    "landing)" + (f'; it said "{DISARM_TEXT}"' if self.said_disarm else ""))
        hint = self.link.signing_hint(self.sysid) if hasattr(self.link, "signing_hint") else ""
        return LogTransferError(f"vehicle {self.sysid} did not answer {what}" + (f": {hint}" if hint else ""))

    # -- listing
    def list_logs(self, deadline: float) -> list[LogEntry]:
        """Every log the vehicle holds, in its own order (ArduPilot: oldest first). Empty when it has none."""
        mav = self.link.mav
        entries: dict[int, LogEntry] = {}
        expected: set[int] | None = None
        start, end = 0, 0xFFFF
        for _ in range(LIST_TRIES):
            mav.log_request_list_send(self.sysid, self.compid, start, end)
            wait_until = min(deadline, time.monotonic() + LIST_WAIT_S)
            while (msg := self._recv(wait_until)) is not None:
                if self.said_disarm:
                    raise self._why_silent("the log list")
                if msg.get_type() != "LOG_ENTRY":
                    continue
                if int(msg.num_logs) == 0:
                    return []
                entry = LogEntry(int(msg.id), int(msg.num_logs), int(msg.last_log_num), int(msg.time_utc),
                                 int(msg.size))
                entries[entry.id] = entry
                # The ids run up to last_log_num, num_logs of them (ArduPilot from 1, PX4 from 0).
                expected = set(range(entry.last_log_num - entry.num_logs + 1, entry.last_log_num + 1))
                if expected <= entries.keys():
                    return [entries[i] for i in sorted(expected)]
                wait_until = min(deadline, time.monotonic() + QUIET_S)  # more are coming
            if time.monotonic() >= deadline:
                break
            if expected is not None:  # ask again for the ones that did not arrive
                missing = expected - entries.keys()
                start, end = min(missing), max(missing)
        if expected is not None:
            missing = sorted(expected - entries.keys())
            raise LogTransferError(f"vehicle {self.sysid} listed {len(entries)} of its {len(expected)} logs; "
                                   f"entries {missing[:5]} never came")
        raise self._why_silent("LOG_REQUEST_LIST")

    # -- downloading
    def download(self, entry: LogEntry, deadline: float, progress: ProgressFn | None = None,
                 done_before: int = 0, total: int | None = None) -> bytes:
        """The bytes of one log (read_range over all of it). progress(done_before + bytes so far, total)."""
        return self.read_range(entry, 0, entry.size, deadline, progress, done_before, total)

    def read_range(self, entry: LogEntry, start: int, stop: int, deadline: float, progress: ProgressFn | None = None,
                   done_before: int = 0, total: int | None = None) -> bytes:
        """Bytes [start, stop) of a log (fewer when the log ends first: a chunk shorter than 90 bytes
        ends it). Asked for WINDOW_BYTES at a time: a whole log in one request comes faster than a
        ground station on UDP reads it (PX4 SIH lost most of a 14 MB log that way; its socket buffer
        overflowed), and one window fits. Within a window the chunks lost on the link are asked for
        again (a gap at a time, close gaps together) once the vehicle has gone quiet: ArduPilot drops a
        request that comes while it is still sending, PX4 replaces the running one."""
        fetch = _Fetch(entry, start, min(stop, entry.size), progress, done_before,
                       entry.size if total is None else total)
        pos = start
        while pos < fetch.end:
            window = (pos, min(pos + WINDOW_BYTES, fetch.end))
            self._fetch_window(fetch, window, deadline)
            pos = window[1]
        return bytes(fetch.data[:max(fetch.end - start, 0)])

    def _fetch_window(self, fetch: _Fetch, window: tuple[int, int], deadline: float) -> None:
        entry = fetch.entry
        fruitless = 0
        while True:
            missing = fetch.missing(window)
            if not missing:
                return
            if fruitless >= DATA_TRIES or time.monotonic() >= deadline:
                if fetch.got == 0:
                    raise self._why_silent(f"LOG_REQUEST_DATA for log {entry.id}")
                raise LogTransferError(f"vehicle {self.sysid}: log {entry.id} incomplete, {fetch.got} of "
                                       f"{fetch.end - fetch.start} bytes after {self.requests} requests (nothing "
                                       f"more came from byte {missing[0]})")
            first = last = missing[0]
            for ofs in missing[1:]:  # the first gap, with the gaps close after it
                if ofs - last > COALESCE_CHUNKS * LOG_DATA_LEN:
                    break
                last = ofs
            want = (first, min(last + LOG_DATA_LEN, fetch.end))
            self.link.mav.log_request_data_send(self.sysid, self.compid, entry.id, want[0], want[1] - want[0])
            self.requests += 1
            before = fetch.got
            sent_at = last_at = time.monotonic()
            first_chunk = True
            quiet_until = min(deadline, sent_at + self._first_wait())  # the first chunk takes a round trip
            while (msg := self._recv(quiet_until)) is not None:
                if self.said_disarm:
                    raise self._why_silent(f"LOG_REQUEST_DATA for log {entry.id}")
                if msg.get_type() != "LOG_DATA" or int(msg.id) != entry.id:
                    continue
                now = time.monotonic()
                if first_chunk:
                    self._round_trip = _smooth(self._round_trip, now - sent_at)
                else:
                    self._chunk_gap = _smooth(self._chunk_gap, now - last_at)
                first_chunk, last_at = False, now
                quiet_until = min(deadline, now + self._quiet())
                ofs, count = int(msg.ofs), int(msg.count)
                fetch.take(ofs, count, bytes(msg.data))
                if ofs + max(count, 1) >= min(want[1], fetch.end):
                    break  # the last chunk of this request: no need to wait for silence
            fruitless = 0 if fetch.got > before else fruitless + 1

    def end(self) -> None:
        """LOG_REQUEST_END: ArduPilot resumes normal logging, PX4 forgets the listing."""
        self.link.mav.log_request_end_send(self.sysid, self.compid)


class _Fetch:
    """The bytes of one range of a log as they arrive, chunk by chunk (a chunk: 90 bytes from `start`)."""

    def __init__(self, entry: LogEntry, start: int, stop: int, progress: ProgressFn | None, done_before: int,
                 total: int) -> None:
        self.entry, self.start, self.end = entry, start, stop
        self.data = bytearray(max(stop - start, 0))
        self.have = bytearray(math.ceil(max(stop - start, 0) / LOG_DATA_LEN))
        self.got = 0
        self.progress, self.done_before, self.total = progress, done_before, total

    def missing(self, window: tuple[int, int]) -> list[int]:
        """The offsets of the chunks of `window` not received yet (the log's end may have moved in)."""
        stop = min(window[1], self.end)
        return [ofs for ofs in range(window[0], stop, LOG_DATA_LEN)
                if not self.have[(ofs - self.start) // LOG_DATA_LEN]]

    def take(self, ofs: int, count: int, data: bytes) -> None:
        if count < LOG_DATA_LEN:
            self.end = min(self.end, ofs + count)  # the log ends here
        if ofs < self.start or (ofs - self.start) % LOG_DATA_LEN or ofs >= self.end:
            return  # not a chunk of ours (an answer to an earlier request of another range)
        k = (ofs - self.start) // LOG_DATA_LEN
        count = min(count, self.end - ofs)
        if count and not self.have[k]:
            self.data[ofs - self.start:ofs - self.start + count] = data[:count]
            self.have[k] = 1
            self.got += count
            if self.progress is not None:
                self.progress(self.done_before + self.got, self.total)


def _smooth(average: float | None, sample: float) -> float:
    return sample if average is None else 0.875 * average + 0.125 * sample


# ---------------------------------------------------------------------------------- reading logs
def _gps_to_utc(week: int, week_ms: int) -> float | None:
    if week <= 0:
        return None
    return GPS_EPOCH_UNIX + week * 604_800 + week_ms / 1000.0 - GPS_LEAP_SECONDS


def read_dataflash_photos(path: str | os.PathLike[str], log_id: int = 0) -> list[LoggedPhoto]:
    """The photos of an ArduPilot DataFlash log: its CAM messages (one per photo), or its TRIG messages
    when it has no CAM (a camera with a feedback pin logs TRIG at the trigger, CAM at the feedback).
    Camera instance 0 only (the one CAMERA_FEEDBACK counts, with its own img_idx); the first message
    of each Img stands."""
    from pymavlink import DFReader

    if Path(path).stat().st_size == 0:
        return []
    reader = DFReader.DFReader_binary(str(path), zero_time_base=True)
    found: dict[str, dict[int, LoggedPhoto]] = {"CAM": {}, "TRIG": {}}
    try:
        while (m := reader.recv_match(type=["CAM", "TRIG"])) is not None:
            if int(getattr(m, "I", 0)) != 0:
                continue
            kind = m.get_type()
            img = int(m.Img)
            if img in found[kind]:
                continue
            found[kind][img] = LoggedPhoto(
                img_idx=img, lat_e7=int(round(m.Lat * 1e7)), lon_e7=int(round(m.Lng * 1e7)),
                alt_amsl=float(m.Alt), alt_rel=float(m.RelAlt), roll=float(m.R), pitch=float(m.P), yaw=float(m.Y),
                time_boot_s=int(m.TimeUS) / 1e6, utc_s=_gps_to_utc(int(m.GPSWeek), int(m.GPSTime)),
                log_id=log_id, message=kind)
    finally:
        reader.close()
    photos = found["CAM"] or found["TRIG"]
    return [photos[k] for k in sorted(photos)]


ULOG_MAGIC = b"ULog\x01\x12\x35"
ULOG_TYPES = {"int8_t": "b", "uint8_t": "B", "int16_t": "h", "uint16_t": "H", "int32_t": "i", "uint32_t": "I",
              "int64_t": "q", "uint64_t": "Q", "float": "f", "double": "d", "bool": "?", "char": "c"}
ULOG_TOPIC = "camera_capture"  # PX4's camera_feedback module: one per photo, what CAMERA_IMAGE_CAPTURED sends


def _ulog_fields(definition: str) -> list[tuple[str, str, int]]:
    """(type, name, count) of each field of a ULog format ("float[4] q;int8_t result;...")."""
    fields = []
    for field in filter(None, definition.split(";")):
        kind, _, name = field.strip().partition(" ")
        count = 1
        if kind.endswith("]"):
            kind, _, n = kind[:-1].partition("[")
            count = int(n)
        fields.append((kind, name, count))
    return fields


def _ulog_decode(formats: dict[str, list[tuple[str, str, int]]], name: str, buf: bytes,
                 at: int = 0) -> tuple[dict[str, Any], int]:
    """One message of format `name` from buf[at:] (nested formats too); fields cut off by the end of
    the buffer are left out (PX4 does not log a message's trailing padding)."""
    row: dict[str, Any] = {}
    for kind, field, count in formats[name]:
        values: list[Any] = []
        for _ in range(count):
            if kind in ULOG_TYPES:
                code = "<" + ULOG_TYPES[kind]
                if at + struct.calcsize(code) > len(buf):
                    return row, at
                values.append(struct.unpack_from(code, buf, at)[0])
                at += struct.calcsize(code)
            else:
                value, at = _ulog_decode(formats, kind, buf, at)
                values.append(value)
        if not field.startswith("_padding"):
            row[field] = values[0] if count == 1 else values
    return row, at


def euler_degrees(q: list[float]) -> tuple[float, float, float] | None:
    """Roll, pitch, yaw (degrees, yaw 0..360) of a unit quaternion w, x, y, z (PX4's Hamilton order);
    None for a quaternion that is not one (all zeros: the sender had no attitude)."""
    if sum(v * v for v in q) < 0.5:
        return None
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw) % 360.0


def read_ulog_photos(data: bytes, log_id: int = 0) -> list[LoggedPhoto]:
    """The photos of a PX4 ULog: its camera_capture messages (instance 0) with result 1 (a capture
    that failed is not a photo), keyed by seq (CAMERA_IMAGE_CAPTURED's image_index). Latitude and
    longitude in 1e-7 degrees truncated, as PX4 truncates them for CAMERA_IMAGE_CAPTURED, so they
    equal its report; alt_rel is camera_capture's ground_distance (the report's relative_alt)."""
    if not data.startswith(ULOG_MAGIC):
        raise LogTransferError(f"log {log_id} is not a ULog (it starts {data[:8]!r})")
    formats: dict[str, list[tuple[str, str, int]]] = {}
    topic_ids: set[int] = set()
    photos: dict[int, LoggedPhoto] = {}
    pos = 16  # magic, version, start time
    while pos + 3 <= len(data):
        size, kind = struct.unpack_from("<HB", data, pos)
        body = data[pos + 3:pos + 3 + size]
        pos += 3 + size
        if len(body) < size:
            break  # the log was cut off mid-message
        if kind == ord("F"):
            name, _, definition = body.decode("ascii", "replace").partition(":")
            formats[name] = _ulog_fields(definition)
        elif kind == ord("A") and size > 3:
            multi_id, msg_id = struct.unpack_from("<BH", body)
            if body[3:].decode("ascii", "replace") == ULOG_TOPIC and multi_id == 0:
                topic_ids.add(msg_id)
        elif kind == ord("D") and size >= 2 and struct.unpack_from("<H", body)[0] in topic_ids:
            row, _ = _ulog_decode(formats, ULOG_TOPIC, body[2:])
            if row.get("result") != 1 or int(row["seq"]) in photos:
                continue
            roll, pitch, yaw = (euler_degrees(list(row["q"])) if "q" in row else None) or (None, None, None)
            photos[int(row["seq"])] = LoggedPhoto(
                img_idx=int(row["seq"]), lat_e7=int(row["lat"] * 1e7), lon_e7=int(row["lon"] * 1e7),
                alt_amsl=float(row["alt"]), alt_rel=float(row["ground_distance"]), roll=roll, pitch=pitch, yaw=yaw,
                time_boot_s=int(row["timestamp"]) / 1e6,
                utc_s=int(row["timestamp_utc"]) / 1e6 if row.get("timestamp_utc") else None,
                log_id=log_id, message=ULOG_TOPIC)
    return [photos[k] for k in sorted(photos)]


# ---------------------------------------------------------------------------------- the one call
def recover_photos(link: Any, sysid: int, flavour: Flavour | str, deadline: float, wanted: set[int] | None = None,
                   progress: ProgressFn | None = None, since_utc: float | None = None,
                   save_dir: str | os.PathLike[str] | None = None, compid: int = AUTOPILOT_COMPONENT_ID,
                   max_logs: int = 3) -> list[LoggedPhoto]:
    """The photos the vehicle logged, read from its onboard log after landing (it must be disarmed).

    link: a link.connection.Link or a link.shared_link.VehicleLink for system `sysid`; deadline:
    time.monotonic() by which to give up (LogTransferError). wanted: the img_idx values to find (the
    ones whose reports were lost); None: every photo of the newest log.

    Which logs: ArduPilot opens a log when it arms and ends it at a reboot or when a log is downloaded,
    so the flight just flown is in the newest log (several flights without a reboot or a download in
    between share one). Logs are read newest first (ArduPilot's highest id; by time_utc where the
    autopilot's ids are not in order), at most `max_logs`, and only those written since `since_utc`
    (the flight's start, UTC seconds; a log's time_utc is its last write, so an older one cannot hold
    the flight): with `wanted`, older logs are read only while some wanted index is still missing;
    the newest log's copy of an index stands (img_idx starts again at 1 after a reboot, so an older
    log's copy is another photo). Without `wanted`, the newest log only. With `since_utc`, photos
    whose logged GPS time is earlier (an earlier flight in the same log) are left out too.
    save_dir: keep each downloaded log there as log{ID}.BIN (atomically); else it lives in a temp
    file only while it is read. progress(bytes received, bytes of the logs listed for download).
    Raises LogTransferError (a BridgeError) in one line: armed, no log, not answering, incomplete."""
    flavour = Flavour(flavour)
    client = LogClient(link, sysid, compid)
    entries = client.list_logs(deadline)
    if not entries:
        why = ("ArduPilot logs only while armed (LOG_DISARMED 0): has it flown since its logs were erased?"
               if flavour is Flavour.ARDUPILOT else
               "PX4 logs only with its logger on (SDLOG_MODE 0..3; -1 turns it off)"
               if flavour is Flavour.PX4 else "")
        raise LogTransferError(f"vehicle {sysid} has no onboard log" + (f": {why}" if why else ""))
    if flavour is Flavour.GENERIC:
        raise LogTransferError(f"vehicle {sysid} has {len(entries)} log(s), but photos are read only from "
                               "ArduPilot DataFlash and PX4 ULog logs")
    # ArduPilot numbers its logs oldest first; PX4 lists them in its folder's order, dated by time_utc.
    newest_first = sorted(entries, key=(lambda e: e.id) if flavour is Flavour.ARDUPILOT
                          else (lambda e: (e.time_utc, e.id)), reverse=True)
    if since_utc is not None:
        recent = [e for e in newest_first if e.time_utc == 0 or e.time_utc >= since_utc - CLOCK_SLACK_S]
        if not recent:
            raise LogTransferError(f"vehicle {sysid} has no log written since the flight started at "
                                   f"{utc_of(since_utc)} (its newest, log {newest_first[0].id}, was last written "
                                   f"at {utc_of(newest_first[0].time_utc)})")
        newest_first = recent
    chosen = newest_first[:max_logs if wanted is not None else 1]
    total = sum(e.size for e in chosen)
    photos: dict[int, LoggedPhoto] = {}
    done = 0
    try:
        for entry in chosen:
            if wanted is not None and wanted <= photos.keys():
                break
            data = client.download(entry, deadline, progress, done, total)
            done += entry.size
            for photo in _read_bytes(data, entry.id, flavour, save_dir):
                photos.setdefault(photo.img_idx, photo)  # the newer log's copy stands
    finally:
        client.end()
    if wanted is not None:
        photos = {k: p for k, p in photos.items() if k in wanted}
    if since_utc is not None:  # earlier flights of the same log
        photos = {k: p for k, p in photos.items() if p.utc_s is None or p.utc_s >= since_utc - CLOCK_SLACK_S}
    return [photos[k] for k in sorted(photos)]


def _read_bytes(data: bytes, log_id: int, flavour: Flavour,
                save_dir: str | os.PathLike[str] | None) -> list[LoggedPhoto]:
    """Read a downloaded log, kept as save_dir/log{ID}.BIN (ArduPilot) or .ulg (PX4) when asked; a
    DataFlash log from a file (DFReader maps a file, it does not read bytes), a temp one if not kept."""
    if save_dir is not None:
        target = Path(save_dir) / f"log{log_id}.{'BIN' if flavour is Flavour.ARDUPILOT else 'ulg'}"
        with atomic_path(target) as tmp:
            tmp.write_bytes(data)
    if flavour is Flavour.PX4:
        return read_ulog_photos(data, log_id)
    if save_dir is not None:
        return read_dataflash_photos(target, log_id)
    fd, tmp_name = tempfile.mkstemp(prefix=f"log{log_id}.", suffix=".BIN")
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(data)
        return read_dataflash_photos(tmp_name, log_id)
    finally:
        os.unlink(tmp_name)


def utc_of(unix_s: float) -> str:
    """A UTC time as ISO text (for messages)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(unix_s)) if unix_s else "unknown"


__all__ = ["LogClient", "LogEntry", "LogTransferError", "LoggedPhoto", "read_dataflash_photos", "read_ulog_photos",
           "recover_photos"]
