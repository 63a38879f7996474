"""A MAVLink camera for the mock and for the SITLs: its own component beside the autopilot.

Owns MockCamera, what a camera that speaks the MAVLink camera protocol does on a link, with no transport of
its own: it sends through the pymavlink encoder it is given (component MAV_COMP_ID_CAMERA, 100) and is handed
every message it hears. It
- says HEARTBEAT once a second as MAV_TYPE_CAMERA (autopilot MAV_AUTOPILOT_INVALID): ArduPilot's
  MAVLinkCamV2 backend (CAM1_TYPE 6) finds its camera by that heartbeat and component id;
- answers MAV_CMD_REQUEST_MESSAGE for CAMERA_INFORMATION (flags CAMERA_CAP_FLAGS_CAPTURE_IMAGE) and
  CAMERA_CAPTURE_STATUS, with a COMMAND_ACK;
- takes MAV_CMD_IMAGE_START_CAPTURE (param2 interval s, param3 count, 0 = until stopped; a count of 1 is
  one photo now, as ArduPilot and PX4 forward each trigger) and MAV_CMD_IMAGE_STOP_CAPTURE. Not the
  legacy MAV_CMD_DO_DIGICAM_CONTROL: PX4 (TRIG_INTERFACE 3) sends it beside each IMAGE_START_CAPTURE, and a
  camera of the camera protocol that took both would take every photo twice. Other commands addressed
  to it are answered UNSUPPORTED; broadcast ones (PX4 forwards every command of its own) go unanswered;
- for each photo sends CAMERA_IMAGE_CAPTURED: its own time_boot_ms, time_utc, where the vehicle was
  (the autopilot's latest GLOBAL_POSITION_INT: lat, lon, alt AMSL and relative altitude in mm), q from its
  latest ATTITUDE, image_index counting from 0 after its own boot, capture_result 1, and a file_url
  naming the image on its card. `fail_indices`: the photos whose capture fails (capture_result 0, no file).

CameraPeer runs one MockCamera on a pymavlink link of its own (a thread): against ArduCopter SITL on a
serial port of its (tcp:127.0.0.1:5762+10·I) or PX4 SIH. The mock autopilot instead embeds MockCamera on its
own link (mock_vehicle) and drives captures from its flight's photos (capture_at).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from ..link.connection import mavlink

CAMERA_COMPONENT_ID: int = mavlink.MAV_COMP_ID_CAMERA
HEARTBEAT_S = 1.0
VENDOR, MODEL = b"missionplan", b"mock camera"


@dataclass(frozen=True)
class CapturedImage:
    """One CAMERA_IMAGE_CAPTURED the camera sent."""

    image_index: int
    lat: float
    lon: float
    alt_amsl_m: float
    relative_alt_m: float
    capture_result: int
    file_url: str


class MockCamera:
    """A MAVLink camera component (see the module docstring); not thread-safe: one owner calls it."""

    def __init__(self, mav: Any, sysid: int, clock: Callable[[], float] = time.monotonic,
                 fail_indices: Iterable[int] = ()) -> None:
        """mav: a pymavlink MAVLink encoder sending as (sysid, CAMERA_COMPONENT_ID); clock: monotonic seconds."""
        self.mav, self.sysid, self.clock = mav, sysid, clock
        self.fail_indices = frozenset(fail_indices)
        self.boot = clock()
        self.images: list[CapturedImage] = []
        self.commands: list[tuple[int, tuple[float, ...]]] = []  # every command addressed to it, in order
        self.position: tuple[float, float, float, float] | None = None  # lat, lon, alt AMSL m, relative m
        self.q = [1.0, 0.0, 0.0, 0.0]
        self._interval_s = 0.0
        self._remaining = 0  # photos left in an interval capture; -1: until stopped
        self._next_photo = math.inf
        self._next_heartbeat = self.boot

    # ------------------------------------------------------------------------------ what it hears
    def handle(self, msg: Any) -> None:
        """One message heard on the link: the autopilot's position and attitude, commands to the camera."""
        kind = msg.get_type()
        if msg.get_srcSystem() != self.sysid and kind != "COMMAND_LONG":
            return
        if kind == "GLOBAL_POSITION_INT" and msg.get_srcComponent() != CAMERA_COMPONENT_ID:
            self.position = (msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000.0, msg.relative_alt / 1000.0)
        elif kind == "ATTITUDE":
            self.q = _quaternion(msg.roll, msg.pitch, msg.yaw)
        elif kind == "COMMAND_LONG" and msg.target_system in (0, self.sysid) \
                and msg.target_component in (0, CAMERA_COMPONENT_ID):
            self._command(msg)

    def _command(self, msg: Any) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        command = int(msg.command)
        self.commands.append((command, params))
        result = mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_REQUEST_MESSAGE and int(params[0]) == mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION:
            self.send_information()
        elif command == mavlink.MAV_CMD_REQUEST_MESSAGE \
                and int(params[0]) == mavlink.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS:
            self.send_capture_status()
        elif command == mavlink.MAV_CMD_IMAGE_START_CAPTURE:
            self.start_capture(float(params[1]), int(params[2]))
        elif command == mavlink.MAV_CMD_IMAGE_STOP_CAPTURE:
            self.stop_capture()
        elif msg.target_component != CAMERA_COMPONENT_ID:
            return  # someone else's command, broadcast: not ours to answer
        else:
            result = mavlink.MAV_RESULT_UNSUPPORTED
        self.mav.command_ack_send(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())

    # ------------------------------------------------------------------------------ capturing
    def start_capture(self, interval_s: float, count: int) -> None:
        """IMAGE_START_CAPTURE: one photo now, then every interval_s until `count` (0: until stopped)."""
        self.capture_now()
        if count == 1 or interval_s <= 0:
            self._remaining = 0
            return
        self._interval_s = interval_s
        self._remaining = -1 if count <= 0 else count - 1
        self._next_photo = self.clock() + interval_s

    def stop_capture(self) -> None:
        self._remaining, self._next_photo = 0, math.inf

    def capture_now(self) -> CapturedImage | None:
        """A photo where the vehicle is now (None before its position was heard: nothing to report)."""
        if self.position is None:
            return None
        return self.capture_at(*self.position)

    def capture_at(self, lat: float, lon: float, alt_amsl_m: float, relative_alt_m: float) -> CapturedImage:
        """A photo taken at this place: one CAMERA_IMAGE_CAPTURED (capture_result 0 for a failing index)."""
        index = len(self.images)
        ok = index not in self.fail_indices
        image = CapturedImage(index, lat, lon, alt_amsl_m, relative_alt_m, 1 if ok else 0,
                              f"DCIM/100MOCK/IMG_{index:04d}.JPG" if ok else "")
        self.images.append(image)
        now = self.clock()
        self.mav.camera_image_captured_send(self.time_boot_ms(now), int(time.time() * 1e6), 0,
                                            int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt_amsl_m * 1e3)),
                                            int(round(relative_alt_m * 1e3)), self.q, index, image.capture_result,
                                            image.file_url.encode())
        return image

    # ------------------------------------------------------------------------------ what it says
    def time_boot_ms(self, now: float) -> int:
        return int((now - self.boot) * 1000) & 0xFFFFFFFF

    def tick(self) -> None:
        """Heartbeat once a second; the next photo of an interval capture when it is due."""
        now = self.clock()
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + HEARTBEAT_S
            self.mav.heartbeat_send(mavlink.MAV_TYPE_CAMERA, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                    mavlink.MAV_STATE_ACTIVE)
        while self._remaining != 0 and now >= self._next_photo:
            self.capture_now()
            self._next_photo += self._interval_s
            if self._remaining > 0:
                self._remaining -= 1

    def send_information(self) -> None:
        self.mav.camera_information_send(self.time_boot_ms(self.clock()), VENDOR.ljust(32, b"\0"),
                                         MODEL.ljust(32, b"\0"), 1, 8.8, 13.2, 8.8, 5472, 3648, 0,
                                         mavlink.CAMERA_CAP_FLAGS_CAPTURE_IMAGE, 0, b"")

    def send_capture_status(self) -> None:
        status = 3 if self._remaining != 0 else 0  # interval set and capturing, or idle
        self.mav.camera_capture_status_send(self.time_boot_ms(self.clock()), status, 0, self._interval_s, 0,
                                            math.nan, len(self.images))


def _quaternion(roll: float, pitch: float, yaw: float) -> list[float]:
    """Euler angles (rad) to the quaternion w, x, y, z that CAMERA_IMAGE_CAPTURED's q carries."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]


class CameraPeer:
    """A MockCamera on a pymavlink link of its own, served by a thread until stop() (a context manager).

    url: where the autopilot is (tcp:127.0.0.1:PORT for an ArduCopter SITL serial port, udpout:/udpin: for
    PX4). It asks the autopilot for GLOBAL_POSITION_INT and ATTITUDE (10 Hz) so each photo has a place."""

    def __init__(self, url: str, sysid: int, fail_indices: Iterable[int] = ()) -> None:
        from pymavlink import mavutil

        # No dialect= here: pymavlink's mavlink_connection(dialect=...) sets the dialect for the whole process, and
        # every link opened after it in this process then drops ArduPilot's own messages (EKF_STATUS_REPORT,
        # CAMERA_FEEDBACK) as unknown. ardupilotmega, the process's dialect, holds all of common.
        self.link = mavutil.mavlink_connection(url, source_system=sysid, source_component=CAMERA_COMPONENT_ID,
                                               autoreconnect=True)
        self.camera = MockCamera(self.link.mav, sysid, fail_indices=fail_indices)
        self.sysid = sysid
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"camera-{sysid}", daemon=True)
        self._lock = threading.Lock()

    def start(self) -> CameraPeer:
        self._thread.start()
        return self

    def images(self) -> list[CapturedImage]:
        with self._lock:
            return list(self.camera.images)

    def _ask_streams(self) -> None:
        for msgid in (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_ATTITUDE):
            self.link.mav.command_long_send(self.sysid, mavlink.MAV_COMP_ID_AUTOPILOT1,
                                            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msgid, 100_000, 0, 0, 0, 0, 0)

    def _serve(self) -> None:
        asked_at = -math.inf
        while not self._stop.is_set():
            with self._lock:
                self.camera.tick()
                if self.camera.position is None and time.monotonic() - asked_at > 2.0:
                    self._ask_streams()  # again until heard: the autopilot may not have been up yet
                    asked_at = time.monotonic()
            msg = self.link.recv_match(blocking=True, timeout=0.02)
            if msg is not None and msg.get_type() != "BAD_DATA":
                with self._lock:
                    self.camera.handle(msg)

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self.link.close()

    def __enter__(self) -> CameraPeer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
