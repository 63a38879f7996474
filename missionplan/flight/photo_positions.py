"""Where each photo of a flight was taken, from a drone's record: the one rule the judge (flight_report)
and a survey ledger rebuilt from the journals (ledger_repair) both use, so both put the same rows into
the ledger.

- Photo positions: every CAMERA_FEEDBACK (ArduPilot) or CAMERA_IMAGE_CAPTURED (PX4's camera_feedback
  module, or a MAVLink camera) the vehicle sent, where each photo was really taken; a photo whose report
  was lost on the link (a gap in img_idx) is placed on the recorded track between its neighbours, in
  proportion to its index, and counted apart. Photos are counted from the first img_idx this flight
  reported (ArduPilot's index keeps counting across flights until a reboot). A vehicle that sent no
  photo report gets one every trigger distance along its flown survey only when the user asked for it
  (`fly --photos-from-track`).
- The ledger's rows: the confirmed photos, as ledger.Ledger.record_flight takes them, each with the camera's
  attitude (camera_attitude: the gimbal's pitch as reported, else as planned; not the airframe's).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from missionplan.bridge.formats.gimbal import planned_pitch
from missionplan.bridge.formats.mission_items import CMD_DO_SET_CAM_TRIGG_DIST, CMD_NAV_WAYPOINT
from missionplan.geo.frame import GridFrame

from ..mission.plan_record import PlanRecord
from .plan_report import frame_of, to_grid_m, trigger_distance_m
from .record import DroneRecord


# ------------------------------------------------------------------------------------------- geometry
def _arc_length(points: np.ndarray) -> np.ndarray:
    steps = np.diff(points, axis=0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(steps[:, 0], steps[:, 1]))])


def _point_at(points: np.ndarray, arc: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])])


def _arc_on_track(track: np.ndarray, arc: np.ndarray, points: np.ndarray, arrived: np.ndarray,
                  lookback: int = 4) -> np.ndarray:
    """Arc length along `track` of each point, projected on the nearest of the few segments flown
    just before its report arrived (`arrived`: samples received before it). Not by arrival order
    alone: a report can come after a sample taken past its photo; and only near in time, since
    a track may cross itself."""
    if len(track) < 2:
        return np.zeros(len(points))
    last = np.clip(arrived - 1, 0, len(track) - 2)
    segments = np.clip(last[:, None] - np.arange(lookback + 1)[None, :], 0, len(track) - 2)  # (m, L)
    a, b = track[segments], track[segments + 1]
    ab = b - a
    length2 = np.maximum((ab ** 2).sum(axis=2), 1e-12)
    frac = np.clip(((points[:, None, :] - a) * ab).sum(axis=2) / length2, 0.0, 1.0)
    foot = a + frac[..., None] * ab
    nearest = np.argmin(((points[:, None, :] - foot) ** 2).sum(axis=2), axis=1)
    rows = np.arange(len(points))
    seg = segments[rows, nearest]
    return arc[seg] + frac[rows, nearest] * np.sqrt(length2[rows, nearest])


def photo_positions(frame: GridFrame, rec: DroneRecord, trigger_m: float,
                    from_track: bool = False) -> tuple[np.ndarray, np.ndarray, str]:
    """(confirmed photos (n, 2) grid metres, photos placed on the track (m, 2), source).

    Confirmed: where the vehicle said each photo was taken, in its report over the link or in its own
    log read after the flight. Placed: a photo the vehicle counted (a gap in its indices, or more
    captures than reports) whose position never came, put on the recorded track between its known
    neighbours in proportion to its index: not confirmed, and counted apart. source: "camera" (photo
    reports), "track" (none reported and from_track: a photo every trigger distance along the flown
    survey, all counted as confirmed, since the user asked for that) or "none"."""
    empty = np.zeros((0, 2))
    if not rec.samples:
        return empty, empty, "none"
    samples = np.array(rec.samples)
    if rec.camera:
        known = sorted(rec.camera.items())
        track = to_grid_m(frame, samples[:, 1], samples[:, 2])
        arc = _arc_length(track)
        idx = np.array([i for i, _ in known], dtype=float)
        reported = to_grid_m(frame, [v[1] for _, v in known], [v[2] for _, v in known])
        arrived = np.searchsorted(samples[:, 0], [v[0] for _, v in known], side="right")
        s_known = np.maximum.accumulate(_arc_on_track(track, arc, reported, arrived))
        total = max(rec.captures, int(idx[-1]) + 1)
        # From the first index this flight reported: the ones below it are earlier flights' photos
        # (ArduPilot counts on until a reboot), not photos lost on the link.
        every = np.arange(int(idx[0]), total, dtype=float)
        lost = every[~np.isin(every, idx)]
        # Lost reports: in proportion to the index between known neighbours, trigger_m per photo past the ends.
        s_lost = np.interp(lost, idx, s_known)
        s_lost = np.where(lost > idx[-1], s_known[-1] + (lost - idx[-1]) * trigger_m, s_lost)
        placed = _point_at(track, arc, np.clip(s_lost, 0.0, arc[-1])) if len(lost) else empty
        return reported, placed, "camera"
    if not from_track:
        return empty, empty, "none"
    # No camera reports, and the user asked for it: a photo every trigger_m along the survey part of the track.
    first, last = _survey_window(rec.wire)
    # The first report at or after each seq: PX4 reports a waypoint with the seq of the DO_ items after it.
    t0 = min((t for t, seq in rec.reached if first is not None and seq >= first), default=samples[0, 0])
    t1 = min((t for t, seq in rec.reached if last is not None and seq >= last), default=samples[-1, 0])
    part = samples[(samples[:, 0] >= t0) & (samples[:, 0] <= t1)]
    if len(part) == 0 or trigger_m <= 0:
        return empty, empty, "track"
    track = to_grid_m(frame, part[:, 1], part[:, 2])
    arc = _arc_length(track)
    return _point_at(track, arc, np.arange(0.0, arc[-1] + 1e-9, trigger_m)), empty, "track"


def _survey_window(wire: list[Any]) -> tuple[int | None, int | None]:
    """Seqs of the first and last waypoint flown with the distance trigger on."""
    first = last = None
    on = False
    for item in wire:
        if item.command == CMD_DO_SET_CAM_TRIGG_DIST:
            on = item.param1 > 0
        elif item.command == CMD_NAV_WAYPOINT and on:
            first = item.seq if first is None else first
            last = item.seq
    return first, last


def camera_attitude(rec: DroneRecord, idx: int, t: float) -> tuple[float | None, float | None, float | None]:
    """Roll, pitch and yaw (degrees) of the camera, not the airframe, when photo `idx` was taken at `t`: pitch
    and roll as the gimbal last reported them before it; where it reported nothing, the pitch the mission's
    gimbal item asked for (gimbal.planned_pitch) and roll 0 (a gimbal holds the camera level across); neither
    without a gimbal item. Yaw: the vehicle's heading, since the gimbal item keeps the camera's yaw along it."""
    yaw = rec.attitude.get(idx, (None, None, None))[2]
    reported = rec.gimbal_at(t)
    if reported is not None:
        pitch, roll = reported
        return roll, pitch, yaw
    planned = planned_pitch(rec.wire)
    return (None if planned is None else 0.0), planned, yaw


def ledger_photos(frame: GridFrame, rec: DroneRecord, points_m: np.ndarray, source: str) -> list[dict[str, Any]]:
    """A vehicle's confirmed photos as the survey ledger keeps them (ledger.Ledger.record_flight), each with
    its camera's attitude (camera_attitude)."""
    if source == "camera":
        return [{"vehicle": rec.id, "img_idx": idx, "time": t, "lat": lat, "lon": lon, "alt_rel": up,
                 "alt_amsl": rec.amsl.get(idx), "source": rec.photo_source.get(idx, "camera"),
                 **dict(zip(("roll", "pitch", "yaw"), camera_attitude(rec, idx, t))),
                 # a MAVLink camera's record: its image_index (the photo's index) and the file it named
                 "image_index": idx if idx in rec.files else None, "file_url": rec.files.get(idx) or None}
                for idx, (t, lat, lon, up) in sorted(rec.camera.items())]
    if source == "track" and len(points_m):
        lat, lon = frame.grid_to_latlon(points_m[:, 0] / frame.cell_m, points_m[:, 1] / frame.cell_m)
        return [{"vehicle": rec.id, "img_idx": i, "lat": float(a), "lon": float(b), "source": "track"}
                for i, (a, b) in enumerate(zip(np.atleast_1d(lat), np.atleast_1d(lon)))]
    return []


def flight_photos(record: PlanRecord, records: list[DroneRecord], photos_from_track: bool) -> list[dict[str, Any]]:
    """The confirmed photos of a flight as the judge puts them into the survey ledger (ledger_photos of
    photo_positions, per drone): what a ledger rebuilt from the journal must hold again."""
    frame = frame_of(record)
    trigger = trigger_distance_m(record)
    kept: list[dict[str, Any]] = []
    for rec in records:
        points, _, source = photo_positions(frame, rec, trigger, from_track=photos_from_track)
        kept += ledger_photos(frame, rec, points, source)
    return kept
