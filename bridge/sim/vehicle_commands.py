"""The mock vehicle's commands: COMMAND_LONG / COMMAND_INT and SET_MODE, each answered as the autopilots do.

Owns, for one mock vehicle (mock_vehicle), what the ground station may tell it to do, each command answered with one
COMMAND_ACK: arm / disarm (refused before the vehicle is ready, as ArduCopter SITL refuses it with FAILED and its
STATUSTEXT reasons and PX4 SIH with TEMPORARILY_REJECTED and its own, and on ArduPilot below a battery failsafe
voltage or while its terrain is loading (mock_terrain); a forced arm or disarm, param2 21196, skips the checks and
stops the motors in flight), mode changes (SET_MODE, MAV_CMD_DO_SET_MODE: the autopilots' own custom_mode numbers;
AUTO needs a mission, and PX4 refuses it while it still checks a new one), MAV_CMD_MISSION_START (refused while
there is no mission or the vehicle is disarmed; on PX4 with "Mission start denied! No valid mission" when the
mission server's start_refusals say so, or before its mission check is done; a repeated start while flying the
mission does not restart it), DO_SET_MISSION_CURRENT, RETURN_TO_LAUNCH, LAND, the requests for HOME_POSITION,
AUTOPILOT_VERSION, HEARTBEAT and (ArduPilot) MISSION_CURRENT, SET_MESSAGE_INTERVAL for the telemetry's streams (and
the terrain's), and in the SITL-like mode MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN (a reboot once its acknowledgement is
out; refused while armed).
"""

from __future__ import annotations

from typing import Any

from ..formats.mission_items import Flavour
from ..formats.px4_rules import START_DENIED
from ..link.connection import mavlink
from .telemetry import ARDUPILOT_MODES, NOT_READY_TEXTS, PX4_MODES
from .vehicle_part import VehiclePart

# COMPONENT_ARM_DISARM's param2 that forces arming or disarming: a magic number of the command's
# definition, not an enum.
FORCE_ARM_DISARM = 21196

# PX4 SIH's answer to arming before "Ready for takeoff!": TEMPORARILY_REJECTED and these (the first
# is 51 characters: PX4 sends it as two STATUSTEXT chunks with one id).
PX4_NOT_READY_TEXTS = ("Arming denied: Resolve system health failures first", "Preflight Fail: horizontal velocity unstable")
PX4_MISSION_MODE_REFUSED = "Switching to Mission is currently not available"  # AUTO.MISSION asked meanwhile


class CommandHandler(VehiclePart):
    """One vehicle's answers to COMMAND_LONG / COMMAND_INT and SET_MODE."""

    HANDLERS = {"SET_MODE": "_on_set_mode", "COMMAND_LONG": "_on_command", "COMMAND_INT": "_on_command"}

    def __init__(self, vehicle: Any) -> None:
        super().__init__(vehicle)
        self._reboot_pending = False  # a reboot command acknowledged: reboot once the ack is out

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
        vehicle = self.vehicle
        missions = vehicle.mission_server
        s = vehicle.flight.state
        if name == "AUTO":
            if not missions.has_mission:
                return False
            if self.flavour is Flavour.PX4 and now < missions.mission_checked_at:  # not checked yet
                vehicle.telemetry.send_text(PX4_MISSION_MODE_REFUSED)
                return False
            missions.resume_on_auto()
            s.mode = "AUTO"
            s.mission_done = False
        else:
            s.mode = name
        vehicle.telemetry.send_heartbeat()
        return True

    def _on_command(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        command = int(msg.command)
        p = [float(getattr(msg, f"param{i}", 0.0) or 0.0) for i in range(1, 8)]
        result = self._command(command, p, now)
        self.mav.command_ack_send(command, result, 0, 0, peer[0], peer[1])
        if self._reboot_pending:
            self._reboot_pending = False
            self.vehicle.reboot(now)

    def _command(self, command: int, p: list[float], now: float) -> int:
        vehicle = self.vehicle
        telemetry, missions = vehicle.telemetry, vehicle.mission_server
        s = vehicle.flight.state
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] >= 0.5:
                if not vehicle.ready and int(p[1]) != FORCE_ARM_DISARM and self.flavour is Flavour.PX4:
                    for text in PX4_NOT_READY_TEXTS:  # PX4 before "Ready for takeoff!"
                        telemetry.send_text(text)
                    return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
                if not vehicle.ready and int(p[1]) != FORCE_ARM_DISARM:  # ArduCopter before its EKF uses the GPS
                    for text in NOT_READY_TEXTS[:2]:
                        telemetry.send_text(text)
                    return mavlink.MAV_RESULT_FAILED
                if (problem := vehicle.battery_arming_problem()) and int(p[1]) != FORCE_ARM_DISARM:
                    telemetry.send_text(f"PreArm: Battery 1 {problem}")  # AP_BattMonitor_Backend::arming_checks
                    return mavlink.MAV_RESULT_FAILED
                if vehicle.terrain is not None and (problem := vehicle.terrain.arming_problem()) \
                        and int(p[1]) != FORCE_ARM_DISARM:
                    telemetry.send_text(problem)  # AP_Arming::terrain_checks
                    return mavlink.MAV_RESULT_FAILED
                s.armed = True
                vehicle.logs.on_armed("ArduCopter V4.7.0-dev (mock)", vehicle.time_us(now))  # a new log (mock_log)
            else:
                if not s.on_ground and int(p[1]) != FORCE_ARM_DISARM:  # a forced disarm stops it in flight
                    return mavlink.MAV_RESULT_DENIED
                s.armed = False
            telemetry.send_heartbeat()
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            ok = self._apply_mode(int(p[1]), int(p[2]) if self.flavour is not Flavour.ARDUPILOT else None, now)
            return mavlink.MAV_RESULT_ACCEPTED if ok else mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_MISSION_START:
            if not missions.has_mission:
                return mavlink.MAV_RESULT_DENIED
            if missions.start_refusals() or now < missions.mission_checked_at:  # PX4's checks (formats.px4_rules)
                telemetry.send_text(START_DENIED)
                return mavlink.MAV_RESULT_DENIED
            if not s.armed:
                return mavlink.MAV_RESULT_DENIED
            if s.mode == "AUTO" and not s.mission_done:
                # Already flying it, or spooling up to: like ArduCopter (GCS_MAVLINK_Copter starts the
                # mission only when it is not running), a repeated start restarts nothing; fly repeats a
                # start whose acknowledgement was lost. (PX4 would go back to param1's item.)
                return mavlink.MAV_RESULT_ACCEPTED
            first = int(p[0]) if p[0] > 0 else None
            last = int(p[1]) if p[1] > 0 else None
            telemetry.publish(vehicle.flight.start_mission(first, last))
            telemetry.send_heartbeat()
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN and self.options.sitl_like:  # param1 = 1 reboots
            if int(p[0]) != 1:
                return mavlink.MAV_RESULT_UNSUPPORTED
            if s.armed:
                return mavlink.MAV_RESULT_DENIED
            self._reboot_pending = True  # after the acknowledgement has gone out
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
            return mavlink.MAV_RESULT_ACCEPTED if missions.set_current(int(p[0])) else mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            s.mode = "RTL"
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_NAV_LAND:
            s.mode = "LAND"
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_GET_HOME_POSITION or (command == mavlink.MAV_CMD_REQUEST_MESSAGE
                                                             and int(p[0]) == mavlink.MAVLINK_MSG_ID_HOME_POSITION):
            # no home yet: nothing to send
            return mavlink.MAV_RESULT_ACCEPTED if telemetry.send_home() else mavlink.MAV_RESULT_FAILED
        if command in (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
            if command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES \
                    or int(p[0]) == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                telemetry.send_version()
                return mavlink.MAV_RESULT_ACCEPTED
            if int(p[0]) == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
                telemetry.send_heartbeat()
                return mavlink.MAV_RESULT_ACCEPTED
            # as ArduPilot answers it
            if int(p[0]) == mavlink.MAVLINK_MSG_ID_MISSION_CURRENT and self.flavour is Flavour.ARDUPILOT:
                telemetry.send_mission_current()
                return mavlink.MAV_RESULT_ACCEPTED
            if int(p[0]) == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT and self.flavour is Flavour.ARDUPILOT:
                telemetry.send_ekf(now)
                return mavlink.MAV_RESULT_ACCEPTED
            return mavlink.MAV_RESULT_UNSUPPORTED
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            terrain = vehicle.terrain
            supported = (terrain is not None and terrain.set_interval(int(p[0]), p[1], now)) \
                or telemetry.set_interval(int(p[0]), p[1], now)
            return mavlink.MAV_RESULT_ACCEPTED if supported else mavlink.MAV_RESULT_UNSUPPORTED

        return mavlink.MAV_RESULT_UNSUPPORTED

