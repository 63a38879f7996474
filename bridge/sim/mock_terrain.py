"""The mock vehicle's terrain database: ArduCopter's AP_Terrain with no terrain files, filled by the ground station.

Owns, for one ArduPilot mock vehicle given a ground (VehicleOptions.ground), what ArduCopter SITL does with its
terrain when its terrain/ folder is empty (ArduPilot's libraries/AP_Terrain: AP_Terrain.cpp, TerrainGCS.cpp,
TerrainMission.cpp, TerrainUtil.cpp; the grid layout is formats/terrain_grid.py's):
- a cache of GRID_CACHE_SIZE grids (28 x 32 int16 heights and a 56-bit bitmap of the 4 x 4 blocks loaded),
  least recently used first out; looking a point up makes its grid's entry, and the entry's missing blocks are
  then pending;
- update(), TERRAIN_UPDATE_HZ of its clock once it has a position: the ground at home, at its position and at
  the 9 points 0.7 grid away around it; the mission's NAV_WAYPOINTs, each with 4 points 10 spacings away at
  45, 135, 225 and 315 degrees, up to 20 points per update and none while blocks are pending;
- the TERRAIN_REQUEST stream (nothing unless asked, as ArduCopter 4.7): each time it is due, at most one
  grid every REQUEST_PACING_S of its clock, its missing blocks as the mask: its own grid first, then the 9
  around it, then any other grid in the cache (a mission point's, a TERRAIN_CHECK's);
- TERRAIN_DATA stored into its grid (ignored for a grid not in the cache or another spacing);
- TERRAIN_REPORT: on the TERRAIN_REPORT stream for its position, and for the point of each TERRAIN_CHECK
  (spacing 0 when it has no ground there or at home; pending and loaded over the whole cache);
- the pre-arm check "waiting for terrain data" while a mission with terrain-frame items is loaded and blocks
  are pending, or the ground at home or at its position or a mission point is still missing;
- the terrain offset the flight (mock_flight) adds to a terrain-frame item's height: the ground at a point
  less the ground at home, both from what it was sent (bilinear between the four grid points around, as
  height_amsl does), never from the DEM file. With no ground at the point, the last ground it had under
  itself stands in (AP_Terrain's extrapolation).
The streams run on the vehicle's simulated clock, as SITL's scheduler does (a sped-up mock asks as often per
simulated second as ArduCopter SITL at that speed-up). TERRAIN_ENABLE 0 or TERRAIN_OPTIONS bit 0 (Disable
Download) stop the asking, as on ArduPilot. The cache lives in RAM: a reboot forgets it.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..formats.mission_items import (
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_GLOBAL_TERRAIN_ALT_INT,
    Flavour,
    MissionType,
    WireItem,
)
from ..formats.terrain_grid import (
    ALL_BLOCKS,
    BLOCK_SIDE,
    BLOCKS_EAST,
    GRID_POINTS_EAST,
    GRID_POINTS_NORTH,
    MASK_BITS,
    GridInfo,
    block_bit,
    grid_info,
    offset_bearing_e7,
    offset_e7,
)
from ..link.connection import mavlink
from .vehicle_part import VehiclePart

GRID_CACHE_SIZE = 12  # TERRAIN_GRID_BLOCK_CACHE_SIZE: grids held in memory
TERRAIN_UPDATE_HZ = 10.0  # ArduCopter's scheduler runs terrain_update at 10 Hz
REQUEST_PACING_S = 2.0  # TerrainGCS.cpp send_request: one TERRAIN_REQUEST per 2 s of the vehicle's clock at most
SURROUNDING_GRID_FRACTION = 0.7  # the 9 points around the vehicle: 0.7 grid away (north x 28, east x 32 spacings)
MISSION_POINT_SPACINGS = 10  # TerrainMission.cpp: 4 points this many grid spacings from each waypoint
MISSION_POINTS_PER_UPDATE = 20
TERRAIN_FRAMES = frozenset({FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT})
WAITING_TEXT = "PreArm: waiting for terrain data"  # AP_Terrain::pre_arm_checks through AP_Arming's "PreArm: "
# ArduCopter's defaults for the terrain parameters the ground station reads or sets (session/terrain.py,
# link.params.terrain_plan_settings). RTL_ALT_TYPE is held, not flown: the mock's RTL stays at RTL_ALT above home.
TERRAIN_PARAMS = {"TERRAIN_ENABLE": 1.0, "TERRAIN_SPACING": 100.0, "TERRAIN_OPTIONS": 0.0, "TERRAIN_OFS_MAX": 30.0,
                  "WPNAV_RFND_USE": 1.0, "RTL_ALT_TYPE": 0.0}
DISABLE_DOWNLOAD = 1  # TERRAIN_OPTIONS bit 0
TERRAIN_STREAMS = (mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST, mavlink.MAVLINK_MSG_ID_TERRAIN_REPORT)
DEFAULT_STREAM_S = 1.0  # SET_MESSAGE_INTERVAL 0: the default rate


class GroundModel(Protocol):
    """The true ground of the simulated world (geo.dem.Ground has this shape): metres above sea level at WGS84
    points, NaN where unknown. The mock lands on it; the terrain it flies by is only what it was sent."""

    def height_amsl(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray: ...


@dataclass
class TerrainGrid:
    """One grid of the cache: 28 x 32 heights (north x east), which 4 x 4 blocks have come, when last used."""

    lat_e7: int
    lon_e7: int
    spacing: int
    heights: np.ndarray = field(repr=False)  # int16 (GRID_POINTS_NORTH, GRID_POINTS_EAST)
    bitmap: int = 0
    last_access: int = 0

    def has(self, idx_north: int, idx_east: int) -> bool:
        return bool(self.bitmap >> block_bit(idx_north, idx_east) & 1)


class MockTerrain(VehiclePart):
    """One ArduPilot mock vehicle's terrain database, its requests and reports, and its terrain pre-arm check."""

    HANDLERS = {"TERRAIN_DATA": "_on_data", "TERRAIN_CHECK": "_on_check"}

    def __init__(self, vehicle: Any) -> None:
        super().__init__(vehicle)
        self.requests_sent = 0  # TERRAIN_REQUESTs sent since the vehicle was made (all boots)
        self.blocks_received = 0  # TERRAIN_DATA stored since then

    def on_boot(self, now: float) -> None:
        """A (re)boot: an empty cache, no streams, nothing asked yet."""
        self.grids: OrderedDict[tuple[int, int, int], TerrainGrid] = OrderedDict()  # least recently used first
        self._accesses = 0
        self.intervals: dict[int, float | None] = dict.fromkeys(TERRAIN_STREAMS)  # simulated seconds; None: off
        self._next_due = dict.fromkeys(TERRAIN_STREAMS, 0.0)
        self._next_update = 0.0
        self._last_request = -REQUEST_PACING_S
        self.home_height: float | None = None
        self.current_height: float | None = None  # the ground under it when it last had it (extrapolation)
        self._mission_seen: list[WireItem] | None = None
        self._next_mission_index = 0  # 0: the mission's points are all loaded (or there is none)
        self._next_mission_pos = 0

    # ------------------------------------------------------------------------------ its parameters and clock
    @property
    def spacing(self) -> int:
        return int(self.vehicle.params.get("TERRAIN_SPACING", TERRAIN_PARAMS["TERRAIN_SPACING"]))

    @property
    def enabled(self) -> bool:
        return self.vehicle.params.get("TERRAIN_ENABLE", 1.0) > 0 and self.spacing > 0

    def _clock(self, now: float) -> float:
        return int(self.vehicle.time_boot_ms(now)) / 1000.0

    def _position_e7(self) -> tuple[int, int]:
        s = self.vehicle.flight.state
        return int(round(s.lat * 1e7)), int(round(s.lon * 1e7))

    def _home_e7(self) -> tuple[int, int]:
        lat, lon, _ = self.options.home
        return int(round(lat * 1e7)), int(round(lon * 1e7))

    # ------------------------------------------------------------------------------ the cache
    def _grid(self, info: GridInfo) -> TerrainGrid:
        """AP_Terrain::find_grid_cache: the grid of `info`, made (and the least recently used one dropped) if new."""
        key = (info.grid_lat_e7, info.grid_lon_e7, self.spacing)
        self._accesses += 1
        grid = self.grids.get(key)
        if grid is None:
            if len(self.grids) >= GRID_CACHE_SIZE:
                self.grids.popitem(last=False)
            grid = TerrainGrid(*key, heights=np.zeros((GRID_POINTS_NORTH, GRID_POINTS_EAST), dtype=np.int16))
            self.grids[key] = grid
        else:
            self.grids.move_to_end(key)
        grid.last_access = self._accesses
        return grid

    def height_amsl(self, lat_e7: int, lon_e7: int) -> float | None:
        """AP_Terrain::height_amsl: the ground (m above sea level) at a point, bilinear between the four grid
        points around it; None until their blocks have come (looking makes the grid's entry: then it is asked for)."""
        if not self.enabled:
            return None
        info = grid_info(lat_e7, lon_e7, self.spacing)
        grid = self._grid(info)
        i, j = info.idx_north, info.idx_east
        if not (grid.has(i, j) and grid.has(i, j + 1) and grid.has(i + 1, j) and grid.has(i + 1, j + 1)):
            return None
        h = grid.heights
        west = (1.0 - info.frac_north) * float(h[i, j]) + info.frac_north * float(h[i + 1, j])
        east = (1.0 - info.frac_north) * float(h[i, j + 1]) + info.frac_north * float(h[i + 1, j + 1])
        height = (1.0 - info.frac_east) * west + info.frac_east * east
        if (lat_e7, lon_e7) == self._home_e7():
            self.home_height = height
        return height

    def statistics(self) -> tuple[int, int]:
        """AP_Terrain::get_statistics: (pending, loaded) blocks over the grids of the cache at the current spacing."""
        pending = loaded = 0
        for grid in self.grids.values():
            if grid.spacing != self.spacing:
                continue
            count = grid.bitmap.bit_count()
            pending += MASK_BITS - count
            loaded += count
        return pending, loaded

    def terrain_offset(self, lat: float, lon: float) -> float | None:
        """The ground at (lat, lon) above the ground at home, from what it was sent (the height a terrain-frame
        item adds to its altitude above home); the last ground under it stands in where it has none; None
        without the ground at home."""
        home = self.height_amsl(*self._home_e7())
        if home is None:
            return None
        here = self.height_amsl(int(round(lat * 1e7)), int(round(lon * 1e7)))
        if here is None:
            here = self.current_height
        return None if here is None else here - home

    # ------------------------------------------------------------------------------ ticking
    def tick(self, now: float) -> None:
        """Its terrain_update and its two streams, each when due on its clock."""
        if not self.vehicle.has_fix or not self.enabled:
            return
        clock = self._clock(now)
        if clock >= self._next_update:
            self._next_update = clock + 1.0 / TERRAIN_UPDATE_HZ
            self._update()
        for msgid, interval in self.intervals.items():
            if interval is not None and clock >= self._next_due[msgid]:
                self._next_due[msgid] = clock + interval
                if msgid == mavlink.MAVLINK_MSG_ID_TERRAIN_REQUEST:
                    self._send_request(clock)
                else:
                    self._send_report(*self._position_e7(), extrapolate=True)

    def set_interval(self, msgid: int, interval_us: float, now: float) -> bool:
        """SET_MESSAGE_INTERVAL for TERRAIN_REQUEST or TERRAIN_REPORT (negative: off; 0: the default rate);
        False for any other message."""
        if msgid not in self.intervals:
            return False
        if interval_us < 0:
            self.intervals[msgid] = None
        else:
            self.intervals[msgid] = DEFAULT_STREAM_S if interval_us == 0 else interval_us / 1e6
        self._next_due[msgid] = self._clock(now)
        return True

    def _update(self) -> None:
        """AP_Terrain::update: the ground at home, here and around here, then the mission's points."""
        self.height_amsl(*self._home_e7())
        lat, lon = self._position_e7()
        here = self.height_amsl(lat, lon)
        if here is not None:
            self.current_height = here
        for north, east in self._surrounding(lat, lon):
            self.height_amsl(north, east)
        self._update_mission()

    def _surrounding(self, lat_e7: int, lon_e7: int) -> list[tuple[int, int]]:
        """The 9 points 0.7 grid away around a position (itself among them), as update_surrounding_tiles and
        send_request visit them: north from -1 to 1, east from -1 to 1 within."""
        step_north = GRID_POINTS_NORTH * SURROUNDING_GRID_FRACTION * self.spacing
        step_east = GRID_POINTS_EAST * SURROUNDING_GRID_FRACTION * self.spacing
        return [offset_e7(lat_e7, lon_e7, x * step_north, y * step_east) for x in (-1, 0, 1) for y in (-1, 0, 1)]

    def _mission_items(self) -> list[WireItem]:
        items: list[WireItem] = self.vehicle.mission_server.stores[MissionType.MISSION]
        return items

    def _update_mission(self) -> None:
        """TerrainMission.cpp update_mission_data: each waypoint's 5 points (4 around it, then itself), from the
        start whenever the mission changes; nothing while blocks are pending."""
        items = self._mission_items()
        if items is not self._mission_seen:
            self._mission_seen = items
            self._next_mission_index, self._next_mission_pos = 1, 0
        if self._next_mission_index == 0 or self.statistics()[0]:
            return
        for _ in range(MISSION_POINTS_PER_UPDATE):
            while True:
                if self._next_mission_index >= len(items):
                    self._next_mission_index = self._next_mission_pos = 0
                    return
                item = items[self._next_mission_index]
                # A spline waypoint is prefetched as a waypoint is (TerrainMission.cpp).
                if item.command in (CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT) and (item.x or item.y):
                    break
                self._next_mission_index += 1
            lat_e7, lon_e7 = int(item.x), int(item.y)
            if self._next_mission_pos != 4:
                lat_e7, lon_e7 = offset_bearing_e7(lat_e7, lon_e7, 45.0 + 90.0 * self._next_mission_pos,
                                                   float(self.spacing * MISSION_POINT_SPACINGS))
            if self.height_amsl(lat_e7, lon_e7) is None:
                return  # asked for: checked again at the next update
            self._next_mission_pos += 1
            if self._next_mission_pos == 5:
                self._next_mission_index += 1
                self._next_mission_pos = 0

    # ------------------------------------------------------------------------------ asking
    def _request_missing(self, grid: TerrainGrid, clock: float) -> bool:
        """TerrainGCS.cpp request_missing: a TERRAIN_REQUEST for the grid's missing blocks, if it has any."""
        if grid.spacing != self.spacing or grid.bitmap & ALL_BLOCKS == ALL_BLOCKS:
            return False
        self.mav.terrain_request_send(grid.lat_e7, grid.lon_e7, grid.spacing, ALL_BLOCKS & ~grid.bitmap)
        self._last_request = clock
        self.requests_sent += 1
        return True

    def _send_request(self, clock: float) -> None:
        """TerrainGCS.cpp send_request: one grid at most, not sooner than REQUEST_PACING_S after the last."""
        if int(self.vehicle.params.get("TERRAIN_OPTIONS", 0.0)) & DISABLE_DOWNLOAD:
            return
        if clock - self._last_request < REQUEST_PACING_S:
            return
        lat, lon = self._position_e7()
        own = self._grid(grid_info(lat, lon, self.spacing))
        if self._request_missing(own, clock):
            return
        for north, east in self._surrounding(lat, lon):
            if self._request_missing(self._grid(grid_info(north, east, self.spacing)), clock):
                return
        for grid in list(self.grids.values()):  # the grids a mission point or a TERRAIN_CHECK made
            if self._request_missing(grid, clock):
                return
        self._request_missing(self._grid(grid_info(lat, lon, self.spacing)), clock)

    # ------------------------------------------------------------------------------ answering
    def _on_data(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        """TerrainGCS.cpp handle_terrain_data: 16 heights into the grid they belong to, if it is in the cache."""
        bit = int(msg.gridbit)
        grid = self.grids.get((int(msg.lat), int(msg.lon), int(msg.grid_spacing)))
        if grid is None or grid.spacing != self.spacing or bit >= MASK_BITS:
            return
        i0, j0 = (bit // BLOCKS_EAST) * BLOCK_SIDE, (bit % BLOCKS_EAST) * BLOCK_SIDE
        grid.heights[i0:i0 + BLOCK_SIDE, j0:j0 + BLOCK_SIDE] = np.asarray(msg.data, dtype=np.int16).reshape(
            BLOCK_SIDE, BLOCK_SIDE)
        grid.bitmap |= 1 << bit
        self.blocks_received += 1

    def _on_check(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        """TerrainGCS.cpp handle_terrain_check: a TERRAIN_REPORT for the point asked about."""
        self._send_report(int(msg.lat), int(msg.lon), extrapolate=False)

    def _send_report(self, lat_e7: int, lon_e7: int, extrapolate: bool) -> None:
        """TerrainGCS.cpp send_terrain_report: the ground at a point (spacing 0 without it or without the ground
        at home), the vehicle's height above it, the cache's pending and loaded blocks."""
        terrain_height = home_height = 0.0
        spacing = 0
        home = self.height_amsl(*self._home_e7()) if self.vehicle.has_fix else None
        there = self.height_amsl(lat_e7, lon_e7) if home is not None else None
        if home is not None:
            home_height = home
        if there is not None:
            terrain_height, spacing = there, self.spacing
        elif extrapolate and self.current_height is not None:
            terrain_height = self.current_height  # what navigation uses meanwhile
        pending, loaded = self.statistics()
        current = 0.0
        if spacing or (extrapolate and self.current_height is not None):
            current = self.vehicle.flight.state.alt  # its altitude above home
        current += home_height - terrain_height
        self.mav.terrain_report_send(lat_e7, lon_e7, spacing, terrain_height, current, pending, loaded)

    # ------------------------------------------------------------------------------ arming
    def mission_needs_terrain(self) -> bool:
        """Whether the stored mission has a terrain-frame item (AP_Mission::contains_terrain_alt_items)."""
        return any(item.frame in TERRAIN_FRAMES for item in self._mission_items()[1:])

    def arming_problem(self) -> str:
        """AP_Arming::terrain_checks: WAITING_TEXT while a terrain-frame mission is loaded and the terrain is not;
        '' when it may arm."""
        if self.flavour is not Flavour.ARDUPILOT or not self.enabled or not self.mission_needs_terrain():
            return ""
        if self._mission_items() is not self._mission_seen:
            return WAITING_TEXT  # a new mission its next update has not looked at yet
        if (self.statistics()[0] or self.current_height is None or self.home_height is None
                or self._next_mission_index != 0):
            return WAITING_TEXT
        return ""
