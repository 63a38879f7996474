"""Vehicle parameters over MAVLink, and the ones the mission upload sets: ArduCopter's WPNAV_RADIUS, and
for a plan over the ground (terrain-frame waypoints) the terrain parameters.

Owns:
- ParamClient: read one parameter (PARAM_REQUEST_READ -> PARAM_VALUE) and set one (PARAM_SET, proved
  by the PARAM_VALUE the vehicle answers with), with retries and a bound, for one vehicle on a Link;
- acceptance_radius_setting: what the upload does about a plan's waypoint acceptance radius. ArduCopter
  does not store NAV_WAYPOINT's param2 (formats.readback.ARDUPILOT_UNSTORED_PARAMS): it turns at every
  waypoint when within WPNAV_RADIUS (cm, default 200, legal range 5..1000). So for an ArduPilot
  multirotor the plan's radius (the smallest positive param2 of its waypoints) goes to WPNAV_RADIUS,
  clamped to that range. PX4 and other autopilots read param2 per waypoint: nothing to set.
- terrain_settings, terrain_plan_settings: what an ArduPilot multirotor needs to fly a mission whose
  waypoints are heights above the ground (MAV_FRAME_GLOBAL_TERRAIN_ALT) from the DEM the ground station
  serves (session.terrain): TERRAIN_ENABLE, TERRAIN_OPTIONS, WPNAV_RFND_USE, and RTL_ALT_TYPE = 1 so that
  its return keeps its height above the ground rather than above home (ArduCopter's ModeRTL::RTLAltType:
  0 relative to home, 1 terrain; refused at arming, "RTL_ALT_TYPE is above-terrain but no terrain data",
  while the vehicle has no terrain). PX4 takes no terrain frame (its plans carry sea-level altitudes).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import BridgeError
from .connection import Link, VehicleInfo, mavlink
from ..formats.mission_items import (CMD_NAV_WAYPOINT, FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT, Flavour,
                                     Mission, as_float32)

PARAM_TRIES = 5
PARAM_WAIT_S = 1.0  # per try: ArduPilot answers within a few ms, a radio within a second

WPNAV_RADIUS = "WPNAV_RADIUS"
WPNAV_RADIUS_RANGE_CM = (5.0, 1000.0)  # ArduCopter's AC_WPNav: @Range 5 1000, minimum 5 cm
# MAV_TYPE of the multirotors ArduCopter flies (quad, coaxial, helicopter, hexa, octo, tri, dodeca,
# deca): they all navigate with AC_WPNav.
MULTIROTOR_TYPES = frozenset({2, 3, 4, 13, 14, 15, 29, 35})
TERRAIN_FRAMES = frozenset({FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT})
RTL_ALT_TYPE = "RTL_ALT_TYPE"
RTL_ALT_TYPE_TERRAIN = 1.0  # ArduCopter ModeRTL::RTLAltType::TERRAIN


class ParamClient:
    """Parameter get / set with one vehicle over a Link (one thread at a time, like MissionClient)."""

    def __init__(self, link: Link, vehicle: VehicleInfo) -> None:
        self.link = link
        self.vehicle = vehicle

    def _await_value(self, name: str, send: Callable[[], None], tries: int, wait_s: float,
                     wanted: Callable[[float], bool] = lambda value: True) -> tuple[float | None, bool]:
        """Send, re-send up to `tries` times, until a PARAM_VALUE for `name` passes `wanted`:
        (the last value heard, or None; whether it passed). A value that does not pass may be a late
        answer to an earlier request (a duplicate, a retry), so it does not end the wait."""
        last: float | None = None
        for _ in range(tries):
            send()
            deadline = time.monotonic() + wait_s
            while (msg := self.link.recv(deadline)) is not None:
                if msg.get_srcSystem() != self.vehicle.sysid or msg.get_type() != "PARAM_VALUE":
                    continue
                if str(msg.param_id).rstrip("\x00") == name:
                    last = float(msg.param_value)
                    if wanted(last):
                        return last, True
        return last, False

    def _failure(self, text: str) -> BridgeError:
        """The error for an unanswered or ignored request, with MAVLink 2 signing named when it is the
        likely cause (link.connection decides)."""
        hint = self.link.signing_hint(self.vehicle.sysid)
        return BridgeError(f"{text}: {hint}" if hint else text)

    def get(self, name: str, tries: int = PARAM_TRIES, wait_s: float = PARAM_WAIT_S) -> float:
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid
        value, _ = self._await_value(name, lambda: mav.param_request_read_send(sysid, compid, name.encode(), -1),
                                     tries, wait_s)
        if value is None:
            raise self._failure(f"vehicle {sysid} did not answer for parameter {name} ({tries} tries, {wait_s:g} s each)")
        return value

    def set(self, name: str, value: float, tries: int = PARAM_TRIES, wait_s: float = PARAM_WAIT_S) -> float:
        """Set and return the value the vehicle then reports; BridgeError when it keeps another one."""
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid
        target = as_float32(value)
        got, ok = self._await_value(
            name,
            lambda: mav.param_set_send(sysid, compid, name.encode(), float(value), mavlink.MAV_PARAM_TYPE_REAL32),
            tries, wait_s, lambda v: math.isclose(v, target, rel_tol=1e-6, abs_tol=1e-6))
        if got is None:
            raise self._failure(f"vehicle {sysid} did not answer for parameter {name} ({tries} tries, {wait_s:g} s each)")
        if not ok:  # it may have ignored our PARAM_SET and answered someone else's read
            raise self._failure(f"vehicle {sysid} kept {name} = {got:g} when set to {value:g}")
        return got


def read_params(client: ParamClient, names: list[str], tries: int = 2, wait_s: float = 0.5,
                give_up_after: int = 2) -> dict[str, float]:
    """The values the vehicle reports for `names` (those it answers for). A vehicle that answers none
    of the first `give_up_after` names does not have them: stop there, so the wait stays short."""
    values: dict[str, float] = {}
    misses = 0
    for name in names:
        try:
            values[name] = client.get(name, tries=tries, wait_s=wait_s)
        except BridgeError:
            misses += 1
            if not values and misses >= give_up_after:
                break
    return values


def set_param(client: ParamClient, name: str, value: float) -> tuple[float | None, float]:
    """(the value before, or None if it could not be read; the value the vehicle reports now)."""
    try:
        old: float | None = client.get(name, tries=2)
    except BridgeError:
        old = None
    return old, client.set(name, value)


@dataclass(frozen=True)
class ParamSetting:
    """A parameter the upload sets so that the vehicle flies the plan as written."""

    name: str
    value: float       # what is sent (after clamping to the legal range)
    wanted: float      # what the plan asked for, in the parameter's unit
    unit: str
    why: str

    @property
    def clamped(self) -> bool:
        return not math.isclose(self.value, round(self.wanted), abs_tol=1e-9)

    def describe(self, old: float | None = None) -> str:
        was = f" (was {old:g})" if old is not None and not math.isclose(old, self.value, abs_tol=1e-6) else ""
        clamp = f", clamped from {self.wanted:g}" if self.clamped else ""
        unit = f" {self.unit}" if self.unit else ""  # a switch (TERRAIN_ENABLE = 1) has none
        return f"{self.name} = {self.value:g}{unit}{was}{clamp}: {self.why}"


def plan_acceptance_radius(mission: Mission) -> float | None:
    """The smallest positive acceptance radius (NAV_WAYPOINT param2, metres) of the mission, if any."""
    radii = [it.param2 for it in mission.items
             if it.command == CMD_NAV_WAYPOINT and math.isfinite(it.param2) and it.param2 > 0]
    return min(radii) if radii else None


def acceptance_radius_setting(vehicle: VehicleInfo, mission: Mission) -> ParamSetting | None:
    """WPNAV_RADIUS for an ArduPilot multirotor from the plan's acceptance radius; None otherwise."""
    if vehicle.flavour is not Flavour.ARDUPILOT or vehicle.mav_type not in MULTIROTOR_TYPES:
        return None
    radius_m = plan_acceptance_radius(mission)
    if radius_m is None:
        return None
    wanted = round(radius_m * 100.0)  # the parameter moves in whole centimetres
    low, high = WPNAV_RADIUS_RANGE_CM
    value = float(min(max(wanted, low), high))
    return ParamSetting(WPNAV_RADIUS, value, radius_m * 100.0, "cm",
                        "the plan's acceptance radius (ArduCopter ignores the waypoints' param2)")


def _ardupilot_multirotor(vehicle: VehicleInfo) -> bool:
    return vehicle.flavour is Flavour.ARDUPILOT and vehicle.mav_type in MULTIROTOR_TYPES


def terrain_settings(vehicle: VehicleInfo, use_rangefinder: bool = False) -> list[ParamSetting]:
    """The parameters an ArduPilot multirotor needs to fly terrain-frame items from the DEM we serve
    (names as ArduCopter 4.7 has them); [] for other vehicles (PX4 takes no terrain frame)."""
    if not _ardupilot_multirotor(vehicle):
        return []
    rangefinder = 1.0 if use_rangefinder else 0.0
    return [
        ParamSetting("TERRAIN_ENABLE", 1.0, 1.0, "",
                     "keep a terrain database, filled from the ground station's DEM"),
        ParamSetting("TERRAIN_OPTIONS", 0.0, 0.0, "",
                     "bit 0 (Disable Download) off, so that the vehicle asks the ground station for its terrain"),
        ParamSetting("WPNAV_RFND_USE", rangefinder, rangefinder, "",
                     "terrain-frame waypoints follow the rangefinder, as asked" if use_rangefinder else
                     "terrain-frame waypoints follow the terrain database (the DEM), not a rangefinder"),
    ]


def rtl_terrain_setting(vehicle: VehicleInfo) -> ParamSetting | None:
    """RTL_ALT_TYPE = 1 for an ArduPilot multirotor (its return at RTL_ALT above the ground); None otherwise.
    Older ArduCopters have no such parameter: the upload then says so and goes on."""
    if not _ardupilot_multirotor(vehicle):
        return None
    return ParamSetting(RTL_ALT_TYPE, RTL_ALT_TYPE_TERRAIN, RTL_ALT_TYPE_TERRAIN, "",
                        "RTL returns at its altitude above the ground (terrain), not above home")


def uses_terrain(mission: Mission) -> bool:
    """Whether any item of the mission is a height above the ground (the terrain frame)."""
    return any(item.frame in TERRAIN_FRAMES for item in mission.items)


def terrain_plan_settings(vehicle: VehicleInfo, mission: Mission, spacing: int | None = None) -> list[ParamSetting]:
    """For a mission with terrain-frame items on an ArduPilot multirotor: terrain_settings, TERRAIN_SPACING when
    the plan says at which grid its heights hold (report.json georeference.terrain.spacing_m), then RTL_ALT_TYPE
    (the one a vehicle may lack: the last); [] otherwise."""
    if not uses_terrain(mission):
        return []
    settings = terrain_settings(vehicle)
    if settings and spacing is not None:
        settings.append(ParamSetting("TERRAIN_SPACING", float(spacing), float(spacing), "m",
                                     "the terrain grid the plan checked its heights above the ground on"))
    rtl = rtl_terrain_setting(vehicle)
    return settings + ([rtl] if rtl is not None else [])
