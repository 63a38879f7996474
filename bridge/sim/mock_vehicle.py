"""One simulated vehicle of the mock autopilot: its state, its clock and its faults, and the parts that speak for it.

Owns the vehicle itself: whether it is armed, its mode and its flight (mock_flight's FlightSim, made anew at each
boot), its simulated clock (VehicleOptions.speedup), readiness like ArduCopter SITL's (gps_fix_after simulated
seconds without a GPS fix: a waiting EKF, no home, a failing pre-arm bit, arming refused), its battery, and the
faults: the reboot fault (forget everything, the flight included, and go silent for a moment; in flight once
reboot_at_item is reached, during an upload after reboot_after_items items) and the kill fault (kill(): silent
for good, as a SITL process killed in flight: no message at all any more; also once kill_at_item is reached).
ArduPilot's battery failsafe (AP_BattMonitor + ArduCopter events.cpp): the battery reads SIM_BATT_VOLTAGE
(12.6 V, SITL's default; SYS_STATUS reports it); armed, below BATT_LOW_VOLT (10.5 V) for more than
BATT_LOW_TIMER (10 s) simulated seconds (BATT_CRT_VOLT / BATT_FS_CRT_ACT likewise), it says
"Battery 1 is low 10.00V used 83 mAh" and "Battery Failsafe" (severity WARNING) and does BATT_FS_LOW_ACT:
1 LAND, 2 RTL (3, 4 and 6, SmartRTL / DO_LAND_START, flown as RTL here; 5, terminate, as LAND), or
disarms at once when on the ground; below either voltage it refuses to arm ("PreArm: Battery 1 low
voltage failsafe"). All by PARAM_SET, as on SITL. Wind (SITL's SIM_WIND_SPD, _DIR, _TURB; flight_models.wind) slows
its legs and changes its current (consumed_mah follows it); a GPS glitch (SITL's SIM_GPS1_GLTCH_X / _Y) is gps_glitch's.
MockVehicle takes every message addressed to it (handle) and hands it to the part that answers it, as
QGroundControl's MockLink hands the mission protocol to its MockLinkMissionItemHandler; each part keeps its own
state and reaches the others through the vehicle:
  telemetry         Telemetry: heartbeat, the streams and their intervals, texts, the flight's events, photos
  mission_server    MissionServer: the stored mission, fence and rally lists and the mission protocol
  vehicle_commands  CommandHandler: COMMAND_LONG / COMMAND_INT and SET_MODE
  vehicle_params    ParamServer: the parameter table, PARAM_REQUEST_READ / PARAM_SET
  mock_log          OnboardLogs: the onboard DataFlash log and the LOG_REQUEST_* transfer
  mock_terrain      MockTerrain (ArduPilot over a ground): the terrain database, TERRAIN_REQUEST / _DATA / _CHECK /
                    _REPORT, and its pre-arm check
Over a ground (VehicleOptions.ground, a DEM: geo.dem.Ground) the vehicle lives in a world that is not flat: its
home altitude is the ground's at home, it lands on the ground (mock_flight), and an ArduPilot vehicle flies
terrain-frame items from the terrain it was sent (mock_terrain), never from the ground itself.
The SITL-like mode (VehicleOptions.sitl_like) adds what ArduCopter SITL does in flight: no
CAMERA_FEEDBACK until a camera is configured (CAM1_TYPE set, then a reboot:
MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN), img_idx from 1 and counting on across flights until a reboot,
ArduCopter's navigation parameters (PARAM_REQUEST_READ / PARAM_SET) and its flight
(flight_models.copter_model: acceleration, stops at corners, RTL_ALT climb, slow final descent); on PX4 a mission
check of PX4_MISSION_CHECK_S after each upload. The link and the other faults are mock's. Everything here runs
on the mock's one loop thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..flight_models.copter_model import CopterParams
from ..flight_models.px4_model import Px4Params
from ..flight_models.wind import Wind, WindField
from ..formats.mission_items import Flavour, MissionType, WireItem
from ..link.connection import mavlink
from .gps_glitch import GpsGlitch
from .mission_server import MissionServer, Upload
from .mock_camera import CAMERA_COMPONENT_ID, MockCamera
from .mock_flight import FlightSim
from .mock_log import OnboardLogs
from .mock_terrain import GroundModel, MockTerrain
from .telemetry import Telemetry
from .vehicle_commands import CommandHandler
from .vehicle_params import ARDUPILOT_BATTERY_PARAMS, ParamServer

# PX4 SIH refused a MISSION_START sent right after the upload with "No valid mission" (1 vehicle in 12):
# it takes the new mission after its own checks. How long is not visible on the link; half a second here.
PX4_MISSION_CHECK_S = 0.5
BATTERY_CURRENT_A = 10.0  # drawn while armed (SYS_STATUS current, the "used N mAh" of the failsafe text)
BATTERY_FAILSAFE_TEXT = "Battery Failsafe"  # Copter::announce_failsafe("Battery"), events.cpp
LOG_REQUESTS = frozenset({"LOG_REQUEST_LIST", "LOG_REQUEST_DATA", "LOG_REQUEST_END"})  # the log transfer: mock_log


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
    # The true ground (a DEM; mock_terrain.GroundModel): the home's altitude is the ground's there, the vehicle
    # lands on it, and an ArduPilot vehicle asks the ground station for its terrain. None: a flat world.
    ground: GroundModel | None = None
    # A MAVLink camera beside the autopilot (mock_camera.MockCamera, component MAV_COMP_ID_CAMERA): one
    # CAMERA_IMAGE_CAPTURED from it per photo, besides the autopilot's own report, as ArduCopter SITL (CAM1_TYPE 6)
    # and PX4 SIH (TRIG_INTERFACE 3) do with one; its capture indices that fail (capture_result 0).
    mavlink_camera: bool = False
    camera_failures: tuple[int, ...] = ()

    def resolved(self) -> VehicleOptions:
        ardupilot = self.flavour is Flavour.ARDUPILOT
        home = self.home
        if self.ground is not None and math.isfinite(at_home := ground_amsl(self.ground, home[0], home[1])):
            home = (home[0], home[1], at_home)
        return replace(self, home=home,
                       request_interval=self.request_interval or (1.0 if ardupilot else 0.25),
                       upload_timeout=self.upload_timeout or (8.0 if ardupilot else 5.0),
                       legacy_requests=ardupilot if self.legacy_requests is None else self.legacy_requests,
                       mission_check_s=(self.mission_check_s if self.mission_check_s is not None
                                        else PX4_MISSION_CHECK_S if self.sitl_like and not ardupilot else 0.0))


def ground_amsl(ground: GroundModel, lat: float, lon: float) -> float:
    """The ground's height above sea level at one point (NaN where it has none)."""
    return float(ground.height_amsl(np.array([lat]), np.array([lon]))[0])


class MockVehicle:
    """The state and behaviour of one system id. Call handle() for each message and tick() often."""

    def __init__(self, sysid: int, options: VehicleOptions, encoder: Any, now: float) -> None:
        self.sysid = sysid
        self.handler_errors = 0  # messages whose answer raised (logged, answered with an error: vehicle_part)
        self.options = options.resolved()
        self.flavour = self.options.flavour
        self.mav = encoder  # pymavlink MAVLink with srcSystem=sysid, srcComponent=1, writing to the mock's link
        self.reboots = 0
        self.reboot_after_items: int | None = None
        self.reboot_offline = 0.3
        self.reboot_at_item: int | None = None  # reboot in flight once this mission item is reached
        self.killed = False  # kill(): silent for good
        self.kill_at_item: int | None = None  # kill in flight once this mission item is reached
        # Its parts, each holding its own state; the parameters survive a reboot, like ArduPilot's EEPROM.
        self.param_server = ParamServer(self)
        self.telemetry = Telemetry(self)
        self.mission_server = MissionServer(self)
        self.command_handler = CommandHandler(self)
        # ArduPilot over a ground asks for its terrain; PX4 takes no terrain frame, so it has no terrain database.
        self.terrain = (MockTerrain(self) if self.options.ground is not None and self.flavour is Flavour.ARDUPILOT
                        else None)
        self.wind_seed = sysid  # its gusts' random.Random seed (set_wind may change it)
        self.wind_field: WindField | None = None  # made from the SIM_WIND_* parameters (_follow_wind)
        self.gps_glitch = GpsGlitch(self)
        self.logs = OnboardLogs(self.flavour, encoder, self.telemetry.send_text)  # on its SD card: survives reboots
        # Its camera speaks as its own component on the same link (unsigned: its own MAVLink stack).
        self.mavlink_camera = (MockCamera(mavlink.MAVLink(encoder.file, srcSystem=sysid, srcComponent=CAMERA_COMPONENT_ID),
                                  sysid, fail_indices=self.options.camera_failures)
                       if self.options.mavlink_camera else None)
        self._boot(now)

    # ------------------------------------------------------------------------------ lifecycle
    def _boot(self, now: float) -> None:
        self.logs.on_boot()
        self.boot_time = now
        self._last_tick = now
        self.offline_until = 0.0
        params = self.params
        copter = CopterParams.from_params(params) if self.options.sitl_like else None
        px4 = Px4Params.from_params(params) if self.options.sitl_like and self.flavour is Flavour.PX4 else None
        if self.terrain is not None:
            self.terrain.on_boot(now)
        self.flight = FlightSim(self.options.home, cruise_speed=self.options.cruise_speed, copter=copter, px4=px4,
                                terrain=None if self.terrain is None else self.terrain.terrain_offset,
                                ground=self._ground_above_home if self.options.ground is not None else None)
        if "WPNAV_RADIUS" in params:  # ArduCopter turns within WPNAV_RADIUS of every waypoint
            self.flight.default_acceptance = max(params["WPNAV_RADIUS"], 5.0) / 100.0
        self.flight.wind = self.wind_field
        self.gps_glitch.on_boot()
        self.mission_server.on_boot()  # every list forgotten; the flight takes what is left
        self.telemetry.on_boot(now)
        self.battery_failsafe = 0  # 0 none, 1 low, 2 critical (the highest reached since boot)
        self.consumed_mah = 0.0
        self.battery_failsafe_sim_time: float | None = None  # the flight's simulated time when it acted
        self._low_since: dict[int, float | None] = {1: None, 2: None}  # simulated s: below the level since

    def _ground_above_home(self, lat: float, lon: float) -> float:
        """The true ground at a point above the home's (where the DEM has none: the home's, a flat world)."""
        assert self.options.ground is not None
        height = ground_amsl(self.options.ground, lat, lon)
        return height - self.options.home[2] if math.isfinite(height) else 0.0

    @property
    def ready(self) -> bool:
        """GPS fix, EKF and home: before it, arming is refused with ArduCopter's reasons."""
        return self.has_fix

    @property
    def has_fix(self) -> bool:
        """Whether the simulated GPS has a fix yet (before it, ArduPilot's home item reads 0, 0, 0)."""
        return (self._last_tick - self.boot_time) * self.options.speedup >= self.options.gps_fix_after

    def reboot(self, now: float, offline: float | None = None) -> None:
        """Forget every mission and the flight, and say nothing for `offline` seconds."""
        if self.killed:
            return
        self.reboots += 1
        if self.mission_server.upload is not None:
            self.mission_server.uploads_failed += 1
        back_at = now + (self.reboot_offline if offline is None else offline)
        self._boot(back_at)
        self.offline_until = back_at

    def kill(self) -> None:
        """Silent for good, as a killed SITL process: no message sent, none heard, nothing flown."""
        self.killed = True
        self.mission_server.upload = None

    @property
    def online(self) -> bool:
        return self.offline_until <= 0.0 and not self.killed

    # ------------------------------------------------------------------------------ its clock
    def time_boot_ms(self, now: float) -> int:
        # Simulated time, as ArduCopter SITL stamps its messages (a sped-up clock runs faster than ours).
        return max(int((now - self.boot_time) * self.options.speedup * 1000), 0)

    def time_us(self, now: float) -> int:
        return max(int((now - self.boot_time) * self.options.speedup * 1e6), 0)

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
        self._follow_wind()
        self.gps_glitch.tick((now - self.boot_time) * self.options.speedup)
        if dt > 0 and self.flight.state.armed:
            self.telemetry.publish(self.flight.advance(dt * self.options.speedup))
            if self.reboot_at_item is not None and any(seq >= self.reboot_at_item for seq in self.reached):
                self.reboot_at_item = None
                self.reboot(now)  # a brown-out in flight: the vehicle is gone, the others fly on
                return
            if self.kill_at_item is not None and any(seq >= self.kill_at_item for seq in self.reached):
                self.kill_at_item = None
                self.kill()  # its process killed in flight: silent for good
                return
            self.consumed_mah += BATTERY_CURRENT_A * self.current_factor * dt * self.options.speedup / 3.6
        if self.flavour is Flavour.ARDUPILOT:
            self._check_battery(now)
        self.logs.tick()
        self.telemetry.tick(now)
        if self.mavlink_camera is not None:
            self.mavlink_camera.tick()
        if self.terrain is not None:
            self.terrain.tick(now)
        self.mission_server.tick(now)  # the upload's re-requests and time-out

    # ------------------------------------------------------------------------------ the battery
    @property
    def battery_voltage(self) -> float:
        """What the battery monitor reads: SITL's simulated battery, a constant SIM_BATT_VOLTAGE."""
        return float(self.params.get("SIM_BATT_VOLTAGE", ARDUPILOT_BATTERY_PARAMS["SIM_BATT_VOLTAGE"]))

    @property
    def battery_current(self) -> float:
        """The current drawn in amperes (SITL: only while the motors run)."""
        return BATTERY_CURRENT_A * self.current_factor if self.flight.state.armed else 0.0

    @property
    def current_factor(self) -> float:
        """The current relative to the calm one: exactly 1 without wind (flight_models.wind)."""
        s = self.flight.state
        return 1.0 if self.wind_field is None else self.wind_field.current_factor(s.vn, s.ve)

    def set_wind(self, speed_mps: float, from_deg: float, turbulence_mps: float = 0.0, seed: int | None = None) -> None:
        """SITL's SIM_WIND_SPD, _DIR, _TURB, as a PARAM_SET of them would; seed: its gusts' (None: unchanged)."""
        self.params.update(SIM_WIND_SPD=float(speed_mps), SIM_WIND_DIR=float(from_deg),
                           SIM_WIND_TURB=float(turbulence_mps))
        self.wind_seed = self.wind_seed if seed is None else int(seed)

    def _follow_wind(self) -> None:
        """The wind field from the SIM_WIND_* parameters, made again when they (or the seed) change."""
        wind = Wind.from_params(self.params)
        field = self.wind_field
        if field is None and wind.calm or field is not None and (field.wind, field.seed) == (wind, self.wind_seed):
            return
        self.wind_field = self.flight.wind = WindField(wind, self.wind_seed)

    def battery_arming_problem(self) -> str:
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
        self.telemetry.send_text(f"Battery 1 is {name} {volts:.2f}V used {self.consumed_mah:.0f} mAh",
                                 mavlink.MAV_SEVERITY_WARNING)
        action = int(self.params.get(action_param, 0.0))
        if s.on_ground and s.mode != "AUTO":  # should_disarm_on_failsafe: landed (AUTO: its mission not started)
            s.armed = False
            self.telemetry.send_text(f"{BATTERY_FAILSAFE_TEXT} - Disarming", mavlink.MAV_SEVERITY_WARNING)
            self.telemetry.send_heartbeat()
            return
        self.telemetry.send_text(BATTERY_FAILSAFE_TEXT, mavlink.MAV_SEVERITY_WARNING)
        if action == 0:
            return
        s.mode = "LAND" if action in (1, 5) else "RTL"  # set_mode_land_with_pause / set_mode_RTL_or_land_with_pause
        self.telemetry.send_heartbeat()

    # ------------------------------------------------------------------------------ receiving
    def handle(self, msg: Any, now: float) -> None:
        if not self.online:
            return
        target = getattr(msg, "target_system", None)
        if target is not None and target not in (0, self.sysid):
            return  # for another vehicle on the same link
        target_comp = getattr(msg, "target_component", None)
        if self.mavlink_camera is not None and target_comp in (mavlink.MAV_COMP_ID_ALL, CAMERA_COMPONENT_ID):
            self.mavlink_camera.handle(msg)
        if target_comp is not None and target_comp not in (mavlink.MAV_COMP_ID_ALL, mavlink.MAV_COMP_ID_AUTOPILOT1):
            return
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.get_type() in LOG_REQUESTS:
            self.logs.handle(msg, peer, self.flight.state.armed)
            return
        # Each part answers its own messages and passes on the others (which message is whose: its HANDLERS).
        for part in (self.mission_server, self.command_handler, self.param_server):
            if part.handle(msg, peer, now):
                return
        if self.terrain is not None:
            self.terrain.handle(msg, peer, now)

    # ------------------------------------------------------------------------------ its parts' state, read here
    # What the mock (mock.py), the tests and the bench read on the vehicle; each part keeps its own.
    @property
    def params(self) -> dict[str, float]:
        return self.param_server.values

    def send_heartbeat(self) -> None:
        self.telemetry.send_heartbeat()

    @property
    def camera(self) -> bool:
        return self.telemetry.camera

    @property
    def intervals(self) -> dict[int, float | None]:
        return self.telemetry.intervals

    @property
    def position_interval(self) -> float | None:
        """The GLOBAL_POSITION_INT interval in wall seconds (None: off)."""
        return self.telemetry.position_interval

    @property
    def reached(self) -> list[int]:
        return self.telemetry.reached

    def mission(self, mission_type: int = MissionType.MISSION) -> list[WireItem]:
        return self.mission_server.mission(mission_type)

    def start_refusals(self) -> list[str]:
        return self.mission_server.start_refusals()

    @property
    def first_mission_seq(self) -> int:
        return self.mission_server.first_mission_seq

    @property
    def stores(self) -> dict[int, list[WireItem]]:
        return self.mission_server.stores

    @property
    def upload(self) -> Upload | None:
        return self.mission_server.upload

    @property
    def last_completed(self) -> tuple[int, int, tuple[int, int]] | None:
        return self.mission_server.last_completed

    @property
    def mission_checked_at(self) -> float:
        return self.mission_server.mission_checked_at

    @property
    def uploads_completed(self) -> int:
        return self.mission_server.uploads_completed

    @property
    def uploads_failed(self) -> int:
        return self.mission_server.uploads_failed

    @property
    def invalid_sequence_acks(self) -> int:
        return self.mission_server.invalid_sequence_acks

    @property
    def stray_item_acks(self) -> int:
        return self.mission_server.stray_item_acks

    @property
    def denied_transfers(self) -> int:
        return self.mission_server.denied_transfers
