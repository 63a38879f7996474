"""The mock vehicle's telemetry: what it tells the ground station about itself.

Owns, for one mock vehicle (mock_vehicle), every message it sends about its own state and when: HEARTBEAT
(quadrotor, ArduPilot or PX4; MAV_STATE_BOOT the first time after a (re)boot) once a second; SYS_STATUS (with the
pre-arm check bit, and the battery: SITL's SIM_BATT_VOLTAGE on ArduPilot), GPS_RAW_INT, EKF_STATUS_REPORT
(ArduPilot), HOME_POSITION (once the home is known), GLOBAL_POSITION_INT, MISSION_CURRENT,
EXTENDED_SYS_STATE (PX4's landed state, also sent at once when it changes) and GIMBAL_DEVICE_ATTITUDE_STATUS
(its camera mount's pitch, as each SITL reports its own; PX4 adds MOUNT_ORIENTATION; in the SITL-like mode only
with a mount configured at boot, MNT1_TYPE > 0 / MNT_MODE_IN >= 0), each at the rate
SET_MESSAGE_INTERVAL asks for (with streams_until_asked, like ArduPilot, none of them before it is asked);
STATUSTEXT (PX4 sends a long one in 50-character chunks under one id), ArduCopter SITL's "AHRS: waiting for
home" and its failing pre-arm check every 30 simulated seconds until the GPS has a fix; the flight's events
(MISSION_CURRENT at each change, MISSION_ITEM_REACHED as each autopilot reports it); one CAMERA_FEEDBACK per
photo, as ArduPilot sends for each trigger (PX4: CAMERA_IMAGE_CAPTURED), each also a photo of the onboard log
(mock_log), and none in the SITL-like mode until a camera is configured (img_idx from 1 then, counting on across
flights until a reboot); AUTOPILOT_VERSION when asked.
"""

from __future__ import annotations

import math
from typing import Any

from ..formats.mission_items import Flavour, MissionType
from ..formats.px4_rules import px4_millimetres, reported_reached
from ..link.connection import mavlink
from .mock_flight import FlightEvent
from .vehicle_params import ARDUPILOT_CAMERA_PARAM, ARDUPILOT_MOUNT_PARAM, NO_MOUNT, PX4_CAMERA_PARAM, PX4_MOUNT_PARAM
from .vehicle_part import VehiclePart

CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY)
STREAMS = (mavlink.MAVLINK_MSG_ID_SYS_STATUS, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
           mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
           mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, mavlink.MAVLINK_MSG_ID_HOME_POSITION,
           mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS)
# GIMBAL_DEVICE_ATTITUDE_STATUS as each SITL sends it for its own mount, the autopilot standing in for the gimbal
# device (component 1): ArduCopter 4.7 (MNT1_TYPE 1) with these flags, gimbal device 1 and NaN rates; PX4 v1.15
# (MNT_MODE_OUT 0) with these, gimbal device 0 and zero rates, and MOUNT_ORIENTATION beside it.
ARDUPILOT_GIMBAL_FLAGS = (mavlink.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | mavlink.GIMBAL_DEVICE_FLAGS_PITCH_LOCK
                          | mavlink.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME)
PX4_GIMBAL_FLAGS = (mavlink.GIMBAL_DEVICE_FLAGS_NEUTRAL | mavlink.GIMBAL_DEVICE_FLAGS_ROLL_LOCK
                    | mavlink.GIMBAL_DEVICE_FLAGS_PITCH_LOCK | mavlink.GIMBAL_DEVICE_FLAGS_YAW_LOCK)
# Flight-model motions (copter_model.Motion.kind) during which PX4 reports taking off, and landing
# (SIH: taking off from "Takeoff detected" to the take-off altitude; landing from "RTL: land at
# destination" until "Landing detected").
TAKING_OFF_KINDS = frozenset({"spool", "takeoff", "settle"})
LANDING_KINDS = frozenset({"descent", "land", "touchdown"})
# EKF_STATUS_REPORT flags as ArduCopter SITL reports them: before its GPS is used (attitude, velocity,
# vertical position, constant-position mode) and after (absolute and relative position, predicted too).
_EKF_ALWAYS = mavlink.EKF_ATTITUDE | mavlink.EKF_VELOCITY_HORIZ | mavlink.EKF_VELOCITY_VERT | mavlink.EKF_POS_VERT_ABS
EKF_FLAGS_WAITING = _EKF_ALWAYS | mavlink.EKF_CONST_POS_MODE
EKF_FLAGS_READY = (_EKF_ALWAYS | mavlink.EKF_POS_HORIZ_REL | mavlink.EKF_POS_HORIZ_ABS | mavlink.EKF_POS_VERT_AGL
                   | mavlink.EKF_PRED_POS_HORIZ_REL | mavlink.EKF_PRED_POS_HORIZ_ABS)
# ArduCopter SITL's texts until its EKF uses the GPS: the first two also answer an arming attempt (vehicle_commands).
NOT_READY_TEXTS = ("PreArm: Need Position Estimate", "Arm: Need Alt Estimate", "AHRS: waiting for home")
PX4_BATTERY_MV = 16_000
PREARM_REPEAT_S = 30.0  # simulated seconds between ArduPilot's reports of a failing pre-arm check
MIN_STREAM_INTERVAL_S = 0.005  # the loop's tick: a faster stream could not be kept anyway

# Mode names <-> custom_mode numbers, the autopilots' own (not MAVLink enums). ArduCopter numbers
# directly; PX4 packs main mode << 16, sub mode << 24.
ARDUPILOT_MODES = {"MANUAL": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
PX4_MODES = {"MANUAL": 1 << 16, "GUIDED": (4 << 16) | (8 << 24), "LOITER": (4 << 16) | (3 << 24),
             "AUTO": (4 << 16) | (4 << 24), "RTL": (4 << 16) | (5 << 24), "LAND": (4 << 16) | (6 << 24)}


class Telemetry(VehiclePart):
    """What one vehicle sends about itself: its streams at their intervals, its texts, its flight's events."""

    def __init__(self, vehicle: Any) -> None:
        super().__init__(vehicle)
        # Sends CAMERA_FEEDBACK (PX4: CAMERA_IMAGE_CAPTURED); SITL-like: only when the camera parameter
        # (CAM1_TYPE, PX4's TRIG_MODE) was set at boot.
        self.camera = True
        self.mount = True  # reports where its camera mount points (SITL-like: only with one configured at boot)
        self._text_id = 0  # PX4's STATUSTEXT id for chunked texts

    def on_boot(self, now: float) -> None:
        """A (re)boot: the streams as they are before any SET_MESSAGE_INTERVAL, nothing reported yet."""
        self._booting = True
        camera_param = PX4_CAMERA_PARAM if self.flavour is Flavour.PX4 else ARDUPILOT_CAMERA_PARAM
        self.camera = not self.options.sitl_like or self.vehicle.params.get(camera_param, 0.0) > 0.0
        mount_param = PX4_MOUNT_PARAM if self.flavour is Flavour.PX4 else ARDUPILOT_MOUNT_PARAM
        # A mount reports where it points; SITL-like: only one configured at boot (MNT1_TYPE > 0, MNT_MODE_IN >= 0).
        self.mount = not self.options.sitl_like or (
            self.vehicle.params.get(mount_param, NO_MOUNT[mount_param]) > NO_MOUNT[mount_param])
        self.reached: list[int] = []  # the mission items reached since boot
        self._next_heartbeat = now
        self.intervals: dict[int, float | None] = self._default_intervals()  # wall seconds; None: off
        self._next_due = {msgid: now for msgid in STREAMS}
        self._photos_sent = 0
        self._gimbal_sent: float | None = None  # the mount pitch last reported
        self._landed_sent = mavlink.MAV_LANDED_STATE_ON_GROUND
        self._said_waiting = False
        self._next_prearm_text = PREARM_REPEAT_S  # simulated seconds since boot

    def _default_intervals(self) -> dict[int, float | None]:
        """Streams before any SET_MESSAGE_INTERVAL: none (streams_until_asked, like ArduPilot whose
        stream-rate parameters are all 0), or what the mock always sent."""
        if self.options.streams_until_asked:
            return {msgid: None for msgid in STREAMS}
        ardupilot = self.flavour is Flavour.ARDUPILOT
        return {mavlink.MAVLINK_MSG_ID_SYS_STATUS: 1.0, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
                mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 1.0 / self.options.telemetry_hz,
                mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
                mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 1.0 if ardupilot else None,
                mavlink.MAVLINK_MSG_ID_HOME_POSITION: None,
                mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: None if ardupilot else 1.0,
                mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: None}

    @property
    def position_interval(self) -> float | None:
        """The GLOBAL_POSITION_INT interval in wall seconds (None: off)."""
        return self.intervals[mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT]

    def set_interval(self, msgid: int, interval_us: float, now: float) -> bool:
        """SET_MESSAGE_INTERVAL: a stream every interval_us (negative: off; 0: its default rate), due now.
        False for a message it does not stream."""
        if msgid not in STREAMS or (msgid == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT
                                    and self.flavour is not Flavour.ARDUPILOT):
            return False
        if interval_us < 0:
            self.intervals[msgid] = None
        elif interval_us == 0:  # the default rate
            position = msgid == mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
            self.intervals[msgid] = 1.0 / self.options.telemetry_hz if position else 1.0
        else:
            self.intervals[msgid] = max(interval_us / 1e6, MIN_STREAM_INTERVAL_S)
        self._next_due[msgid] = now
        return True

    # ------------------------------------------------------------------------------ ticking
    def tick(self, now: float) -> None:
        """What is due: the heartbeat, the streams, ArduPilot's not-ready texts, a landed state that
        changed, the photos taken since the last tick."""
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + 1.0
            self.send_heartbeat()
        for msgid, interval in self.intervals.items():
            if interval is not None and now >= self._next_due[msgid]:
                self._next_due[msgid] = now + interval
                self._send_stream(msgid, now)
        v = self.vehicle
        if not v.ready and self.flavour is Flavour.ARDUPILOT:
            if not self._said_waiting:
                self._said_waiting = True
                self.send_text(NOT_READY_TEXTS[2], mavlink.MAV_SEVERITY_INFO)
            simulated = (now - v.boot_time) * self.options.speedup
            if simulated >= self._next_prearm_text:  # ArduPilot repeats a failing pre-arm check every 30 s
                self._next_prearm_text = simulated + PREARM_REPEAT_S
                self.send_text(NOT_READY_TEXTS[0])
        if self.intervals.get(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE) is not None \
                and self._landed_state() != self._landed_sent:
            self._send_landed_state()  # at once, not a stream interval late (a sped-up mock's second is long)
        if self.intervals.get(mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS) is not None \
                and self.vehicle.flight.state.gimbal_pitch != self._gimbal_sent:
            self._send_gimbal(now)  # at once too, and before the photo the gimbal item precedes
        self._send_camera_feedback(now)

    def _send_stream(self, msgid: int, now: float) -> None:
        if msgid == mavlink.MAVLINK_MSG_ID_SYS_STATUS:
            self._send_status(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_GPS_RAW_INT:
            self._send_gps(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            self._send_position(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.send_mission_current()
        elif msgid == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT:
            self.send_ekf(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            self.send_home()
        elif msgid == mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            self._send_landed_state()
        elif msgid == mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS:
            self._send_gimbal(now)

    # ------------------------------------------------------------------------------ the messages
    def _custom_mode(self) -> int:
        table = ARDUPILOT_MODES if self.flavour is Flavour.ARDUPILOT else PX4_MODES
        return table.get(self.vehicle.flight.state.mode, 0)

    def send_heartbeat(self) -> None:
        s = self.vehicle.flight.state
        base = (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
                | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED)
        if s.mode == "AUTO":
            base |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED
        if s.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        status = mavlink.MAV_STATE_ACTIVE if s.armed else mavlink.MAV_STATE_STANDBY
        if self._booting:
            status = mavlink.MAV_STATE_BOOT  # the first heartbeat after a (re)boot, as autopilots report
            self._booting = False
        self.mav.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, self.flavour.autopilot, base, self._custom_mode(), status)

    def _send_status(self, now: float) -> None:
        v = self.vehicle
        sensors = 0x0020_FFFF | mavlink.MAV_SYS_STATUS_PREARM_CHECK  # the usual sensors (bits 0-15, 21) and pre-arm
        health = sensors if v.ready else sensors & ~mavlink.MAV_SYS_STATUS_PREARM_CHECK
        millivolts, centiamps = PX4_BATTERY_MV, 1_000
        if self.flavour is Flavour.ARDUPILOT:  # SITL: SIM_BATT_VOLTAGE, current only while the motors run
            millivolts = int(round(v.battery_voltage * 1000))
            centiamps = int(v.battery_current * 100)
        self.mav.sys_status_send(sensors, sensors, health, 200, millivolts, centiamps, 90, 0, 0, 0, 0, 0, 0)

    def _send_gps(self, now: float) -> None:
        s, ready = self.vehicle.flight.state, self.vehicle.ready
        fix, sats = (mavlink.GPS_FIX_TYPE_3D_FIX, 12) if ready else (mavlink.GPS_FIX_TYPE_NO_FIX, 0)
        lat, lon = self.vehicle.gps_glitch.raw_position(s.lat, s.lon)  # the truth plus a glitch (gps_glitch)
        self.mav.gps_raw_int_send(int(now * 1e6), fix, int(round(lat * 1e7)) if ready else 0,
                                  int(round(lon * 1e7)) if ready else 0,
                                  int(round((s.home[2] + s.alt) * 1000)) if ready else 0,
                                  80 if ready else 9999, 120 if ready else 9999,
                                  int(round(math.hypot(s.vn, s.ve) * 100)), 0, sats)

    def send_ekf(self, now: float) -> None:
        flags = EKF_FLAGS_READY if self.vehicle.ready else EKF_FLAGS_WAITING
        self.mav.ekf_status_report_send(flags, 0.01, 0.01, 0.01, 0.01, 0.0)

    def send_home(self) -> bool:
        """HOME_POSITION, once the home is known (as ArduPilot: not before the EKF has a position)."""
        if not self.vehicle.ready:
            return False
        lat, lon, alt = self.options.home
        self.mav.home_position_send(int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000)),
                                    0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0)
        return True

    def send_text(self, text: str, severity: int = mavlink.MAV_SEVERITY_CRITICAL) -> None:
        if self.flavour is not Flavour.PX4 or len(text) <= 50:
            self.mav.statustext_send(severity, text.encode()[:50])
            return
        self._text_id = self._text_id % 65535 + 1  # PX4: a long text in 50-character chunks, one id
        for chunk, start in enumerate(range(0, len(text), 50)):
            self.mav.statustext_send(severity, text[start:start + 50].encode(), self._text_id, chunk)

    def _landed_state(self) -> int:
        flight = self.vehicle.flight
        s = flight.state
        kind = flight.motion_kind if s.armed else None
        if kind in TAKING_OFF_KINDS:
            return mavlink.MAV_LANDED_STATE_TAKEOFF
        if kind in LANDING_KINDS:
            return mavlink.MAV_LANDED_STATE_LANDING
        on_ground = s.on_ground and not (s.armed and s.mode == "AUTO" and not s.mission_done)
        return mavlink.MAV_LANDED_STATE_ON_GROUND if on_ground else mavlink.MAV_LANDED_STATE_IN_AIR

    def _send_landed_state(self) -> None:
        """EXTENDED_SYS_STATE, as PX4 streams it: on the ground, taking off, in the air or landing."""
        self._landed_sent = self._landed_state()
        self.mav.extended_sys_state_send(mavlink.MAV_VTOL_STATE_UNDEFINED, self._landed_sent)

    def _send_position(self, now: float) -> None:
        s = self.vehicle.flight.state
        home_alt = s.home[2]
        self.mav.global_position_int_send(self.vehicle.time_boot_ms(now), int(round(s.lat * 1e7)),
                                          int(round(s.lon * 1e7)),
                                          int(round((home_alt + s.alt) * 1000)), int(round(s.alt * 1000)),
                                          int(round(s.vn * 100)), int(round(s.ve * 100)), int(round(s.vz * 100)),
                                          int(round(s.heading * 100)) % 36000)

    def send_mission_current(self, seq: int | None = None) -> None:
        s = self.vehicle.flight.state
        total = len(self.vehicle.mission_server.stores[MissionType.MISSION])
        if total <= self.vehicle.first_mission_seq:
            state = mavlink.MISSION_STATE_NO_MISSION
        elif s.mission_done:
            state = mavlink.MISSION_STATE_COMPLETE
        elif s.mode == "AUTO" and s.armed:
            state = mavlink.MISSION_STATE_ACTIVE
        else:
            state = mavlink.MISSION_STATE_NOT_STARTED
        self.mav.mission_current_send(s.current if seq is None else seq, total, state, 1 if s.mode == "AUTO" else 0)

    def send_version(self) -> None:
        self.mav.autopilot_version_send(CAPABILITIES, (4 << 24) | (6 << 16), 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                                        0, 0, self.vehicle.sysid)

    # ------------------------------------------------------------------------------ the flight's events
    def publish(self, events: list[FlightEvent]) -> None:
        """The flight's events (mock_flight) on the link: the current item, each item reached, landed / done."""
        for event in events:
            if event.kind == "current":
                self.send_mission_current(event.seq)  # each change, even several in one step
            elif event.kind == "reached":
                self.reached.append(event.seq)
                seq: int | None = event.seq
                if self.flavour is Flavour.PX4:  # PX4's own way of reporting it (formats.px4_rules.reported_reached)
                    seq = reported_reached([int(item.command) for item in self.vehicle.flight.items], event.seq)
                if seq is not None:
                    self.mav.mission_item_reached_send(seq)
            elif event.kind in ("landed", "done"):
                self.send_mission_current()
                self.send_heartbeat()

    def _send_gimbal(self, now: float) -> None:
        """Where the mount points (FlightState.gimbal_pitch; roll and yaw 0), as each SITL reports it; nothing
        without a mount."""
        if not self.mount:
            return
        s = self.vehicle.flight.state
        self._gimbal_sent = s.gimbal_pitch
        half = math.radians(s.gimbal_pitch) / 2.0
        q = [math.cos(half), 0.0, math.sin(half), 0.0]
        boot_ms = self.vehicle.time_boot_ms(now)
        if self.flavour is Flavour.PX4:
            self.mav.gimbal_device_attitude_status_send(0, 0, boot_ms, PX4_GIMBAL_FLAGS, q, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0)
            self.mav.mount_orientation_send(boot_ms, 0.0, s.gimbal_pitch, 0.0, s.heading % 360.0)
            return
        nan = math.nan
        self.mav.gimbal_device_attitude_status_send(0, 0, boot_ms, ARDUPILOT_GIMBAL_FLAGS, q, nan, nan, nan, 0, nan, nan,
                                                    1)

    def _send_camera_feedback(self, now: float) -> None:
        """One CAMERA_FEEDBACK per photo taken since the last call, with where it was taken."""
        s = self.vehicle.flight.state
        points = s.photo_points
        home_alt = s.home[2]
        if not self.camera:  # no camera configured: ArduCopter sends nothing
            self._photos_sent = len(points)
            return
        camera = self.vehicle.mavlink_camera  # a MAVLink camera beside it: it reports each photo itself too
        if camera is not None:
            for lat, lon, alt in points[self._photos_sent:]:
                camera.capture_at(lat, lon, home_alt + alt, alt)
        if self.flavour is Flavour.PX4:
            self._send_image_captured(now, points, home_alt)
            return
        first = 1 if self.options.sitl_like else 0  # ArduPilot's img_idx starts at 1 after a boot
        while self._photos_sent < len(points):
            lat, lon, alt = points[self._photos_sent]
            self._photos_sent += 1
            self._log_photo(now, self._photos_sent - 1 + first, lat, lon, home_alt, alt)
            self.mav.camera_feedback_send(int(now * 1e6), self.vehicle.sysid, 0,
                                          (self._photos_sent - 1 + first) % 65536,
                                          int(round(lat * 1e7)), int(round(lon * 1e7)), home_alt + alt, alt,
                                          0.0, 0.0, s.heading, 0.0, 0, self._photos_sent)

    def _log_photo(self, now: float, img_idx: int, lat: float, lon: float, home_alt: float, alt: float) -> None:
        """The onboard log's CAM of a photo (mock_log): what CAMERA_FEEDBACK reports, kept on the vehicle."""
        v = self.vehicle
        v.logs.log_photo(img_idx, lat, lon, home_alt + alt, alt, 0.0, 0.0, v.flight.state.heading, v.time_us(now))

    def _send_image_captured(self, now: float, points: list[tuple[float, float, float]], home_alt: float) -> None:
        """PX4 (camera_trigger + camera_feedback): one CAMERA_IMAGE_CAPTURED per photo on the GCS link,
        image_index from 0 after boot (counting on across flights), capture_result 1, no CAMERA_FEEDBACK."""
        while self._photos_sent < len(points):
            lat, lon, alt = points[self._photos_sent]
            self._log_photo(now, self._photos_sent, lat, lon, home_alt, alt)
            # PX4 truncates camera_capture's doubles, and its float32 metres times 1e3f, into the message
            self.mav.camera_image_captured_send(self.vehicle.time_boot_ms(now), int(now * 1e6), 1, int(lat * 1e7),
                                                int(lon * 1e7), px4_millimetres(home_alt + alt),
                                                px4_millimetres(alt), [1.0, 0.0, 0.0, 0.0], self._photos_sent, 1, b"")
            self._photos_sent += 1
