"""From a smoothed track to one MAVLink mission per drone (SPEC section 9).

Each drone's mission, in order:

1. NAV_TAKEOFF to its altitude above the launch point;
2. DO_CHANGE_SPEED to the cruise speed (with a transit speed, `plan --transit-speed` or a camera that slows the
   survey: the way out flies at the transit speed, a DO_CHANGE_SPEED after the survey's first waypoint sets the
   survey speed and one after its last sets the transit speed again for the way home);
3. the gimbal item that points the camera at the gimbal pitch (straight down by default) before the first photo:
   DO_MOUNT_CONTROL, which ArduPilot and PX4 both turn their mounts for (bridge/formats/gimbal.py says why);
4. DO_SET_CAM_TRIGG_DIST: a photo every `trigger distance` metres, the first at once;
5. per corrected waypoint: NAV_WAYPOINT (acceptance radius a quarter cell), then
   DO_SET_CAM_TRIGG_DIST again with "trigger once now", so each corner gets a photo and the
   photos of the next leg are spaced from it; after the last waypoint the distance is 0 (camera off);
6. NAV_RETURN_TO_LAUNCH, or NAV_LAND where the track ends.

With `capture` camera-interval, items 4 and 5's DO_SET_CAM_TRIGG_DIST give way to one IMAGE_START_CAPTURE
(a photo every trigger distance / speed seconds) where the survey starts and one IMAGE_STOP_CAPTURE after
its last waypoint; relay and camera missions are the same items (docs/capture.md, "Camera protocol").

Positions use the relative-altitude frame (MAV_FRAME_GLOBAL_RELATIVE_ALT). Drone k (from 0)
flies at altitude H + k * altitude_step: layers go up from H, never below it, so the
footprint (and the coverage) never shrinks. Over a DEM (`ground`: heights above sea level) H is a height
above the ground under the drone and the home position is at the ground's height: ArduPilot gets its
waypoints in the terrain frame (MAV_FRAME_GLOBAL_TERRAIN_ALT: it follows the terrain the ground station
serves it); PX4, which takes no terrain frame, gets altitudes above sea level (MAV_FRAME_GLOBAL), each
leg split where the ground departs from the straight line (terrain_legs.amsl_track). The take-off climbs
to H above the launch point in either case, which is the home. The trigger distance is the footprint side
times (1 - frontal overlap); the default overlap 8/9 gives one photo per grid cell.

The result is a `missionplan.bridge.formats.mission_items.Mission`, a plain list of items: bridge/ uploads it without
knowing anything about grids.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from missionplan.bridge.formats.mission_items import (CMD_DO_CHANGE_SPEED, CMD_DO_SET_CAM_TRIGG_DIST,
                            CMD_IMAGE_START_CAPTURE, CMD_IMAGE_STOP_CAPTURE, CMD_NAV_LAND, CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT,
                            FRAME_GLOBAL_TERRAIN_ALT, FRAME_MISSION, SPEED_TYPE_GROUNDSPEED, Mission, MissionItem)
from missionplan.bridge.formats.gimbal import NADIR_PITCH_DEG, gimbal_item
from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.geo.capture import CRUISE_SPEED_M_S

DEFAULT_SPEED_M_S = CRUISE_SPEED_M_S
# 8/9: a photo every cell (S/9), exactly what the grid world assumes when it photographs the
# 9 x 9 block under the drone at every step. A smaller overlap saves photos but leaves the
# coverage to the footprint's margin.
DEFAULT_OVERLAP = (CELLS_PER_FOOTPRINT - 1) / CELLS_PER_FOOTPRINT
END_ACTIONS = ("rtl", "land")
# How photos are taken (`plan --capture`, docs/capture.md "Camera protocol"): relay, the autopilot's own trigger
# by distance (DO_SET_CAM_TRIGG_DIST); camera, the same items for a MAVLink camera the autopilot forwards each
# trigger to (IMAGE_START_CAPTURE, one photo) and whose CAMERA_IMAGE_CAPTURED are the capture records;
# camera-interval, IMAGE_START_CAPTURE every trigger distance / speed seconds from the survey's start,
# IMAGE_STOP_CAPTURE at its end.
CAPTURE_MODES = ("relay", "camera", "camera-interval")
# The ground under a plan: heights above sea level (m) at arrays of latitudes and longitudes (geo.dem.Ground).
GroundHeights = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class MissionSettings:
    altitude_m: float
    footprint_m: float  # side S of the square camera footprint at altitude_m
    speed_m_s: float = DEFAULT_SPEED_M_S
    overlap: float = DEFAULT_OVERLAP
    end: str = "rtl"
    altitude_step_m: float = 0.0
    autopilot: str = "ardupilot"  # `plan --autopilot`: whose flight the timeline times (px4: flight_models.px4_model)
    capture: str = "relay"  # `plan --capture`: one of CAPTURE_MODES
    # The way out to the survey and home from it, camera off (`plan --transit-speed`, or the cruise speed when the
    # camera's capture interval slows the survey); None: flown at speed_m_s like the survey, one speed throughout.
    transit_speed_m_s: float | None = None
    gimbal_pitch_deg: float = NADIR_PITCH_DEG  # `plan --gimbal-pitch`: where the camera points, -90 straight down

    @property
    def transit_m_s(self) -> float:
        """The speed of the ways out and home: transit_speed_m_s, else the survey's speed_m_s."""
        return self.speed_m_s if self.transit_speed_m_s is None else self.transit_speed_m_s

    @property
    def camera_records(self) -> bool:
        """The capture records are a MAVLink camera's CAMERA_IMAGE_CAPTURED, not the autopilot's reports."""
        return self.capture != "relay"

    @property
    def capture_interval_s(self) -> float:
        """camera-interval: seconds between photos, the trigger distance at the cruise speed."""
        return self.trigger_distance_m / self.speed_m_s

    @property
    def acceptance_m(self) -> float:
        """Waypoint acceptance radius: a quarter cell, so no vehicle cuts a corner by more than that
        (left at 0, the autopilot's default of a metre or two would skip whole legs on small grids)."""
        return self.footprint_m / 36.0

    @property
    def trigger_distance_m(self) -> float:
        return self.footprint_m * (1.0 - self.overlap)

    def altitude_of(self, drone: int) -> float:
        return self.altitude_m + drone * self.altitude_step_m


@dataclass
class DroneMission:
    """One drone's mission and the numbers report.json gives for it."""

    sysid: int
    mission: Mission
    waypoints: int
    length_m: float  # climb + survey legs + the way back (RTL) or the descent (land)
    flight_s: float
    photos: int


def build_mission(drone: int, launch_latlon: tuple[float, float], waypoints_latlon: np.ndarray,
                  waypoints_m: np.ndarray, launch_m: np.ndarray, settings: MissionSettings,
                  flight_s: float | None = None, end: str | None = None, resumes: bool = False,
                  transit: tuple[np.ndarray, np.ndarray] | None = None,
                  back: tuple[np.ndarray, np.ndarray] | None = None, ground: GroundHeights | None = None) -> DroneMission:
    """The mission of drone `drone` (0-based; its system id is drone + 1).

    A battery sortie after the first (`resumes`) flies from the launch point to its first waypoint
    with the camera off, and takes its first photo there; `end` overrides settings.end (every sortie
    but the last returns to launch for its battery swap). `transit` and `back`: (latlon (n, 2), metres
    (n, 2)) waypoints flown with the camera off from the launch point to the first survey waypoint and
    from the last one home (routed round obstacles; `back` ends over the launch point).

    `waypoints_latlon` (n, 2) are the corrected waypoints; `waypoints_m` the same points in
    a local metric frame and `launch_m` the launch point there, for lengths and photo counts.
    `flight_s` is the planned duration (missionplan.mission.timeline); without it, length over cruise speed.
    `ground`: the plan is over a DEM (the module docstring says how each autopilot gets its heights).
    """
    altitude = settings.altitude_of(drone)
    end = settings.end if end is None else end
    empty = (np.zeros((0, 2)), np.zeros((0, 2)))
    transit_latlon, transit_m = transit if transit is not None else empty
    back_latlon, back_m = back if back is not None else empty
    camera_off = resumes or len(transit_latlon) > 0
    lat0, lon0 = launch_latlon
    # Where the positions' heights are measured from: the launch point (home), or the ground under the drone.
    frame = FRAME_GLOBAL_RELATIVE_ALT if ground is None else FRAME_GLOBAL_TERRAIN_ALT
    items = [
        MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=lat0, y=lon0, z=altitude),
        _change_speed(settings.transit_m_s if camera_off else settings.speed_m_s),
        # The camera pointed before the first photo: it is wherever it was left otherwise (every sortie too).
        gimbal_item(settings.autopilot, settings.gimbal_pitch_deg),
    ]
    interval = settings.capture == "camera-interval"
    if not interval:
        # param3 = 1: take the first photo at once, not only after the first trigger distance; a resumed
        # sortie keeps the camera off on its way out (the first waypoint's item below turns it on).
        items.append(MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION,
                                 param1=0.0 if camera_off else settings.trigger_distance_m,
                                 param3=0.0 if camera_off else 1.0))
    elif not camera_off:  # a photo at once, then one every interval until the stop after the last waypoint
        items.append(_start_capture(settings))
    for lat, lon in transit_latlon:  # camera off on the way out
        items.append(MissionItem(CMD_NAV_WAYPOINT, frame, param2=settings.acceptance_m,
                                 x=float(lat), y=float(lon), z=altitude))
    # After every waypoint, DO_SET_CAM_TRIGG_DIST again with "trigger once now": a photo where the
    # track turns, and the distance count restarts there, so photos stay aligned with each leg's start
    # (a corner's photo would otherwise fall up to one trigger distance short of it). The last one
    # sets the distance to 0: one photo at the end of the track, then the camera stops.
    # Two speeds (settings.transit_speed_m_s): the way out at the transit speed up to the survey's first
    # waypoint, the survey from there at speed_m_s, the way home at the transit speed again
    # (timeline.leg_speeds times the same legs).
    two_speeds = settings.transit_m_s != settings.speed_m_s
    for index, (lat, lon) in enumerate(waypoints_latlon):
        last = index == len(waypoints_latlon) - 1
        items.append(MissionItem(CMD_NAV_WAYPOINT, frame, param2=settings.acceptance_m,
                                 x=float(lat), y=float(lon), z=altitude))
        if two_speeds and camera_off and index == 0 and not last:
            items.append(_change_speed(settings.speed_m_s))
        if not interval:
            items.append(MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION,
                                     param1=0.0 if last else settings.trigger_distance_m, param3=1.0))
            continue
        if camera_off and index == 0:
            items.append(_start_capture(settings))
        if last:
            items.append(MissionItem(CMD_IMAGE_STOP_CAPTURE, FRAME_MISSION))
    if not len(waypoints_latlon):
        items.append(MissionItem(CMD_IMAGE_STOP_CAPTURE, FRAME_MISSION) if interval else
                     MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=0.0))
    if two_speeds and len(back_latlon):
        items.append(_change_speed(settings.transit_m_s))
    for lat, lon in back_latlon:  # camera off on the way home, round the obstacles RTL would fly through
        items.append(MissionItem(CMD_NAV_WAYPOINT, frame, param2=settings.acceptance_m,
                                 x=float(lat), y=float(lon), z=altitude))
    if end == "rtl":
        items.append(MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION))
    else:
        last_lat, last_lon = (back_latlon[-1] if len(back_latlon) else
                              waypoints_latlon[-1] if len(waypoints_latlon) else launch_latlon)
        items.append(MissionItem(CMD_NAV_LAND, FRAME_GLOBAL_RELATIVE_ALT, x=float(last_lat), y=float(last_lon), z=0.0))

    flown = np.vstack([np.reshape(launch_m, (1, 2)), np.reshape(transit_m, (-1, 2)), np.reshape(waypoints_m, (-1, 2)),
                       np.reshape(back_m, (-1, 2))])
    across = float(np.hypot(*np.diff(flown, axis=0).T).sum()) if len(flown) > 1 else 0.0
    home_m = float(np.hypot(*(flown[-1] - np.reshape(launch_m, 2)))) if end == "rtl" else 0.0
    length = altitude + across + home_m + altitude  # up, across, (back,) down
    # One photo at the start and one at each waypoint, plus one per trigger distance inside each survey
    # leg (not on a way out or home: the camera is off there, and a resumed survey starts at its first waypoint).
    survey = np.vstack([np.reshape(launch_m, (1, 2)), waypoints_m]) if not camera_off else np.reshape(waypoints_m, (-1, 2))
    photo_legs = np.hypot(*np.diff(survey, axis=0).T) if len(survey) > 1 else np.zeros(0)
    if interval:  # one at the start, then one a trigger distance's flight time: at least this many (corners slow it)
        started = not camera_off or len(waypoints_m) > 0
        flown_s = float(photo_legs.sum()) / settings.speed_m_s
        photos = int(started) + (int(np.floor(flown_s / settings.capture_interval_s + 1e-9))
                                 if started and settings.trigger_distance_m > 0 else 0)
    else:
        photos = (0 if camera_off else 1) + len(waypoints_m)
        if settings.trigger_distance_m > 0 and len(photo_legs):
            photos += int(np.maximum(np.ceil(photo_legs / settings.trigger_distance_m - 1e-9) - 1, 0).sum())
    count = len(transit_latlon) + len(waypoints_latlon) + len(back_latlon)
    home_amsl = 0.0 if ground is None else float(ground(np.array([lat0]), np.array([lon0]))[0])
    mission = Mission(items=items, home=(lat0, lon0, home_amsl))
    if ground is not None and settings.autopilot == "px4":
        from .terrain_missions import px4_over_ground

        over_ground = px4_over_ground(mission, ground)
        count += len(over_ground.items) - len(mission.items)  # the points its legs were split at are waypoints too
        mission = over_ground
    return DroneMission(sysid=drone + 1, mission=mission, waypoints=count, length_m=length,
                        flight_s=length / settings.speed_m_s if flight_s is None else flight_s, photos=photos)


def _change_speed(speed_m_s: float) -> MissionItem:
    """DO_CHANGE_SPEED: the ground speed of the legs from here on (throttle unchanged)."""
    return MissionItem(CMD_DO_CHANGE_SPEED, FRAME_MISSION, param1=SPEED_TYPE_GROUNDSPEED, param2=speed_m_s, param3=-1.0)


def _start_capture(settings: MissionSettings) -> MissionItem:
    """IMAGE_START_CAPTURE: a photo now, then every capture_interval_s until IMAGE_STOP_CAPTURE (count 0)."""
    return MissionItem(CMD_IMAGE_START_CAPTURE, FRAME_MISSION, param2=settings.capture_interval_s, param3=0.0)
