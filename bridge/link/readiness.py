"""Before a vehicle flies: its telemetry streams, its readiness, its launch site, arming, a safe stop.

Owns, for one vehicle on a link (a Link or a link.shared_link.VehicleLink):
- request_streams: ArduPilot sends nothing beyond HEARTBEAT until asked (all MAVn_* stream rates are
  0), so every message the ground station reads is asked for by MAV_CMD_SET_MESSAGE_INTERVAL:
  SYS_STATUS, GPS_RAW_INT, EKF_STATUS_REPORT, HOME_POSITION (readiness), GLOBAL_POSITION_INT and
  MISSION_CURRENT (following the flight). MISSION_ITEM_REACHED, STATUSTEXT and CAMERA_FEEDBACK are
  events, sent without asking;
- VehicleState: what those messages say (GPS fix, EKF flags, home, pre-arm checks, armed, mode: from its
  autopilot's HEARTBEAT only, is_autopilot_heartbeat) and the vehicle's own STATUSTEXT reasons, and which
  MAVLink cameras beside the autopilot were heard (camera_check);
- wait_ready: until the vehicle has a 3-D GPS fix, a home position, (ArduPilot) an EKF with attitude,
  velocity and absolute position (asked for again while none comes), (when it reports them) passing pre-arm
  checks, and a position estimate that stands still (STEADY_M over STEADY_WINDOW_S: PX4 takes off towards the
  position it had at the start); bounded, with a line each time what it waits for changes. ArduCopter SITL needs
  35-40 simulated seconds;
- launch_offset_m / site_problem: how far the vehicle's home is from the plan's launch point
  (plannedHomePosition): a plan for another site, or two vehicles with swapped system ids;
- arm: COMPONENT_ARM_DISARM, retried while the vehicle refuses with TEMPORARILY_REJECTED or FAILED
  (ArduPilot's answer while a pre-arm check still fails), with the reasons it gave; each try once the
  vertical velocity estimate is at rest (wait_still: PX4 otherwise believes it is already flying);
- make_safe: a vehicle that will not fly is left disarmed and out of AUTO, and we say how it was left.

PX4 (learned from the HEARTBEAT's autopilot field): its modes are custom modes with a main mode in
bits 16-23 and a sub mode in bits 24-31 of custom_mode (AUTO = 4 with LOITER 3 ("HOLD"), MISSION 4,
TAKEOFF 2, RTL 5, LAND 6); DO_SET_MODE takes base mode 1 (custom), param2 the main and param3 the
sub mode (px4_mode). It sends EXTENDED_SYS_STATE (landed state) and a home position from boot on, long
before it can fly: it refuses arming with TEMPORARILY_REJECTED and a STATUSTEXT ("Preflight Fail:
...") until its estimator has settled ("Ready for takeoff!", tens of seconds after boot), so arming
is retried. Its long STATUSTEXTs come in 50-character chunks (MAVLink 2 `id` / `chunk_seq`), joined
here before they are said.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .connection import VehicleInfo, mavlink
from .camera_check import is_camera_heartbeat
from ..formats.mission_items import Flavour

# EKF_STATUS_REPORT flags an ArduPilot EKF needs before it can fly a mission: attitude, horizontal
# and vertical velocity, absolute horizontal and vertical position; and not in constant-position
# mode (no GPS yet) nor uninitialised.
EKF_NEEDED = (mavlink.EKF_ATTITUDE | mavlink.EKF_VELOCITY_HORIZ | mavlink.EKF_VELOCITY_VERT | mavlink.EKF_POS_HORIZ_ABS
              | mavlink.EKF_POS_VERT_ABS)
EKF_BAD = mavlink.EKF_CONST_POS_MODE | mavlink.EKF_UNINITIALIZED
# ArduCopter's custom_mode numbers (its own mode list, not a MAVLink enum) and PX4's main / sub modes
# (px4_custom_mode.h): both autopilots' own numbering.
ARDUPILOT_AUTO, ARDUPILOT_GUIDED, ARDUPILOT_LOITER, ARDUPILOT_RTL, ARDUPILOT_LAND = 3, 4, 5, 6, 9
ARDUPILOT_MODE_NAMES = {0: "STABILIZE", 2: "ALT_HOLD", ARDUPILOT_AUTO: "AUTO", ARDUPILOT_GUIDED: "GUIDED",
                        ARDUPILOT_LOITER: "LOITER", ARDUPILOT_RTL: "RTL", ARDUPILOT_LAND: "LAND"}
PX4_AUTO_MAIN, PX4_LOITER_SUB, PX4_MISSION_SUB = 4, 3, 4
PX4_TAKEOFF_SUB, PX4_RTL_SUB, PX4_LAND_SUB = 2, 5, 6
PX4_MAIN_NAMES = {1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 5: "ACRO", 6: "OFFBOARD", 7: "STABILIZED"}
PX4_AUTO_NAMES = {PX4_TAKEOFF_SUB: "TAKEOFF", PX4_LOITER_SUB: "HOLD", PX4_MISSION_SUB: "MISSION",
                  PX4_RTL_SUB: "RTL", PX4_LAND_SUB: "LAND"}
STATUSTEXT_CHUNK = 50  # characters in one STATUSTEXT: a full one may be continued (same id, next chunk_seq)
CHUNK_WAIT_S = 1.0     # a started text waits this long for its next chunk
EARTH_RADIUS_M = 6_378_137.0
DEFAULT_LAUNCH_OFFSET_M = 5.0  # plus the GPS's own horizontal error
ARM_RETRY_S = 1.0
HOME_ASK_S = 2.0   # re-ask for HOME_POSITION this often while it is unknown
# ArduPilot: ask for the EKF_STATUS_REPORT stream again this often while none has come (a request lost on the way).
EKF_ASK_S = 3.0
READY_RATES_HZ = {mavlink.MAVLINK_MSG_ID_SYS_STATUS: 1.0, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
                  mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 1.0, mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
                  mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: 2.0,
                  # where the camera points, for the photos' geotags (ArduPilot sends it only when asked)
                  mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: 2.0}
STREAM_NAMES = {mavlink.MAVLINK_MSG_ID_SYS_STATUS: "SYS_STATUS", mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: "GPS_RAW_INT",
                mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: "GLOBAL_POSITION_INT",
                mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: "MISSION_CURRENT",
                mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: "EKF_STATUS_REPORT",
                mavlink.MAVLINK_MSG_ID_HOME_POSITION: "HOME_POSITION",
                mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: "EXTENDED_SYS_STATE",
                mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: "GIMBAL_DEVICE_ATTITUDE_STATUS"}
TEXTS_KEPT = 20
# A vehicle is ready only once its position estimate stands still on the ground: moved at most STEADY_M
# over the last STEADY_WINDOW_S of its own clock. Why: PX4 takes off towards where it believed it was at
# the mission start, and its trajectory generator waits while the vehicle is more than MPC_XY_ERR_MAX
# (2 m) from it. Right after "Ready for takeoff!" PX4's global position may still converge by metres
# (SIH: 0.9-2.5 m within 6 s); if it moves 2 m while the vehicle is on the ground, the vehicle, which
# cannot slide over the ground, sits armed and tilted for minutes (SIH: 220 s) before it climbs. A
# settled estimate wanders less than 0.8 m in 5 s (SIH's GPS noise).
STEADY_WINDOW_S = 5.0
STEADY_M = 1.0
# Arm only while the vertical velocity estimate is at rest (or after QUIET_WAIT_S anyway). Why: at the
# start PX4 asks its land detector whether the vehicle already flies; an estimate moving faster than
# LNDMC_Z_VEL_MAX (0.25 m/s) says yes, and PX4 then flies the take-off as a plain climb, without its
# take-off ramp (SIH: first waypoint after 11.7 s instead of 18.5 s), and may report a take-off that did
# not happen. On SIH that estimate wanders by up to 0.9 m/s on the ground, slowly (tenths per second),
# more the longer after boot: above 0.25 m/s in 0 % of samples before 42 s, 27 % at 46-60 s, 61 % later.
QUIET_CLIMB_M_S = 0.1
QUIET_WAIT_S = 15.0

Say = Callable[[str], None]


def is_autopilot_heartbeat(msg: Any) -> bool:
    """A HEARTBEAT that speaks for the vehicle's flight (armed, mode): an autopilot's, not a ground station's nor one
    of a component beside it (a MAVLink camera or gimbal says MAV_AUTOPILOT_INVALID, base_mode 0: not disarmed)."""
    return msg.type != mavlink.MAV_TYPE_GCS and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID


def stream_rates(telemetry_hz: float, flavour: Flavour = Flavour.ARDUPILOT) -> dict[int, float]:
    """Every stream fly reads, in Hz: readiness and progress at low rates, positions at telemetry_hz;
    on PX4 also EXTENDED_SYS_STATE (its landed state: PX4's relative altitude drifts by decimetres
    on the ground) and no EKF_STATUS_REPORT (an ArduPilot message)."""
    rates = {**READY_RATES_HZ, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: float(telemetry_hz)}
    if flavour is Flavour.PX4:
        del rates[mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT]
        rates[mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE] = 2.0
    return rates


def px4_mode(main: int, sub: int = 0) -> int:
    """A PX4 custom_mode from its main and sub mode."""
    return (main << 16) | (sub << 24)


def mode_params(*custom: int) -> list[float]:
    """DO_SET_MODE's params for a custom mode: ArduPilot's mode number, or PX4's main and sub mode."""
    return [float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), *map(float, custom)]


def mission_mode_params(flavour: Flavour) -> list[float]:
    """DO_SET_MODE's params of the mode a mission flies in: ArduPilot AUTO, PX4 AUTO.MISSION."""
    if flavour is Flavour.ARDUPILOT:
        return mode_params(ARDUPILOT_AUTO)
    return mode_params(PX4_AUTO_MAIN, PX4_MISSION_SUB)


def request_streams(link: Any, sysid: int, rates_hz: dict[int, float], deadline: float,
                    other: Callable[[Any], Any] | None = None) -> list[str]:
    """SET_MESSAGE_INTERVAL for each message id; the names of the streams the vehicle did not accept.
    The vehicle's other messages meanwhile go to `other` (the first of each stream among them)."""
    refused: list[str] = []
    for msgid, hz in rates_hz.items():
        result = link.command_long(sysid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [float(msgid), 1e6 / hz], deadline,
                                   other=other)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            refused.append(STREAM_NAMES.get(msgid, str(msgid)))
    return refused


@dataclass
class VehicleState:
    """What one vehicle's telemetry says about its readiness (None: not heard yet)."""

    flavour: Flavour
    fix_type: int | None = None
    satellites: int | None = None
    h_acc_m: float | None = None      # GPS horizontal accuracy, when the receiver reports one
    ekf_flags: int | None = None
    home: tuple[float, float, float] | None = None  # lat, lon, alt AMSL (m)
    prearm_ok: bool | None = None     # None: the vehicle does not report its pre-arm checks
    armed: bool | None = None
    custom_mode: int | None = None
    base_mode: int = 0
    landed_state: int | None = None   # EXTENDED_SYS_STATE (PX4): 1 on the ground, 2 in the air, 3 taking off, 4 landing
    texts: list[str] = field(default_factory=list)  # STATUSTEXT, oldest first
    new_texts: list[str] = field(default_factory=list)  # not yet said
    texts_total: int = 0  # how many STATUSTEXT lines have come, all told (texts keeps the last few)
    # GLOBAL_POSITION_INT of the last STEADY_WINDOW_S and one before: vehicle seconds, lat, lon
    positions: deque[tuple[float, float, float]] = field(default_factory=deque)
    climb_m_s: float | None = None  # the latest vertical velocity estimate (up), GLOBAL_POSITION_INT
    cameras: set[int] = field(default_factory=set)  # component ids of the MAVLink cameras heard (their HEARTBEAT)
    _chunks: tuple[int, str, float] | None = None  # a STATUSTEXT waiting for its next chunk: id, text, since

    def take(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "GPS_RAW_INT":
            self.fix_type, self.satellites = int(msg.fix_type), int(msg.satellites_visible)
            h_acc = int(getattr(msg, "h_acc", 0) or 0)  # mm; 0 when not reported
            self.h_acc_m = h_acc / 1000.0 if h_acc > 0 else None
        elif kind == "EKF_STATUS_REPORT":
            self.ekf_flags = int(msg.flags)
        elif kind == "HOME_POSITION":
            if msg.latitude or msg.longitude:
                self.home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
        elif kind == "SYS_STATUS":
            if msg.onboard_control_sensors_present & mavlink.MAV_SYS_STATUS_PREARM_CHECK:
                self.prearm_ok = bool(msg.onboard_control_sensors_health & mavlink.MAV_SYS_STATUS_PREARM_CHECK)
        elif kind == "HEARTBEAT" and is_camera_heartbeat(msg):
            self.cameras.add(int(msg.get_srcComponent()))
        elif kind == "HEARTBEAT" and is_autopilot_heartbeat(msg):
            self.base_mode = int(msg.base_mode)
            self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            self.custom_mode = int(msg.custom_mode)
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = int(msg.landed_state)
        elif kind == "GLOBAL_POSITION_INT":
            self._position(msg.time_boot_ms / 1000.0, msg.lat / 1e7, msg.lon / 1e7)
            self.climb_m_s = -msg.vz / 100.0
        if kind == "STATUSTEXT":
            self._statustext(msg)
        elif self._chunks is not None and time.monotonic() - self._chunks[2] > CHUNK_WAIT_S:
            self._said(self._chunks[1])  # its next chunk never came
            self._chunks = None

    def _position(self, t: float, lat: float, lon: float) -> None:
        if lat == 0.0 and lon == 0.0:
            return  # no estimate yet (ArduPilot sends zeros until its EKF has an origin)
        if self.positions and t < self.positions[-1][0]:
            self.positions.clear()  # the vehicle's clock restarted: a reboot
        self.positions.append((t, lat, lon))
        while len(self.positions) > 1 and self.positions[1][0] <= t - STEADY_WINDOW_S:
            self.positions.popleft()  # the oldest kept is the last one at least a window old

    def position_wander_m(self) -> float | None:
        """How far the position estimate moved over the last STEADY_WINDOW_S: the farthest of those
        positions from the newest (None: not reported for that long yet)."""
        if not self.positions or self.positions[-1][0] - self.positions[0][0] < STEADY_WINDOW_S:
            return None
        _, lat, lon = self.positions[-1]
        return max(ground_distance_m((lat, lon), (a, b)) for _, a, b in self.positions)

    def _statustext(self, msg: Any) -> None:
        """One STATUSTEXT, or one chunk of a long one: chunks with the same id (not 0) are joined."""
        raw = str(msg.text).rstrip("\x00")
        text_id, chunk = int(getattr(msg, "id", 0) or 0), int(getattr(msg, "chunk_seq", 0) or 0)
        if self._chunks is not None:
            pending_id, pending, _ = self._chunks
            self._chunks = None
            if text_id == pending_id and chunk > 0:
                raw = pending + raw
            else:
                self._said(pending)
        if text_id and len(raw) % STATUSTEXT_CHUNK == 0 and raw:  # full: more may follow
            self._chunks = (text_id, raw, time.monotonic())
            return
        self._said(raw)

    def _said(self, raw: str) -> None:
        text = raw.strip()
        if text:
            self.texts = (self.texts + [text])[-TEXTS_KEPT:]
            self.texts_total += 1
            self.new_texts.append(text)

    @property
    def ekf_ok(self) -> bool:
        flags = self.ekf_flags
        return flags is not None and flags & EKF_NEEDED == EKF_NEEDED and not flags & EKF_BAD

    def missing(self) -> list[str]:
        """What the vehicle still lacks before it can fly, in words ([] when ready)."""
        out: list[str] = []
        if self.fix_type is None:
            out.append("GPS (no GPS_RAW_INT yet)")
        elif self.fix_type < mavlink.GPS_FIX_TYPE_3D_FIX:
            out.append(f"a 3-D GPS fix (fix type {self.fix_type}, {self.satellites} satellites)")
        if self.flavour is Flavour.ARDUPILOT and not self.ekf_ok:
            out.append("the EKF (no EKF_STATUS_REPORT yet)" if self.ekf_flags is None
                       else f"the EKF (flags 0x{self.ekf_flags:04x})")
        if self.home is None:
            out.append("a home position")
        if self.prearm_ok is False:
            out.append("its pre-arm checks")
        wander = self.position_wander_m()
        if wander is None:
            out.append(f"a position estimate ({STEADY_WINDOW_S:g} s of GLOBAL_POSITION_INT)")
        elif wander > STEADY_M:
            out.append(f"a steady position estimate (moving more than {STEADY_M:g} m in {STEADY_WINDOW_S:g} s)")
        return out

    def reasons(self, last: int = 3) -> str:
        """The vehicle's latest distinct STATUSTEXT lines, for a message."""
        seen: list[str] = []
        for text in reversed(self.texts):
            if text not in seen:
                seen.append(text)
            if len(seen) == last:
                break
        return "; ".join(reversed(seen))

    def mode_name(self) -> str:
        if self.custom_mode is None:
            return "an unknown mode"
        if self.flavour is Flavour.ARDUPILOT:
            return ARDUPILOT_MODE_NAMES.get(self.custom_mode, f"mode {self.custom_mode}")
        main, sub = (self.custom_mode >> 16) & 0xFF, (self.custom_mode >> 24) & 0xFF
        if main == PX4_AUTO_MAIN:
            return PX4_AUTO_NAMES.get(sub, f"AUTO sub-mode {sub}")
        return PX4_MAIN_NAMES.get(main, f"mode {main}.{sub}")

    @property
    def on_ground(self) -> bool | None:
        """What the vehicle's landed state says (None: it does not report one)."""
        if self.landed_state in (None, mavlink.MAV_LANDED_STATE_UNDEFINED):
            return None
        return self.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND

    @property
    def in_auto(self) -> bool:
        if self.custom_mode is None:
            return False
        if self.flavour is Flavour.ARDUPILOT:
            return self.custom_mode == ARDUPILOT_AUTO
        return (self.custom_mode >> 16) & 0xFF == PX4_AUTO_MAIN and (self.custom_mode >> 24) & 0xFF == PX4_MISSION_SUB


class Vehicle:
    """Readiness, arming and the safe stop of one vehicle. `take` may be chained to record telemetry
    that arrives meanwhile (fly keeps the first positions)."""

    def __init__(self, link: Any, info: VehicleInfo, say: Say | None = None,
                 also: Callable[[Any], None] | None = None) -> None:
        self.link, self.info = link, info
        self.sysid = info.sysid
        self.state = VehicleState(info.flavour)
        self.say = say or (lambda text: None)
        self.also = also
        # Answers the vehicle's TERRAIN_REQUESTs whoever reads (VehicleSession.serve_terrain sets it).
        self.terrain: Callable[[Any], Any] | None = None

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid:
            return
        self.state.take(msg)
        if self.terrain is not None and msg.get_type() == "TERRAIN_REQUEST":
            self.terrain(msg)
        for text in self.state.new_texts:
            self.say(f"uav{self.sysid} says: {text}")
        self.state.new_texts.clear()
        if self.also is not None:
            self.also(msg)

    def listen(self, until: float) -> None:
        """Take the vehicle's messages until then."""
        while (msg := self.link.recv(until)) is not None:
            self.take(msg)

    def _ask_home(self) -> None:
        self.link.mav.command_long_send(self.sysid, self.info.compid, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                        float(mavlink.MAVLINK_MSG_ID_HOME_POSITION), 0, 0, 0, 0, 0, 0)

    def _ask_ekf(self) -> None:
        """EKF_STATUS_REPORT once now, and its stream again (no answer awaited: listen takes the ACK)."""
        ekf = float(mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT)
        self.link.mav.command_long_send(self.sysid, self.info.compid, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                        ekf, 0, 0, 0, 0, 0, 0)
        self.link.mav.command_long_send(self.sysid, self.info.compid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                        ekf, 1e6 / READY_RATES_HZ[mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT],
                                        0, 0, 0, 0, 0)

    def wait_ready(self, deadline: float) -> list[str]:
        """Until ready or deadline: [] when ready, else what is still missing. Says what it waits for
        each time that changes."""
        said: list[str] | None = None
        next_ask = 0.0
        start = time.monotonic()
        next_ekf_ask = start + EKF_ASK_S
        while True:
            missing = self.state.missing()
            if missing != said:
                said = missing
                if missing:
                    self.say(f"uav{self.sysid}: waiting for {', '.join(missing)}")
            if not missing:
                self.say(f"uav{self.sysid}: ready after {time.monotonic() - start:.1f} s")
                return []
            now = time.monotonic()
            if now >= deadline:
                return missing
            if self.state.home is None and now >= next_ask:
                self._ask_home()  # a vehicle that streams no HOME_POSITION sends it when asked
                next_ask = now + HOME_ASK_S
            if self.state.flavour is Flavour.ARDUPILOT and self.state.ekf_flags is None and now >= next_ekf_ask:
                self._ask_ekf()
                next_ekf_ask = now + EKF_ASK_S
            self.listen(min(deadline, now + 0.25))

    def wait_still(self, deadline: float) -> bool:
        """Until the vertical velocity estimate is at rest (QUIET_CLIMB_M_S), at most QUIET_WAIT_S or
        to the deadline; whether it was (a vehicle that reports none counts as at rest)."""
        until = min(deadline, time.monotonic() + QUIET_WAIT_S)
        said = False
        while self.state.climb_m_s is not None and abs(self.state.climb_m_s) > QUIET_CLIMB_M_S:
            if not said:
                said = True
                self.say(f"uav{self.sysid}: waiting for its vertical velocity estimate to settle "
                         f"({self.state.climb_m_s:+.2f} m/s on the ground) before arming")
            if time.monotonic() >= until:
                return False
            self.listen(min(until, time.monotonic() + 0.1))
        return True

    def arm(self, deadline: float) -> tuple[bool, str]:
        """Arm, retrying while the vehicle says it is not ready yet (TEMPORARILY_REJECTED / FAILED, or
        no answer), each time once its vertical velocity estimate is at rest (wait_still); (armed, why not)."""
        last: int | None = None
        tries = 0
        while True:
            tries += 1
            self.wait_still(deadline)
            result = self.link.command_long(self.sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], deadline,
                                            other=self.take)
            if result == mavlink.MAV_RESULT_ACCEPTED:
                return True, ""
            last = result
            if result not in (None, mavlink.MAV_RESULT_TEMPORARILY_REJECTED, mavlink.MAV_RESULT_FAILED):
                break  # DENIED / UNSUPPORTED: asking again will not help
            if time.monotonic() + ARM_RETRY_S >= deadline:
                break
            self.listen(time.monotonic() + ARM_RETRY_S)
        what = "not acknowledged" if last is None else f"refused (MAV_RESULT {last})"
        reasons = self.state.reasons()
        return False, f"arming {what} after {tries} tries" + (f"; the vehicle said: {reasons}" if reasons else "")

    def make_safe(self, deadline: float) -> str:
        """Disarm if armed, leave AUTO if in it; how the vehicle was left, as its last heartbeat says."""
        if self.state.armed:
            self.link.command_long(self.sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0.0], deadline,
                                   other=self.take)
        if self.state.in_auto:
            if self.info.flavour is Flavour.ARDUPILOT:
                params = mode_params(ARDUPILOT_LOITER)
            else:
                params = mode_params(PX4_AUTO_MAIN, PX4_LOITER_SUB)
            self.link.command_long(self.sysid, mavlink.MAV_CMD_DO_SET_MODE, params, deadline, other=self.take)
        # The heartbeat after the commands says what really holds.
        until = min(deadline, time.monotonic() + 1.5)
        while (msg := self.link.recv(until)) is not None:
            self.take(msg)
            if msg.get_type() == "HEARTBEAT":
                break
        armed = {True: "ARMED", False: "disarmed", None: "in an unknown arming state"}[self.state.armed]
        return f"left {armed} in {self.state.mode_name()}, not flown"


def launch_offset_m(home: tuple[float, float], planned: tuple[float, float]) -> float:
    """Great-circle distance in metres between the vehicle's home and the plan's launch point."""
    return ground_distance_m(home, planned)


def ground_distance_m(p: tuple[float, float], q: tuple[float, float]) -> float:
    """Great-circle distance in metres between two (lat, lon) in degrees."""
    lat1, lon1, lat2, lon2 = map(math.radians, (p[0], p[1], q[0], q[1]))
    a = math.sin((lat2 - lat1) / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(a)))


def site_problem(state: VehicleState, planned: tuple[float, float] | None, max_offset_m: float) -> str:
    """'' when the vehicle's home is within max_offset_m (plus its GPS's reported error) of the plan's
    launch point; else one phrase naming the distance."""
    if planned is None:
        return ""
    if state.home is None:
        return "no home position to compare with the plan's launch point"
    gps_error = state.h_acc_m or 0.0
    allowed = max_offset_m + gps_error
    offset = launch_offset_m(state.home[:2], planned)
    if offset <= allowed:
        return ""
    far = f"{offset / 1000:.1f} km" if offset >= 10_000 else f"{offset:.1f} m"
    return (f"its home ({state.home[0]:.6f}, {state.home[1]:.6f}) is {far} from the plan's launch point "
            f"({planned[0]:.6f}, {planned[1]:.6f}); allowed {max_offset_m:g} m"
            + (f" + {gps_error:.1f} m GPS error" if gps_error else "")
            + ": a plan for another site, or swapped system ids?")
