"""Judging a flown fleet from its recordings: coverage, separation, times, problems; flight.json and flight.png.

No MAVLink here: fly.py records (DroneRecord), this module judges what was recorded.
- Photo positions (photo_positions.py): where the vehicle said each photo was taken; a photo whose
  report was lost is placed on the recorded track and counted apart. A vehicle that sends no photo
  report has no photos as evidence: that is a problem of the flight (no camera configured, or no
  feedback), unless the user asked for photos from the track (`fly --photos-from-track`), said so in
  flight.json.
- Coverage: a target cell counts as photographed when the square footprint of one photo holds the
  cell, short of at most a quarter cell on a side (SLACK_CELLS): the grid world's and the corrector's
  rule (whole cell in the footprint) with the slack a real vehicle needs, since it may turn a
  waypoint's acceptance radius (a quarter cell) early and reports positions to about a centimetre.
  flight.json also gives the whole-cell and cell-centre figures. Only reachable targets count.
- Overlaps (mission/photo_overlap.py): front and side overlap and photos per target point of the
  confirmed photos, next to what the plan asked; printed by fly, and in flight.json (`overlap`) when the
  plan recorded its own (a plan that asks its overlaps), so the two can be compared.
- Separation: the closest approach of any two recorded tracks (timeline.closest_approach), against
  what the plan promised (report.json `separation`), with a tolerance for what telemetry cannot pin down:
  two acceptance radii, the spread of the mission start times, and one telemetry interval of flight.
- Times: flight_s on the vehicle's own clock, next to the plan (and the plan re-timed with the
  vehicle's parameters, mission_motions); per drone its phases and events (phases.py: where the
  time went).
- flight.png (flight_plot.py): a map in metres of covered and missed targets, the flown tracks, and
  flight time per drone; flight.html, flight.gpkg, flight.kmz (flight_layers.py): the same over the city.
- A disk that refuses a file (full, read-only): the judge writes every other file and names the ones it
  could not write (FlightResult.unwritten); fly keeps the rest elsewhere and says so.
"""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from scipy.spatial import cKDTree

from missionplan.base.atomic import write_text_atomic
from missionplan.bridge.flight_models.copter_model import CopterParams, Motion, total_time
from missionplan.bridge.formats.mission_items import (CMD_DO_CHANGE_SPEED, CMD_NAV_LAND, CMD_NAV_TAKEOFF,
                                                      CMD_NAV_WAYPOINT)
from missionplan.bridge.flight_models.px4_model import Px4Params
from missionplan.geo.cells import cells_feature
from missionplan.geo.errors import GeoError
from missionplan.geo.frame import GridFrame

from ..mission.timeline import FlightModel, closest_approach, planned_motions
from ..mission.layers import Layers, drone_paths_latlon, planned_photos
from .above_ground import HEIGHT_TOLERANCE_M, PlanGround, judge_heights, plan_ground, survey_heights
from .flight_layers import flight_layers, flight_summary, plan_layers_on_disk
from .flight_plot import HeightProfiles, draw_flight
from .phases import event_rows, on_vehicle_clock, phase_rows
from .photo_positions import ledger_photos, photo_positions
from ..mission.photo_overlap import OverlapMeasure, measure_overlap
from ..mission.plan_blocks import SeparationPromise, cells_of
from ..maps.gridmap import GridMap
from ..mission.plan_record import PlanRecord
from .plan_report import (SLACK_CELLS, asked_overlaps, frame_of, georeference_of, planned_grid, target_cells,
                          to_grid_m, trigger_distance_m)
from .record import DroneRecord

COVERAGE_OK = 99.0
MIN_RATE_SPAN_S = 2.0  # of our time: a vehicle's clock rate is fitted over at least this long a record
REAL_TIME_TOLERANCE = 0.05  # a clock within 5 % of ours runs in real time
# A vehicle has left the ground at the first sample this high (at most half the fleet's lowest take-off
# altitude: liftoff_height) and
# climbing this fast. PX4's estimate on the ground wanders by up to 0.8 m and 0.9 m/s (SIH): lower
# thresholds took that for lift-offs, 9 s before the real ones, and so widened the separation tolerance
# (start spread times speed) to 46 m.
LIFTOFF_M, LIFTOFF_CLIMB_M_S = 1.5, 0.5


@dataclass
class FlightResult:
    coverage: float  # from the photos the vehicles confirmed (their reports, their logs)
    targets: int
    separation: dict[str, Any]
    drones: list[dict[str, Any]]
    problems: list[str]
    photo_source: str
    wall_s: float
    json_path: Path
    png_path: Path
    missed_path: Path = Path("missed.geojson")
    coverage_with_unconfirmed: float = 0.0  # counting the photos placed on the track as well
    survey: dict[str, Any] | None = None  # the survey's coverage from the ledger, all flights (survey_summary)
    map_paths: list[Path] = field(default_factory=list)  # flight.html, flight.gpkg, flight.kmz
    doc: dict[str, Any] = field(default_factory=dict)  # flight.json's content, written or not
    unwritten: dict[str, str] = field(default_factory=dict)  # files the judge could not write -> why (one line)
    record_faults: list[str] = field(default_factory=list)  # why the flight's record in its folder is not whole
    notices: list[str] = field(default_factory=list)  # what the judge repaired on the way (a rebuilt ledger)
    overlap: OverlapMeasure | None = None  # front / side overlap and photos per target point of the confirmed photos

    @property
    def ok(self) -> bool:
        # kept None: fewer than two drones flew; the drones that did not fly are problems of their own.
        return self.coverage >= COVERAGE_OK and not self.problems and self.separation.get("kept") is not False

    @property
    def recorded(self) -> bool:
        """Whether the flight's record is whole in its plan folder: its journal and every file the judge writes."""
        return not self.unwritten and not self.record_faults


def nearest_photo_gap(frame: GridFrame, targets: np.ndarray, photos_m: np.ndarray) -> np.ndarray:
    """Per target cell: Chebyshev distance (metres) from its centre to the nearest photo position."""
    if len(photos_m) == 0:
        return np.full(len(targets), np.inf)
    gap, _ = cKDTree(photos_m).query(targets.astype(float) * frame.cell_m, p=np.inf)
    return np.atleast_1d(gap)


def covered_by_gap(frame: GridFrame, gap: np.ndarray, footprint_m: float, slack_m: float) -> np.ndarray:
    """Which cells one photo holds, short of at most slack_m on a side (see coverage)."""
    return gap <= footprint_m / 2.0 - frame.cell_m / 2.0 + slack_m + 1e-6  # a micrometre for the float round trip


def coverage(frame: GridFrame, targets: np.ndarray, photos_m: np.ndarray, footprint_m: float,
             slack_m: float) -> np.ndarray:
    """Per target cell: does one photo's footprint hold the cell's square, short of at most slack_m on a side?

    slack_m = 0 asks for the whole square; cell/2 only for its centre."""
    return covered_by_gap(frame, nearest_photo_gap(frame, targets, photos_m), footprint_m, slack_m)


def vehicle_rate(samples: np.ndarray) -> float | None:
    """The vehicle's clock rate: its seconds (time_boot_ms) per second of ours, fitted over the record.
    A simulator sped up S times reports S (ArduCopter SITL stamps simulated time); a real vehicle 1.
    None when the record is too short to tell it from our threads' jitter."""
    if len(samples) < 10 or samples[-1, 0] - samples[0, 0] < MIN_RATE_SPAN_S:
        return None
    slope = float(np.polyfit(samples[:, 0] - samples[0, 0], samples[:, 5], 1)[0])
    return slope if slope > 0 else None


def vehicle_clock(samples: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """When each sample was taken, on our clock: the vehicle's own time stamps (free of our threads'
    scheduling jitter), at the vehicle's clock rate (a sped-up simulator's clock runs faster), shifted
    by the smallest arrival delay seen, the usual one-way clock sync. A record too short to fit the
    rate (a short flight at a high speed-up) runs at `scale`, the fleet's time scale."""
    rate = vehicle_rate(samples) or scale
    if abs(rate - 1.0) < REAL_TIME_TOLERANCE:
        rate = 1.0  # a real-time clock: take its stamps as they are
    ours = samples[:, 5] / rate
    return ours + float(np.min(samples[:, 0] - ours))


def flown_seconds(rec: DroneRecord, scale: float) -> float:
    """How long the flight took on the vehicle's own clock (simulated seconds on a simulator: a loaded
    machine slows the wall clock's pace, not the vehicle's), from the mission start to the end we saw.
    Without two samples in that window, or across a reboot, our clock times the scale."""
    end = rec.t_end if rec.t_end is not None else (rec.samples[-1][0] if rec.samples else rec.t_start)
    if rec.t_start is None or end is None:
        return 0.0
    return float(on_vehicle_clock(rec, [end], scale)[0])


def takeoff_altitude(rec: DroneRecord) -> float:
    """The altitude of the uploaded mission's NAV_TAKEOFF (inf without one)."""
    return next((float(it.z) for it in rec.wire if it.command == CMD_NAV_TAKEOFF), float("inf"))


def liftoff_height(records: list[DroneRecord]) -> float:
    """The height at which every drone of a fleet counts as climbing: LIFTOFF_M, at most half the lowest
    take-off altitude. One for all: the back-extrapolation from it errs alike for drones that climb
    alike, so their start spread stays true."""
    return min([LIFTOFF_M] + [0.5 * takeoff_altitude(rec) for rec in records])


def lifted_off_at(samples: np.ndarray, clock: np.ndarray, scale: float, above: float) -> float | None:
    """When the vehicle left the ground, on our clock (`clock`: each sample's time, flight_report.vehicle_clock):
    back from the first sample higher than `above` (liftoff_height) climbing faster than LIFTOFF_CLIMB_M_S,
    at the climb rate it reported. None if it never climbed."""
    climbing = np.flatnonzero((samples[:, 3] > above) & (samples[:, 6] > LIFTOFF_CLIMB_M_S))
    if not len(climbing):
        return None
    first = climbing[0]
    return float(clock[first] - samples[first, 3] / samples[first, 6] / scale)


def mission_motions(frame: GridFrame, rec: DroneRecord) -> list[Motion] | None:
    """The uploaded mission as the flight model flies it (PX4's model when the vehicle is PX4), with
    the navigation parameters the vehicle reported (the model's defaults for those it did not).
    None when the mission has no take-off to start from."""
    items = list(rec.wire)
    start = next((i for i, it in enumerate(items) if it.command == CMD_NAV_TAKEOFF), None)
    if start is None:
        return None
    takeoff = items[start]
    copter = CopterParams.from_params(rec.params)
    px4 = Px4Params.from_params(rec.params) if rec.flavour == "px4" else None
    # Each leg at the speed the last DO_CHANGE_SPEED before its waypoint set (a transit speed on the ways out
    # and home, the survey speed between), the vehicle's default before any.
    speed = copter.wp_speed if px4 is None else px4.xy_cruise
    waypoints, speeds = [], []
    for item in items[start + 1:]:
        if item.command == CMD_DO_CHANGE_SPEED and item.param2 > 0:
            speed = float(item.param2)
        elif item.command == CMD_NAV_WAYPOINT:
            waypoints.append(item)
            speeds.append(speed)
    launch = to_grid_m(frame, [takeoff.x / 1e7], [takeoff.y / 1e7])[0]
    route = to_grid_m(frame, [w.x / 1e7 for w in waypoints], [w.y / 1e7 for w in waypoints])
    end = "land" if items[-1].command == CMD_NAV_LAND else "rtl"
    return planned_motions(launch, route, float(takeoff.z), end, FlightModel(speeds[0] if speeds else speed, 0.0,
                                                                               copter, px4), np.array(speeds))


def estimate_time_scale(records: list[DroneRecord]) -> float:
    """Simulated seconds per wall second: distance flown between samples over the reported ground speed."""
    ratios: list[float] = []
    for rec in records:
        s = np.array(rec.samples)
        if len(s) < 2:
            continue
        dt = np.diff(s[:, 0])
        speed = 0.5 * (s[1:, 4] + s[:-1, 4])
        dn = np.radians(np.diff(s[:, 1])) * 6_378_137.0
        de = np.radians(np.diff(s[:, 2])) * 6_378_137.0 * np.cos(np.radians(s[1:, 1]))
        dist = np.hypot(dn, de)
        ok = (dt > 0.01) & (speed > 0.5) & (dist > 0)
        ratios.extend((dist[ok] / (dt[ok] * speed[ok])).tolist())
    return float(np.median(ratios)) if len(ratios) >= 3 else 1.0


# ------------------------------------------------------------------------------------------- sorties
def sortie_view(record: PlanRecord, sortie: int, missions: dict[int, dict[int, list[Any]]]) -> PlanRecord:
    """The plan record as `fly --sortie J` judges it: the drones that fly sortie J with that sortie's planned
    photos and time, that sortie's separation promise, and as targets only the cells that are its duty.

    A plan with several sorties: a cell is sortie J's duty when J's planned photos hold it with room to
    spare (SLACK_CELLS, the acceptance radius a vehicle may cut), or hold it at all and no other sortie's
    planned photos do. A cell held only at the edge of J's last photo and again by the next sortie's
    first is not J's alone to hold. `missions`: sortie -> sysid -> that sortie's mission items
    (missionplan.bridge.formats.mission_items.MissionItem, latitude / longitude in degrees); needed only with several
    sorties."""
    planned = record.drones or ()
    view = replace(record, drones=tuple(d for drone in planned if (d := drone.for_sortie(sortie)) is not None))
    if record.promise is not None and sortie <= len(record.promise.separation.sorties):
        view = replace(view, promise=replace(record.promise, separation=record.promise.separation.for_sortie(sortie)))
    if any(len(d.sorties) > 1 for d in planned):
        frame = frame_of(record)
        trigger, footprint = trigger_distance_m(record), georeference_of(record).footprint_m
        targets = target_cells(record)

        def gap(which: list[int]) -> np.ndarray:
            photos = [planned_photos(items, trigger, lambda lat, lon: to_grid_m(frame, lat, lon)[0], from_takeoff=False)
                      for j in which for items in missions.get(j, {}).values()]
            return nearest_photo_gap(frame, targets, np.vstack(photos) if photos else np.zeros((0, 2)))

        mine = gap([sortie])
        others = gap([j for j in missions if j != sortie])
        slack = SLACK_CELLS * frame.cell_m
        duty = covered_by_gap(frame, mine, footprint, -slack) | (
            covered_by_gap(frame, mine, footprint, 0.0) & ~covered_by_gap(frame, others, footprint, 0.0))
        view = replace(view, unreachable_cells=record.unreachable_cells + cells_of(targets[~duty].tolist()))
    return view


# ------------------------------------------------------------------------------------------- judging
Result = TypeVar("Result")
WRITE_ERRORS: tuple[type[BaseException], ...] = (OSError, sqlite3.Error)  # a full disk, a read-only folder...


def _written(unwritten: dict[str, str], names: str, write: Callable[[], Result]) -> Result | None:
    """write(), or None with the reason in `unwritten` under `names` when the disk refused it: the judge
    writes every file it can and says which it could not, never stops at the first."""
    from .ledger import LedgerError

    try:
        return write()
    except (*WRITE_ERRORS, LedgerError) as err:
        text = str(err.strerror if isinstance(err, OSError) and err.strerror else err)
        head, sep, tail = text.partition(": ")
        unwritten[names] = tail if sep and os.sep in head else text  # the file is named already
        return None


def judge(plan_dir: Path, record: PlanRecord, records: list[DroneRecord], time_scale: float | None,
          wall_s: float, telemetry_hz: float, photos_from_track: bool = False, flight: int | None = None,
          sortie: int = 1, retasks: list[dict[str, Any]] | None = None,
          record_faults: list[str] | None = None) -> FlightResult:
    """Everything flight.json says, from the recordings; writes flight.json, flight.png and
    missed.geojson (the targets no confirmed photo covered, as polygons on the Earth).

    flight: the journal's number of this flight; given, its photos go into the survey ledger
    (ledger.py), the coverage is the ledger's for this flight, flight.json says the survey's too, and
    photos.csv, photos.geojson and geo.txt are written (geotag.py).
    photos_from_track: a vehicle that reported no photo (no CAMERA_FEEDBACK) gets one every trigger
    distance along its flown survey; without it, that vehicle's flight is a problem.
    record_faults: why the flight's journal is not whole (a damaged or cut journal, writes that never
    went through), said in flight.json's `record_faults`.
    A file the disk refuses (full, read-only) is not written and named in the result's `unwritten`; the
    rest are written all the same, and the figures are the judge's own when the ledger cannot be used."""
    frame = frame_of(record)
    footprint, trigger = georeference_of(record).footprint_m, trigger_distance_m(record)
    scale = time_scale if time_scale else estimate_time_scale(records)
    planned = {d.id: d for d in record.drones or ()}
    targets = target_cells(record)
    grid = planned_grid(record)  # what was flyable (the overlaps' reach), the classes, the picture
    photos, unconfirmed, tracks_m, timed, rows, sources, kept = [], [], {}, {}, [], set(), []
    runs: list[np.ndarray] = []  # each confirmed photo's drone: its photos, in the order taken, make its strips
    liftoff: dict[int, float] = {}  # when each vehicle left the ground, on our clock
    liftoff_above = liftoff_height(records)
    for rec in records:
        points, placed, source = photo_positions(frame, rec, trigger, from_track=photos_from_track)
        photos.append(points)
        runs.append(np.full(len(points), rec.id))
        kept += ledger_photos(frame, rec, points, source)
        unconfirmed.append(placed)
        if source != "none":
            sources.add(source)
        elif rec.started and rec.samples:
            rec.problems.append(f"uav{rec.id}: the vehicle reported no photo (no CAMERA_FEEDBACK, no "
                                "CAMERA_IMAGE_CAPTURED): nothing shows its camera took any (configure it, e.g. "
                                "ArduPilot CAM1_TYPE or PX4 TRIG_MODE 4, and a reboot, or pass --photos-from-track "
                                "to count a photo every trigger distance along the track)")
        samples = np.array(rec.samples) if rec.samples else np.zeros((0, 7))
        tracks_m[rec.id] = to_grid_m(frame, samples[:, 1], samples[:, 2])
        if len(samples):
            timed[rec.id] = np.column_stack([vehicle_clock(samples, scale), tracks_m[rec.id], samples[:, 3]])
            lifted = lifted_off_at(samples, timed[rec.id][:, 0], scale, liftoff_above)
            if lifted is not None:
                liftoff[rec.id] = lifted
        flight_s = flown_seconds(rec, scale)
        motions = mission_motions(frame, rec)
        # The plan re-timed with the navigation parameters the vehicle reported (None without any).
        retimed = total_time(motions) if rec.params and motions is not None else None
        rows.append({"id": rec.id, "flight_s": round(flight_s, 2), "finished": rec.finished,
                     "ended_early": rec.ended_early or None,
                     "photos": int(len(points)), "photos_placed_on_track": int(len(placed)),
                     "photos_from_log": sum(1 for src in rec.photo_source.values() if src == "log"),
                     "planned_photos": rec.planned_photos,
                     "planned_flight_s": float(planned[rec.id].flight_s) if rec.id in planned else 0.0,
                     "planned_flight_s_vehicle": None if retimed is None else round(retimed, 1),
                     "vehicle_params": rec.params,
                     "uploaded": rec.uploaded, "held_after_flight": rec.held_after_flight,
                     "samples": len(samples), "items_reached": len({seq for _, seq in rec.reached}),
                     "last_position": _last_position(rec),
                     "phases": phase_rows(rec, motions, scale),
                     "events": event_rows(rec, scale), "notes": rec.notes})
    heights_problems, ground, profiles = _above_ground(plan_dir, record, records, rows)
    all_photos = np.vstack(photos) if photos else np.zeros((0, 2))
    slack = frame.cell_m * SLACK_CELLS
    gap = nearest_photo_gap(frame, targets, all_photos)  # once; each rule is a threshold on it
    covered = covered_by_gap(frame, gap, footprint, slack)
    survey = None
    unwritten: dict[str, str] = {}
    notices: list[str] = []
    if flight is not None:  # the ledger's figure: the same rule, kept for the survey as a whole
        from .geotag import GEOTAG_FILES, write_geotags
        from .ledger_repair import open_ledger

        def into_ledger() -> tuple[np.ndarray, dict[str, Any], Any]:
            with open_ledger(plan_dir, notices.append) as ledger:
                ledger.record_flight(plan_dir, flight, sortie, kept)
                return (ledger.covered_mask(plan_dir, flight)[targets[:, 0], targets[:, 1]], survey_summary(ledger),
                        ledger.photos(plan_dir))

        from_ledger = _written(unwritten, "ledger.sqlite", into_ledger)
        if from_ledger is not None:
            covered, survey, folder_photos = from_ledger
            _written(unwritten, ", ".join(GEOTAG_FILES), lambda: write_geotags(plan_dir, folder_photos, ground))
        else:
            unwritten[", ".join(GEOTAG_FILES)] = "written from the survey ledger"
    percent = 100.0 * float(covered.mean()) if len(targets) else 100.0
    with_placed = np.vstack([all_photos, *unconfirmed]) if unconfirmed else all_photos
    covered_with_placed = covered_by_gap(frame, nearest_photo_gap(frame, targets, with_placed), footprint, slack)
    percent_with_placed = 100.0 * float(covered_with_placed.mean()) if len(targets) else 100.0
    asked_front, asked_side = asked_overlaps(record)
    overlap = measure_overlap(all_photos, np.concatenate(runs) if runs else np.zeros(0), footprint,
                              targets, frame.cell_m, asked_front=asked_front, asked_side=asked_side,
                              flyable=~grid.obstacle)  # judged on the points a strip can reach
    other_rules = {name: round(100.0 * float(covered_by_gap(frame, gap, footprint, frame.cell_m * cells).mean()), 2)
                   if len(targets) else 100.0 for name, cells in (("whole_cell", 0.0), ("cell_centre", 0.5))}
    separation = _separation(record.separation, records, timed, liftoff, scale, telemetry_hz)
    problems = [p for rec in records for p in rec.problems]
    problems += [f"uav{rec.id}: mission not finished" for rec in records
                 if rec.started and not rec.finished and not rec.problems]
    problems += heights_problems
    if separation["kept"] is False:
        problems.append(f"uav{separation['pair_3d'][0]} and uav{separation['pair_3d'][1]} came within "
                        f"{separation['3d']} m; the plan promised {separation['planned_3d']} m")
    photo_source = " and ".join(sorted(sources)) or "none"
    missed = targets[~covered]
    missed_lat, missed_lon = frame.cell_to_latlon(missed[:, 0], missed[:, 1]) if len(missed) else ([], [])
    doc = {"coverage": round(percent, 2), "targets": int(len(targets)), "covered": int(covered.sum()),
           "coverage_with_unconfirmed": round(percent_with_placed, 2),
           "missed_cells": missed.tolist(),
           "missed_cells_latlon": [[round(float(a), 7), round(float(b), 7)] for a, b in zip(missed_lat, missed_lon)],
           "min_separation_m": separation, "drones": rows,
           "problems": problems, "photos_from": photo_source, "time_scale": round(scale, 3),
           "telemetry_hz": telemetry_hz, "wall_s": round(wall_s, 2),
           "coverage_rule": f"a target cell counts as photographed when one photo's square footprint, at the "
                            f"position the vehicle reported for it (over the link or in its log), holds the cell "
                            f"short of at most {SLACK_CELLS:g} cell ({slack:.3f} m) on a side; photos placed on "
                            f"the track (their reports lost) are counted apart, in coverage_with_unconfirmed",
           "coverage_other_rules": other_rules}
    if record.roofs is not None:  # a plan of roofs (--targets roofs|all): each class's coverage apart
        doc["coverage_by_class"] = _coverage_by_class(record, grid, targets, covered)
    if ground is not None:
        doc["above_ground_rule"] = (
            f"over the plan's ground ({', '.join(georeference_of(record).terrain.files)}), a drone's height above "
            f"the ground is the ground at its launch point (its home) plus the height it reported, less the "
            f"ground under it; every sample from its take-off's end to its last waypoint counts, and must stay "
            f"within {HEIGHT_TOLERANCE_M:g} m (what the missions promise over the ground) plus the mission's "
            f"waypoint acceptance radius (the vehicle's altitude-hold error) of the planned height")
    if record.coverage is not None and record.coverage.overlap is not None:  # the plan recorded its own: compare
        doc["overlap"] = overlap.to_json()
    if survey is not None:
        doc["survey"] = survey
    if retasks:
        doc["retasks"] = retasks
    faults = list(record_faults or []) + [f"{name}: not written ({why})" for name, why in unwritten.items()]
    if faults:
        doc["record_faults"] = faults
    json_path, png_path, missed_path = plan_dir / "flight.json", plan_dir / "flight.png", plan_dir / "missed.geojson"
    _written(unwritten, json_path.name, lambda: write_text_atomic(json_path, json.dumps(doc, indent=1) + "\n"))
    missed_doc = {"type": "FeatureCollection", "features": [cells_feature(frame, missed, {
        "what": "target cells no confirmed photo covered", "cells": int(len(missed)),
        "area_m2": round(float(len(missed)) * frame.cell_m ** 2, 1), "coverage": round(percent, 2)})]}
    _written(unwritten, missed_path.name, lambda: write_text_atomic(missed_path, json.dumps(missed_doc) + "\n"))
    plan = plan_layers_on_disk(plan_dir)
    _written(unwritten, png_path.name, lambda: draw_flight(
        png_path, grid, frame, targets, covered, tracks_m, {r["id"]: r["flight_s"] for r in rows}, percent,
        paths_latlon=drone_paths_latlon(plan) if plan.get("paths") else None, heights=profiles))
    map_paths = _written(unwritten, "flight.html, flight.gpkg, flight.kmz", lambda: write_flight_maps(
        plan_dir, plan, record, doc, frame, records, kept, targets, covered)) or []
    return FlightResult(coverage=round(percent, 2), targets=int(len(targets)), separation=separation, drones=rows,
                        problems=problems, photo_source=photo_source, wall_s=round(wall_s, 2),
                        json_path=json_path, png_path=png_path, missed_path=missed_path,
                        coverage_with_unconfirmed=round(percent_with_placed, 2), survey=survey,
                        map_paths=map_paths, doc=doc, unwritten=unwritten, record_faults=list(record_faults or []),
                        notices=notices, overlap=overlap)


def _coverage_by_class(record: PlanRecord, grid: GridMap, targets: np.ndarray,
                       covered: np.ndarray) -> dict[str, Any]:
    """flight.json `coverage_by_class`: per target class the plan asked (streets, roofs), its target cells and
    those the confirmed photos covered (mission/roof_targets.py)."""
    from ..mission.roof_targets import class_coverage

    assert record.roofs is not None
    reachable, held = np.zeros(grid.shape, dtype=bool), np.zeros(grid.shape, dtype=bool)
    reachable[targets[:, 0], targets[:, 1]] = True
    held[targets[covered, 0], targets[covered, 1]] = True
    return {c.name: c.to_json() for c in class_coverage(grid, reachable, held, record.roofs.targets)}


def _above_ground(plan_dir: Path, record: PlanRecord, records: list[DroneRecord],
                  rows: list[dict[str, Any]]) -> tuple[list[str], PlanGround | None, HeightProfiles | None]:
    """For a plan over a DEM: each drone's heights above the ground into its row (`above_ground`), the problems
    of the drones that left the tolerance (above_ground.py) and the heights along each survey for flight.png.
    Nothing for a plan taken as flat."""
    try:
        ground = plan_ground(plan_dir, record)
    except GeoError as err:
        return [f"heights above the ground not judged: {err}"], None, None
    if ground is None:
        return [], None, None
    planned = {d.id: d.altitude_m for d in record.drones or ()}
    problems: list[str] = []
    profiles: HeightProfiles = {}
    for rec, row in zip(records, rows):
        height = planned.get(rec.id, takeoff_altitude(rec))
        block, problem = judge_heights(ground, rec, height)
        row["above_ground"] = block
        if problem is not None:
            problems.append(problem)
        samples, above = survey_heights(ground, rec)
        began = samples[0, 5] if len(samples) else 0.0  # the vehicle's clock: simulated seconds on a simulator
        profiles[rec.id] = (samples[:, 5] - began, above, height, block["tolerance_m"])
    return problems, ground, profiles


def write_flight_maps(plan_dir: Path, plan: Layers, record: PlanRecord, doc: dict[str, Any], frame: GridFrame,
                      records: list[DroneRecord], photos: list[dict[str, Any]], targets: np.ndarray,
                      covered: np.ndarray) -> list[Path]:
    """flight.html, flight.gpkg and flight.kmz: the plan's layers (its tracks.geojson) and what was flown."""
    from ..mission.mapfiles import write_map_files

    tracks = {rec.id: np.array(rec.samples)[:, 1:4] for rec in records if rec.samples}
    flight_s = {row["id"]: row["flight_s"] for row in doc["drones"]}
    layers = flight_layers(plan, frame, tracks, photos, targets, covered, flight_s)
    return write_map_files(plan_dir, "flight", layers, flight_summary(record, doc, layers), basemap=record.basemap)


def survey_summary(ledger: Any) -> dict[str, Any]:
    """flight.json's `survey`: the whole survey's coverage from the ledger (every flight of every folder)."""
    targets = ledger.survey.targets
    missing = ledger.missing_cells()
    done = len(targets) - len(missing)
    return {"root": str(ledger.survey.root), "flights": len(ledger.flights()), "targets": int(len(targets)),
            "covered": int(done), "coverage": round(100.0 * done / len(targets), 2) if len(targets) else 100.0,
            "missing_cells": int(len(missing))}


def _last_position(rec: DroneRecord) -> dict[str, Any] | None:
    """Where the vehicle was last heard of (its last sample, or the last journaled position)."""
    if rec.samples:
        t, lat, lon, up = rec.samples[-1][:4]
    elif rec.last_position:
        lat, lon, up, t = rec.last_position
    else:
        return None
    return {"lat": round(float(lat), 7), "lon": round(float(lon), 7), "up_m": round(float(up), 2),
            "time_utc": datetime.fromtimestamp(float(t), timezone.utc).isoformat(timespec="milliseconds")}


def _flight_speed_and_acceptance(records: list[DroneRecord]) -> tuple[float, float]:
    speed = max((float(item.param2) for rec in records for item in rec.wire if item.command == CMD_DO_CHANGE_SPEED),
                default=5.0)
    acceptance = max((float(item.param2) for rec in records for item in rec.wire if item.command == CMD_NAV_WAYPOINT),
                     default=0.0)
    return speed, acceptance


def live_tolerance(records: list[DroneRecord], scale: float, telemetry_hz: float) -> float:
    """How much closer than promised two drones may seem in live telemetry: two acceptance radii and one
    telemetry interval of flight (the judge adds the start spread, which the live watch cannot know)."""
    speed, acceptance = _flight_speed_and_acceptance(records)
    return 2 * acceptance + speed * scale / telemetry_hz


def _separation(promise: SeparationPromise | None, records: list[DroneRecord], timed: dict[int, np.ndarray],
                liftoff: dict[int, float], scale: float, telemetry_hz: float) -> dict[str, Any]:
    """Flown closest approach next to the plan's promise (None: it promised none), and whether it was kept.

    The tolerance is what telemetry cannot pin down (two acceptance radii, one telemetry interval of
    flight) plus how far apart the vehicles really left the ground, which the plan assumed all at once;
    it never exceeds half the promise, so a start spread (or a vehicle that never took off with the
    others) cannot make the check unable to fail."""
    flown = closest_approach(timed)
    speed, _ = _flight_speed_and_acceptance(records)
    start_spread_s = (max(liftoff.values()) - min(liftoff.values())) * scale if liftoff else 0.0
    planned_3d = promise.closest.d3 if promise is not None else None
    tolerance = live_tolerance(records, scale, telemetry_hz) + speed * start_spread_s
    if planned_3d is not None:
        tolerance = min(tolerance, 0.5 * float(planned_3d))
    # Fewer than two tracks: nothing was measured, so the promise was neither kept nor broken.
    kept = None if flown["3d"] is None else bool(planned_3d is None or flown["3d"] >= planned_3d - tolerance)
    return {**flown, "planned_horizontal": promise.closest.horizontal if promise is not None else None,
            "planned_3d": planned_3d,
            "tolerance": round(float(tolerance), 3), "start_spread_s": round(float(start_spread_s), 3),
            "kept": kept, "tracks": len(timed)}

