"""`missionplan fly DIR`: fly a planned fleet over MAVLink, keep its journal, judge it.

Owns the fleet: one connection per --connect URL, shared by the vehicles on it (missionplan.bridge.link.shared_link: one
udpin port all vehicles send to, a TCP port, a radio); one thread per drone (drone_flight.DroneFlight:
readiness, site check, upload, arming, the common start, following, the end); the journal every drone
writes to as things happen (journal.Journal, DIR/journal.sqlite); the live separation watch; what
Ctrl-C does; and the judgement, made from the journal (flight_report.judge: flight.json, flight.png,
missed.geojson).

Ctrl-C (or SIGTERM) stops following: the vehicles fly on with their missions (they are autonomous), the
record is written from the journal and fly says so. A second Ctrl-C within ABORT_WINDOW_S, or
`--on-abort rtl|land`, commands every vehicle this run started to return (RTL) or to land.
`fly --resume DIR` re-attaches to the flight a killed or stopped run left (drone_flight: only vehicles
holding this flight's mission, and nothing commanded) and judges the whole flight, with the photos of
both runs. The plan folder is fly's alone for the whole run (missionplan.bridge.folder_lock): a second
process gets one line naming this one, before it opens any link or writes any file. Every link fly
opens signs with --signing-key when given and speaks as ground station --gcs-sysid / --gcs-compid
(missionplan.cli.vehicle.add_gcs_arguments). The command line (its options, the exit codes) is
missionplan/cli/fly.py.

The camera: a plan whose photos a MAVLink camera takes (`plan --capture camera`, `camera-interval`) has each
vehicle's camera parameters and its camera checked before anything is uploaded to it (bridge.link.camera_check,
drone_flight); a vehicle without them is told what to set and vetoes arming, as at the wrong site.

The ground: a plan over a DEM has each ArduPilot vehicle served the plan folder's copy of it from when it is
found to the end of its flight, and none armed before each has it loaded (terrain_service, drone_flight).

The disk: fly checks before any link is opened that the plan folder's disk has room for the flight's
record (disk_space.py); in flight a journal that cannot write pauses and says so (journal.py); what of
the record the folder would not take goes to a fallback file, said in one line, exit EXIT_NOT_RECORDED.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.base.naming import Named
from missionplan.bridge.errors import BridgeUsageError
from missionplan.bridge.folder_lock import holding_folder
from missionplan.bridge.link.connection import GCS_COMPONENT_ID, GCS_SYSTEM_ID, mavlink, parse_gcs_sysid
from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.link.readiness import DEFAULT_LAUNCH_OFFSET_M, ground_distance_m
from missionplan.bridge.link.shared_link import LinkPool
from missionplan.bridge.terminal_text import printable
from missionplan.bridge.link.signing import SigningKey
from missionplan.bridge.session.action import HOMING
from missionplan.bridge.transfer.uploader import check_gcs_identity

from ..mission.plan_record import PlanRecord, PlanRecordError, read_plan_record
from ..mission.sorties import sortie_file
from .disk_space import check_space
from .display import progress_display
from .drone_flight import DroneFlight
from .event_journal import EventJournal
from .fleet_start import DEFAULT_READY_S, FleetGate, FleetStart
from .follower_mail import Mailbox, RecordEvent, RecordProblem
from .flight_report import FlightResult, judge, live_tolerance, sortie_view
from .journal import RETRY_S, Journal, write_fallback
from .journal_db import JournalError
from .link_silence import GONE_SILENT_S, SilenceRule
from .live_replan import Retasker
from .retask_planner import RetaskPlanner
from .record import DroneRecord
from .terrain_service import FleetTerrain, plan_ground

DEFAULT_TELEMETRY_HZ = 25.0
UPLOADERS = ("missionplan", "mavsdk")  # who reads the .plan files and uploads them
ON_ABORT = ("none", *HOMING)
ABORT_WINDOW_S = 5.0  # after a Ctrl-C, a second one this soon commands the fleet home
WATCH_S = 1.0  # the live separation watch looks this often
EXIT_NOT_RECORDED = 3  # the flight's record is not whole in its folder (the rest went to a fallback file)


def flight_view(plan_dir: Path, record: PlanRecord, sortie: int) -> PlanRecord:
    """The plan record as a flight of `sortie` is judged (flight_report.sortie_view): with several sorties,
    every sortie's planned photos (read from its files) decide which cells are this one's duty."""
    count = record.sorties
    missions = {j: {d.id: read_mission_file(path).mission.items for d in record.drones or ()
                    if (path := plan_dir / sortie_file(d.id, j)).is_file()}
                for j in range(1, count + 1)} if count > 1 else {}
    return sortie_view(record, sortie, missions)


class SeparationWatch:
    """The live check of the plan's separation promise, from each drone's latest position: one alert
    when two drones come closer than promised (less the tolerance the judge allows), one more when they
    are apart again."""

    def __init__(self, records: list[DroneRecord], promised_3d: float | None, tolerance: float,
                 alert: Any, mail: dict[int, Mailbox]) -> None:
        self.records, self.promised, self.tolerance, self.alert = records, promised_3d, tolerance, alert
        self.mail = mail  # the alert goes into both drones' records through their followers
        self.close: set[tuple[int, int]] = set()

    def look(self) -> None:
        if self.promised is None:
            return
        latest = {rec.id: rec.samples[-1] for rec in self.records if rec.started and rec.samples}
        ids = sorted(latest)
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                pa, pb = latest[a], latest[b]
                if abs(pa[0] - pb[0]) > 2.0:  # not heard at the same moment: nothing to compare
                    continue
                apart = float(np.hypot(ground_distance_m((pa[1], pa[2]), (pb[1], pb[2])), pa[3] - pb[3]))
                pair = (a, b)
                if apart < self.promised - self.tolerance and pair not in self.close:
                    self.close.add(pair)
                    text = (f"uav{a} and uav{b}: separation breach, {apart:.1f} m apart (the plan promised "
                            f"{self.promised:g} m, tolerance {self.tolerance:.1f} m)")
                    for sysid in pair:
                        self.mail[sysid].post(RecordEvent(time.time(), f"alert: {text}"))
                    self.alert(text)
                elif apart >= self.promised and pair in self.close:
                    self.close.discard(pair)
                    self.alert(f"uav{a} and uav{b}: {apart:.1f} m apart again")


def _abort(flights: list[DroneFlight], action: str, alert: Any) -> None:
    """Command every vehicle this run started and that is still armed to return (RTL) or land. Only the
    drones whose followers have ended (joined: their sessions are this thread's now; the messages meanwhile
    are left unread); one whose follower is still running is not commanded, and that is said."""
    for flight in flights:
        rec, session = flight.record, flight.session
        if not rec.started or session is None:
            continue
        if not flight.mail.closed:
            alert(f"uav{rec.id}: not commanded {action.upper()}: its follower had not stopped; command it by hand")
            continue
        if not flight.armed:
            continue
        result = session.action.homing_mode(action, time.monotonic() + 5.0, observe=False)
        text = f"commanded {action.upper()}: " + ("accepted" if result == mavlink.MAV_RESULT_ACCEPTED else
                                                 "not acknowledged" if result is None else f"refused ({result})")
        flight.tell(RecordEvent(time.time(), f"fly: {text}"))
        alert(f"uav{rec.id}: {text}")


@holding_folder  # one owner per folder: a second fly, plan or replan here is refused before any link opens
def fly(plan_dir: Path, connect: str | list[str], timeout_s: float = 600.0, progress: bool = True,
        time_scale: float | None = None, telemetry_hz: float = DEFAULT_TELEMETRY_HZ,
        upload_with: str = "missionplan", sortie: int = 1, ready_s: float = DEFAULT_READY_S,
        max_launch_offset_m: float = DEFAULT_LAUNCH_OFFSET_M, photos_from_track: bool = False,
        key: SigningKey | None = None, source_system: int = GCS_SYSTEM_ID,
        source_component: int = GCS_COMPONENT_ID, resume: bool = False, on_abort: str = "none",
        command: str = "", replan: RetaskPlanner | None = None,
        replan_after_s: float = GONE_SILENT_S, silences_in_vehicle_time: bool = False) -> FlightResult:
    """Fly every drone of plan_dir at once (or, resume=True, follow again the flight a stopped run
    left), journal it as it happens, and judge it from the journal: flight.json, flight.png,
    missed.geojson.

    connect: one URL or several (each URL, or SYSID=URL; missionplan.bridge.link.shared_link.parse_connects): one
    connection per URL, shared by the vehicles on it, signed with `key` when given, and speaking as
    ground station (source_system, source_component).
    progress: one bar per drone on stderr when it is a terminal, else plain lines (a log); False: none
    (alerts are said all the same).
    sortie=J flies battery sortie J (uavK-sJ.plan, J >= 2) of every drone that has one, judged on the
    targets that sortie's plan photographs (a resumed flight keeps its own sortie).
    photos_from_track: count a photo every trigger distance along the track of a vehicle that reports
    none (no CAMERA_FEEDBACK); without it such a flight is judged a failure (flight_report.judge).
    upload_with="mavsdk": MAVSDK's QGroundControl importer reads each .plan and MAVSDK uploads it;
    the read-back must then equal what our own reader makes of the same file.
    on_abort: what Ctrl-C commands the vehicles this run started ("none": nothing; a second Ctrl-C
    within ABORT_WINDOW_S then commands RTL). command: the command line, kept in the journal.
    replan: `fly --replan`, the planner of live re-tasks (missionplan.planning.retask.retask_planner): a drone gone
    (ended early, or silent for replan_after_s mid-mission) has what is left re-planned among the drones
    still flying, uploaded to them in flight (live_replan.Retasker).
    silences_in_vehicle_time: every silence threshold (replan_after_s, the link-lost notice, a survivor heard lately
    enough) counts the vehicles' seconds at time_scale, so a sped-up simulator meets them as a crew at 1x would
    (missionplan verify); fly itself counts ours."""
    if upload_with not in UPLOADERS:
        raise BridgeUsageError(Named("{upload_with} {0}: choose {1}", upload_with, " or ".join(UPLOADERS)))
    if on_abort not in ON_ABORT:
        raise BridgeUsageError(Named("{on_abort} {0}: choose {1}", on_abort, ", ".join(ON_ABORT)))
    check_gcs_identity(upload_with, source_system, source_component, "upload_with")
    plan_dir = Path(plan_dir)
    record = read_plan_record(plan_dir)
    if record.georeference is None or record.drones is None:
        raise BridgeUsageError(f"{plan_dir / 'report.json'}: not a georeferenced plan (no missions to fly)")
    # Bad URLs: exit 2, before anything.
    pool = LinkPool([connect] if isinstance(connect, str) else list(connect), key, source_system, source_component)
    if sortie < 1:
        raise BridgeUsageError(Named("{sortie} must be 1 or more, got {0}", sortie))
    terrain = fleet_terrain(plan_dir, record)  # a missing or broken ground copy: one line, before anything is written
    try:
        # Room for the flight's record, before any link is opened (a resume writes as much at most).
        check_space(plan_dir, record, telemetry_hz, None if resume else sortie)
        journal = (Journal.continue_flight(plan_dir, command) if resume
                   else Journal.start_flight(plan_dir, sortie, command))
    except JournalError as err:
        raise BridgeUsageError(str(err)) from None
    for line in journal.repairs:  # a damaged journal salvaged, a cut one: said, then flown
        print(f"missionplan fly: {printable(line)}", file=sys.stderr)
    result: FlightResult | None = None
    try:
        result = _fly_journaled(plan_dir, record, pool, journal, timeout_s, progress, time_scale, telemetry_hz,
                                upload_with, ready_s, max_launch_offset_m, photos_from_track, key, resume, on_abort,
                                source_system, replan=replan, terrain=terrain,
                                silence=SilenceRule(replan_after_s, time_scale if silences_in_vehicle_time else None))
        return result
    finally:
        journal.close()
        _keep_the_rest(plan_dir, journal, result)


def _keep_the_rest(plan_dir: Path, journal: Journal, result: FlightResult | None) -> None:
    """After the journal closed: what of the flight's record could not be written into plan_dir (journal
    records still held, flight.json and the other files the judge writes) is said in one line, and the
    records and flight.json's content go to a fallback file elsewhere (journal.write_fallback)."""
    missing = dict(result.unwritten) if result is not None else {}
    if not journal.unwritten and not missing:
        return
    parts = []
    if journal.unwritten:
        why = journal.paused or "the disk did not answer"
        parts.append(f"{len(journal.unwritten)} journal records not written ({why})")
    if missing:  # each run of files with the same reason, then the reason
        groups: list[tuple[list[str], str]] = []
        for names, why in missing.items():
            if groups and groups[-1][1] == why:
                groups[-1][0].append(names)
            else:
                groups.append(([names], why))
        parts.append("not written: " + ", ".join(f"{', '.join(names)} ({why})" for names, why in groups))
    line = f"{plan_dir}: the flight's record is not whole there: {'; '.join(parts)}"
    if journal.unwritten or "flight.json" in missing:
        doc = result.doc if result is not None and "flight.json" in missing else None
        try:
            line += f"; kept instead in {write_fallback(journal, doc, '; '.join(parts))}"
        except OSError as err:
            line += f"; no fallback file could be written either ({err}): that part is lost"
    print(f"missionplan fly: {printable(line)}", file=sys.stderr)
    if result is not None:
        result.record_faults.append(line)


def _fly_journaled(plan_dir: Path, record: PlanRecord, pool: LinkPool, journal: Journal, timeout_s: float,
                   progress: bool, time_scale: float | None, telemetry_hz: float, upload_with: str, ready_s: float,
                   max_launch_offset_m: float, photos_from_track: bool, key: SigningKey | None, resume: bool,
                   on_abort: str, source_system: int, replan: RetaskPlanner | None = None,
                   terrain: FleetTerrain | None = None, silence: SilenceRule = SilenceRule()) -> FlightResult:
    sortie = journal.sortie
    files = {d.id: plan_dir / sortie_file(d.id, sortie) for d in record.drones or ()}
    view = flight_view(plan_dir, record, sortie)
    drones = view.drones or ()
    if not drones:
        raise BridgeUsageError(f"{plan_dir}: no drone has a sortie {sortie}")
    ids = [d.id for d in drones]
    parse_gcs_sysid(source_system, ids)  # not a drone's own id
    records = journal.records(ids) if resume else [DroneRecord(id=k) for k in ids]
    for rec, drone in zip(records, drones):
        rec.sink = journal.sink(rec.id)
        rec.set(planned_photos=int(drone.photos))
    start = time.monotonic()
    deadline = start + timeout_s
    for rec in records:
        if not files[rec.id].exists():
            rec.add_problem(f"uav{rec.id}: {files[rec.id]} is missing")
    runnable = [rec for rec in records if files[rec.id].exists()]
    # From here on a drone's record is written by its follower's thread; other threads post to its mailbox.
    mail = {rec.id: Mailbox(rec, followed=rec in runnable) for rec in records}
    bars, say, alert = progress_display({rec.id: f"uav{rec.id}" for rec in runnable}, progress)

    def journal_alert(text: str) -> None:  # the journal paused or resumed (its writer's thread): said as every alert
        for box in mail.values():
            box.post(RecordEvent(time.time(), f"alert: {text}"))
        alert(text)

    journal.set_alert(journal_alert)
    interrupted, flights, retasker = False, [], None
    try:
        pool.open_all()
        pool.register(rec.id for rec in runnable)
        planned_s = {d.id: float(d.flight_s) for d in drones}
        fleet = FleetStart(pool, FleetGate(len(runnable)), FleetGate(len(runnable)), threading.Event(), key=key,
                           ready_s=ready_s, max_offset_m=max_launch_offset_m, say=say, alert=alert, resume=resume,
                           time_scale=time_scale, planned_s=planned_s, commit=journal.flush,
                           silence=silence, terrain=terrain,
                           camera_records=record.settings is not None and record.settings.mission.camera_records,
                           capture=record.settings.mission.capture if record.settings is not None else "relay")
        # What the followers decide goes into their records and alerts in their own threads, and to the
        # re-tasker on a queue it reads in this one.
        fleet.events.subscribe(EventJournal({rec.id: rec for rec in runnable}, alert))
        retask_events = fleet.events.new_queue() if replan is not None and not resume else None
        flights = [DroneFlight(fleet, rec, files[rec.id], deadline, telemetry_hz, bars.get(rec.id), upload_with,
                               mail[rec.id]) for rec in runnable]
        threads = [threading.Thread(target=f.run, name=f"fly-uav{f.sysid}", daemon=True) for f in flights]
        for thread in threads:
            thread.start()
        watch = SeparationWatch(runnable, promised_3d(view), live_tolerance(runnable, time_scale or 1.0, telemetry_hz),
                                alert, mail)
        retasker = None if replan is None or retask_events is None else Retasker(
            plan_dir, view, flights, replan, alert, retask_events, fleet.silence, time_scale)
        try:
            while any(t.is_alive() for t in threads) and time.monotonic() < deadline + 5.0:
                _wait_any(threads, WATCH_S)
                watch.look()
                if retasker is not None:
                    retasker.look()
                    # After a re-task the promise is the new tracks' (retasked_promise); the lost drone's
                    # last position is no neighbour any more.
                    watch.promised = promised_3d(retasked_promise(view, retasker.retasks))
                    watch.records = [r for r in runnable if r.id not in retasker.handled]
        except KeyboardInterrupt:
            interrupted = True
            _stopped(fleet, flights, threads, on_abort, alert)
        finally:
            fleet.stop.set()
            for thread in threads:
                thread.join(2.0)
    finally:
        pool.close()
        for bar in bars.values():
            bar.close()
        for box in mail.values():  # a follower that did not stop within its bound: what waits for it is written
            box.close()            # now, and its record is judged as it stands
    if interrupted:
        for flight in flights:
            if flight.record.started and not (flight.record.finished or flight.record.ended_early):
                flight.tell(RecordProblem(f"uav{flight.sysid}: not followed to the end (fly was stopped); it flies "
                                          f"on with its mission: `missionplan fly --resume {plan_dir}` follows it"))
    # flight.json is a view of the journal: the records read back from it, both runs' if resumed. A journal
    # still paused (its disk full) gets two more tries; failing those, the records kept here are judged
    # (the same changes, in memory) and what the journal lacks goes to the fallback file when it closes.
    faults = list(journal.repairs) if resume else []  # a damaged or cut journal: this flight's record has holes
    if journal.flush(through_pause_s=2 * RETRY_S + 1.0):
        judged = journal.records(ids)
    else:
        judged = records
        faults.append(f"{journal.path}: {journal.paused}: {journal.held} records not in the journal when the "
                      "flight was judged")
    if retasker is not None:
        view = retasked_promise(view, retasker.retasks)
    result = judge(plan_dir, view, judged, time_scale, wall_s=time.monotonic() - start, telemetry_hz=telemetry_hz,
                   photos_from_track=photos_from_track, flight=journal.flight, sortie=sortie,
                   retasks=retasker.retasks if retasker is not None else None, record_faults=faults)
    for notice in result.notices:  # a ledger the judge had to rebuild
        print(f"missionplan fly: {printable(notice)}", file=sys.stderr)
    journal.mark_judged(photos_from_track)
    return result


def fleet_terrain(plan_dir: Path, record: PlanRecord) -> FleetTerrain | None:
    """The ground the flight serves its ArduPilot vehicles (terrain_service): for a plan over a DEM whose
    missions are for ArduPilot; None otherwise (flat ground, or PX4 missions at sea-level altitudes)."""
    if record.georeference is None or record.georeference.terrain is None:
        return None
    firmwares = set()
    for drone in record.drones or ():
        path = plan_dir / sortie_file(drone.id, 1)
        if path.is_file():
            firmwares.add(read_mission_file(path).firmware)
    if firmwares and Flavour.ARDUPILOT not in firmwares and None not in firmwares:
        return None
    ground = plan_ground(plan_dir, record)
    return FleetTerrain(ground, record.georeference.terrain.spacing_m) if ground is not None else None


def promised_3d(record: PlanRecord) -> float | None:
    """The 3-D separation the plan promises (None: no two drones fly together)."""
    return record.separation.d3 if record.separation is not None else None


def retasked_promise(record: PlanRecord, retasks: list[dict[str, Any]]) -> PlanRecord:
    """The plan record as the judge sees it after live re-tasks: the separation promised is the smaller of the
    plan's and each re-task's (its new tracks' closest approach, checked against the minimum separation
    before upload); the flight is held to what was promised for each part of it."""
    promised = [r["separation_m"] for r in retasks if r.get("separation_m") is not None]
    planned = promised_3d(record)
    if not promised or planned is None or record.promise is None:
        return record
    separation = record.promise.separation.promising(min([float(planned)] + promised))
    return replace(record, promise=replace(record.promise, separation=separation))


def _wait_any(threads: list[threading.Thread], seconds: float) -> None:
    """Wait up to `seconds` while every thread runs (a short join on the first one still alive)."""
    alive = [t for t in threads if t.is_alive()]
    if alive:
        alive[0].join(seconds)


def _stopped(fleet: FleetStart, flights: list[DroneFlight], threads: list[threading.Thread], on_abort: str,
             alert: Any) -> None:
    """Ctrl-C: stop following and command nothing, unless --on-abort says what, or a second Ctrl-C comes."""
    fleet.stop.set()
    for thread in threads:
        thread.join(2.0)
    # A follower that has ended hands its record and session to this thread; one still running keeps them.
    flying = [f for f in flights if f.record.started and (not f.mail.closed or f.armed)]
    if on_abort != "none":
        alert(f"stopped following; --on-abort {on_abort}: commanding the vehicles this run started")
        _abort(flights, on_abort, alert)
        return
    if not flying:
        alert("stopped following")
        return
    alert(f"stopped following: {', '.join(f'uav{f.sysid}' for f in flying)} fly on with their missions; Ctrl-C "
          f"again within {ABORT_WINDOW_S:g} s sends them home (RTL)")
    try:
        time.sleep(ABORT_WINDOW_S)  # the window for a second Ctrl-C: waiting for the crew, not for a vehicle
    except KeyboardInterrupt:
        _abort(flights, "rtl", alert)


def refuse_empty_missions(plan_dir: Path, sortie: int) -> None:
    """BridgeUsageError naming the first mission file of the sortie that holds no mission item: uploading it
    would wipe that vehicle's mission (as `upload` refuses without --allow-empty). Checked before any vehicle
    is contacted; each file is read as the upload will read it, so a bad file fails here too, in one line.
    A report.json that cannot be read is left to fly(), which says what is wrong with it."""
    try:
        ids = [d.id for d in read_plan_record(plan_dir).drones or ()]
    except PlanRecordError:
        return
    for sysid in ids:
        path = plan_dir / sortie_file(sysid, sortie)
        if path.is_file() and not read_mission_file(path).mission.items:
            raise BridgeUsageError(f"{path}: the file holds no mission items; flying it would wipe vehicle {sysid}'s "
                                   "mission (plan the folder again, or `missionplan clear` the vehicle to mean that)")
