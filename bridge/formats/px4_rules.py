"""What PX4 (v1.15.4, measured on PX4 SIH) accepts in a mission and when it refuses to start one.

Owns PX4's rules, as data and pure functions, for the mock's PX4 flavour and for `upload`:
- item_result: the MAV_MISSION_RESULT PX4 answers a mission item with (its frame and command
  matrix: positional NAV_* commands only in a global frame, everything else only in frame 2);
- px4_stored: what PX4 hands back on download (frames 3 -> 6 and 0 -> 5, NAV_WAYPOINT's pass
  radius dropped, fence items not auto-continued and without altitude);
- start_refusals: PX4's mission feasibility check that refuses a start with "Mission start denied!
  No valid mission" when the first positional item is MIS_DIST_1WP (900 m) or more from the
  vehicle's home (a vehicle started elsewhere, e.g. at SIH's default home in Montreal, is refused
  so). PX4 gives the same answer to any start before it is ready;
- fence_problems: a geofence that leaves the vehicle's home out ("Geofence invalid, doesn't contain
  Home position"): PX4 then ignores it and still starts the mission, unfenced;
- reported_reached / reached_item / reported_items: which MISSION_ITEM_REACHED PX4 sends when it
  reaches an item (none for a take-off or a final RTL; a waypoint's report usually carries the seq of
  the DO_ items right after it), and back from a report to the item it is about;
- px4_millimetres: a photo's altitude as PX4's CAMERA_IMAGE_CAPTURED rounds it.
Each problem is PX4's own console / STATUSTEXT line.
Everything here was measured (sitl_tests/px4_mission_session.py, docs/px4-missions.md).

Pure Python, no MAVLink library: the mock and the uploader both use it.
"""

from __future__ import annotations

import math
from dataclasses import replace

from .mission_items import (
    CMD_CONDITION_DELAY,
    CMD_DO_CHANGE_SPEED,
    CMD_DO_DIGICAM_CONTROL,
    CMD_DO_GIMBAL_MANAGER_PITCHYAW,
    CMD_DO_JUMP,
    CMD_DO_LAND_START,
    CMD_DO_MOUNT_CONTROL,
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_DO_SET_CAM_TRIGG_INTERVAL,
    CMD_DO_SET_ROI,
    CMD_DO_SET_ROI_LOCATION,
    CMD_DO_VTOL_TRANSITION,
    CMD_FENCE_CIRCLE_EXCLUSION,
    CMD_FENCE_CIRCLE_INCLUSION,
    CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_IMAGE_START_CAPTURE,
    CMD_IMAGE_STOP_CAPTURE,
    CMD_NAV_DELAY,
    CMD_NAV_LAND,
    CMD_NAV_LAST,
    CMD_NAV_LOITER_TIME,
    CMD_NAV_LOITER_TO_ALT,
    CMD_NAV_LOITER_UNLIM,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_INT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_RELATIVE_ALT_INT,
    FRAME_MISSION,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_ERROR,
    MAV_MISSION_UNSUPPORTED,
    MAV_MISSION_UNSUPPORTED_FRAME,
    MissionType,
    WireItem,
    as_float32,
)

PX4_GLOBAL_FRAMES = frozenset({FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT})
# Commands PX4 takes in a global frame (a position).
GLOBAL_COMMANDS = frozenset({CMD_NAV_WAYPOINT, CMD_NAV_LOITER_UNLIM, CMD_NAV_LOITER_TIME, CMD_NAV_LAND, CMD_NAV_TAKEOFF,
                             CMD_NAV_LOITER_TO_ALT, CMD_DO_SET_ROI_LOCATION, CMD_DO_SET_ROI})
# Commands PX4 takes in frame 2 (MAV_FRAME_MISSION).
MISSION_FRAME_COMMANDS = frozenset({
    CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_DELAY, CMD_CONDITION_DELAY, CMD_DO_JUMP, CMD_DO_CHANGE_SPEED, CMD_DO_LAND_START,
    CMD_DO_SET_ROI, CMD_DO_DIGICAM_CONTROL, CMD_DO_MOUNT_CONTROL, CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_DO_SET_CAM_TRIGG_INTERVAL, CMD_DO_GIMBAL_MANAGER_PITCHYAW, CMD_IMAGE_START_CAPTURE, CMD_IMAGE_STOP_CAPTURE,
    CMD_DO_VTOL_TRANSITION})
# param4 is a yaw PX4 keeps in radians
YAW_COMMANDS = frozenset({CMD_NAV_WAYPOINT, CMD_NAV_LOITER_UNLIM, CMD_NAV_LOITER_TIME, CMD_NAV_LAND, CMD_NAV_TAKEOFF})
FENCE_COMMANDS = frozenset({CMD_FENCE_POLYGON_VERTEX_INCLUSION, CMD_FENCE_POLYGON_VERTEX_EXCLUSION,
                            CMD_FENCE_CIRCLE_INCLUSION, CMD_FENCE_CIRCLE_EXCLUSION})
_INT_FRAMES = {FRAME_GLOBAL: FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT: FRAME_GLOBAL_RELATIVE_ALT_INT}

MIS_DIST_1WP_DEFAULT = 900.0  # metres: PX4's default limit from the vehicle to the first waypoint
EARTH_RADIUS_M = 6371000.0    # PX4's CONSTANTS_RADIUS_OF_EARTH

# PX4's own words (seen on SIH: STATUSTEXT for the first and last, the console for the distance).
GEOFENCE_WITHOUT_HOME = "Geofence invalid, doesn't contain Home position"
START_DENIED = "Mission start denied! No valid mission"


def item_result(item: WireItem) -> int:
    """The MISSION_ACK type PX4 answers this item with (ACCEPTED or why not)."""
    frame, command = item.frame, item.command
    if frame != FRAME_MISSION and frame not in PX4_GLOBAL_FRAMES:
        return MAV_MISSION_UNSUPPORTED_FRAME  # LOCAL_NED, TERRAIN_ALT(_INT), ...
    if item.mission_type == MissionType.MISSION and command == CMD_RALLY_POINT and frame != FRAME_MISSION:
        return MAV_MISSION_ERROR
    if item.mission_type == MissionType.FENCE:
        return MAV_MISSION_ACCEPTED if command in FENCE_COMMANDS and frame != FRAME_MISSION else MAV_MISSION_UNSUPPORTED
    if item.mission_type == MissionType.RALLY:
        return MAV_MISSION_ACCEPTED if command == CMD_RALLY_POINT and frame != FRAME_MISSION else MAV_MISSION_UNSUPPORTED
    allowed = MISSION_FRAME_COMMANDS if frame == FRAME_MISSION else GLOBAL_COMMANDS
    return MAV_MISSION_ACCEPTED if command in allowed else MAV_MISSION_UNSUPPORTED


_PI_F = as_float32(math.pi)
_DEG_TO_RAD_F, _RAD_TO_DEG_F = as_float32(_PI_F / 180.0), as_float32(180.0 / _PI_F)
_TWO_PI_F = as_float32(2.0 * math.pi)


def px4_millimetres(metres: float) -> int:
    """An altitude as CAMERA_IMAGE_CAPTURED carries it: camera_capture keeps metres in a float32 and
    PX4's stream multiplies by 1e3f in float32, then truncates (209.99999 m -> 210000 mm, not 209999)."""
    return int(as_float32(as_float32(metres) * 1000.0))


def px4_yaw(degrees: float) -> float:
    """A yaw param as PX4 hands it back: kept in float32 radians wrapped to [0, 2 pi), then degrees
    again (7 -> 6.9999995, -90 -> 270; NaN stays NaN)."""
    if not math.isfinite(degrees):
        return degrees
    radians = as_float32(as_float32(degrees) * _DEG_TO_RAD_F)
    radians = as_float32(math.fmod(radians, _TWO_PI_F))
    if radians < 0:
        radians = as_float32(radians + _TWO_PI_F)
    return as_float32(radians * _RAD_TO_DEG_F)


def px4_stored(item: WireItem) -> WireItem:
    """The item as PX4 returns it on download (its seq, current flag and mission_type kept)."""
    frame = _INT_FRAMES.get(item.frame, item.frame)
    if item.mission_type == MissionType.FENCE:
        return replace(item, frame=frame, z=0.0, autocontinue=0)
    if item.mission_type == MissionType.MISSION and item.command in YAW_COMMANDS:
        param3 = 0.0 if item.command == CMD_NAV_WAYPOINT else item.param3  # no pass radius on PX4
        return replace(item, frame=frame, param3=param3, param4=px4_yaw(item.param4))
    if item.mission_type == MissionType.MISSION and item.command == CMD_DO_JUMP and math.isfinite(item.param2) \
            and abs(item.param2) < 2**31:
        # Its repeat count is a uint16: "for ever" (-1) comes back as 65535 (measured on SIH).
        return replace(item, frame=frame, param2=float(int(item.param2) & 0xFFFF))
    return replace(item, frame=frame)


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance in metres (PX4's get_distance_to_next_waypoint: haversine)."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.atan2(math.sqrt(a), math.sqrt(max(1 - a, 0.0)))


def _in_polygon(lat: float, lon: float, ring: list[tuple[float, float]]) -> bool:
    """Even-odd rule on (lat, lon) as plane coordinates, as PX4's geofence does."""
    inside = False
    j = len(ring) - 1
    for i, (yi, xi) in enumerate(ring):
        yj, xj = ring[j]
        if (yi > lat) != (yj > lat) and lon < (xj - xi) * (lat - yi) / (yj - yi) + xi:
            inside = not inside
        j = i
    return inside


def _fence_shapes(fence: list[WireItem]) -> list[tuple[int, object]]:
    """(command, shape): polygons as [(lat, lon), ...], circles as (lat, lon, radius)."""
    shapes: list[tuple[int, object]] = []
    i = 0
    while i < len(fence):
        item = fence[i]
        if item.command in (CMD_FENCE_POLYGON_VERTEX_INCLUSION, CMD_FENCE_POLYGON_VERTEX_EXCLUSION):
            count = max(int(round(item.param1)), 1)
            shapes.append((item.command, [(v.x / 1e7, v.y / 1e7) for v in fence[i:i + count]]))
            i += count
        else:
            shapes.append((item.command, (item.x / 1e7, item.y / 1e7, item.param1)))
            i += 1
    return shapes


def home_in_fence(fence: list[WireItem], lat: float, lon: float) -> bool:
    """Whether (lat, lon) is inside some inclusion area (when there is one) and outside every exclusion."""
    included: bool | None = None
    for command, shape in _fence_shapes(fence):
        if command in (CMD_FENCE_CIRCLE_INCLUSION, CMD_FENCE_CIRCLE_EXCLUSION):
            clat, clon, radius = shape  # type: ignore[misc]
            inside = distance_m(lat, lon, clat, clon) <= radius
        else:
            inside = _in_polygon(lat, lon, shape)  # type: ignore[arg-type]
        if command in (CMD_FENCE_POLYGON_VERTEX_INCLUSION, CMD_FENCE_CIRCLE_INCLUSION):
            included = bool(included) or inside
        elif inside:
            return False
    return included is not False


def first_position(mission: list[WireItem]) -> tuple[float, float] | None:
    """Latitude and longitude of the first mission item with a position (PX4's "first waypoint")."""
    for item in sorted(mission, key=lambda it: it.seq):
        if item.frame in PX4_GLOBAL_FRAMES and item.command in GLOBAL_COMMANDS:
            return item.x / 1e7, item.y / 1e7
    return None


def fence_problems(fence: list[WireItem], home: tuple[float, float]) -> list[str]:
    """PX4's line when the fence leaves the vehicle's home out: it then takes the fence as invalid
    (and, measured on SIH, still starts the mission: the flight is unfenced)."""
    return [GEOFENCE_WITHOUT_HOME] if fence and not home_in_fence(fence, *home) else []


def start_refusals(mission: list[WireItem], home: tuple[float, float],
                   dist_1wp: float = MIS_DIST_1WP_DEFAULT) -> list[str]:
    """PX4's reasons (its own lines) for refusing to start `mission` on a vehicle whose home is `home`
    (lat, lon): the first waypoint MIS_DIST_1WP or more away; empty when PX4 would start it."""
    problems = []
    first = first_position(mission)
    if first is not None and dist_1wp > 0:
        distance = distance_m(first[0], first[1], *home)
        if distance >= dist_1wp:
            problems.append(f"First waypoint too far away: {int(distance)}m, {int(dist_1wp)} max")
    return problems


UNREPORTED = frozenset({CMD_NAV_TAKEOFF, CMD_NAV_RETURN_TO_LAUNCH})


def reported_reached(commands: list[int], seq: int) -> int | None:
    """The seq of the MISSION_ITEM_REACHED PX4 sends when it reaches mission item `seq` (`commands`:
    the mission's commands by seq), or None when it sends none. Measured on SIH v1.15.4 flying our
    missions (sitl_tests/test_fleet_px4.py): nothing for the NAV_TAKEOFF nor for the final RTL (it
    lands and disarms without one); a waypoint is reported only after PX4 has run the DO_ items that
    follow it, with the last of their seqs (waypoint 3, DO_SET_CAM_TRIGG_DIST 4: "reached 4")."""
    if not 0 <= seq < len(commands) or commands[seq] in UNREPORTED:
        return None
    while seq + 1 < len(commands) and commands[seq + 1] > CMD_NAV_LAST:
        seq += 1
    return seq


def reached_item(commands: list[int], reported: int) -> int:
    """The navigation item a MISSION_ITEM_REACHED with seq `reported` is about: the last one at or before
    it. PX4 sends either the waypoint's own seq or, once it has run the DO_ items after it, the last of
    theirs (SIH: waypoint 11 of the fleet test came once as "reached 11" then "reached 12", usually as 12)."""
    seq = min(reported, len(commands) - 1)
    while seq > 0 and commands[seq] > CMD_NAV_LAST:
        seq -= 1
    return seq


def reported_items(commands: list[int]) -> list[int]:
    """The navigation items PX4 reports reaching when it flies a whole mission (`commands` by seq), in
    order: every one but the NAV_TAKEOFF and the final RTL."""
    return [k for k, command in enumerate(commands) if command <= CMD_NAV_LAST and command not in UNREPORTED]
