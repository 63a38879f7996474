"""One drone of a fleet flight, in its own thread: from finding the vehicle to its landing.

A fresh flight (`fly DIR`):
1. find the vehicle on its link and hear its HEARTBEAT (a VehicleSession: missionplan.bridge.session,
   through which every request to the vehicle goes). A vehicle that is ARMED was not started by
   this run of fly: nothing is sent to it (no upload, mode or arming), it vetoes the fleet's arming, and
   fly says so (`fly --resume DIR` follows a flight this folder started);
2. ask for every stream fly reads (missionplan.bridge.link.readiness: ArduPilot sends nothing until asked) and wait,
   bounded by --ready-timeout, until it has a GPS fix, an EKF solution, a home position and passing
   pre-arm checks, saying what it waits for and what the vehicle says (STATUSTEXT);
3. site check: its home within --max-launch-offset (plus its GPS error) of the plan's launch point, and for a plan
   a MAVLink camera takes the photos of, its camera (bridge.link.camera_check); else nothing is uploaded to it and
   no drone arms at all (the arm gate's veto);
4. upload uavK.plan (or let MAVSDK's QGroundControl importer upload it) and prove it by read-back; over a
   DEM, an ArduPilot vehicle (served the plan's ground from when it was found: terrain_service) must then
   report that ground loaded for its waypoints within --ready-timeout, else it vetoes arming as in 3;
5. the arm gate (nobody arms until every drone got this far), GUIDED (ArduPilot), arm (retried while
   the vehicle says it is not ready), the start gate, MAV_CMD_MISSION_START: all start together;
6. follow it (below) until it has landed and disarmed.
A resumed flight (`fly --resume DIR`) skips 1-5: the vehicle must hold the mission this flight uploaded
(downloaded and compared, not assumed); an armed one is followed again, one that landed meanwhile is
closed, one never started is left alone. Nothing is commanded in either case.

Following: every message of the vehicle goes into the drone's record (telemetry_record), and through it
into the flight journal, as it comes. What the follower decides is published as a typed event
(events.py) on the fleet's FlightEvents: the journal and the alerts take it in this thread
(event_journal), the re-tasker in fly's (live_replan). Said at once, as alerts (the terminal and the
journal): the link lost and back, a mode changed by someone else (RC, another ground station, a
failsafe), a failsafe or fence the vehicle reports, a reboot. The drone's flight ends when the vehicle is
on the ground and disarmed: finished when its mission was complete, else ended early, with the reason
(the failsafe it reported, the mode it was switched to, or the item it stopped at). What a silence means
is link_silence's to say: a silent vehicle is "link lost", not gone, until its mission would be long over
or the time-out; heard again, it is followed again.
After landing: the photos whose reports never arrived are read from the vehicle's log where the
autopilot keeps one, and the mission is read back once more (still the one uploaded) (after_landing).
"""

from __future__ import annotations

import math
import queue
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any, Callable

import numpy as np

from missionplan.bridge.errors import BridgeError
from missionplan.bridge.formats.mission_items import Flavour, to_wire
from missionplan.bridge.formats.missionfile import check_firmware, read_mission_file
from missionplan.bridge.link.camera_check import CAMERA_MODES, check_camera
from missionplan.bridge.link.connection import COMMAND_TRIES, COMMAND_WAIT_S, mavlink
from missionplan.bridge.link.readiness import site_problem
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.transfer.protocol import Timeouts

from .after_landing import check_still_held, recover_photos
from .event_journal import refused
from .events import (EndedEarly, Finished, FlightEvent, FollowingStopped, GaveUpWaiting, LinkBack, LinkLost, LinkQuiet,
                     MissionStarted, Rebooted, SentHome, ShareGivenAway, TimedOut)
from .fleet_start import FleetStart
from .flight_report import vehicle_rate
from .follower_mail import Mailbox, Message
from .link_silence import LinkWatch, SilenceStep, give_up_at
from .record import DroneRecord
from .retask_actions import RetaskActions
from .telemetry_record import TelemetryRecorder
from .terrain_service import DroneTerrain

PX4_START_RETRY_S = 5.0   # MISSION_START retried this long while PX4 checks a new mission (see _mission_start)
START_RETRY_WAIT_S = 0.5
# A lost MISSION_START is sent again after a few of the vehicle's acknowledgement round trips (the
# slowest seen on its link), within these bounds, not after the usual half second: the plan's
# separation assumes the missions start together, and half a second lost in a sped-up simulator, or
# on a radio, shifts one drone's whole track against the others'.
START_ACK_RTTS, START_WAIT_MIN_S = 4.0, 0.1
HEARTBEAT_WAIT_S = 3.0  # for the first HEARTBEAT that says whether a vehicle is armed (sent at 1 Hz)
MISSION_STATE_WAIT_S = 3.0  # after a link gap, how long a landed vehicle's fresh MISSION_CURRENT is waited for
TIMEOUTS = Timeouts(item_timeout=0.5, retries=10)  # the mission protocol's, on a fleet's links


def unanswered(text: str, session: VehicleSession) -> str:
    """text, with MAVLink 2 signing named when it is the likely reason the vehicle did not answer
    (missionplan.bridge.link.connection.Link.signing_hint decides)."""
    hint = session.signing_hint()
    return f"{text}: {hint}" if hint else text


class DroneFlight:
    """One drone's thread: what it learns goes into `record` (and the journal behind it), what it decides
    is published on fleet.events."""

    def __init__(self, fleet: FleetStart, record: DroneRecord, plan_path: Path, deadline: float,
                 telemetry_hz: float, bar: Any, upload_with: str = "missionplan", mail: Mailbox | None = None) -> None:
        self.fleet, self.record, self.plan_path, self.deadline = fleet, record, plan_path, deadline
        self.mail = mail if mail is not None else Mailbox(record)  # what other threads tell this one
        self.upload_with = upload_with
        self.telemetry_hz, self.stop, self.bar = telemetry_hz, fleet.stop, bar
        self.session: VehicleSession | None = None
        self.recorder: TelemetryRecorder | None = None  # its messages into its record, from the session on
        self.watch: LinkWatch | None = None  # its link, from the mission start (or the re-attach) on
        self.retasking: RetaskActions | None = None  # fly --replan: hold, re-task, release, from the session on
        self.url = ""
        self.checked_in = self.arm_checked_in = False  # at the start gate, at the arm gate
        self.found_armed = False  # armed when found: someone else's flight, never to be touched
        # Silences in flight: the link lost, or the time no run of fly listened (a resumed flight). What
        # happened in one is not in the record: the photos then are read from the log in full, and a
        # vehicle found landed after one is judged from a MISSION_CURRENT heard after it.
        self.gaps = 0
        self.back_at = 0.0  # our monotonic clock: the end of the latest silence
        # fly --replan: what the main thread asks this one to do with the vehicle (retask_actions: hold, re-task,
        # release), run here because this thread owns the link's receive loop; each answers through its Future.
        self.requests: queue.SimpleQueue[tuple[Callable[[], Any], Future[Any]]] = queue.SimpleQueue()
        self.given_away = False  # fly --replan gave this drone's share to others: heard again, it goes home
        self.terrain: DroneTerrain | None = None  # a plan over a DEM, an ArduPilot vehicle: its ground, served
        self.found_at, self.ready_by = time.monotonic(), deadline  # a camera listened for since; the readiness bound

    @property
    def sysid(self) -> int:
        return self.record.id

    @property
    def armed(self) -> bool:
        """Armed as last reported (True until a vehicle was heard)."""
        return self.recorder.armed if self.recorder is not None else True

    def publish(self, event: FlightEvent) -> None:
        self.fleet.events.publish(event)

    def problem(self, text: str) -> None:
        self.record.add_problem(f"uav{self.sysid}: {text}")

    def run(self) -> None:
        try:
            if self.fleet.resume:
                if self._connect() and self._attach():
                    self._follow_to_the_end()
            elif (self._connect() and self._not_airborne() and self._streams() and self._ready() and self._site()
                  and self._camera() and self._upload() and self._terrain_loaded() and self._arm() and self._start()):
                self._follow_to_the_end()
        except Exception as err:  # noqa: BLE001 - one drone's failure must not hide the others'
            self.problem(f"{type(err).__name__}: {err}")
        finally:
            if self.watch is not None:  # the re-tasker times its silence from here
                self.publish(FollowingStopped(self.sysid, time.time(), self.watch.heard_at))
            if not self.fleet.resume:
                if not self.arm_checked_in:  # failed before the arm gate: the others need not wait for us
                    self.fleet.arm_gate.check_in(0.0)
                if not self.checked_in:  # failed before the start: let the others go without us
                    self.fleet.start_gate.check_in(0.0)
                if not self.record.started and self.session is not None and not self.found_armed:
                    self._leave_safe()  # a vehicle this run got ready (or armed) but will not fly
            if self.terrain is not None:
                self.record.add_note(self.terrain.served_line())
            if self.session is not None:
                self.session.close()
            self.mail.close()  # from here on the record is fly's main thread's, which joins this one

    # ------------------------------------------------------------------ finding the vehicle
    def _connect(self) -> bool:
        """Find the vehicle on its link, learn its flavour, hear whether it is armed."""
        rec = self.record
        try:
            # Started right after power-on, a vehicle may take a while to send its first heartbeat.
            wait_s = max(1.0, min(self.fleet.ready_s, self.deadline - time.monotonic()))
            view = self.fleet.pool.vehicle(rec.id, wait_s)
            self.url = view.url
            self.session = VehicleSession.open(view, rec.id, wait_s, TIMEOUTS, self.fleet.say, observe=self._observe)
        except BridgeError as err:
            self.problem(f"not found: {err}")
            return False
        self.recorder = TelemetryRecorder(rec, self.session.state, self.session.action.commanded, self.publish,
                                          self.bar, camera_records=self.fleet.camera_records)
        self.retasking = RetaskActions(self.session, rec, self.recorder, self.deadline, self.problem, self.bar)
        if self.fleet.terrain is not None:  # ArduPilot asks for its ground from its first seconds
            self.terrain = self.fleet.terrain.for_vehicle(self.session.flavour)
            if self.terrain is not None:
                self.terrain.attach(self.session)
        self.session.wait_heartbeat(min(self.deadline, time.monotonic() + HEARTBEAT_WAIT_S))
        return True

    def _observe(self, msg: Any) -> None:
        """Every message of the vehicle the session takes: recorded from the mission start on."""
        if self.recorder is not None:
            self.recorder.take_if_started(msg)

    def _not_airborne(self) -> bool:
        """A vehicle already armed was started by someone else (or by a run of fly that is gone): touch
        nothing on it, and no drone arms."""
        assert self.session is not None
        state = self.session.state
        if state.armed is not True:
            return True
        self.found_armed = True
        return self._veto(f"is ARMED ({state.mode_name()}): this run of fly did not start it, so nothing was sent to "
                          f"it (no upload, mode or arming) and no drone arms; to follow a flight this folder started, "
                          f"`missionplan fly --resume {self.plan_path.parent}`", "is already armed")

    def _streams(self) -> bool:
        """Ask for every stream fly reads (telemetry only: nothing that moves the vehicle)."""
        assert self.session is not None
        refused_streams = self.session.request_streams(self.telemetry_hz, self.deadline)
        if self.terrain is not None:  # its requests and reports, so that it loads while it gets ready
            refused_streams += self.terrain.ask(self.session, self.deadline)
        if refused_streams:
            self.record.add_note(unanswered(f"streams not accepted (SET_MESSAGE_INTERVAL): "
                                            f"{', '.join(refused_streams)}; the vehicle's own rates", self.session))
        return True

    def _ready(self) -> bool:
        """Bounded wait for GPS, EKF, home and pre-arm checks (missionplan.bridge.link.readiness)."""
        assert self.session is not None
        self.ready_by = min(self.deadline, time.monotonic() + self.fleet.ready_s)
        missing = self.session.wait_ready(self.ready_by)
        if missing:
            reasons = self.session.state.reasons()
            # A vehicle that ignores us (signing) never sends what it sends only when asked (its home).
            self.problem(unanswered(f"not ready to fly within {self.fleet.ready_s:g} s: still waiting for "
                                    f"{', '.join(missing)}" + (f"; the vehicle said: {reasons}" if reasons else ""),
                                    self.session))
            return False
        return True

    def _leave_safe(self) -> None:
        """A vehicle this run will not fly (and did not find armed): disarmed and out of AUTO, said how."""
        assert self.session is not None
        try:
            how = self.session.action.make_safe(time.monotonic() + 5.0)
        except BridgeError as err:
            how = f"could not be made safe: {err}"
        self.record.add_note(how)
        self.fleet.say(f"uav{self.sysid}: {how}")

    # ------------------------------------------------------------------ a fresh start
    def _upload(self) -> bool:
        rec = self.record
        try:
            plan = read_mission_file(self.plan_path)
            check_firmware(plan, self.plan_path, self.session.flavour if self.session else None, rec.id)
            if self.upload_with == "mavsdk":
                self._upload_by_mavsdk()
            assert self.session is not None
            wire = to_wire(plan.mission, self.session.flavour)
            rec.set(wire=wire)
            if self.upload_with == "mavsdk":
                # What MAVSDK made of the file must be exactly what our reader makes of it.
                differences = self.session.mission.differences(wire)
                if differences:
                    raise BridgeError("the mission MAVSDK read from the .plan and uploaded differs from ours: "
                                      + "; ".join(differences))
                # MAVSDK sets no parameters
                params_set = self.session.mission.set_plan_params(plan.mission, self._terrain_spacing())
            else:
                params_set = self.session.mission.upload(plan.parts(), verify=True,
                                                         terrain_spacing=self._terrain_spacing()).params
            rec.set(uploaded=True, flavour=self.session.flavour.value)
            if self.terrain is not None:  # what the vehicle flies over the ground with
                rec.add_note("; ".join(params_set))
            params = self.session.navigation_params()  # what it will fly with: re-times the plan (its autopilot's model)
            if params is not None:
                rec.set(params=params)
            return True
        except (BridgeError, OSError) as err:
            self.problem(f"upload failed: {err}")
            return False

    def _upload_by_mavsdk(self) -> None:
        """MAVSDK's own QGroundControl importer opens the .plan and MAVSDK uploads what it read."""
        assert self.session is not None
        connect_s = max(1.0, min(10.0, self.deadline - time.monotonic()))
        self.session.mission.upload_qgc_plan_by_mavsdk(self.plan_path, self.url, self.fleet.key, connect_s, TIMEOUTS)

    def _site(self) -> bool:
        """The site check, before anything is uploaded: the vehicle's home against its plan's launch
        point. A vehicle at the wrong site vetoes arming for the whole fleet at the arm gate at once
        (nothing is uploaded to it: PX4 would refuse a mission that starts that far away anyway)."""
        assert self.session is not None
        try:
            home = read_mission_file(self.plan_path).mission.home
        except (BridgeError, OSError) as err:
            self.problem(f"upload failed: {err}")
            return False
        wrong_site = site_problem(self.session.state, (home[0], home[1]) if home is not None else None,
                                  self.fleet.max_offset_m)
        if not wrong_site:
            return True
        return self._veto(f"site check failed: {wrong_site}", "failed the site check")

    def _camera(self) -> bool:
        """A plan whose photos a MAVLink camera takes: the vehicle's camera parameters and its camera, heard within
        the readiness bound (camera_check), before anything is uploaded; a vehicle without them vetoes arming."""
        assert self.session is not None
        if self.fleet.capture not in CAMERA_MODES:
            return True
        problem = check_camera(self.session.vehicle, self.fleet.capture, max(self.ready_by, time.monotonic()),
                               self.found_at)
        return not problem or self._veto(unanswered(problem, self.session), "cannot take the plan's photos")

    def _veto(self, problem: str, veto: str) -> bool:
        """A problem that keeps the whole fleet on the ground: said, and a veto at the arm gate at once. False."""
        self.problem(problem)
        self.arm_checked_in = True
        self.fleet.arm_gate.check_in(0.0, veto=f"uav{self.sysid} {veto}")
        return False

    def _terrain_spacing(self) -> int | None:
        return self.terrain.spacing if self.terrain is not None else None

    def _terrain_loaded(self) -> bool:
        """Over a DEM, an ArduPilot vehicle's ground loaded for its waypoints, bounded by --ready-timeout; a
        vehicle without it vetoes arming for the fleet (it would refuse to arm, or fly without its ground)."""
        if self.terrain is None:
            return True
        assert self.session is not None
        status = self.terrain.wait_loaded(self.session, min(self.deadline, time.monotonic() + self.fleet.ready_s),
                                          self.record.wire)
        if status.loaded_ok:
            self.record.add_note(status.line())
            return True
        return self._veto(unanswered(f"not armed: {status.line()}", self.session), "has not loaded its terrain")

    def _arm(self) -> bool:
        """The arm gate (nobody arms while a drone is still getting ready, none if any was vetoed),
        then GUIDED (ArduPilot) and arming, retried while not ready."""
        assert self.session is not None
        self.arm_checked_in = True
        vetoes = self.fleet.arm_gate.check_in(self.deadline - time.monotonic())
        if vetoes:
            self.problem(f"not armed: {'; '.join(vetoes)} (no drone arms when one is at the wrong site, "
                         "already armed, or without its terrain or its camera)")
            return False
        if self.stop.is_set():
            return False
        # In the journal before the arm command, so that `fly --resume` finds this vehicle whatever follows.
        self.record.set(arming=time.time())
        if not self.fleet.commit():
            self.problem("not armed: its start could not be written to the flight journal (a flight that cannot be "
                         "recorded is not started)")
            return False
        if self.session.flavour is Flavour.ARDUPILOT:  # arms in GUIDED, starts AUTO by MISSION_START
            self.session.action.guided(self.deadline)
        armed, why = self.session.action.arm(min(self.deadline, time.monotonic() + self.fleet.ready_s))
        if not armed:
            self.problem(unanswered(why, self.session) if "not acknowledged" in why else why)
            return False
        return True

    def _start(self) -> bool:
        assert self.session is not None and self.recorder is not None
        rec, session = self.record, self.session
        self.checked_in = True
        self.fleet.start_gate.check_in(self.deadline - time.monotonic())
        # The first positions may come before the acknowledgement: keep them (and what the vehicle says
        # from now on, not before).
        self.recorder.start()
        result = self._mission_start()
        if result != mavlink.MAV_RESULT_ACCEPTED and session.flavour is Flavour.PX4:
            # PX4 also starts a mission in its AUTO.MISSION mode (from the current item, 0 after an upload).
            if session.action.mission_mode(self.deadline) == mavlink.MAV_RESULT_ACCEPTED:
                rec.add_note(f"{refused('MISSION_START', result)}; started in AUTO.MISSION mode")
                result = mavlink.MAV_RESULT_ACCEPTED
        if result != mavlink.MAV_RESULT_ACCEPTED:
            what = refused("mission start", result)
            self.problem(unanswered(what, session) if result is None else what)
            return False
        now = time.time()
        self.publish(MissionStarted(self.sysid, now))
        rec.last_heard = now
        self.watch = LinkWatch(self.fleet.silence, time.monotonic())
        if self.bar is not None:
            self.bar.reset(total=max(len(rec.wire) - 1, 1))
        return True

    def _mission_start(self) -> int | None:
        """MAV_CMD_MISSION_START; its MAV_RESULT. PX4 takes a new mission only after its own checks (its
        navigator's, then commander's), so a start right after the upload may be DENIED ("Mission start
        denied! No valid mission") for a moment: retried for PX4_START_RETRY_S, within which PX4 does not
        yet disarm an armed vehicle that has not taken off (COM_DISARM_PRFLT, 10 s)."""
        assert self.session is not None
        rec, session = self.record, self.session
        px4 = session.flavour is Flavour.PX4
        until = min(self.deadline, time.monotonic() + (PX4_START_RETRY_S if px4 else 0.0))
        wait_s = self._start_wait_s()
        sends = math.ceil(COMMAND_TRIES * COMMAND_WAIT_S / wait_s)  # as long in all as any other command
        tries = 0
        while True:
            tries += 1
            result = session.action.start_mission(self.deadline,
                                                  done=lambda: rec.mission_state == mavlink.MISSION_STATE_ACTIVE,
                                                  tries=sends, wait_s=wait_s)
            if result not in (mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED) or \
                    time.monotonic() + START_RETRY_WAIT_S >= until:
                break
            session.listen(time.monotonic() + START_RETRY_WAIT_S)
        if tries > 1 and result == mavlink.MAV_RESULT_ACCEPTED:
            rec.add_note(f"MISSION_START accepted after {tries} tries (the vehicle had not yet taken the "
                         f"new mission: {session.state.reasons(1)})")
        return result

    def _start_wait_s(self) -> float:
        """How long a MISSION_START waits for its acknowledgement before it is sent again: START_ACK_RTTS of
        the slowest round trip this vehicle's link has shown (its mode and arming commands were acknowledged
        just before), never under START_WAIT_MIN_S nor over the usual COMMAND_WAIT_S."""
        assert self.session is not None
        rtt = self.session.ack_rtt_s()
        if rtt is None:
            return COMMAND_WAIT_S
        return min(COMMAND_WAIT_S, max(START_WAIT_MIN_S, START_ACK_RTTS * rtt))

    # ------------------------------------------------------------------ a resumed flight
    def _attach(self) -> bool:
        """Take up this flight's vehicle again (fly --resume): only if it holds the mission this flight
        uploaded; commands nothing. Whether there is anything to follow."""
        assert self.session is not None and self.recorder is not None
        rec, recorder = self.record, self.recorder
        if rec.finished or rec.ended_early:
            self.fleet.say(f"uav{self.sysid}: its flight had already ended; nothing to follow")
            return False
        if not (rec.started or rec.arming) or not rec.wire:
            rec.add_note("not started by the run that was stopped; left alone (`missionplan fly` starts it)")
            self.fleet.say(f"uav{self.sysid}: was not started by the stopped run; left alone")
            return False
        try:
            differences = self.session.mission.differences(rec.wire)
        except BridgeError as err:
            self.problem(f"could not read its mission to check it is this flight's: {err}; nothing was sent to it")
            return False
        if differences:
            self.problem("holds another mission than this flight uploaded (" + "; ".join(differences[:3])
                         + "): not this flight; nothing was sent to it")
            return False
        if not rec.started:  # armed by the stopped run, its start never journaled (it was killed first)
            rec.add_note(f"its start was not in the journal (the stopped run was about to arm it at "
                         f"{time.strftime('%H:%M:%S', time.gmtime(rec.arming))} UTC); followed from here")
            rec.set(started=True, t_start=rec.arming)
        self.back_at = time.monotonic()  # the silence since the stopped run ends here (before any MISSION_CURRENT)
        self.gaps += 1  # nobody listened between the stopped run and this one
        self._streams()
        state = self.session.state
        recorder.armed = bool(state.armed)
        recorder.last_reached = max((seq for _, seq in rec.reached), default=-1)
        if not recorder.armed:  # landed while nobody followed: how far did its mission get?
            until = min(self.deadline, time.monotonic() + HEARTBEAT_WAIT_S)
            while (msg := self.session.recv(until)) is not None:
                self.session.take(msg)
                if msg.get_type() == "MISSION_CURRENT":
                    recorder.mission_current(msg)
                    break
        recorder.start()
        self.watch = LinkWatch(self.fleet.silence, time.monotonic())
        rec.last_heard = time.time()
        rec.add_event(time.time(), f"re-attached by fly --resume ({'armed' if state.armed else 'disarmed'}, "
                                   f"{state.mode_name()})")
        self.fleet.say(f"uav{self.sysid}: re-attached, {'armed' if state.armed else 'disarmed'} in {state.mode_name()}")
        if self.bar is not None:
            self.bar.reset(total=max(len(rec.wire) - 1, 1))
        return True

    # ------------------------------------------------------------------ following
    def _follow_to_the_end(self) -> None:
        assert self.session is not None and self.recorder is not None
        self._follow()
        rec = self.record
        if self.stop.is_set() and not (rec.finished or rec.ended_early):
            return  # Ctrl-C: the vehicle flies on; nothing is asked of it
        if self.recorder.disarmed_on_ground():
            recover_photos(self.session, rec, self.fleet, self.deadline, self.gaps, self.recorder.rel_alt,
                           self.plan_path.parent / "logs" / f"uav{self.sysid}", self.url, self.publish)
        if rec.finished:
            check_still_held(self.session, rec)

    def _follow(self) -> None:
        assert self.session is not None and self.recorder is not None and self.watch is not None
        rec, session, watch = self.record, self.session, self.watch
        last_seq = len(rec.wire) - 1
        reboots = session.reboots()  # the link notices reboots (boot heartbeat, clock restart)
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= self.deadline:
                self.publish(TimedOut(self.sysid, time.time(), rec.current, last_seq))
                return
            for step in watch.look(now):
                self._silence(step, last_seq)
            if watch.lost_since is not None and now > self._give_up_at():
                self.publish(GaveUpWaiting(self.sysid, time.time(), now - watch.lost_since, rec.current, last_seq))
                return
            msg = session.recv(min(self.deadline, now + 0.5))
            self._read_mail()
            if msg is None or msg.get_srcSystem() != self.sysid:
                continue
            self._heard(last_seq)
            if session.reboots() > reboots:
                self.publish(Rebooted(self.sysid, time.time(), rec.current, last_seq))
                return
            session.take(msg)  # readiness state and STATUSTEXT, then the recorder records it
            if self.recorder.disarmed_on_ground():
                self._end(last_seq)
                return
            if not self.requests.empty():
                self._run_requests()
                last_seq = len(rec.wire) - 1

    def _silence(self, step: SilenceStep, last_seq: int) -> None:
        """A silence that has just come to matter, or to count as the link lost: published."""
        assert self.watch is not None
        rec = self.record
        if step is SilenceStep.MATTERS:
            self.publish(LinkQuiet(self.sysid, time.time(), self.watch.heard_at))
        else:
            where = None
            if rec.last_position is not None:
                lat, lon, up, _ = rec.last_position
                where = (lat, lon, up)
            self.publish(LinkLost(self.sysid, time.time(), self.watch.heard_at, rec.current, last_seq, where))

    def _heard(self, last_seq: int) -> None:
        """The vehicle was heard: a silence that mattered is over (published); after a lost link, a gap in
        the record, and a drone whose share was given away meanwhile goes home."""
        assert self.watch is not None
        over = self.watch.heard(time.monotonic())
        if over is None:
            return
        rec = self.record
        self.publish(LinkBack(self.sysid, time.time(), over.silent_s, over.was_lost, rec.current, last_seq))
        if over.was_lost:
            self.gaps += 1
            self.back_at = time.monotonic()
            if self.given_away and self.armed:
                self._send_home()

    def _read_mail(self) -> None:
        """What the other threads told this one: lines for its record, written here; the re-tasker's order
        (its share was given away)."""
        for order in self.mail.take():
            if isinstance(order, ShareGivenAway):
                self.given_away = True

    # ------------------------------------------------------------------ fly --replan
    def tell(self, message: Message) -> None:
        """From another thread: taken by this one before it next acts on what it hears (follower_mail)."""
        self.mail.post(message)

    def ask(self, action: Callable[[], Any]) -> Future[Any]:
        """Have this drone's thread run `action` between two of its vehicle's messages; its outcome."""
        done: Future[Any] = Future()
        self.requests.put((action, done))
        return done

    def _run_requests(self) -> None:
        while not self.requests.empty():
            action, done = self.requests.get_nowait()
            try:
                done.set_result(action())
            except Exception as err:  # noqa: BLE001 - said to the asker; the vehicle is still followed
                done.set_exception(err)
            self._heard(len(self.record.wire) - 1)  # heard meanwhile (the action's reads go to the session)

    def _send_home(self) -> None:
        """A drone whose share fly --replan gave to others is heard again: it would fly their streets, so
        it returns to launch (what --replan asks for), once."""
        assert self.session is not None
        self.given_away = False
        result = self.session.action.return_to_launch(min(self.deadline, time.monotonic() + 5.0))
        self.publish(SentHome(self.sysid, time.time(), result == mavlink.MAV_RESULT_ACCEPTED, result))

    def _end(self, last_seq: int) -> None:
        """The vehicle is on the ground and disarmed: finished, or ended early and why."""
        assert self.session is not None and self.recorder is not None and self.watch is not None
        rec, recorder = self.record, self.recorder
        complete = recorder.mission_complete(last_seq)
        if not complete and self.gaps and recorder.mission_heard_at <= self.back_at:
            # Found landed after a silence (it may have finished its mission meanwhile): what we know of its
            # mission is from before the silence. Judge it from its own word after it, bounded.
            until = min(self.deadline, time.monotonic() + MISSION_STATE_WAIT_S)
            while recorder.mission_heard_at <= self.back_at and (msg := self.session.recv(until)) is not None:
                if msg.get_srcSystem() == self.sysid:
                    self.session.take(msg)
            complete = recorder.mission_complete(last_seq)
        if complete:
            self.publish(Finished(self.sysid, rec.last_heard))
            if self.bar is not None:
                self.bar.n = self.bar.total
                self.bar.refresh()
            return
        why = "; ".join(recorder.warnings[-2:]) or (f"switched to {recorder.left_mission}, not by fly"
                                                     if recorder.left_mission else "landed and disarmed")
        self.publish(EndedEarly(self.sysid, rec.last_heard, f"{why} (at item {rec.current} of {last_seq})",
                                self.watch.heard_at))

    def _give_up_at(self) -> float:
        """Our monotonic time after which a silent vehicle's mission is surely over (link_silence.give_up_at),
        at its clock's rate: the simulator's time scale when known, else measured from its samples."""
        rec = self.record
        rate = self.fleet.time_scale
        if rate is None and len(rec.samples) >= 10:
            rate = vehicle_rate(np.array(rec.samples))
        started_ago = time.time() - (rec.t_start if rec.t_start is not None else time.time())
        return give_up_at(self.fleet.planned_s.get(self.sysid, 0.0), rate or 1.0, started_ago, time.monotonic(),
                          self.deadline)
