"""One simulated vehicle of the mock autopilot: its telemetry, mission protocol and commands.

Owns the vehicle side of the mission protocol for every mission_type (mission, fence, rally):
upload with re-requests on a timer and a give-up time-out (the old mission stays until an upload
completes), download of any in-range item in any order, clear-all, set-current. The ArduPilot flavour
does what ArduCopter SITL does: it stores items as formats.readback.ardupilot_stored says (NAV_WAYPOINT
keeps only param1, DO_* come back in frame 0, ...), keeps its home as item 0 (0, 0, 0 until its GPS
has a fix), re-requests after 1 s, answers an item it did not ask for with INVALID_SEQUENCE and one
after the upload completed with ERROR, and flies every waypoint to WPNAV_RADIUS (PARAM_SET /
PARAM_REQUEST_READ), not to param2. The PX4 flavour does what PX4 SIH does with missions (formats.px4_rules,
measured; sitl_tests/test_mock_vs_px4.py keeps it honest): PX4's frame / command matrix and result
codes, its stored form (3 -> 6, 0 -> 5, no pass radius, float32-radian yaws), the `current` flag on
its active item and on item 0 of fence and rally, the legacy MISSION_REQUEST until the ground
station speaks *_INT (an error answer flips it), and a MISSION_START refused with "Mission start
denied! No valid mission" before its GPS fix or when the first waypoint is MIS_DIST_1WP or more
from its home; a fence without its home draws "Geofence invalid, doesn't contain Home position".
A mission replaced while the vehicle flies is taken as each autopilot took it (docs/live-retasking.md,
_replaced_in_flight): ArduPilot keeps its item and restarts it, PX4 goes to the item flagged current.
COMMAND_LONG arm /
disarm, mode changes, MAV_CMD_MISSION_START, DO_SET_MISSION_CURRENT and AUTOPILOT_VERSION requests,
each answered with COMMAND_ACK; HEARTBEAT (quadrotor, ArduPilot or PX4), SYS_STATUS (with the pre-arm
check bit), GPS_RAW_INT, EKF_STATUS_REPORT (ArduPilot), HOME_POSITION, GLOBAL_POSITION_INT, MISSION_CURRENT
(each at the rate SET_MESSAGE_INTERVAL asks for; with streams_until_asked, like ArduPilot, none of them
before it is asked), STATUSTEXT,
MISSION_ITEM_REACHED and one CAMERA_FEEDBACK per photo (as ArduPilot sends for each trigger);
readiness like ArduCopter SITL's (gps_fix_after simulated seconds without a GPS fix, with a waiting
EKF, no home, a failing pre-arm bit, and arming refused with FAILED and its STATUSTEXT reasons);
and the reboot fault (forget everything, the flight included, and go silent for a moment); the kill
fault (kill(): silent for good, as a SITL process killed in flight: no message at all any more).
ArduPilot's battery failsafe (AP_BattMonitor + ArduCopter events.cpp): the battery reads SIM_BATT_VOLTAGE
(12.6 V, SITL's default; SYS_STATUS reports it); armed, below BATT_LOW_VOLT (10.5 V) for more than
BATT_LOW_TIMER (10 s) simulated seconds (BATT_CRT_VOLT / BATT_FS_CRT_ACT likewise), it says
"Battery 1 is low 10.00V used 83 mAh" and "Battery Failsafe" (severity WARNING) and does BATT_FS_LOW_ACT:
1 LAND, 2 RTL (3, 4 and 6, SmartRTL / DO_LAND_START, flown as RTL here; 5, terminate, as LAND), or
disarms at once when on the ground; below either voltage it refuses to arm ("PreArm: Battery 1 low
voltage failsafe"). All by PARAM_SET, as on SITL. Another ground station's transfer:
while one (sysid, compid) uploads, ArduPilot's MissionItemProtocol answers another's MISSION_COUNT and
MISSION_CLEAR_ALL with MAV_MISSION_DENIED (clear-all then also ERROR), its items with INVALID_SEQUENCE
or DENIED, and any MISSION_REQUEST_LIST / MISSION_REQUEST_INT with DENIED, until the upload completes
or times out (8 s without an item).
The SITL-like mode (VehicleOptions.sitl_like) adds what ArduCopter SITL does in flight: no
CAMERA_FEEDBACK until a camera is configured (CAM1_TYPE set, then a reboot:
MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN), img_idx from 1 and counting on across flights until a reboot,
ArduCopter's navigation parameters (PARAM_REQUEST_READ / PARAM_SET) and its flight
(flight_models.copter_model: acceleration, stops at corners, RTL_ALT climb, slow final descent). The flight itself is
mock_flight's; the link and the other faults are mock's; the onboard log (a DataFlash log with one CAM per photo, and
the LOG_REQUEST_* transfer) is mock_log's. Everything here runs on the mock's one loop thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from ..flight_models.copter_model import CopterParams
from ..link.connection import mavlink
from ..flight_models.px4_model import Px4Params
from ..formats.mission_items import GLOBAL_FRAMES, Flavour, MissionType, WireItem, encode_xy
from ..formats.readback import ardupilot_stored
from .mock_flight import FlightEvent, FlightSim
from .mock_log import OnboardLogs
from ..formats.px4_rules import (GEOFENCE_WITHOUT_HOME, MIS_DIST_1WP_DEFAULT, START_DENIED, fence_problems, item_result,
                  px4_millimetres, px4_stored, reported_reached, start_refusals)

CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY)
# COMPONENT_ARM_DISARM's param2 that forces arming or disarming: a magic number of the command's
# definition, not an enum.
FORCE_ARM_DISARM = 21196

# Mode names <-> custom_mode numbers, the autopilots' own (not MAVLink enums). ArduCopter numbers
# directly; PX4 packs main mode << 16, sub mode << 24.
ARDUPILOT_MODES = {"MANUAL": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
PX4_MODES = {"MANUAL": 1 << 16, "GUIDED": (4 << 16) | (8 << 24), "LOITER": (4 << 16) | (3 << 24),
             "AUTO": (4 << 16) | (4 << 24), "RTL": (4 << 16) | (5 << 24), "LAND": (4 << 16) | (6 << 24)}

STREAMS = (mavlink.MAVLINK_MSG_ID_SYS_STATUS, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
           mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
           mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, mavlink.MAVLINK_MSG_ID_HOME_POSITION,
           mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)
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
NOT_READY_TEXTS = ("PreArm: Need Position Estimate", "Arm: Need Alt Estimate", "AHRS: waiting for home")
# PX4 SIH's answer to arming before "Ready for takeoff!": TEMPORARILY_REJECTED and these (the first
# is 51 characters: PX4 sends it as two STATUSTEXT chunks with one id).
PX4_NOT_READY_TEXTS = ("Arming denied: Resolve system health failures first", "Preflight Fail: horizontal velocity unstable")
# PX4 SIH refused a MISSION_START sent right after the upload with "No valid mission" (1 vehicle in 12):
# it takes the new mission after its own checks. How long is not visible on the link; half a second here.
PX4_MISSION_CHECK_S = 0.5
PX4_MISSION_MODE_REFUSED = "Switching to Mission is currently not available"  # AUTO.MISSION asked meanwhile
PX4_CAMERA_PARAM, ARDUPILOT_CAMERA_PARAM = "TRIG_MODE", "CAM1_TYPE"  # read at boot: the camera reports only then
# ArduPilot's battery monitor and its failsafe (AP_BattMonitor_Params.cpp: BATT_LOW_VOLT 10.5 V on copters,
# BATT_LOW_TIMER 10 s, actions 0 = none; copter.parm sets BATT_MONITOR 4; SITL's SIM_BATT_VOLTAGE 12.6 V).
ARDUPILOT_BATTERY_PARAMS = {"BATT_MONITOR": 4.0, "BATT_LOW_VOLT": 10.5, "BATT_LOW_TIMER": 10.0, "BATT_FS_LOW_ACT": 0.0,
                            "BATT_CRT_VOLT": 0.0, "BATT_FS_CRT_ACT": 0.0, "SIM_BATT_VOLTAGE": 12.6}
BATTERY_CURRENT_A = 10.0  # drawn while armed (SYS_STATUS current, the "used N mAh" of the failsafe text)
BATTERY_FAILSAFE_TEXT = "Battery Failsafe"  # Copter::announce_failsafe("Battery"), events.cpp
PX4_BATTERY_MV = 16_000
PREARM_REPEAT_S = 30.0  # simulated seconds between ArduPilot's reports of a failing pre-arm check
MIN_STREAM_INTERVAL_S = 0.005  # the loop's tick: a faster stream could not be kept anyway

MISSION_COMMANDS_REJECTED = range(5000, 6000)  # fence and rally commands do not belong in a mission
FENCE_COMMANDS = frozenset({mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION})


@dataclass
class VehicleOptions:
    """How one mock vehicle behaves. None picks the flavour's real-world default."""

    flavour: Flavour = Flavour.ARDUPILOT
    home: tuple[float, float, float] = (45.0703, 7.6869, 240.0)  # lat, lon, alt AMSL
    request_interval: float | None = None  # re-request a missing item after this long (ArduPilot 1 s, PX4 0.25 s)
    upload_timeout: float | None = None    # give a stalled upload up after this long (ArduPilot 8 s, PX4 5 s)
    legacy_requests: bool | None = None    # ask with MISSION_REQUEST (#40) like ArduCopter does
    max_items: int = 10_000
    gps_fix_after: float = 0.0  # simulated seconds from boot until GPS fix, EKF, home and arming (SITL: 35-40)
    streams_until_asked: bool = False  # like ArduPilot: nothing but HEARTBEAT until SET_MESSAGE_INTERVAL
    speedup: float = 1.0
    cruise_speed: float = 5.0
    telemetry_hz: float = 4.0
    sitl_like: bool = False  # ArduCopter SITL's camera, image index, parameters and flight (see the module doc)
    # PX4: simulated seconds after a mission upload until PX4 has checked it (its navigator's feasibility
    # check, then commander's health checks): a MISSION_START before then is DENIED, "No valid mission".
    # None: PX4_MISSION_CHECK_S when sitl_like, else 0.
    mission_check_s: float | None = None

    def resolved(self) -> VehicleOptions:
        ardupilot = self.flavour is Flavour.ARDUPILOT
        return replace(self,
                       request_interval=self.request_interval or (1.0 if ardupilot else 0.25),
                       upload_timeout=self.upload_timeout or (8.0 if ardupilot else 5.0),
                       legacy_requests=ardupilot if self.legacy_requests is None else self.legacy_requests,
                       mission_check_s=(self.mission_check_s if self.mission_check_s is not None
                                        else PX4_MISSION_CHECK_S if self.sitl_like and not ardupilot else 0.0))


@dataclass
class _Upload:
    mission_type: int
    count: int
    peer: tuple[int, int]
    received: list[WireItem]
    last_sent: float
    last_progress: float


class MockVehicle:
    """The state and behaviour of one system id. Call handle() for each message and tick() often."""

    def __init__(self, sysid: int, options: VehicleOptions, encoder: Any, now: float) -> None:
        self.sysid = sysid
        self.options = options.resolved()
        self.flavour = self.options.flavour
        self.mav = encoder  # pymavlink MAVLink with srcSystem=sysid, srcComponent=1, writing to the mock's link
        self.reboots = 0
        self.uploads_completed = 0
        self.mission_checked_at = 0.0  # PX4: MISSION_START is refused before then (VehicleOptions.mission_check_s)
        self.uploads_failed = 0
        self.reboot_after_items: int | None = None
        self.reboot_offline = 0.3
        self.reboot_at_item: int | None = None  # reboot in flight once this mission item is reached
        self.invalid_sequence_acks = 0  # INVALID_SEQUENCE answers to items it did not ask for
        self.stray_item_acks = 0        # ERROR answers to items that came after an upload completed
        # Parameters survive a reboot, like ArduPilot's EEPROM. Only the one the bridge sets is known.
        self.params: dict[str, float] = {"WPNAV_RADIUS": 200.0} if self.flavour is Flavour.ARDUPILOT else {}
        if self.flavour is Flavour.ARDUPILOT:
            self.params.update(ARDUPILOT_BATTERY_PARAMS)
        self.killed = False  # kill(): silent for good
        self.kill_at_item: int | None = None  # kill in flight once this mission item is reached
        self.denied_transfers = 0  # DENIED answers to another ground station during an upload
        self.battery_failsafe = 0  # 0 none, 1 low, 2 critical (the highest reached since boot)
        self.consumed_mah = 0.0
        if self.flavour is Flavour.PX4:
            self.params["MIS_DIST_1WP"] = MIS_DIST_1WP_DEFAULT  # its mission feasibility check (formats.px4_rules)
        if self.options.sitl_like and self.flavour is Flavour.PX4:
            self.params.update({**Px4Params().as_params(), PX4_CAMERA_PARAM: 0.0})
        elif self.options.sitl_like:
            self.params.update({**CopterParams().as_params(), ARDUPILOT_CAMERA_PARAM: 0.0})
        # Sends CAMERA_FEEDBACK (PX4: CAMERA_IMAGE_CAPTURED); SITL-like: only when the camera parameter
        # (CAM1_TYPE, PX4's TRIG_MODE) was set at boot.
        self.camera = True
        self._text_id = 0  # PX4's STATUSTEXT id for chunked texts
        self._reboot_pending = False  # a reboot command acknowledged: reboot once the ack is out
        self.logs = OnboardLogs(self.flavour, encoder, self._send_text)  # on its SD card: survives reboots
        self._boot(now)

    # ------------------------------------------------------------------------------ lifecycle
    def _boot(self, now: float) -> None:
        self._booting = True
        self.logs.on_boot()
        self.boot_time = now
        self._last_tick = now
        self.offline_until = 0.0
        home = self.options.home
        self.stores: dict[int, list[WireItem]] = {MissionType.MISSION: [], MissionType.FENCE: [], MissionType.RALLY: []}
        if self.flavour.has_home_item(MissionType.MISSION):
            self.stores[MissionType.MISSION] = [self._home_item()]
        self.upload: _Upload | None = None
        self._flight_stale = False  # ArduPilot: flying an item of a mission replaced since (_replaced_in_flight)
        self._restart_on_auto = False  # ArduPilot: its item cut off by a shorter mission while out of AUTO
        # PX4 asks with the legacy MISSION_REQUEST until the ground station has used an *_INT message.
        self._int_mode = False
        self.last_completed: tuple[int, int, tuple[int, int]] | None = None  # type, count, peer
        camera_param = PX4_CAMERA_PARAM if self.flavour is Flavour.PX4 else ARDUPILOT_CAMERA_PARAM
        self.camera = not self.options.sitl_like or self.params.get(camera_param, 0.0) > 0.0
        copter = CopterParams.from_params(self.params) if self.options.sitl_like else None
        px4 = Px4Params.from_params(self.params) if self.options.sitl_like and self.flavour is Flavour.PX4 else None
        self.flight = FlightSim(home, cruise_speed=self.options.cruise_speed, copter=copter, px4=px4)
        if "WPNAV_RADIUS" in self.params:  # ArduCopter turns within WPNAV_RADIUS of every waypoint
            self.flight.default_acceptance = max(self.params["WPNAV_RADIUS"], 5.0) / 100.0
        self._load_flight()
        self.reached: list[int] = []
        self._next_heartbeat = now
        self.intervals: dict[int, float | None] = self._default_intervals()  # wall seconds; None: off
        self._next_due = {msgid: now for msgid in STREAMS}
        self._photos_sent = 0
        self._landed_sent = mavlink.MAV_LANDED_STATE_ON_GROUND
        self._said_waiting = False
        self._next_prearm_text = PREARM_REPEAT_S  # simulated seconds since boot
        self.battery_failsafe = 0
        self.consumed_mah = 0.0
        self.battery_failsafe_sim_time: float | None = None  # the flight's simulated time when it acted
        self._low_since: dict[int, float | None] = {1: None, 2: None}  # simulated s: below the level since

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
                mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: None if ardupilot else 1.0}

    @property
    def position_interval(self) -> float | None:
        """The GLOBAL_POSITION_INT interval in wall seconds (None: off)."""
        return self.intervals[mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT]

    @property
    def ready(self) -> bool:
        """GPS fix, EKF and home: before it, arming is refused with ArduCopter's reasons."""
        return self.has_fix

    @property
    def has_fix(self) -> bool:
        """Whether the simulated GPS has a fix yet (before it, ArduPilot's home item reads 0, 0, 0)."""
        return (self._last_tick - self.boot_time) * self.options.speedup >= self.options.gps_fix_after

    def _home_item(self) -> WireItem:
        lat, lon, alt = self.options.home if self.has_fix else (0.0, 0.0, 0.0)
        frame = mavlink.MAV_FRAME_GLOBAL
        return WireItem(seq=0, frame=frame, command=mavlink.MAV_CMD_NAV_WAYPOINT, current=0, autocontinue=1,
                        param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=encode_xy(frame, lat),
                        y=encode_xy(frame, lon), z=float(alt), mission_type=int(MissionType.MISSION))

    def reboot(self, now: float, offline: float | None = None) -> None:
        """Forget every mission and the flight, and say nothing for `offline` seconds."""
        if self.killed:
            return
        self.reboots += 1
        if self.upload is not None:
            self.uploads_failed += 1
        self._boot(now + (self.reboot_offline if offline is None else offline))
        self.offline_until = now + (self.reboot_offline if offline is None else offline)

    def kill(self) -> None:
        """Silent for good, as a killed SITL process: no message sent, none heard, nothing flown."""
        self.killed = True
        self.upload = None

    @property
    def online(self) -> bool:
        return self.offline_until <= 0.0 and not self.killed

    def mission(self, mission_type: int = MissionType.MISSION) -> list[WireItem]:
        items = list(self.stores[int(mission_type)])
        if items and self.flavour.has_home_item(int(mission_type)):
            items[0] = self._home_item()  # the home as it is now
        return items

    @property
    def first_mission_seq(self) -> int:
        return 1 if self.flavour.has_home_item(MissionType.MISSION) else 0

    def _load_flight(self) -> None:
        self.flight.load(self.stores[MissionType.MISSION], self.first_mission_seq)

    # ------------------------------------------------------------------------------ sending
    def _time_boot_ms(self, now: float) -> int:
        # Simulated time, as ArduCopter SITL stamps its messages (a sped-up clock runs faster than ours).
        return max(int((now - self.boot_time) * self.options.speedup * 1000), 0)

    def _custom_mode(self) -> int:
        table = ARDUPILOT_MODES if self.flavour is Flavour.ARDUPILOT else PX4_MODES
        return table.get(self.flight.state.mode, 0)

    def send_heartbeat(self) -> None:
        s = self.flight.state
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
        sensors = 0x0020_FFFF | mavlink.MAV_SYS_STATUS_PREARM_CHECK  # the usual sensors (bits 0-15, 21) and pre-arm
        health = sensors if self.ready else sensors & ~mavlink.MAV_SYS_STATUS_PREARM_CHECK
        millivolts, centiamps = PX4_BATTERY_MV, 1_000
        if self.flavour is Flavour.ARDUPILOT:  # SITL: SIM_BATT_VOLTAGE, current only while the motors run
            millivolts = int(round(self.battery_voltage * 1000))
            centiamps = int(BATTERY_CURRENT_A * 100) if self.flight.state.armed else 0
        self.mav.sys_status_send(sensors, sensors, health, 200, millivolts, centiamps, 90, 0, 0, 0, 0, 0, 0)

    def _send_gps(self, now: float) -> None:
        s = self.flight.state
        fix, sats = (mavlink.GPS_FIX_TYPE_3D_FIX, 12) if self.ready else (mavlink.GPS_FIX_TYPE_NO_FIX, 0)
        self.mav.gps_raw_int_send(int(now * 1e6), fix, int(round(s.lat * 1e7)) if self.ready else 0,
                                  int(round(s.lon * 1e7)) if self.ready else 0,
                                  int(round((s.home[2] + s.alt) * 1000)) if self.ready else 0,
                                  80 if self.ready else 9999, 120 if self.ready else 9999,
                                  int(round(math.hypot(s.vn, s.ve) * 100)), 0, sats)

    def _send_ekf(self, now: float) -> None:
        flags = EKF_FLAGS_READY if self.ready else EKF_FLAGS_WAITING
        self.mav.ekf_status_report_send(flags, 0.01, 0.01, 0.01, 0.01, 0.0)

    def _send_home(self) -> bool:
        """HOME_POSITION, once the home is known (as ArduPilot: not before the EKF has a position)."""
        if not self.ready:
            return False
        lat, lon, alt = self.options.home
        self.mav.home_position_send(int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000)),
                                    0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0)
        return True

    def _send_text(self, text: str, severity: int = mavlink.MAV_SEVERITY_CRITICAL) -> None:
        if self.flavour is not Flavour.PX4 or len(text) <= 50:
            self.mav.statustext_send(severity, text.encode()[:50])
            return
        self._text_id = self._text_id % 65535 + 1  # PX4: a long text in 50-character chunks, one id
        for chunk, start in enumerate(range(0, len(text), 50)):
            self.mav.statustext_send(severity, text[start:start + 50].encode(), self._text_id, chunk)

    def _landed_state(self) -> int:
        s = self.flight.state
        kind = self.flight.motion_kind if s.armed else None
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

    def _send_stream(self, msgid: int, now: float) -> None:
        if msgid == mavlink.MAVLINK_MSG_ID_SYS_STATUS:
            self._send_status(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_GPS_RAW_INT:
            self._send_gps(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            self._send_position(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_MISSION_CURRENT:
            self._send_mission_current()
        elif msgid == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT:
            self._send_ekf(now)
        elif msgid == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            self._send_home()
        elif msgid == mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            self._send_landed_state()

    def _send_position(self, now: float) -> None:
        s = self.flight.state
        home_alt = s.home[2]
        self.mav.global_position_int_send(self._time_boot_ms(now), int(round(s.lat * 1e7)), int(round(s.lon * 1e7)),
                                          int(round((home_alt + s.alt) * 1000)), int(round(s.alt * 1000)),
                                          int(round(s.vn * 100)), int(round(s.ve * 100)), int(round(s.vz * 100)),
                                          int(round(s.heading * 100)) % 36000)

    def _send_camera_feedback(self, now: float) -> None:
        """One CAMERA_FEEDBACK per photo taken since the last call, with where it was taken."""
        points = self.flight.state.photo_points
        home_alt = self.flight.state.home[2]
        if not self.camera:  # no camera configured: ArduCopter sends nothing
            self._photos_sent = len(points)
            return
        if self.flavour is Flavour.PX4:
            self._send_image_captured(now, points, home_alt)
            return
        first = 1 if self.options.sitl_like else 0  # ArduPilot's img_idx starts at 1 after a boot
        while self._photos_sent < len(points):
            lat, lon, alt = points[self._photos_sent]
            self._photos_sent += 1
            self._log_photo(now, self._photos_sent - 1 + first, lat, lon, home_alt, alt)
            self.mav.camera_feedback_send(int(now * 1e6), self.sysid, 0, (self._photos_sent - 1 + first) % 65536,
                                          int(round(lat * 1e7)), int(round(lon * 1e7)), home_alt + alt, alt,
                                          0.0, 0.0, self.flight.state.heading, 0.0, 0, self._photos_sent)

    def _log_photo(self, now: float, img_idx: int, lat: float, lon: float, home_alt: float, alt: float) -> None:
        """The onboard log's CAM of a photo (mock_log): what CAMERA_FEEDBACK reports, kept on the vehicle."""
        self.logs.log_photo(img_idx, lat, lon, home_alt + alt, alt, 0.0, 0.0, self.flight.state.heading,
                            self._time_us(now))

    def _time_us(self, now: float) -> int:
        return max(int((now - self.boot_time) * self.options.speedup * 1e6), 0)

    def _send_image_captured(self, now: float, points: list[tuple[float, float, float]], home_alt: float) -> None:
        """PX4 (camera_trigger + camera_feedback): one CAMERA_IMAGE_CAPTURED per photo on the GCS link,
        image_index from 0 after boot (counting on across flights), capture_result 1, no CAMERA_FEEDBACK."""
        while self._photos_sent < len(points):
            lat, lon, alt = points[self._photos_sent]
            self._log_photo(now, self._photos_sent, lat, lon, home_alt, alt)
            # PX4 truncates camera_capture's doubles, and its float32 metres times 1e3f, into the message
            self.mav.camera_image_captured_send(self._time_boot_ms(now), int(now * 1e6), 1, int(lat * 1e7),
                                                int(lon * 1e7), px4_millimetres(home_alt + alt),
                                                px4_millimetres(alt), [1.0, 0.0, 0.0, 0.0], self._photos_sent, 1, b"")
            self._photos_sent += 1

    def _send_mission_current(self, seq: int | None = None) -> None:
        s = self.flight.state
        items = self.stores[MissionType.MISSION]
        total = len(items)
        if total <= self.first_mission_seq:
            state = mavlink.MISSION_STATE_NO_MISSION
        elif s.mission_done:
            state = mavlink.MISSION_STATE_COMPLETE
        elif s.mode == "AUTO" and s.armed:
            state = mavlink.MISSION_STATE_ACTIVE
        else:
            state = mavlink.MISSION_STATE_NOT_STARTED
        self.mav.mission_current_send(s.current if seq is None else seq, total, state, 1 if s.mode == "AUTO" else 0)

    # ------------------------------------------------------------------------------ ticking
    def tick(self, now: float) -> None:
        if self.killed:
            return
        if not self.online:
            if now < self.offline_until:
                self._last_tick = now
                return
            self.offline_until = 0.0  # back from the reboot
            self.boot_time = now
        dt = max(now - self._last_tick, 0.0)
        self._last_tick = now
        if dt > 0 and self.flight.state.armed:
            self._publish(self.flight.advance(dt * self.options.speedup))
            if self.reboot_at_item is not None and any(seq >= self.reboot_at_item for seq in self.reached):
                self.reboot_at_item = None
                self.reboot(now)  # a brown-out in flight: the vehicle is gone, the others fly on
                return
            if self.kill_at_item is not None and any(seq >= self.kill_at_item for seq in self.reached):
                self.kill_at_item = None
                self.kill()  # its process killed in flight: silent for good
                return
            self.consumed_mah += BATTERY_CURRENT_A * dt * self.options.speedup / 3.6
        if self.flavour is Flavour.ARDUPILOT:
            self._check_battery(now)
        self.logs.tick()
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + 1.0
            self.send_heartbeat()
        for msgid, interval in self.intervals.items():
            if interval is not None and now >= self._next_due[msgid]:
                self._next_due[msgid] = now + interval
                self._send_stream(msgid, now)
        if not self.ready and self.flavour is Flavour.ARDUPILOT:
            if not self._said_waiting:
                self._said_waiting = True
                self._send_text(NOT_READY_TEXTS[2], mavlink.MAV_SEVERITY_INFO)
            simulated = (now - self.boot_time) * self.options.speedup
            if simulated >= self._next_prearm_text:  # ArduPilot repeats a failing pre-arm check every 30 s
                self._next_prearm_text = simulated + PREARM_REPEAT_S
                self._send_text(NOT_READY_TEXTS[0])
        if self.intervals.get(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE) is not None \
                and self._landed_state() != self._landed_sent:
            self._send_landed_state()  # at once, not a stream interval late (a sped-up mock's second is long)
        self._send_camera_feedback(now)
        self._upload_timers(now)

    @property
    def battery_voltage(self) -> float:
        """What the battery monitor reads: SITL's simulated battery, a constant SIM_BATT_VOLTAGE."""
        return float(self.params.get("SIM_BATT_VOLTAGE", ARDUPILOT_BATTERY_PARAMS["SIM_BATT_VOLTAGE"]))

    def _battery_arming_problem(self) -> str:
        """ArduPilot refuses to arm below a failsafe voltage (AP_BattMonitor_Backend::arming_checks)."""
        if self.flavour is not Flavour.ARDUPILOT or self.params.get("BATT_MONITOR", 0.0) <= 0:
            return ""
        volts = self.battery_voltage
        for name, param in (("low", "BATT_LOW_VOLT"), ("critical", "BATT_CRT_VOLT")):
            if volts > 0 and 0 < self.params.get(param, 0.0) and volts < self.params[param]:
                return f"{name} voltage failsafe"
        return ""

    def _check_battery(self, now: float) -> None:
        """AP_BattMonitor::check_failsafes (only while armed): a level (low, critical) counts once the
        voltage has stayed below it for more than BATT_LOW_TIMER simulated seconds; each level is
        announced once ("Battery 1 is low ...", "Battery Failsafe") and its action taken
        (Copter::handle_battery_failsafe)."""
        s = self.flight.state
        if not s.armed or self.params.get("BATT_MONITOR", 0.0) <= 0:
            self._low_since = {1: None, 2: None}
            return
        sim = (now - self.boot_time) * self.options.speedup
        volts = self.battery_voltage
        timer = self.params.get("BATT_LOW_TIMER", 10.0)
        levels = {1: ("low", "BATT_LOW_VOLT", "BATT_FS_LOW_ACT"), 2: ("critical", "BATT_CRT_VOLT", "BATT_FS_CRT_ACT")}
        reached = 0
        for level, (_, volt_param, _) in levels.items():
            threshold = self.params.get(volt_param, 0.0)
            if volts > 0 and threshold > 0 and volts < threshold:
                since = self._low_since[level]
                if since is None:
                    self._low_since[level] = sim
                elif timer > 0 and sim - since > timer:
                    reached = level
            else:
                self._low_since[level] = None
        if reached <= self.battery_failsafe:
            return
        self.battery_failsafe = reached
        self.battery_failsafe_sim_time = s.sim_time
        name, _, action_param = levels[reached]
        self._send_text(f"Battery 1 is {name} {volts:.2f}V used {self.consumed_mah:.0f} mAh",
                        mavlink.MAV_SEVERITY_WARNING)
        action = int(self.params.get(action_param, 0.0))
        if s.on_ground and s.mode != "AUTO":  # should_disarm_on_failsafe: landed (AUTO: its mission not started)
            s.armed = False
            self._send_text(f"{BATTERY_FAILSAFE_TEXT} - Disarming", mavlink.MAV_SEVERITY_WARNING)
            self.send_heartbeat()
            return
        self._send_text(BATTERY_FAILSAFE_TEXT, mavlink.MAV_SEVERITY_WARNING)
        if action == 0:
            return
        s.mode = "LAND" if action in (1, 5) else "RTL"  # set_mode_land_with_pause / set_mode_RTL_or_land_with_pause
        self.send_heartbeat()

    def _publish(self, events: list[FlightEvent]) -> None:
        for event in events:
            if event.kind == "current":
                self._send_mission_current(event.seq)  # each change, even several in one step
            elif event.kind == "reached":
                self.reached.append(event.seq)
                seq: int | None = event.seq
                if self.flavour is Flavour.PX4:  # PX4's own way of reporting it (formats.px4_rules.reported_reached)
                    seq = reported_reached([int(item.command) for item in self.flight.items], event.seq)
                if seq is not None:
                    self.mav.mission_item_reached_send(seq)
            elif event.kind in ("landed", "done"):
                self._send_mission_current()
                self.send_heartbeat()

    def _upload_timers(self, now: float) -> None:
        up = self.upload
        if up is None:
            return
        if now - up.last_progress >= self.options.upload_timeout:
            self.upload = None
            self.uploads_failed += 1
            self._ack(up.peer, up.mission_type, mavlink.MAV_MISSION_OPERATION_CANCELLED)  # the old mission stays
            return
        if now - up.last_sent >= self.options.request_interval:
            self._request(up, now)

    # ------------------------------------------------------------------------------ receiving
    def handle(self, msg: Any, now: float) -> None:
        if not self.online:
            return
        target = getattr(msg, "target_system", None)
        if target is not None and target not in (0, self.sysid):
            return  # for another vehicle on the same link
        target_comp = getattr(msg, "target_component", None)
        if target_comp is not None and target_comp not in (mavlink.MAV_COMP_ID_ALL, mavlink.MAV_COMP_ID_AUTOPILOT1):
            return
        kind = msg.get_type()
        handler = _HANDLERS.get(kind)
        if handler is not None:
            handler(self, msg, (msg.get_srcSystem(), msg.get_srcComponent()), now)

    def _ack(self, peer: tuple[int, int], mission_type: int, result: int) -> None:
        self.mav.mission_ack_send(peer[0], peer[1], result, mission_type)

    def _request(self, up: _Upload, now: float) -> None:
        seq = len(up.received)
        if self.options.legacy_requests or (self.flavour is Flavour.PX4 and not self._int_mode):
            self.mav.mission_request_send(up.peer[0], up.peer[1], seq, up.mission_type)
        else:
            self.mav.mission_request_int_send(up.peer[0], up.peer[1], seq, up.mission_type)
        up.last_sent = now

    # -- upload
    def _on_count(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in self.stores:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self.upload is not None and self.upload.peer != peer:
            # ArduPilot's MissionItemProtocol::cancel_upload: another (sysid, compid) is uploading; only it
            # may restart its upload, the others are DENIED until it completes or times out.
            self.denied_transfers += 1
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        count = int(msg.count)
        if count > self.options.max_items:
            self.upload = None
            self._ack(peer, mission_type, mavlink.MAV_MISSION_NO_SPACE)
            return
        if count == 0:
            self.upload = None
            self._commit(mission_type, [], peer, now)
            return
        # A new (or repeated) count starts the requests over from item 0.
        self.upload = _Upload(mission_type, count, peer, [], last_sent=now, last_progress=now)
        self._request(self.upload, now)

    def _check_item(self, item: WireItem) -> int:
        """The MAV_MISSION_RESULT an item earns: ACCEPTED or why not."""
        frame, command = item.frame, item.command
        if self.flavour is Flavour.PX4:
            result = item_result(item)  # PX4's frame / command matrix, measured on SIH
            if result != mavlink.MAV_MISSION_ACCEPTED:
                return result
        elif item.mission_type == MissionType.FENCE:
            if command not in FENCE_COMMANDS:
                return mavlink.MAV_MISSION_UNSUPPORTED
        elif item.mission_type == MissionType.RALLY:
            if command != mavlink.MAV_CMD_NAV_RALLY_POINT:
                return mavlink.MAV_MISSION_UNSUPPORTED
        elif command in MISSION_COMMANDS_REJECTED:
            return mavlink.MAV_MISSION_UNSUPPORTED
        if frame not in GLOBAL_FRAMES and frame != mavlink.MAV_FRAME_MISSION:
            return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
        if frame in GLOBAL_FRAMES:
            if abs(item.x) > 900_000_000:
                return mavlink.MAV_MISSION_INVALID_PARAM5_X
            if abs(item.y) > 1_800_000_000:
                return mavlink.MAV_MISSION_INVALID_PARAM6_Y
        if not all(math.isfinite(v) or math.isnan(v) for v in (item.param1, item.param2, item.param3, item.param4)):
            return mavlink.MAV_MISSION_ERROR
        return mavlink.MAV_MISSION_ACCEPTED

    def _on_item(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        self._int_mode = msg.get_type() == "MISSION_ITEM_INT"
        item = WireItem.from_message(msg)
        up = self.upload
        if up is None or up.peer != peer or up.mission_type != item.mission_type:
            done = self.last_completed
            if self.flavour is Flavour.ARDUPILOT:
                if up is not None and up.peer != peer and up.mission_type == item.mission_type:
                    # MissionItemProtocol::handle_mission_item: the sequence first, then the sender
                    self.denied_transfers += item.seq == len(up.received)
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE
                              if item.seq != len(up.received) else mavlink.MAV_MISSION_DENIED)
                    return
                if up is None:
                    # ArduPilot: "mission item received while not receiving", even for a copy of the
                    # last item of an upload that just completed (its ACCEPTED is not repeated).
                    self.stray_item_acks += done is not None
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ERROR)
                return
            if done is not None and done[0] == item.mission_type and done[2] == peer and item.seq < done[1]:
                if item.seq == done[1] - 1:
                    # the last item again: our ACK was lost
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ACCEPTED)
                return  # a late copy of an item of the finished upload
            if up is None:
                # no upload in progress (after a reboot, say)
                self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ERROR)
            return
        if item.seq != len(up.received):
            if self.flavour is Flavour.ARDUPILOT:  # ArduPilot complains about any item it did not ask for
                self.invalid_sequence_acks += 1
                self._ack(peer, up.mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return  # out of order or repeated: the timer re-requests what is missing
        result = self._check_item(item)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.upload = None
            self.uploads_failed += 1
            self._ack(peer, up.mission_type, result)
            return
        up.received.append(item)
        up.last_progress = now
        if self.reboot_after_items is not None and len(up.received) >= self.reboot_after_items:
            self.reboot_after_items = None
            self.reboot(now)
            return
        if len(up.received) == up.count:
            self.upload = None
            self._commit(up.mission_type, up.received, peer, now)
        else:
            self._request(up, now)

    def _commit(self, mission_type: int, items: list[WireItem], peer: tuple[int, int], now: float) -> None:
        """The upload completed: the new list replaces the old one."""
        stored = [self._stored(replace(it, current=0)) for it in items]
        if self.flavour.has_home_item(mission_type):
            # ArduPilot keeps its own home as item 0, whatever was uploaded there.
            stored = [self._home_item()] + stored[1:]
        self.stores[mission_type] = stored
        self.uploads_completed += 1
        self.last_completed = (mission_type, len(items), peer)
        if mission_type == MissionType.MISSION:
            self.mission_checked_at = now + (self.options.mission_check_s or 0.0) / self.options.speedup
            s = self.flight.state
            if s.armed and not s.on_ground:
                self._replaced_in_flight(items)
            else:
                s.current = self.first_mission_seq
                s.mission_done = False
                self._load_flight()
        self._ack(peer, mission_type, mavlink.MAV_MISSION_ACCEPTED)
        self._send_mission_current()
        if mission_type == MissionType.FENCE and self.flavour is Flavour.PX4 and fence_problems(
                stored, self.options.home[:2]):
            self._send_text(GEOFENCE_WITHOUT_HOME)  # as PX4 says it right after such a fence upload

    def _stored(self, item: WireItem) -> WireItem:
        # ArduPilot keeps what its storage has room for (formats.readback.ardupilot_stored, measured on
        # ArduCopter SITL: no NAV_WAYPOINT param2, frame 0 for DO_* ...); PX4 what formats.px4_rules.px4_stored
        # says (frames 3 -> 6, 0 -> 5, no pass radius; measured on PX4 SIH); others keep what they got.
        if self.flavour is Flavour.ARDUPILOT:
            return ardupilot_stored(item)
        return px4_stored(item) if self.flavour is Flavour.PX4 else item

    def start_refusals(self) -> list[str]:
        """Why PX4 would refuse to start the stored mission (formats.px4_rules), from this vehicle's home;
        empty for other flavours and for a mission PX4 would start."""
        if self.flavour is not Flavour.PX4:
            return []
        if not self.ready:  # measured on SIH: until "Ready for takeoff!" every start is "No valid mission"
            return ["no home position yet"]
        return start_refusals(self.stores[MissionType.MISSION], self.options.home[:2],
                              self.params.get("MIS_DIST_1WP", MIS_DIST_1WP_DEFAULT))

    def _on_gcs_ack(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        up = self.upload
        if up is not None and up.peer == peer and int(getattr(msg, "mission_type", 0)) == up.mission_type:
            if self.flavour is Flavour.PX4 \
                    and int(msg.type) not in (mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_OPERATION_CANCELLED):
                # PX4 (mavlink_mission.cpp): an error answer to its request means "ask the other way":
                # MAVSDK refuses the legacy MISSION_REQUEST, and PX4 asks again with MISSION_REQUEST_INT.
                self._int_mode = not self._int_mode
                self._request(up, now)
                return
            if int(msg.type) != mavlink.MAV_MISSION_ACCEPTED:
                self.upload = None  # the ground station cancelled: keep the old mission
                self.uploads_failed += 1

    # -- download
    def _receiving(self, mission_type: int) -> bool:
        """ArduPilot: an upload of this type is in progress (MissionItemProtocol `receiving`)."""
        up = self.upload
        return self.flavour is Flavour.ARDUPILOT and up is not None and up.mission_type == mission_type

    def _on_request_list(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in self.stores:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self._receiving(mission_type):  # "someone is uploading a mission; reject fetching of points"
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        self.mav.mission_count_send(peer[0], peer[1], len(self.stores[mission_type]), mission_type)

    def _on_request(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        store = self.stores.get(mission_type)
        if store is None:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        seq = int(msg.seq)
        self._int_mode = msg.get_type() == "MISSION_REQUEST_INT"
        if self._int_mode and self._receiving(mission_type):  # ArduPilot checks this for the *_INT request only
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        if not 0 <= seq < len(store):
            self._ack(peer, mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        stored = self._home_item() if seq == 0 and self.flavour.has_home_item(mission_type) else store[seq]
        # ArduPilot marks no item current in a download; PX4 marks the one it is at (and item 0 of its
        # fence and rally lists).
        current = self.flavour is not Flavour.ARDUPILOT and seq == (self.flight.state.current if mission_type == 0
                                                                     else 0 if self.flavour is Flavour.PX4 else -1)
        item = replace(stored, seq=seq, current=int(current))
        if msg.get_type() == "MISSION_REQUEST":  # legacy request: legacy float item
            x = item.x / 1e7 if item.frame in GLOBAL_FRAMES else float(item.x)
            y = item.y / 1e7 if item.frame in GLOBAL_FRAMES else float(item.y)
            self.mav.mission_item_send(peer[0], peer[1], seq, item.frame, item.command, item.current,
                                       item.autocontinue, item.param1, item.param2, item.param3, item.param4,
                                       x, y, item.z, mission_type)
        else:
            self.mav.mission_item_int_send(peer[0], peer[1], **item.fields())

    # -- clear, set current
    def _on_clear_all(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        types = list(self.stores) if mission_type == MissionType.ALL else [mission_type]
        if any(t not in self.stores for t in types):
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        up = self.upload
        if self.flavour is Flavour.ARDUPILOT and up is not None and up.mission_type in types:
            if up.peer != peer:  # MissionItemProtocol::handle_mission_clear_all: cancel_upload refused
                self.denied_transfers += 1
                self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
                self._ack(peer, mission_type, mavlink.MAV_MISSION_ERROR)
                return
            self.upload = None  # its own upload: cancelled, then cleared
        if self.flight.state.armed and self.flight.state.mode == "AUTO" and MissionType.MISSION in types:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)  # not while flying it
            return
        for t in types:
            self.stores[t] = [self._home_item()] if self.flavour.has_home_item(t) else []
        if MissionType.MISSION in types:
            self.flight.state.current = self.first_mission_seq
            self._load_flight()
        self._ack(peer, mission_type, mavlink.MAV_MISSION_ACCEPTED)

    def _replaced_in_flight(self, received: list[WireItem]) -> None:
        """A mission replaced while the vehicle flies (measured: docs/live-retasking.md). ArduPilot keeps
        its current index; flying its mission, it restarts the item now there when the navigation
        items from it on changed ("Auto mission changed, restarted command"), and past the new end it
        finishes the item it flies ("... but failed to restart command"); out of AUTO, it resumes there
        (from the first item when that index is gone). PX4 takes the item flagged `current` in the
        upload (else keeps its index, within the new mission) and, in mission mode, flies from it at once."""
        s, flight = self.flight.state, self.flight
        flying_mission = s.mode == "AUTO" and not s.mission_done
        new = self.stores[MissionType.MISSION]
        old, index = flight.items, s.current
        self._restart_on_auto = False
        if self.flavour is not Flavour.ARDUPILOT:
            if new == old:
                return  # the same mission (PX4: the same checksum): nothing changes
            flagged = [it.seq for it in received if it.current]
            target = flagged[-1] if flagged else min(index, len(new) - 1)
            self._load_flight()
            s.current = target
            s.mission_done = False
            if flying_mission:
                self._publish(flight.set_current(target))
            return
        if index >= len(new):
            if flying_mission:  # the item flown stays loaded; after it the mission is complete
                self._send_text("Auto mission changed but failed to restart command")
                flight.last_seq = index
                self._flight_stale = True
            else:
                self._load_flight()
                s.current = index  # still reported (MISSION_CURRENT), as SITL does, until set or resumed
                self._restart_on_auto = True  # AP_Mission::resume: its item is gone, start() again
            return
        self._load_flight()
        s.current = index
        if flying_mission and _next_nav(old, index) != _next_nav(new, index):
            self._send_text("Auto mission changed, restarted command")
            self._publish(flight.set_current(index))

    def _set_current(self, seq: int) -> bool:
        if not 0 <= seq < len(self.stores[MissionType.MISSION]):
            return False
        if self._flight_stale:  # still finishing an item of the replaced mission: the new one from now on
            self._flight_stale = False
            self._load_flight()
            self.flight.last_seq = None
        self._restart_on_auto = False
        self.flight.set_current(max(seq, self.first_mission_seq))
        self._send_mission_current()
        return True

    def _on_set_current(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        if not self._set_current(int(msg.seq)):
            self._send_mission_current()  # unchanged: the ground station sees its request failed

    # -- commands
    def _on_set_mode(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        self._apply_mode(int(msg.custom_mode), None, now)

    def _apply_mode(self, custom: int, px4_sub: int | None, now: float) -> bool:
        if self.flavour is Flavour.ARDUPILOT:
            names = {v: k for k, v in ARDUPILOT_MODES.items()}
            name = names.get(custom)
        else:
            if px4_sub is not None:  # DO_SET_MODE: param2 main mode, param3 sub mode
                custom = (custom << 16) | (px4_sub << 24)
            names = {v: k for k, v in PX4_MODES.items()}
            name = names.get(custom)
        if name is None:
            return False
        s = self.flight.state
        if name == "AUTO":
            if len(self.stores[MissionType.MISSION]) <= self.first_mission_seq:
                return False
            if self.flavour is Flavour.PX4 and now < self.mission_checked_at:  # not checked yet
                self._send_text(PX4_MISSION_MODE_REFUSED)
                return False
            if self._restart_on_auto:
                self._restart_on_auto = False
                self.flight.set_current(self.first_mission_seq)
            s.mode = "AUTO"
            s.mission_done = False
        else:
            s.mode = name
        self.send_heartbeat()
        return True

    def _on_command(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        command = int(msg.command)
        p = [float(getattr(msg, f"param{i}", 0.0) or 0.0) for i in range(1, 8)]
        result = self._command(command, p, now)
        self.mav.command_ack_send(command, result, 0, 0, peer[0], peer[1])
        if self._reboot_pending:
            self._reboot_pending = False
            self.reboot(now)

    def _command(self, command: int, p: list[float], now: float) -> int:
        s = self.flight.state
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] >= 0.5:
                if not self.ready and int(p[1]) != FORCE_ARM_DISARM and self.flavour is Flavour.PX4:
                    for text in PX4_NOT_READY_TEXTS:  # PX4 before "Ready for takeoff!"
                        self._send_text(text)
                    return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
                if not self.ready and int(p[1]) != FORCE_ARM_DISARM:  # ArduCopter before its EKF uses the GPS
                    for text in NOT_READY_TEXTS[:2]:
                        self._send_text(text)
                    return mavlink.MAV_RESULT_FAILED
                if (problem := self._battery_arming_problem()) and int(p[1]) != FORCE_ARM_DISARM:
                    self._send_text(f"PreArm: Battery 1 {problem}")  # AP_BattMonitor_Backend::arming_checks
                    return mavlink.MAV_RESULT_FAILED
                s.armed = True
                self.logs.on_armed("ArduCopter V4.7.0-dev (mock)", self._time_us(now))  # a new log (mock_log)
            else:
                if not s.on_ground and int(p[1]) != FORCE_ARM_DISARM:  # a forced disarm stops it in flight
                    return mavlink.MAV_RESULT_DENIED
                s.armed = False
            self.send_heartbeat()
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            ok = self._apply_mode(int(p[1]), int(p[2]) if self.flavour is not Flavour.ARDUPILOT else None, now)
            return mavlink.MAV_RESULT_ACCEPTED if ok else mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_MISSION_START:
            if len(self.stores[MissionType.MISSION]) <= self.first_mission_seq:
                return mavlink.MAV_RESULT_DENIED
            if self.start_refusals() or now < self.mission_checked_at:  # PX4's mission checks (formats.px4_rules)
                self._send_text(START_DENIED)
                return mavlink.MAV_RESULT_DENIED
            if not s.armed:
                return mavlink.MAV_RESULT_DENIED
            if s.mode == "AUTO" and not s.mission_done and not s.on_ground:
                # already flying it: like ArduCopter, a repeated start does not restart
                return mavlink.MAV_RESULT_ACCEPTED
            first = int(p[0]) if p[0] > 0 else None
            last = int(p[1]) if p[1] > 0 else None
            self._publish(self.flight.start_mission(first, last))
            self.send_heartbeat()
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN and self.options.sitl_like:  # param1 = 1 reboots
            if int(p[0]) != 1:
                return mavlink.MAV_RESULT_UNSUPPORTED
            if s.armed:
                return mavlink.MAV_RESULT_DENIED
            self._reboot_pending = True  # after the acknowledgement has gone out
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
            return mavlink.MAV_RESULT_ACCEPTED if self._set_current(int(p[0])) else mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            s.mode = "RTL"
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_NAV_LAND:
            s.mode = "LAND"
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_GET_HOME_POSITION or (command == mavlink.MAV_CMD_REQUEST_MESSAGE
                                                             and int(p[0]) == mavlink.MAVLINK_MSG_ID_HOME_POSITION):
            # no home yet: nothing to send
            return mavlink.MAV_RESULT_ACCEPTED if self._send_home() else mavlink.MAV_RESULT_FAILED
        if command in (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
            if command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES \
                    or int(p[0]) == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                self._send_version()
                return mavlink.MAV_RESULT_ACCEPTED
            if int(p[0]) == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
                self.send_heartbeat()
                return mavlink.MAV_RESULT_ACCEPTED
            # as ArduPilot answers it
            if int(p[0]) == mavlink.MAVLINK_MSG_ID_MISSION_CURRENT and self.flavour is Flavour.ARDUPILOT:
                self._send_mission_current()
                return mavlink.MAV_RESULT_ACCEPTED
            return mavlink.MAV_RESULT_UNSUPPORTED
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            msgid = int(p[0])
            if msgid not in STREAMS or (msgid == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT
                                        and self.flavour is not Flavour.ARDUPILOT):
                return mavlink.MAV_RESULT_UNSUPPORTED
            interval_us = p[1]
            if interval_us < 0:
                self.intervals[msgid] = None
            elif interval_us == 0:  # the default rate
                position = msgid == mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
                self.intervals[msgid] = 1.0 / self.options.telemetry_hz if position else 1.0
            else:
                self.intervals[msgid] = max(interval_us / 1e6, MIN_STREAM_INTERVAL_S)
            self._next_due[msgid] = now
            return mavlink.MAV_RESULT_ACCEPTED

        return mavlink.MAV_RESULT_UNSUPPORTED

    # -- parameters
    def _send_param(self, name: str, peer: tuple[int, int]) -> None:
        names = sorted(self.params)
        self.mav.param_value_send(name.encode(), float(self.params[name]), mavlink.MAV_PARAM_TYPE_REAL32, len(names),
                                  names.index(name))

    def _on_param_read(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        name = str(msg.param_id).rstrip("\x00")
        if name in self.params:
            self._send_param(name, peer)  # an unknown name gets no answer, as on ArduPilot

    def _on_param_set(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        name = str(msg.param_id).rstrip("\x00")
        if name not in self.params:
            return
        value = float(msg.param_value)
        self.params[name] = value  # stored as given, out of range or not (ArduCopter SITL does the same)
        if name == "WPNAV_RADIUS":
            self.flight.default_acceptance = max(value, 5.0) / 100.0  # AC_WPNav flies at least 5 cm
        if self.flight.copter is not None:  # navigation parameters take effect at once (CAM1_TYPE at boot)
            self.flight.copter = CopterParams.from_params(self.params)
        self._send_param(name, peer)

    def _on_log_request(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        self.logs.handle(msg, peer, self.flight.state.armed)  # the log transfer: mock_log

    def _send_version(self) -> None:
        self.mav.autopilot_version_send(CAPABILITIES, (4 << 24) | (6 << 16), 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                                        0, 0, self.sysid)


def _next_nav(items: list[WireItem], index: int, count: int = 3) -> list[tuple[object, ...]]:
    """The next `count` navigation items from `index` on, as ArduPilot's AP_Mission_ChangeDetector
    compares them (a change in them while in AUTO restarts the current item)."""
    nav = [it for it in items[index:] if it.command <= mavlink.MAV_CMD_NAV_LAST]
    return [(it.command, it.frame, it.param1, it.param2, it.param3, it.param4, it.x, it.y, it.z) for it in nav[:count]]


_HANDLERS = {
    "MISSION_COUNT": MockVehicle._on_count,
    "MISSION_ITEM_INT": MockVehicle._on_item,
    "MISSION_ITEM": MockVehicle._on_item,
    "MISSION_ACK": MockVehicle._on_gcs_ack,
    "MISSION_REQUEST_LIST": MockVehicle._on_request_list,
    "MISSION_REQUEST_INT": MockVehicle._on_request,
    "MISSION_REQUEST": MockVehicle._on_request,
    "MISSION_CLEAR_ALL": MockVehicle._on_clear_all,
    "MISSION_SET_CURRENT": MockVehicle._on_set_current,
    "SET_MODE": MockVehicle._on_set_mode,
    "COMMAND_LONG": MockVehicle._on_command,
    "COMMAND_INT": MockVehicle._on_command,
    "PARAM_REQUEST_READ": MockVehicle._on_param_read,
    "PARAM_SET": MockVehicle._on_param_set,
    "LOG_REQUEST_LIST": MockVehicle._on_log_request,
    "LOG_REQUEST_DATA": MockVehicle._on_log_request,
    "LOG_REQUEST_END": MockVehicle._on_log_request,
}
