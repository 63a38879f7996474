"""A mission over a DEM for an autopilot that takes no terrain frame (PX4): altitudes above sea level.

drone_missions.build_mission writes a plan over a DEM with its waypoints in the terrain frame (a height
above the ground under the drone), which ArduPilot flies as it is. PX4 refuses that frame, so for PX4
each waypoint becomes an altitude above sea level (MAV_FRAME_GLOBAL: the ground there plus the height), and
each leg is split where the ground under it departs from the straight line between its ends by more
than TERRAIN_TOLERANCE_M (terrain_legs.amsl_track), as QGroundControl does for PX4, and the first stretch of
each leg cut short enough that PX4 stays within it while it turns onto the leg (it heads for the next
waypoint's altitude then, not along the line: terrain_legs' docstring says where in PX4). The added points are
plain waypoints: the camera commands stay after the waypoints they followed, so the photos are spaced
as before (the trigger distance runs on through an added point).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from missionplan.bridge.formats.mission_items import (CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL,
                                                       FRAME_GLOBAL_TERRAIN_ALT, Mission, MissionItem)

from .terrain_legs import amsl_track

TERRAIN_TOLERANCE_M = 2.0  # the most a leg's straight line may depart from the height above the ground
TERRAIN_STEP_M = 5.0  # the ground is looked at this often along each leg

GroundHeights = Callable[[np.ndarray, np.ndarray], np.ndarray]


def px4_over_ground(mission: Mission, ground: GroundHeights) -> Mission:
    """`mission` (terrain-frame waypoints after a take-off from home) with its waypoints above sea level and
    its legs split over the ground; every other item as it was."""
    legs = [i for i, item in enumerate(mission.items) if item.frame == FRAME_GLOBAL_TERRAIN_ALT
            and item.command == CMD_NAV_WAYPOINT]
    if not legs:
        return mission
    assert mission.home is not None
    home_lat, home_lon, _ = mission.home
    takeoff = next(item for item in mission.items if item.command == CMD_NAV_TAKEOFF)
    # The track starts over the launch point at the take-off height, so the first leg is split too.
    lat = np.array([home_lat] + [mission.items[i].x for i in legs])
    lon = np.array([home_lon] + [mission.items[i].y for i in legs])
    height = np.array([takeoff.z] + [mission.items[i].z for i in legs])
    out_lat, out_lon, amsl, source = amsl_track(lat, lon, height, ground, tolerance_m=TERRAIN_TOLERANCE_M,
                                                step_m=TERRAIN_STEP_M, lead_in_turns=True)
    added: dict[int, list[MissionItem]] = {}  # before item index: the points added on the leg that ends there
    at: dict[int, float] = {}  # item index: its altitude above sea level
    pending: list[MissionItem] = []
    template = mission.items[legs[0]]  # an added point is a waypoint like the others, above sea level
    for k in range(1, len(out_lat)):
        if source[k] < 0:
            pending.append(replace(template, frame=FRAME_GLOBAL, x=float(out_lat[k]), y=float(out_lon[k]),
                                   z=float(amsl[k])))
            continue
        index = legs[int(source[k]) - 1]
        at[index], added[index], pending = float(amsl[k]), pending, []
    items: list[MissionItem] = []
    for i, item in enumerate(mission.items):
        if i in at:
            items.extend(added[i])
            item = replace(item, frame=FRAME_GLOBAL, z=at[i])
        items.append(item)
    return replace(mission, items=items)


# ------------------------------------------------------------------------------------------- as flown
# ArduPilot follows the ground it is served on a grid TERRAIN_SPACING apart (bilinear between grid points), not
# the DEM itself: over a hill narrower than a few grid squares it cuts the crest and sags into the hollows. A
# plan looks at every metre of its tracks on that grid and picks the coarsest spacing that stays within
# FOLLOW_TOLERANCE_M of the DEM (the rest of TERRAIN_TOLERANCE_M is the vehicle's own height hold); upload and fly
# set TERRAIN_SPACING to it.
TERRAIN_SPACINGS = (100, 50, 30, 20, 10)  # ArduCopter's default first; each quadruples the blocks of the last
FOLLOW_TOLERANCE_M = 1.0


def _waypoint_legs(mission: Mission) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """lat, lon, the altitude as written and the frame of each positional waypoint after the take-off."""
    points = [(item.x, item.y, item.z, item.frame) for item in mission.items if item.command == CMD_NAV_WAYPOINT]
    if not points:
        return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=int)
    lat, lon, z, frame = (np.array(column) for column in zip(*points))
    return lat, lon, z, frame.astype(int)


def flown_above_ground(mission: Mission, ground: GroundHeights, spacing: int | None,
                       step_m: float = TERRAIN_STEP_M) -> np.ndarray:
    """Heights above the DEM along a mission's waypoint legs as its autopilot flies them: terrain-frame legs on
    ArduPilot's grid at `spacing` (the height interpolated between the waypoints' heights, over the ground it
    was served), above-sea-level legs (PX4's) straight. Empty for a mission of fewer than two waypoints."""
    from missionplan.bridge.formats.terrain_grid import served_heights

    from .terrain_legs import flown_heights, sample_legs

    lat, lon, z, frames = _waypoint_legs(mission)
    if len(lat) < 2:
        return np.zeros(0)
    if (frames == FRAME_GLOBAL).all():
        return flown_heights(lat, lon, z, ground, step_m)
    at_lat, at_lon, leg = sample_legs(lat, lon, step_m)
    # Where along its leg each sample lies (0 at its start, 1 at its end), for the height between the two.
    start = np.column_stack([lat[leg], lon[leg]])
    span = np.column_stack([lat[leg + 1], lon[leg + 1]]) - start
    travelled = np.column_stack([at_lat, at_lon]) - start
    length2 = (span ** 2).sum(axis=1)
    share = np.divide((travelled * span).sum(axis=1), length2, out=np.zeros_like(length2), where=length2 > 0)
    height = z[leg] + (z[leg + 1] - z[leg]) * np.clip(share, 0.0, 1.0)
    served = served_heights(at_lat, at_lon, int(spacing or TERRAIN_SPACINGS[0]), ground)
    return served + height - ground(at_lat, at_lon)


def terrain_spacing(missions: list[Mission], ground: GroundHeights) -> tuple[int, list[np.ndarray]]:
    """The coarsest of TERRAIN_SPACINGS at which every terrain-frame mission stays within FOLLOW_TOLERANCE_M of
    its heights above the DEM (the finest when none does: the plan then says how far off it is), and each
    mission's heights as flown at it (flown_above_ground), which the plan reports."""
    for spacing in TERRAIN_SPACINGS:
        worst, flown_all = 0.0, []
        for mission in missions:
            _, _, z, _ = _waypoint_legs(mission)
            flown = flown_above_ground(mission, ground, spacing)
            flown_all.append(flown)
            if len(flown):
                wanted = float(np.max(z))  # a survey holds one height above the ground
                worst = max(worst, float(np.nanmax(np.abs(flown - wanted))))
        if worst <= FOLLOW_TOLERANCE_M or spacing == TERRAIN_SPACINGS[-1]:
            return spacing, flown_all
    raise AssertionError("unreachable: the finest spacing returns")
