"""Heights above the ground of a flight over a DEM: what the judge measures and what the photos' geotags carry.

A plan made over a DEM (report.json `georeference.terrain`) keeps the ground it used in its folder (geo.dem_copy),
and put each drone's home on that ground: its altitude above sea level is the DEM's at the launch point. A vehicle
reports its height above its home (GLOBAL_POSITION_INT relative_alt in every sample, CAMERA_FEEDBACK alt_rel
for every photo), so
    altitude above sea level = the ground at the launch point + the reported height,
    height above the ground  = that altitude - the ground under the vehicle,
the way ArduPilot's terrain following measures it too (the terrain's height at home plus the height above
home, less the terrain's height under the vehicle). The vehicle's own sea-level altitude (GPS at arming)
is not used: it wanders by metres from one flight to the next, while the DEM is the truth the plan was
made against.

The judge (flight_report) measures every sample of a drone's survey, from the end of its take-off (the
take-off item reached) to its last waypoint reached: the climb, the way home and the landing are meant to
be below the planned height. A drone left the tolerance when a sample's height above the ground departs
from the planned height by more than HEIGHT_TOLERANCE_M plus the mission's waypoint acceptance radius:
    - HEIGHT_TOLERANCE_M (2 m): what the missions promise over the ground, PX4's legs split wherever the
      ground departs from their straight line by more than 2 m (mission.terrain_missions), ArduPilot
      following the terrain it was served;
    - the acceptance radius (NAV_WAYPOINT param2, a quarter cell): the vehicle's own altitude-hold error,
      as the judge already allows it for a drone's position elsewhere (one radius per drone in the
      separation tolerance, flight_report.live_tolerance): ArduCopter counts a waypoint reached within
      that 3-D distance of it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.bridge.formats.mission_items import CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT
from missionplan.geo.dem import Ground
from missionplan.geo.dem_copy import read_ground_copy

from ..mission.plan_record import PlanRecord
from .record import DroneRecord

HEIGHT_TOLERANCE_M = 2.0  # what the missions promise over the ground (mission.terrain_missions.TERRAIN_TOLERANCE_M)
GROUND_MARGIN_M = 200.0  # read around the grid: a drone's fence lies at most its margin (5-10 m) beyond it
PERCENTILES = (("min", 0.0), ("p5", 5.0), ("median", 50.0), ("p95", 95.0), ("max", 100.0))


@dataclass(frozen=True)
class PlanGround:
    """A terrain plan's ground (the copy in its folder) and each vehicle's home on it (metres above sea level)."""

    ground: Ground
    home_amsl: dict[int, float]  # system id -> the ground at its launch point

    def altitude_amsl(self, vehicle: int, up_m: np.ndarray) -> np.ndarray:
        """Above sea level, from heights above the vehicle's home (NaN for a vehicle the plan does not know)."""
        return self.home_amsl.get(vehicle, np.nan) + np.asarray(up_m, dtype=float)

    def above_ground(self, vehicle: int, lat: np.ndarray, lon: np.ndarray, up_m: np.ndarray) -> np.ndarray:
        """Heights above the ground under each point (NaN where the copy has no ground there)."""
        return self.altitude_amsl(vehicle, up_m) - self.ground.height_amsl(lat, lon)


def plan_ground(plan_dir: Path, record: PlanRecord) -> PlanGround | None:
    """The ground of a plan made over a DEM, read from its folder's copy around the grid; None for a plan taken
    as flat. GeoError (one line) when the copy cannot be read (gone, or rasterio not installed)."""
    georef = record.georeference
    if georef is None or georef.terrain is None:
        return None
    frame = georef.frame
    ground = read_ground_copy(Path(plan_dir), georef.terrain, frame, margin_m=GROUND_MARGIN_M)
    ids = list(record.drone_ids or range(1, len(record.launch) + 1))
    rows = np.array([cell[0] for cell in record.launch], dtype=float)
    cols = np.array([cell[1] for cell in record.launch], dtype=float)
    lat, lon = frame.cell_to_latlon(rows, cols)
    heights = np.atleast_1d(ground.height_amsl(np.atleast_1d(lat), np.atleast_1d(lon)))
    return PlanGround(ground, {sysid: float(h) for sysid, h in zip(ids, heights) if np.isfinite(h)})


def _stats(values: np.ndarray) -> dict[str, Any] | None:
    """count, min, p5, median, p95, max of the finite values (None without any)."""
    values = values[np.isfinite(values)]
    if not len(values):
        return None
    levels = np.percentile(values, [level for _, level in PERCENTILES])
    return {"count": int(len(values)), **{name: round(float(v), 2) for (name, _), v in zip(PERCENTILES, levels)}}


def survey_window(rec: DroneRecord) -> tuple[float, float] | None:
    """(start, end) on our clock of a drone's survey: from its take-off item reached to its last waypoint
    reached (or the last it reached, when it ended early); None before its take-off ended."""
    takeoff = next((it.seq for it in rec.wire if it.command == CMD_NAV_TAKEOFF), None)
    last = max((it.seq for it in rec.wire if it.command == CMD_NAV_WAYPOINT), default=None)
    if takeoff is None or last is None:
        return None
    # The first report at or after each seq: PX4 may report a waypoint with the seq of the items after it.
    start = min((t for t, seq in rec.reached if seq >= takeoff), default=None)
    end = min((t for t, seq in rec.reached if seq >= last), default=None)
    if end is None:
        end = max((t for t, seq in rec.reached if seq > takeoff), default=None)
    if start is None or end is None or end < start:
        return None
    return start, end


def acceptance_radius(rec: DroneRecord) -> float:
    """The mission's waypoint acceptance radius (NAV_WAYPOINT param2; 0 without waypoints)."""
    return max((float(it.param2) for it in rec.wire if it.command == CMD_NAV_WAYPOINT), default=0.0)


def survey_heights(plan: PlanGround, rec: DroneRecord) -> tuple[np.ndarray, np.ndarray]:
    """The samples of a drone's survey (survey_window; (n, 7) as DroneRecord keeps them) and their heights above
    the ground (NaN where the plan's ground has none)."""
    window = survey_window(rec)
    if window is None or not rec.samples:
        return np.zeros((0, 7)), np.zeros(0)
    samples = np.array(rec.samples, dtype=float)
    samples = samples[(samples[:, 0] >= window[0]) & (samples[:, 0] <= window[1])]
    return samples, plan.above_ground(rec.id, samples[:, 1], samples[:, 2], samples[:, 3])


def judge_heights(plan: PlanGround, rec: DroneRecord, planned_m: float) -> tuple[dict[str, Any], str | None]:
    """flight.json's `above_ground` block of one drone, and its problem line when a sample of its survey
    left the tolerance (None when none did)."""
    tolerance = HEIGHT_TOLERANCE_M + acceptance_radius(rec)
    block: dict[str, Any] = {"samples": None, "photos": None, "planned_m": round(float(planned_m), 2),
                             "tolerance_m": round(tolerance, 2),
                             "home_amsl_m": round(plan.home_amsl[rec.id], 2) if rec.id in plan.home_amsl else None}
    if rec.camera:
        photos = np.array([(lat, lon, up) for _, lat, lon, up in rec.camera.values()], dtype=float)
        block["photos"] = _stats(plan.above_ground(rec.id, photos[:, 0], photos[:, 1], photos[:, 2]))
    samples, heights = survey_heights(plan, rec)
    block["samples"] = _stats(heights)
    off = np.abs(heights - planned_m)
    if not np.isfinite(off).any() or np.nanmax(off) <= tolerance:
        return block, None
    worst = int(np.nanargmax(off))
    return block, (f"uav{rec.id} flew {heights[worst]:.1f} m above the ground at {samples[worst, 1]:.5f}, "
                   f"{samples[worst, 2]:.5f} (planned {planned_m:g} m, tolerance {tolerance:g} m)")


def photo_heights(plan: PlanGround, vehicles: Sequence[int], lat: Sequence[float], lon: Sequence[float],
                  up_m: Sequence[float | None]) -> tuple[np.ndarray, np.ndarray]:
    """(ground under each photo, its height above that ground), metres; NaN where its height above the launch
    point or the ground is unknown."""
    lat_a, lon_a = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    up = np.array([np.nan if u is None else u for u in up_m], dtype=float)
    home = np.array([plan.home_amsl.get(v, np.nan) for v in vehicles], dtype=float)
    ground = plan.ground.height_amsl(lat_a, lon_a) if len(lat_a) else np.zeros(0)
    return ground, home + up - ground
