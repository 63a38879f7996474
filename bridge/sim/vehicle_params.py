"""The mock vehicle's parameters: its table and the PARAM_REQUEST_READ / PARAM_SET / PARAM_VALUE exchange.

Owns, for one mock vehicle (mock_vehicle), the parameter table and the ground station's access to it. The table
survives a reboot, like ArduPilot's EEPROM, and holds only what the bridge and the tests set or read: the
ArduPilot flavour's WPNAV_RADIUS (200 cm; every waypoint is flown to it, not to param2) and its battery monitor
and failsafe (ARDUPILOT_BATTERY_PARAMS, SITL's SIM_BATT_VOLTAGE among them) and SITL's GPS glitch (gps_glitch), both
flavours' SITL wind (SIM_WIND_SPD, _DIR, _TURB: flight_models.wind), the PX4 flavour's MIS_DIST_1WP
(formats.px4_rules), the ArduPilot flavour's terrain parameters over a ground (mock_terrain.TERRAIN_PARAMS); in
the SITL-like mode also the autopilot's navigation parameters (flight_models:
copter_model.CopterParams, px4_model.Px4Params), its camera parameter (CAM1_TYPE, PX4's TRIG_MODE), 0
(PX4's TRIG_INTERFACE 3, as SIH has it), and its mount parameter (MNT1_TYPE 0, PX4's MNT_MODE_IN -1: no mount);
otherwise its camera parameters as set up (configured_camera).
PARAM_REQUEST_READ of a name is answered with its PARAM_VALUE, an unknown name not at all (as on ArduPilot);
PARAM_SET stores the value as given, out of range or not (as ArduCopter SITL does), answers with PARAM_VALUE,
and the navigation parameters take effect in the flight at once; the camera and mount parameters only at the next
boot.
"""

from __future__ import annotations

from typing import Any

from ..flight_models.copter_model import CopterParams
from ..flight_models.px4_model import Px4Params
from ..formats.mission_items import Flavour
from ..flight_models.wind import WIND_PARAMS
from ..formats.px4_rules import MIS_DIST_1WP_DEFAULT
from .gps_glitch import GLITCH_PARAMS
from ..link.connection import mavlink
from .mock_terrain import TERRAIN_PARAMS
from .vehicle_part import VehiclePart

PX4_CAMERA_PARAM, ARDUPILOT_CAMERA_PARAM = "TRIG_MODE", "CAM1_TYPE"  # read at boot: the camera reports only then
PX4_TRIGGER_INTERFACE = "TRIG_INTERFACE"  # 3: MAVLink (IMAGE_START_CAPTURE to a MAVLink camera), 4: generic PWM
# The camera mount, read at boot too: ArduPilot's MNT1_TYPE (0 none, 1 servo, ...), PX4's MNT_MODE_IN (-1: no gimbal
# module; 0 and up: it runs and reports). The SITLs' defaults: no mount.
PX4_MOUNT_PARAM, ARDUPILOT_MOUNT_PARAM = "MNT_MODE_IN", "MNT1_TYPE"
NO_MOUNT = {PX4_MOUNT_PARAM: -1.0, ARDUPILOT_MOUNT_PARAM: 0.0}
# ArduPilot's battery monitor and its failsafe (AP_BattMonitor_Params.cpp: BATT_LOW_VOLT 10.5 V on copters,
# BATT_LOW_TIMER 10 s, actions 0 = none; copter.parm sets BATT_MONITOR 4; SITL's SIM_BATT_VOLTAGE 12.6 V).
ARDUPILOT_BATTERY_PARAMS = {"BATT_MONITOR": 4.0, "BATT_LOW_VOLT": 10.5, "BATT_LOW_TIMER": 10.0, "BATT_FS_LOW_ACT": 0.0,
                            "BATT_CRT_VOLT": 0.0, "BATT_FS_CRT_ACT": 0.0, "SIM_BATT_VOLTAGE": 12.6}


def configured_camera(flavour: Flavour, mavlink_camera: bool) -> dict[str, float]:
    """The camera parameters of a vehicle whose camera is set up: ArduPilot CAM1_TYPE 6 (MAVLinkCamV2) with a
    MAVLink camera, else 1 (servo / relay); PX4 TRIG_MODE 4 (distance, by the mission) and TRIG_INTERFACE 3
    (MAVLink) with a MAVLink camera, else 4 (generic PWM)."""
    if flavour is Flavour.PX4:
        return {PX4_CAMERA_PARAM: 4.0, PX4_TRIGGER_INTERFACE: 3.0 if mavlink_camera else 4.0}
    return {ARDUPILOT_CAMERA_PARAM: 6.0 if mavlink_camera else 1.0}


class ParamServer(VehiclePart):
    """One vehicle's parameter table and its answers to PARAM_REQUEST_READ and PARAM_SET."""

    HANDLERS = {"PARAM_REQUEST_READ": "_on_read", "PARAM_SET": "_on_set"}

    def __init__(self, vehicle: Any) -> None:
        super().__init__(vehicle)
        flavour, sitl_like = vehicle.flavour, vehicle.options.sitl_like
        self.values: dict[str, float] = {"WPNAV_RADIUS": 200.0} if flavour is Flavour.ARDUPILOT else {}
        if flavour is Flavour.ARDUPILOT:
            self.values.update({**ARDUPILOT_BATTERY_PARAMS, **GLITCH_PARAMS})
        self.values.update(WIND_PARAMS)  # SITL's wind (flight_models.wind), set by PARAM_SET as on SITL
        if flavour is Flavour.PX4:
            self.values["MIS_DIST_1WP"] = MIS_DIST_1WP_DEFAULT  # its mission feasibility check (formats.px4_rules)
        if flavour is Flavour.ARDUPILOT and vehicle.options.ground is not None:
            self.values.update(TERRAIN_PARAMS)  # its terrain database (mock_terrain), as ArduCopter has it
        if sitl_like and flavour is Flavour.PX4:  # SIH's start-up script sets TRIG_INTERFACE 3 by default
            self.values.update({**Px4Params().as_params(), PX4_CAMERA_PARAM: 0.0, PX4_TRIGGER_INTERFACE: 3.0,
                                PX4_MOUNT_PARAM: NO_MOUNT[PX4_MOUNT_PARAM]})
        elif sitl_like:
            self.values.update({**CopterParams().as_params(), ARDUPILOT_CAMERA_PARAM: 0.0,
                                ARDUPILOT_MOUNT_PARAM: NO_MOUNT[ARDUPILOT_MOUNT_PARAM]})
        else:  # its camera set up as a team sets it up once: a MAVLink camera, or one on the relay / PWM
            self.values.update(configured_camera(flavour, vehicle.options.mavlink_camera))

    def _send_value(self, name: str, peer: tuple[int, int]) -> None:
        names = sorted(self.values)
        self.mav.param_value_send(name.encode(), float(self.values[name]), mavlink.MAV_PARAM_TYPE_REAL32, len(names),
                                  names.index(name))

    def _on_read(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        name = str(msg.param_id).rstrip("\x00")
        if name in self.values:
            self._send_value(name, peer)  # an unknown name gets no answer, as on ArduPilot

    def _on_set(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        name = str(msg.param_id).rstrip("\x00")
        if name not in self.values:
            return
        value = float(msg.param_value)
        self.values[name] = value  # stored as given, out of range or not (ArduCopter SITL does the same)
        flight = self.vehicle.flight
        if name == "WPNAV_RADIUS":
            flight.default_acceptance = max(value, 5.0) / 100.0  # AC_WPNav flies at least 5 cm
        if flight.copter is not None:  # navigation parameters take effect at once (CAM1_TYPE at boot)
            flight.copter = CopterParams.from_params(self.values)
        self._send_value(name, peer)

