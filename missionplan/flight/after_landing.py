"""After a drone landed: the photos whose reports never arrived, read from its own log; its mission read back.

Run by the drone's follower (drone_flight.DroneFlight) in its own thread, once the vehicle is on the
ground and disarmed. The photos read from the log are published as events.PhotoTaken (source "log"),
those still missing as events.PhotosNotConfirmed; the logs read are kept in DIR/logs/uavK/.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from missionplan.bridge.errors import BridgeError
from missionplan.bridge.session.vehicle_session import VehicleSession

from .events import FlightEvent, PhotosNotConfirmed, PhotoTaken
from .fleet_start import FleetStart
from .record import DroneRecord

LOG_READ_S = 120.0  # at most this long to read a vehicle's log after landing


def recover_photos(session: VehicleSession, rec: DroneRecord, fleet: FleetStart, deadline: float, gaps: int,
                   rel_alt: float, log_folder: Path, url: str, publish: Callable[[FlightEvent], None]) -> None:
    """The photos whose reports were lost (a gap in the indices, or fewer reports than the camera
    counted), read from the vehicle's own log where its autopilot keeps one
    (missionplan.bridge.transfer.onboard_log: ArduPilot's DataFlash log, served once the vehicle is disarmed).
    gaps: the silences of its flight (photos taken in one are unknown: every photo of its log is read);
    rel_alt: its last height, for a logged photo without one; url: its link (one log read at a time on it)."""
    if not (rec.camera or gaps):
        return
    first = min(rec.camera) if rec.camera else 1
    # A MAVLink camera's failed capture (capture_result 0) is no lost report: it was heard, and took no photo.
    reported = set(rec.camera) | rec.failed_indices
    missing = set(range(first, max(rec.captures, max(rec.camera, default=0) + 1))) - reported
    if not missing and not gaps:
        return
    # After a silence nobody knows how many photos it took in it (the vehicle may have landed before it
    # was heard again): every photo of its flight's log is read, and those not yet recorded are added.
    wanted = None if gaps else missing
    lost = "photo reports lost on the link" if not gaps else "photo reports not heard in a link gap"
    if fleet.camera_records:  # the autopilot's log numbers its own triggers, not the MAVLink camera's images
        rec.add_note(f"{len(missing) if missing else 'some'} {lost}; not read from the autopilot's log (it does not "
                     "hold the MAVLink camera's records)")
        if missing:
            publish(PhotosNotConfirmed(rec.id, time.time(), len(missing), ""))
        return
    fleet.say(f"uav{rec.id}: {len(missing) if missing else 'some'} {lost}; reading its log")
    lock = fleet.log_lock(url)
    if not _acquire(lock, fleet.stop, deadline):  # another vehicle's log is being read on this link
        rec.add_note(f"{lost}; its log was not read (fly was stopped or timed out first)")
        return
    try:
        found = session.photos_from_log(min(deadline, time.monotonic() + LOG_READ_S), wanted, rec.t_start,
                                        _log_folder(log_folder))
    except (BridgeError, OSError) as err:
        if not missing:  # after a gap: nothing known to be missing, but what it took in the gap is unknown
            rec.add_note(f"{lost}: its log could not be read: {err}")
            publish(PhotosNotConfirmed(rec.id, time.time(), None, str(err)))
            return
        rec.add_note(f"{len(missing)} {lost}; not read from the vehicle's log: {err}")
        publish(PhotosNotConfirmed(rec.id, time.time(), len(missing), str(err)))
        return
    finally:
        lock.release()
    samples = np.array(rec.samples) if rec.samples else np.zeros((0, 7))
    got = 0
    for photo in found:
        # When it was taken, on our clock: through the samples' vehicle clock (time since boot).
        t = float(np.interp(photo.time_boot_s, samples[:, 5], samples[:, 0])) if len(samples) else time.time()
        up = photo.alt_rel if photo.alt_rel is not None else rel_alt
        attitude = (None if photo.roll is None or photo.pitch is None or photo.yaw is None
                    else (photo.roll, photo.pitch, photo.yaw))
        got += photo.img_idx not in rec.camera  # the first word about an index stands
        publish(PhotoTaken(rec.id, t, photo.img_idx, photo.lat, photo.lon, up, source="log", attitude=attitude,
                           amsl_m=photo.alt_amsl))
    rec.add_note(f"{len(missing) if missing else 'some'} {lost}; {got} read back from the vehicle's log")
    unconfirmed = len(missing - set(rec.camera))
    if unconfirmed:
        publish(PhotosNotConfirmed(rec.id, time.time(), unconfirmed, ""))


def _acquire(lock: threading.Lock, stop: threading.Event, deadline: float) -> bool:
    """The link's log lock, unless fly is stopped or times out first."""
    while not lock.acquire(timeout=0.5):
        if stop.is_set() or time.monotonic() >= deadline:
            return False
    return True


def _log_folder(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def check_still_held(session: VehicleSession, rec: DroneRecord) -> None:
    """After landing: does the vehicle still hold exactly the mission that was uploaded?"""
    try:
        differences = session.mission.differences(rec.wire)
    except BridgeError as err:
        rec.add_problem(f"uav{rec.id}: could not read the mission back after landing: {err}")
        return
    rec.set(held_after_flight=not differences)
    if differences:
        rec.add_problem(f"uav{rec.id}: holds another mission after the flight: " + "; ".join(differences))
