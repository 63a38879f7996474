"""Kinematics of the mock autopilot: a point that flies a mission.

Owns the flight of one vehicle in simulated time: takeoff climb, straight legs at the cruise speed
(DO_CHANGE_SPEED changes it) to every waypoint itself (one already within its acceptance radius is
reached at once), hold times, DO_JUMP, the camera mount's pitch (DO_MOUNT_CONTROL, DO_GIMBAL_MANAGER_PITCHYAW),
photos by distance (DO_SET_CAM_TRIGG_DIST) or time (IMAGE_START_CAPTURE), their positions kept, land and return-to-launch, and the flown track: the same
whatever the lengths of the ticks that advance it. With `copter` (flight_models.copter_model.CopterParams: the
SITL-like mode) it flies as ArduCopter does instead, on the very model the planner's timeline uses:
spool-up and a climb with acceleration, every leg from rest to rest with WPNAV_ACCEL, RTL's climb to
RTL_ALT, its return at RTL_SPEED / WPNAV_SPEED and loiter, the slow last LAND_ALT_LOW metres of the
landing, and a touchdown pause before disarming. With `px4` (flight_models.px4_model.Px4Params, the PX4
flavour's SITL-like mode) it flies as PX4 SIH does: take-off at MPC_TKO_SPEED, a turn of the nose
before every leg, PX4's RTL and its three landing speeds. In wind (`wind`, flight_models.wind.WindField: SITL's
SIM_WIND_*) every horizontal motion is no faster than the wind lets it be; calm, nothing changes. No MAVLink
here: the vehicle (mock_vehicle) feeds it the stored wire items and publishes the events it returns (current item
changed, item reached). Positions use a local flat-earth approximation around home, good to centimetres over a city.
Over a ground (mock_vehicle's VehicleOptions.ground) two more things hold. Terrain-frame items (MAV_FRAME
10 / 11, `terrain`: the vehicle's own terrain database, mock_terrain) are flown as ArduCopter's AC_WPNav flies
them: the leg runs in height above the terrain, and the altitude above home at each point is that height plus
the terrain there less the terrain at home, from the database (what the vehicle was sent); without a database
they are flown as relative items. Landing (LAND, RTL, a LAND item) ends on the true ground (`ground`: the DEM,
the world the vehicle lives in), whose height above the home's ground is FlightState.ground under it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..flight_models import copter_model as cm
from ..flight_models import px4_model
from ..flight_models.copter_model import CopterParams
from ..flight_models.px4_model import Px4Params
from .capture_clock import CaptureClock
from ..formats.gimbal import GIMBAL_COMMANDS
from ..formats.mission_items import (
    CMD_DO_CHANGE_SPEED, CMD_DO_JUMP, CMD_DO_SET_CAM_TRIGG_DIST, CMD_IMAGE_START_CAPTURE, CMD_IMAGE_STOP_CAPTURE,
    CMD_NAV_LAND, CMD_NAV_LOITER_TIME, CMD_NAV_LOITER_TO_ALT, CMD_NAV_LOITER_TURNS, CMD_NAV_LOITER_UNLIM,
    CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL, FRAME_GLOBAL_INT,
    FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT, WireItem, is_global,
)
from ..flight_models.wind import WindField

EARTH_RADIUS = 6_378_137.0
TRIGGER_TOLERANCE_M = 1e-6  # a photo this close to its trigger distance is due now
TERRAIN_FRAMES = frozenset({FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT})
GROUND_RESAMPLE_M = 1.0  # the true ground under the vehicle is looked up again once it has moved this far
# The vehicle's terrain database (mock_terrain.MockTerrain.terrain_offset): the terrain at (lat, lon) above the
# terrain at home, in metres; None when it has none.
TerrainOffset = Callable[[float, float], "float | None"]
# The true ground (the DEM) at (lat, lon) above the ground at home, in metres.
GroundAbove = Callable[[float, float], float]
NAV_COMMANDS_WITH_POSITION = frozenset({CMD_NAV_WAYPOINT, CMD_NAV_LOITER_UNLIM, CMD_NAV_LOITER_TURNS,
                                        CMD_NAV_LOITER_TIME, CMD_NAV_LAND, CMD_NAV_TAKEOFF, CMD_NAV_LOITER_TO_ALT})


@dataclass
class FlightEvent:
    kind: str  # "current" (new current item), "reached" (item reached), "landed", "done"
    seq: int = 0


@dataclass
class FlightState:
    lat: float
    lon: float
    alt: float  # metres above home
    home: tuple[float, float, float]  # lat, lon, alt AMSL
    armed: bool = False
    mode: str = "LOITER"  # LOITER, AUTO, GUIDED, RTL, LAND, MANUAL
    speed: float = 5.0
    vz: float = 0.0
    vn: float = 0.0
    ve: float = 0.0
    heading: float = 0.0
    current: int = 0
    mission_done: bool = False
    photos: int = 0
    photo_points: list[tuple[float, float, float]] = field(default_factory=list)  # lat, lon, alt above home
    track: list[tuple[float, float, float, float]] = field(default_factory=list)  # t, lat, lon, alt
    distance: float = 0.0
    sim_time: float = 0.0
    ground: float = 0.0  # the true ground under it, metres above the home's ground (0 over a flat world)
    gimbal_pitch: float = 0.0  # where its camera mount points, degrees (-90 down): set by the gimbal items

    @property
    def on_ground(self) -> bool:
        return self.alt - self.ground <= 0.01


class FlightSim:
    """Advances a FlightState through a mission in simulated seconds."""

    def __init__(self, home: tuple[float, float, float], cruise_speed: float = 5.0, climb_rate: float = 2.5,
                 land_rate: float = 1.5, default_acceptance: float = 1.0, track_interval: float = 1.0,
                 copter: CopterParams | None = None, px4: Px4Params | None = None,
                 terrain: TerrainOffset | None = None, ground: GroundAbove | None = None) -> None:
        self.terrain = terrain  # None: terrain-frame items flown as relative ones
        self.ground = ground  # None: a flat world, the ground at home's height everywhere
        self._ground_at: tuple[float, float] | None = None  # (north, east) where FlightState.ground was looked up
        self._last_offset = 0.0  # the terrain offset last known (it stands in where the database has none)
        self._motions_terrain = False  # the motions flown now are in height above the terrain
        self.copter = copter  # None: straight legs at the cruise speed; else ArduCopter's flight (copter_model)
        self.px4 = px4  # with copter: PX4's flight instead (px4_model)
        self.wind: WindField | None = None  # None or calm: no wind (flight_models.wind)
        self._motions: list[cm.Motion] = []
        self._motion_t = 0.0
        self._motions_key: tuple[object, ...] | None = None
        self._entries = 0
        self.cruise_speed = cruise_speed
        self.climb_rate = climb_rate
        self.land_rate = land_rate
        self.default_acceptance = default_acceptance
        self.track_interval = track_interval
        self.state = FlightState(lat=home[0], lon=home[1], alt=0.0, home=home, speed=cruise_speed)
        self.items: list[WireItem] = []
        self.first_seq = 0
        self.last_seq: int | None = None
        self._hold_left = 0.0
        self._accepted_at_entry: bool | None = None  # a waypoint within its acceptance radius when entered
        self._entered = False
        self._trigger_dist = 0.0
        self._trigger_acc = 0.0
        self._capture = CaptureClock()  # IMAGE_START_CAPTURE's photos by time
        self._jumps_left: dict[int, int] = {}
        self._last_track = -math.inf

    # ------------------------------------------------------------------------------- geometry
    def _to_local(self, lat: float, lon: float) -> tuple[float, float]:
        lat0, lon0 = self.state.home[0], self.state.home[1]
        north = math.radians(lat - lat0) * EARTH_RADIUS
        east = math.radians(lon - lon0) * EARTH_RADIUS * math.cos(math.radians(lat0))
        return north, east

    def _to_global(self, north: float, east: float) -> tuple[float, float]:
        lat0, lon0 = self.state.home[0], self.state.home[1]
        lat = lat0 + math.degrees(north / EARTH_RADIUS)
        lon = lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0))))
        return lat, lon

    def _target_of(self, item: WireItem) -> tuple[float, float, float]:
        """Where a positional item points: lat, lon, altitude above home (0, 0 means here)."""
        s = self.state
        lat, lon = item.x / 1e7, item.y / 1e7
        if not is_global(item.frame) or (item.x == 0 and item.y == 0):
            lat, lon = s.lat, s.lon
        alt = float(item.z)
        if item.frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT):
            alt -= s.home[2]  # AMSL -> above home
        return lat, lon, alt

    def _follows_terrain(self, item: WireItem) -> bool:
        """A terrain-frame item (its z is a height above the terrain) on a vehicle with a terrain database."""
        return self.terrain is not None and item.frame in TERRAIN_FRAMES

    def terrain_offset(self, lat: float, lon: float) -> float:
        """The vehicle's terrain at (lat, lon) above its terrain at home; where its database has none, the last
        it had (ArduPilot extrapolates the same way)."""
        assert self.terrain is not None
        offset = self.terrain(lat, lon)
        if offset is not None:
            self._last_offset = offset
        return self._last_offset

    def _update_ground(self, within: float = GROUND_RESAMPLE_M) -> None:
        """FlightState.ground under the vehicle, looked up again once it has moved more than `within` metres
        (0 when it lands: exactly where it touches down)."""
        if self.ground is None:
            return
        s = self.state
        here = self._to_local(s.lat, s.lon)
        if self._ground_at is None or math.dist(here, self._ground_at) > within:
            self._ground_at = here
            s.ground = self.ground(s.lat, s.lon)

    def ground_below(self, lat: float, lon: float) -> float:
        """The true ground at (lat, lon) above the home's ground (0 over a flat world)."""
        return 0.0 if self.ground is None else self.ground(lat, lon)

    # ------------------------------------------------------------------------------- control
    def load(self, items: list[WireItem], first_seq: int) -> None:
        self.items = list(items)
        self.first_seq = first_seq
        self.state.current = min(max(self.state.current, first_seq), max(len(items) - 1, 0))

    def start_mission(self, first: int | None = None, last: int | None = None) -> list[FlightEvent]:
        s = self.state
        s.mode = "AUTO"
        s.mission_done = False
        self.last_seq = last
        s.current = first if first is not None and first >= self.first_seq else self.first_seq
        self._entered = False
        self._jumps_left.clear()
        return [FlightEvent("current", s.current)]

    def set_current(self, seq: int) -> list[FlightEvent]:
        self.state.current = seq
        self.state.mission_done = False
        self._entered = False
        return [FlightEvent("current", seq)]

    # ------------------------------------------------------------------------------- stepping
    def advance(self, dt: float) -> list[FlightEvent]:
        """Fly dt simulated seconds; returns the events to publish."""
        events: list[FlightEvent] = []
        s = self.state
        s.vn = s.ve = s.vz = 0.0
        remaining = dt
        guard = 0
        while remaining > 1e-9 and guard < 10_000:
            guard += 1
            if not s.armed:
                break
            used = self._step(remaining, events)
            for _ in range(self._capture.due(used if s.armed else 0.0)):  # IMAGE_START_CAPTURE's, where it is now
                self._photo()
            remaining -= used
            if used <= 0 and not self._pending_instant():
                break
        self._update_ground()
        s.sim_time += dt
        if s.sim_time - self._last_track >= self.track_interval and s.armed:
            self._last_track = s.sim_time
            s.track.append((s.sim_time, s.lat, s.lon, s.alt))
        return events

    def _pending_instant(self) -> bool:
        return self.state.mode == "AUTO" and not self.state.mission_done and self.state.current < len(self.items)

    def _step(self, dt: float, events: list[FlightEvent]) -> float:
        s = self.state
        if s.mode == "AUTO":
            return self._step_mission(dt, events)
        if s.mode in ("RTL", "LAND") and self.copter is not None:
            here = self._here()
            motions = (lambda: self._rtl_motions(here)) if s.mode == "RTL" else \
                (lambda: self._landing_motions(here))
            used, done = self._run_motions((s.mode,), motions, dt)
            if done:
                self._touchdown(events)
                return dt
            return used
        if s.mode == "RTL":
            return self._fly_home_and_land(dt, events)
        if s.mode == "LAND":
            return self._descend(dt, events)
        return dt  # LOITER / GUIDED / MANUAL: hold position

    def _finish_mission(self, events: list[FlightEvent]) -> None:
        if self.state.mission_done:
            return
        self.state.mission_done = True
        events.append(FlightEvent("done", self.state.current))

    def _advance_item(self, events: list[FlightEvent], reached: bool) -> None:
        s = self.state
        if reached:
            events.append(FlightEvent("reached", s.current))
        if self.last_seq is not None and s.current >= self.last_seq:
            self._finish_mission(events)
            return
        s.current += 1
        self._entered = False
        if s.current >= len(self.items):
            s.current = len(self.items) - 1
            self._finish_mission(events)
            return
        events.append(FlightEvent("current", s.current))

    def _do_at_once(self, item: WireItem) -> None:
        """A DO_ item's effect, at once: the speed, the camera's trigger or capture, the mount's pitch."""
        cmd = item.command
        if cmd == CMD_DO_CHANGE_SPEED and item.param2 > 0:
            self.state.speed = float(item.param2)
        elif cmd in (CMD_IMAGE_START_CAPTURE, CMD_IMAGE_STOP_CAPTURE):  # a photo now, then one every param2 s
            if self._capture.set(float(item.param2) if cmd == CMD_IMAGE_START_CAPTURE else 0.0):
                self._photo()
        elif cmd == CMD_DO_SET_CAM_TRIGG_DIST:
            self._trigger_dist, self._trigger_acc = max(float(item.param1), 0.0), 0.0
            if item.param3 == 1:
                self._photo()
        elif cmd in GIMBAL_COMMANDS:  # the mount turns at once (both SITLs report the new pitch within a second)
            self.state.gimbal_pitch = float(item.param1)

    def _step_mission(self, dt: float, events: list[FlightEvent]) -> float:
        s = self.state
        if s.mission_done or s.current >= len(self.items):
            if not s.mission_done:
                self._finish_mission(events)
            return dt
        item = self.items[s.current]
        cmd = item.command
        if not self._entered:
            self._entered = True
            self._entries += 1
            self._hold_left = float(item.param1) if cmd == CMD_NAV_WAYPOINT and item.param1 > 0 else 0.0
            self._accepted_at_entry = None
            if cmd == CMD_DO_JUMP:
                target = int(round(item.param1))
                repeats = int(round(item.param2))
                left = self._jumps_left.setdefault(s.current, repeats if repeats >= 0 else 1_000_000)
                if left > 0 and 0 <= target < len(self.items):
                    self._jumps_left[s.current] = left - 1
                    s.current = target
                    self._entered = False
                    events.append(FlightEvent("current", target))
                else:
                    self._advance_item(events, reached=False)
                return 0.0
            if cmd not in NAV_COMMANDS_WITH_POSITION and cmd not in (CMD_NAV_RETURN_TO_LAUNCH,):
                self._do_at_once(item)  # DO_ / condition commands: their effect now, nothing to fly
                self._advance_item(events, reached=False)
                return 0.0
        if self.copter is not None:
            return self._step_copter_item(item, dt, events)
        if cmd == CMD_NAV_TAKEOFF:
            target_alt = self._target_of(item)[2]
            used, done = self._climb_to(target_alt, dt)
            if done:
                self._advance_item(events, reached=True)
            return used
        if cmd == CMD_NAV_RETURN_TO_LAUNCH:
            used = self._fly_home_and_land(dt, events)
            if s.on_ground and not s.armed:
                self._advance_item(events, reached=True)
            return used
        if cmd == CMD_NAV_LAND:
            lat, lon, _ = self._target_of(item)
            used, arrived = self._fly_to(lat, lon, s.alt, dt)
            if not arrived:
                return used
            used2 = self._descend(dt - used, events)
            if s.on_ground:
                self._advance_item(events, reached=True)
                self._finish_mission(events)
            return used + used2
        # waypoint (and loiter commands, flown as waypoints)
        lat, lon, alt = self._target_of(item)
        terrain = self._follows_terrain(item)
        if self._accepted_at_entry is None:  # the item's first tick
            radius = float(item.param2) if item.param2 > 0 else self.default_acceptance
            above_home = alt + self.terrain_offset(lat, lon) if terrain else alt
            self._accepted_at_entry = math.hypot(*self._leg_to(lat, lon, above_home)[2:]) <= radius
        used, arrived = (0.0, True) if self._accepted_at_entry else self._fly_to(lat, lon, alt, dt, terrain)
        if not arrived:
            return used
        return self._hold_then_advance(events, used, dt)

    def _hold_then_advance(self, events: list[FlightEvent], used: float, dt: float) -> float:
        """At a waypoint: spend what is left of its hold time (param1) within this tick, then take the
        next item; the seconds of `dt` used."""
        if self._hold_left > 0:
            hold = min(self._hold_left, dt - used)
            self._hold_left -= hold
            used += hold
            if self._hold_left > 1e-9:
                return used
        self._advance_item(events, reached=True)
        return used

    def _photo(self) -> None:
        self._photo_at(self.state.lat, self.state.lon, self.state.alt)

    def _photo_at(self, lat: float, lon: float, alt: float) -> None:
        self.state.photos += 1
        self.state.photo_points.append((lat, lon, alt))

    def _climb_to(self, target_alt: float, dt: float) -> tuple[float, bool]:
        s = self.state
        delta = target_alt - s.alt
        if abs(delta) <= 1e-9:  # exactly: stopping wherever a tick got close would depend on the ticks
            return 0.0, True
        step = self.climb_rate * dt
        if abs(delta) <= step:
            s.alt = target_alt
            return abs(delta) / self.climb_rate, True
        s.alt += math.copysign(step, delta)
        s.vz = -math.copysign(self.climb_rate, delta)  # NED: down positive
        return dt, False

    def _leg_to(self, lat: float, lon: float, alt: float) -> tuple[float, float, float, float, float]:
        """Here (north, east of home) and the way to the point (north, east, up), in metres."""
        n0, e0 = self._to_local(self.state.lat, self.state.lon)
        n1, e1 = self._to_local(lat, lon)
        return n0, e0, n1 - n0, e1 - e0, alt - self.state.alt

    def _fly_to(self, lat: float, lon: float, alt: float, dt: float, terrain: bool = False) -> tuple[float, bool]:
        """Straight 3-D leg at the cruise speed to the target itself. ArduCopter all but stops at every
        corner of our missions (copter_model); a leg that ended wherever a tick first got inside the
        acceptance radius would make the track, and every photo, depend on the ticks' lengths.
        `terrain`: `alt` is a height above the terrain, and the leg is flown in that height (AC_WPNav's
        terrain following): the altitude above home is the height plus the terrain offset where it is."""
        s = self.state
        offset0 = self.terrain_offset(s.lat, s.lon) if terrain else 0.0
        n0, e0, dn, de, du = self._leg_to(lat, lon, alt)
        du += offset0  # the leg's vertical: from its height above the terrain now (above home without `terrain`)
        dist = math.sqrt(dn * dn + de * de + du * du)
        if dist <= 1e-9:
            return 0.0, True
        speed = max(s.speed, 0.1) if self.wind is None else max(self.wind.leg_speed(s.speed, dn, de), 0.1)
        if speed * dt >= dist:
            frac, used, arrived = 1.0, dist / speed, True
        else:
            frac, used, arrived = speed * dt / dist, dt, False
        horizontal = math.hypot(dn, de) * frac
        alt0 = s.alt
        s.lat, s.lon = self._to_global(n0 + dn * frac, e0 + de * frac)
        s.alt += du * frac
        if terrain:
            s.alt += self.terrain_offset(s.lat, s.lon) - offset0
        climb = s.alt - alt0
        s.distance += horizontal
        if used > 0:
            s.vn, s.ve, s.vz = dn * frac / used, de * frac / used, -climb / used
        if horizontal > 0:
            s.heading = math.degrees(math.atan2(de, dn)) % 360
        self._count_photos(horizontal, (n0, e0, alt0), (dn * frac, de * frac, climb))
        return used, arrived

    def _count_photos(self, horizontal: float, start: tuple[float, float, float],
                      step: tuple[float, float, float]) -> None:
        """Photos due on a step of `horizontal` metres from `start` (north, east, alt), each where its
        trigger distance was reached along the step (a long step, after a stall, holds several)."""
        if self._trigger_dist <= 0 or horizontal <= 0:
            return
        self._trigger_acc += horizontal
        # The tolerance makes a photo due exactly at a step's end fire in that step, however the
        # rounding of a sum of steps fell: the same photos whatever the ticks' lengths.
        while self._trigger_acc >= self._trigger_dist - TRIGGER_TOLERANCE_M:
            self._trigger_acc = max(self._trigger_acc - self._trigger_dist, 0.0)
            frac = 1.0 - self._trigger_acc / horizontal
            lat, lon = self._to_global(start[0] + step[0] * frac, start[1] + step[1] * frac)
            self._photo_at(lat, lon, start[2] + step[2] * frac)

    def _descend(self, dt: float, events: list[FlightEvent]) -> float:
        s = self.state
        self._update_ground(within=0.0)
        if s.on_ground:
            self._touchdown(events)
            return dt
        step = self.land_rate * dt
        height = s.alt - s.ground
        if step >= height:
            used = height / self.land_rate
            s.alt = s.ground
            self._touchdown(events)
            return used
        s.alt -= step
        s.vz = self.land_rate
        if s.on_ground:  # within a centimetre: down, or a LAND item would finish still armed
            s.alt = s.ground
            self._touchdown(events)
        return dt

    def _touchdown(self, events: list[FlightEvent]) -> None:
        s = self.state
        self._update_ground(within=0.0)  # the ground exactly where it stands
        if s.armed:
            s.armed = False  # autopilots disarm after landing
            events.append(FlightEvent("landed", s.current))
        self._trigger_dist = 0.0
        self._capture.set(0.0)

    def _fly_home_and_land(self, dt: float, events: list[FlightEvent]) -> float:
        s = self.state
        used, arrived = self._fly_to(s.home[0], s.home[1], s.alt, dt)
        if not arrived:
            return used
        return used + self._descend(dt - used, events)

    # ------------------------------------------------------------------------------- SITL-like flight
    def _here(self) -> tuple[float, float, float]:
        north, east = self._to_local(self.state.lat, self.state.lon)
        return north, east, self.state.alt

    def replan(self) -> None:
        """Make the motions of what it flies now again, from where it is (its position estimate jumped)."""
        self._motions_key = None

    @property
    def motion_kind(self) -> str | None:
        """The kind (copter_model.Motion.kind) of the flight-model motion flown now; None between motions."""
        return self._motions[0].kind if self._motions else None

    def _run_motions(self, key: tuple[object, ...], build: Callable[[], list[cm.Motion]],
                     dt: float, terrain: bool = False) -> tuple[float, bool]:
        """Fly the motions `build` makes (made once per key: an item entered, a mode set) for up to dt
        seconds: (seconds used, all flown). `terrain`: their altitudes are heights above the terrain."""
        if self._motions_key != key:
            motions = build() if self.wind is None else self.wind.apply(build())
            self._motions_key, self._motions, self._motion_t = key, motions, 0.0
            self._motions_terrain = terrain
        used = 0.0
        while self._motions and used < dt - 1e-12:
            motion = self._motions[0]
            step = min(motion.duration - self._motion_t, dt - used)
            self._move_along(motion, self._motion_t, self._motion_t + step, step)
            self._motion_t += step
            used += step
            if self._motion_t >= motion.duration - 1e-9:
                self._motions.pop(0)
                self._motion_t = 0.0
        return used, not self._motions

    def _move_along(self, motion: cm.Motion, t0: float, t1: float, step: float) -> None:
        s = self.state
        (n0, e0, a0), (n1, e1, a1) = motion.position(np.array([t0, t1]))
        s.lat, s.lon = self._to_global(float(n1), float(e1))
        if self._motions_terrain:  # heights above the terrain: the altitude above home is that plus the offset
            a0, a1 = s.alt, a1 + self.terrain_offset(s.lat, s.lon)
        s.alt = float(a1)
        dn, de, du = float(n1 - n0), float(e1 - e0), float(a1 - a0)
        if step > 0:
            s.vn, s.ve, s.vz = dn / step, de / step, -du / step
        horizontal = math.hypot(dn, de)
        s.distance += horizontal
        if horizontal > 0:
            s.heading = math.degrees(math.atan2(de, dn)) % 360
        self._count_photos(horizontal, (float(n0), float(e0), float(a0)), (dn, de, du))

    # The motions of the model flown: ArduCopter's (copter_model) or PX4's (px4_model).
    def _takeoff_motions(self, here: tuple[float, float, float], target_alt: float) -> list[cm.Motion]:
        p, q = self.copter, self.px4
        assert p is not None
        top = (here[0], here[1], target_alt)
        if q is not None:
            return px4_model.takeoff(here, target_alt - here[2], q) if self.state.on_ground else \
                [cm.Motion(here, top, q.z_auto_up, q.acc_up, kind="takeoff")]
        return cm.takeoff(here, target_alt - here[2], p) if self.state.on_ground else \
            [cm.Motion(here, top, p.speed_up, p.accel_z, kind="takeoff")]

    def _leg_motions(self, here: tuple[float, float, float], target: tuple[float, float, float]) -> list[cm.Motion]:
        assert self.copter is not None
        if self.px4 is not None:  # PX4 turns its nose to the leg first (the first leg: as the plan assumes)
            heading = self.state.heading if self.state.distance > 0 else None
            return px4_model.legs(here, [target], self.state.speed, self.px4, heading)[0]
        return [cm.leg(here, target, self.state.speed, self.copter)]

    def _rtl_motions(self, here: tuple[float, float, float]) -> list[cm.Motion]:
        assert self.copter is not None
        if self.px4 is not None:
            return px4_model.rtl(here, (0.0, 0.0, 0.0), self.px4)
        return cm.rtl(here, (0.0, 0.0, 0.0), self.copter)

    def _landing_motions(self, here: tuple[float, float, float]) -> list[cm.Motion]:
        """Down to the true ground under `here` (north, east, altitude above home)."""
        assert self.copter is not None
        ground = self.ground_below(*self._to_global(here[0], here[1]))
        if self.px4 is not None:
            return px4_model.landing(here, ground, self.px4)
        return cm.landing(here, ground, self.copter)

    def _step_copter_item(self, item: WireItem, dt: float, events: list[FlightEvent]) -> float:
        """One positional mission item flown as ArduCopter (copter_model) or PX4 (px4_model) does."""
        assert self.copter is not None
        key = ("AUTO", self._entries)
        here = self._here()
        cmd = item.command
        if cmd == CMD_NAV_TAKEOFF:
            target_alt = self._target_of(item)[2]
            used, done = self._run_motions(key, lambda: self._takeoff_motions(here, target_alt), dt)
            if done:
                self._advance_item(events, reached=True)
            return used
        if cmd == CMD_NAV_RETURN_TO_LAUNCH:
            used, done = self._run_motions(key, lambda: self._rtl_motions(here), dt)
            if done:
                self._touchdown(events)
                self._advance_item(events, reached=True)
                return dt
            return used
        lat, lon, alt = self._target_of(item)
        north, east = self._to_local(lat, lon)
        if cmd == CMD_NAV_LAND:
            used, done = self._run_motions(
                key, lambda: [*self._leg_motions(here, (north, east, here[2])),
                              *self._landing_motions((north, east, here[2]))], dt)
            if done:
                self._touchdown(events)
                self._advance_item(events, reached=True)
                self._finish_mission(events)
                return dt
            return used
        # waypoint (and loiter commands, flown as waypoints): from rest to rest, then the hold time
        if self._follows_terrain(item):  # the leg in height above the terrain, from its height now
            start = (here[0], here[1], here[2] - self.terrain_offset(self.state.lat, self.state.lon))
            used, done = self._run_motions(key, lambda: self._leg_motions(start, (north, east, alt)), dt, terrain=True)
        else:
            used, done = self._run_motions(key, lambda: self._leg_motions(here, (north, east, alt)), dt)
        if not done:
            return used
        return self._hold_then_advance(events, used, dt)
