"""One drone of a fleet flight, in its own thread: from finding the vehicle to its landing.

A fresh flight (`fly DIR`):
1. find the vehicle on its link and hear its HEARTBEAT. A vehicle that is ARMED was not started by
   this run of fly: nothing is sent to it (no upload, mode or arming), it vetoes the fleet's arming, and
   fly says so (`fly --resume DIR` follows a flight this folder started);
2. ask for every stream fly reads (missionplan.bridge.link.readiness: ArduPilot sends nothing until asked) and wait,
   bounded by --ready-timeout, until it has a GPS fix, an EKF solution, a home position and passing
   pre-arm checks, saying what it waits for and what the vehicle says (STATUSTEXT);
3. site check: its home within --max-launch-offset (plus its GPS error) of the plan's launch point,
   else nothing is uploaded to it and no drone arms at all (the arm gate's veto);
4. upload uavK.plan (or let MAVSDK's QGroundControl importer upload it) and prove it by read-back;
5. the arm gate (nobody arms until every drone got this far), GUIDED (ArduPilot), arm (retried while
   the vehicle says it is not ready), the start gate, MAV_CMD_MISSION_START: all start together;
6. follow it (below) until it has landed and disarmed.
A resumed flight (`fly --resume DIR`) skips 1-5: the vehicle must hold the mission this flight uploaded
(downloaded and compared, not assumed); an armed one is followed again, one that landed meanwhile is
closed, one never started is left alone. Nothing is commanded in either case.

Following: every GLOBAL_POSITION_INT, MISSION_CURRENT, MISSION_ITEM_REACHED, photo report (ArduPilot's
CAMERA_FEEDBACK, PX4's CAMERA_IMAGE_CAPTURED), mode / arming / landed change and STATUSTEXT goes into the
drone's record, and through it into the flight journal, as it comes. Said at once, as alerts (the
terminal and the journal): the link lost and back, a mode changed by someone else (RC, another ground
station, a failsafe), a failsafe or fence the vehicle reports, a reboot. The drone's flight ends when
the vehicle is on the ground and disarmed: finished when its mission was complete, else ended early,
with the reason (the failsafe it reported, the mode it was switched to, or the item it stopped at). A
silent vehicle is "link lost", not gone, until its mission would be long over (LINK_WAIT_FACTOR times
its planned time plus LINK_MARGIN_S, on its clock) or the time-out; heard again, it is followed again.
After landing: the photos whose reports never arrived are read from the vehicle's log where the
autopilot keeps one (missionplan.bridge.transfer.onboard_log), and the mission is read back once more (still the one
uploaded).
"""

from __future__ import annotations

import math
import queue
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from missionplan.bridge.flight_models.copter_model import PARAMETERS as COPTER_PARAMETERS
from missionplan.bridge.errors import BridgeError
from missionplan.bridge.link.connection import COMMAND_TRIES, COMMAND_WAIT_S, mavlink
from missionplan.bridge.formats.mission_items import Flavour, to_wire
from missionplan.bridge.formats.missionfile import check_firmware, read_mission_file
from missionplan.bridge.transfer.onboard_log import euler_degrees, recover_photos
from missionplan.bridge.link.params import ParamClient, read_params
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.flight_models.px4_model import FLOAT_PARAMETERS as PX4_PARAMETERS
from missionplan.bridge.transfer.retask import replace_mission_in_flight
from missionplan.bridge.link.readiness import (ARDUPILOT_GUIDED, DEFAULT_LAUNCH_OFFSET_M, PX4_AUTO_MAIN, PX4_LOITER_SUB,
                                               Vehicle, mission_mode_params, mode_params, request_streams, site_problem,
                                               stream_rates)
from missionplan.bridge.link.shared_link import LinkPool
from missionplan.bridge.link.signing import SigningKey
from missionplan.bridge.transfer.uploader import (MissionBackend, open_backend, read_back_differences, set_plan_params,
                                                  upload_plan)

from .flight_report import vehicle_rate
from .record import DroneRecord

CAPTURE_OK = 1  # CAMERA_IMAGE_CAPTURED capture_result (a flag, not an enum): 1 success
LANDED_STATE_NAMES = {mavlink.MAV_LANDED_STATE_ON_GROUND: "on ground", mavlink.MAV_LANDED_STATE_IN_AIR: "in air",
                      mavlink.MAV_LANDED_STATE_TAKEOFF: "taking off", mavlink.MAV_LANDED_STATE_LANDING: "landing"}
PX4_START_RETRY_S = 5.0   # MISSION_START retried this long while PX4 checks a new mission (see _mission_start)
START_RETRY_WAIT_S = 0.5
# A lost MISSION_START is sent again after a few of the vehicle's acknowledgement round trips (the
# slowest seen on its link), within these bounds, not after the usual half second: the plan's
# separation assumes the missions start together, and half a second lost in a sped-up simulator, or
# on a radio, shifts one drone's whole track against the others'.
START_ACK_RTTS, START_WAIT_MIN_S = 4.0, 0.1
ON_GROUND_M = 0.3      # relative altitude under which a disarmed vehicle counts as landed
DEFAULT_READY_S = 120.0  # a real vehicle's GPS and EKF may take a minute or two after power-on
LINK_LOST_S = 5.0      # a vehicle silent this long has lost its link (said at once; followed on)
LINK_WAIT_FACTOR, LINK_MARGIN_S = 1.5, 60.0  # a silent vehicle is waited for until its mission would be long over
LOG_READ_S = 120.0  # at most this long to read a vehicle's log after landing
RETASK_UPLOAD_S = 30.0  # at most this long to put a re-task's mission on a flying vehicle
HOLD_S, HOLD_SPEED = 10.0, 0.5  # a vehicle held for a re-task stops (m/s) within this long (wall s)
HEARTBEAT_WAIT_S = 3.0  # for the first HEARTBEAT that says whether a vehicle is armed (sent at 1 Hz)
# Modes a mission flies in (ArduPilot AUTO; PX4 AUTO.MISSION, and AUTO.TAKEOFF), and the modes of its
# final return (PX4 switches to AUTO.RTL / AUTO.LAND for a mission's final RTL / LAND item; ArduPilot
# flies it in AUTO).
MISSION_MODES = {Flavour.ARDUPILOT: {"AUTO"}, Flavour.PX4: {"MISSION", "TAKEOFF"}}
RETURN_MODES = {"RTL", "LAND", "SMART_RTL"}
# Words of a STATUSTEXT that a crew must hear at once (a failsafe, a fence, the EKF, a crash).
ALERT_WORDS = ("failsafe", "fence", "ekf", "crash", "battery", "low bat", "critical", "emergency", "lost")
# ...said with a severity of WARNING or worse (MAV_SEVERITY 0-4): ArduCopter says "EKF3 IMU0 MAG0 in-flight
# yaw alignment complete" at INFO on every take-off, which is no alert and no reason a flight ended.
ALERT_SEVERITY = mavlink.MAV_SEVERITY_WARNING
MISSION_STATE_WAIT_S = 3.0  # after a link gap, how long a landed vehicle's fresh MISSION_CURRENT is waited for
USER_MODES = {"GUIDED"}  # what fly itself commands before the start


def refused(what: str, result: int | None) -> str:
    return f"{what} {'not acknowledged' if result is None else f'refused (MAV_RESULT {result})'}"


def unanswered(text: str, link: Any, sysid: int) -> str:
    """text, with MAVLink 2 signing named when it is the likely reason the vehicle did not answer
    (missionplan.bridge.link.connection.Link.signing_hint decides)."""
    hint = link.signing_hint(sysid)
    return f"{text}: {hint}" if hint else text


class FleetGate:
    """Where the drones' threads meet: nobody goes on before every drone has checked in once (or the wait ran
    out). fly has two: nobody arms before every drone is ready, uploaded and site-checked (arm_gate), and the
    armed drones start their missions together (start_gate). A drone that failed checks in without waiting,
    so the rest are not held up by it. A drone may check in with a veto (its site check failed, it was found
    armed): a wrong site, swapped system ids or a vehicle already flying is a fleet problem, and every drone
    hears the vetoes, so the fleet starts together or not at all."""

    def __init__(self, parties: int) -> None:
        self._waiting_for = parties
        self.vetoes: list[str] = []
        self._all_in = threading.Condition()

    def check_in(self, wait_s: float, veto: str = "") -> list[str]:
        """Check in (waiting up to wait_s for the others); the vetoes heard, [] when the fleet may go on."""
        with self._all_in:
            self._waiting_for -= 1
            if veto:
                self.vetoes.append(veto)
            if self._waiting_for <= 0:
                self._all_in.notify_all()
            elif wait_s > 0:
                self._all_in.wait_for(lambda: self._waiting_for <= 0, timeout=wait_s)
            return list(self.vetoes)


@dataclass
class RetaskRequest:
    """fly --replan's new mission for one vehicle in flight (missionplan.planning.retask.RetaskPlan's share)."""

    mission: Any  # missionplan.bridge.formats.mission_items.Mission
    fence: Any  # missionplan.bridge.formats.mission_items.Mission (inclusion fence) or None
    resume_index: int  # index in mission.items to continue at
    photos: int  # photos the new mission plans


@dataclass
class FleetStart:
    """What the drones' threads share: the links, both gates, the stop flag, how to say things."""

    pool: LinkPool
    arm_gate: FleetGate  # nobody arms before all are ready (or vetoed)
    start_gate: FleetGate  # the armed drones start together
    stop: threading.Event  # set on Ctrl-C: stop following, command nothing
    key: SigningKey | None = None  # for the links fly opens beside the pool (MAVSDK's upload)
    ready_s: float = DEFAULT_READY_S
    max_offset_m: float = DEFAULT_LAUNCH_OFFSET_M
    say: Callable[[str], None] = lambda text: None      # progress lines
    alert: Callable[[str], None] = lambda text: None    # what a crew must hear at once
    resume: bool = False
    time_scale: float | None = None  # vehicle seconds per second of ours, when known (a sped-up simulator)
    planned_s: dict[int, float] = field(default_factory=dict)  # each drone's planned flight, vehicle seconds
    # Until everything the records handed to the journal is committed; whether it is (fly: Journal.flush).
    # Asked before each arm command: a vehicle whose start cannot be recorded is not armed.
    commit: Callable[[], bool] = lambda: True
    # One log read at a time per link: three vehicles' LOG_DATA bursts into one ground-station socket at
    # once overflowed it, and ArduCopter SITL's downloads stalled half-way ("log incomplete").
    log_locks: dict[str, threading.Lock] = field(default_factory=dict)

    def log_lock(self, url: str) -> threading.Lock:
        return self.log_locks.setdefault(url, threading.Lock())  # atomic: one lock per url, whoever asks first


class DroneFlight:
    """One drone's thread: what it learns goes into `record` (and the journal behind it)."""

    def __init__(self, fleet: FleetStart, record: DroneRecord, plan_path: Path, deadline: float,
                 telemetry_hz: float, bar: Any, upload_with: str = "missionplan") -> None:
        self.fleet, self.record, self.plan_path, self.deadline = fleet, record, plan_path, deadline
        self.upload_with = upload_with
        self.telemetry_hz, self.stop, self.bar = telemetry_hz, fleet.stop, bar
        self.backend: MissionBackend | None = None
        self.vehicle: Vehicle | None = None
        self.url = ""
        self.armed, self.rel_alt, self.last_reached = True, 0.0, -1  # as last reported
        self.checked_in = self.arm_checked_in = False  # at the start gate, at the arm gate
        self.recording = False  # from the mission start on: what came before is not this flight
        self.camera_component: int | None = None  # who sends this vehicle's CAMERA_IMAGE_CAPTURED: the first heard
        self.said = (None, None, None, 0)  # mode, armed, landed state, STATUSTEXT count already in record.events
        self.heard_at = 0.0  # our monotonic clock: the vehicle's last message
        self.commanded: set[str] = set(USER_MODES)  # modes fly itself asked for
        self.left_mission: str = ""  # the mode someone else switched it to mid-mission
        self.warnings: list[str] = []  # what the vehicle said that a crew must hear (failsafes...)
        self.found_armed = False  # armed when found: someone else's flight, never to be touched
        self.severity: dict[str, int] = {}  # STATUSTEXT text -> its MAV_SEVERITY, as last heard
        # Silences in flight: the link lost, or the time no run of fly listened (a resumed flight). What
        # happened in one is not in the record: the photos then are read from the log in full, and a
        # vehicle found landed after one is judged from a MISSION_CURRENT heard after it.
        self.gaps = 0
        self.mission_heard_at = 0.0  # our monotonic clock: the latest MISSION_CURRENT
        self.back_at = 0.0  # our monotonic clock: the end of the latest silence
        # fly --replan: what the main thread asks this one to do with the vehicle (hold, re-task, release),
        # run here because this thread owns the link's receive loop; each answers through its Future.
        self.requests: queue.SimpleQueue[tuple[Callable[[], Any], Future[Any]]] = queue.SimpleQueue()
        self.given_away = False  # fly --replan gave this drone's share to others: heard again, it goes home

    @property
    def sysid(self) -> int:
        return self.record.id

    def problem(self, text: str) -> None:
        self.record.add_problem(f"uav{self.sysid}: {text}")

    def alert(self, text: str) -> None:
        """One line now, on the terminal and in the journal."""
        self.record.add_event(time.time(), f"alert: {text}")
        self.fleet.alert(f"uav{self.sysid}: {text}")

    def run(self) -> None:
        try:
            if self.fleet.resume:
                if self._connect() and self._attach():
                    self._follow_to_the_end()
            elif (self._connect() and self._not_airborne() and self._streams() and self._ready() and self._site()
                  and self._upload() and self._arm() and self._start()):
                self._follow_to_the_end()
        except Exception as err:  # noqa: BLE001 - one drone's failure must not hide the others'
            self.problem(f"{type(err).__name__}: {err}")
        finally:
            if not self.fleet.resume:
                if not self.arm_checked_in:  # failed before the arm gate: the others need not wait for us
                    self.fleet.arm_gate.check_in(0.0)
                if not self.checked_in:  # failed before the start: let the others go without us
                    self.fleet.start_gate.check_in(0.0)
                if not self.record.started and self.vehicle is not None and not self.found_armed:
                    self._leave_safe()  # a vehicle this run got ready (or armed) but will not fly
            if self.backend is not None:
                self.backend.close()

    # ------------------------------------------------------------------ finding the vehicle
    def _connect(self) -> bool:
        """Find the vehicle on its link, learn its flavour, hear whether it is armed."""
        rec = self.record
        try:
            # Started right after power-on, a vehicle may take a while to send its first heartbeat.
            wait_s = max(1.0, min(self.fleet.ready_s, self.deadline - time.monotonic()))
            view = self.fleet.pool.vehicle(rec.id, wait_s)
            self.url = view.url
            self.backend = open_backend("pymavlink", self.url, rec.id, timeouts=Timeouts(item_timeout=0.5, retries=10),
                                        connect_timeout=wait_s, link=view)
        except BridgeError as err:
            self.problem(f"not found: {err}")
            return False
        self.vehicle = Vehicle(view, self.backend.vehicle, self.fleet.say, also=self._take_if_started)
        until = min(self.deadline, time.monotonic() + HEARTBEAT_WAIT_S)
        while self.vehicle.state.armed is None and (msg := view.recv(until)) is not None:
            self.vehicle.take(msg)
        self.heard_at = time.monotonic()
        return True

    def _not_airborne(self) -> bool:
        """A vehicle already armed was started by someone else (or by a run of fly that is gone): touch
        nothing on it, and no drone arms."""
        assert self.vehicle is not None
        state = self.vehicle.state
        if state.armed is not True:
            return True
        self.found_armed = True
        self.problem(f"is ARMED ({state.mode_name()}): this run of fly did not start it, so nothing was sent to it "
                     f"(no upload, mode or arming) and no drone arms; to follow a flight this folder started, "
                     f"`missionplan fly --resume {self.plan_path.parent}`")
        self.arm_checked_in = True
        self.fleet.arm_gate.check_in(0.0, veto=f"uav{self.sysid} is already armed")
        return False

    def _streams(self) -> bool:
        """Ask for every stream fly reads (telemetry only: nothing that moves the vehicle)."""
        assert self.vehicle is not None and self.backend is not None
        view = self.vehicle.link
        refused_streams = request_streams(view, self.sysid, stream_rates(self.telemetry_hz, self.backend.vehicle.flavour),
                                          self.deadline, other=self.vehicle.take)
        if refused_streams:
            self.record.add_note(unanswered(f"streams not accepted (SET_MESSAGE_INTERVAL): "
                                            f"{', '.join(refused_streams)}; the vehicle's own rates", view, self.sysid))
        return True

    def _ready(self) -> bool:
        """Bounded wait for GPS, EKF, home and pre-arm checks (missionplan.bridge.link.readiness)."""
        assert self.vehicle is not None
        missing = self.vehicle.wait_ready(min(self.deadline, time.monotonic() + self.fleet.ready_s))
        if missing:
            reasons = self.vehicle.state.reasons()
            # A vehicle that ignores us (signing) never sends what it sends only when asked (its home).
            self.problem(unanswered(f"not ready to fly within {self.fleet.ready_s:g} s: still waiting for "
                                    f"{', '.join(missing)}" + (f"; the vehicle said: {reasons}" if reasons else ""),
                                    self.vehicle.link, self.sysid))
            return False
        return True

    def _leave_safe(self) -> None:
        """A vehicle this run will not fly (and did not find armed): disarmed and out of AUTO, said how."""
        assert self.vehicle is not None
        try:
            how = self.vehicle.make_safe(time.monotonic() + 5.0)
        except BridgeError as err:
            how = f"could not be made safe: {err}"
        self.record.add_note(how)
        self.fleet.say(f"uav{self.sysid}: {how}")

    # ------------------------------------------------------------------ a fresh start
    def _upload(self) -> bool:
        rec = self.record
        try:
            plan = read_mission_file(self.plan_path)
            check_firmware(plan, self.plan_path, self.backend.vehicle.flavour if self.backend else None, rec.id)
            if self.upload_with == "mavsdk":
                self._upload_by_mavsdk()
            assert self.backend is not None
            wire = to_wire(plan.mission, self.backend.vehicle.flavour)
            rec.set(wire=wire)
            if self.upload_with == "mavsdk":
                # What MAVSDK made of the file must be exactly what our reader makes of it.
                differences = read_back_differences(self.backend, 0, wire)
                if differences:
                    raise BridgeError("the mission MAVSDK read from the .plan and uploaded differs from ours: "
                                      + "; ".join(differences))
                set_plan_params(self.backend, plan.mission)  # WPNAV_RADIUS: MAVSDK sets no parameters
            else:
                upload_plan(self.backend, plan.parts(), verify=True)
            rec.set(uploaded=True, flavour=self.backend.vehicle.flavour.value)
            names = {Flavour.ARDUPILOT: list(COPTER_PARAMETERS), Flavour.PX4: PX4_PARAMETERS}
            if self.backend.vehicle.flavour in names:  # what it will fly with: re-times the plan (its autopilot's model)
                rec.set(params=read_params(ParamClient(self.backend.link, self.backend.vehicle),
                                           names[self.backend.vehicle.flavour]))
            return True
        except (BridgeError, OSError) as err:
            self.problem(f"upload failed: {err}")
            return False

    def _upload_by_mavsdk(self) -> None:
        """MAVSDK's own QGroundControl importer opens the .plan and MAVSDK uploads what it read."""
        connect_s = max(1.0, min(10.0, self.deadline - time.monotonic()))
        mavsdk = open_backend("mavsdk", self.url, self.sysid, key=self.fleet.key,
                              timeouts=Timeouts(item_timeout=0.5, retries=10), connect_timeout=connect_s)
        try:
            mavsdk.upload_qgc_plan(str(self.plan_path))  # type: ignore[attr-defined]
        finally:
            mavsdk.close()

    def _site(self) -> bool:
        """The site check, before anything is uploaded: the vehicle's home against its plan's launch
        point. A vehicle at the wrong site vetoes arming for the whole fleet at the arm gate at once
        (nothing is uploaded to it: PX4 would refuse a mission that starts that far away anyway)."""
        assert self.vehicle is not None
        try:
            home = read_mission_file(self.plan_path).mission.home
        except (BridgeError, OSError) as err:
            self.problem(f"upload failed: {err}")
            return False
        wrong_site = site_problem(self.vehicle.state, (home[0], home[1]) if home is not None else None,
                                  self.fleet.max_offset_m)
        if not wrong_site:
            return True
        self.problem(f"site check failed: {wrong_site}")
        self.arm_checked_in = True
        self.fleet.arm_gate.check_in(0.0, veto=f"uav{self.sysid} failed the site check")
        return False

    def _arm(self) -> bool:
        """The arm gate (nobody arms while a drone is still getting ready, none if any was vetoed),
        then GUIDED (ArduPilot) and arming, retried while not ready."""
        assert self.vehicle is not None and self.backend is not None
        self.arm_checked_in = True
        vetoes = self.fleet.arm_gate.check_in(self.deadline - time.monotonic())
        if vetoes:
            self.problem(f"not armed: {'; '.join(vetoes)} (no drone arms when one is at the wrong site or "
                         "already armed)")
            return False
        if self.stop.is_set():
            return False
        # In the journal before the arm command, so that `fly --resume` finds this vehicle whatever follows.
        self.record.set(arming=time.time())
        if not self.fleet.commit():
            self.problem("not armed: its start could not be written to the flight journal (a flight that cannot be "
                         "recorded is not started)")
            return False
        link = self.backend.link
        if self.backend.vehicle.flavour is Flavour.ARDUPILOT:  # arms in GUIDED, starts AUTO by MISSION_START
            link.command_long(self.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), self.deadline,
                              other=self.vehicle.take)
        armed, why = self.vehicle.arm(min(self.deadline, time.monotonic() + self.fleet.ready_s))
        if not armed:
            self.problem(unanswered(why, link, self.sysid) if "not acknowledged" in why else why)
            return False
        return True

    def _start(self) -> bool:
        rec, link = self.record, self.backend.link
        self.checked_in = True
        self.fleet.start_gate.check_in(self.deadline - time.monotonic())
        # The first positions may come before the acknowledgement: keep them (and what the vehicle says
        # from now on, not before).
        self.said = (None, None, None, self.vehicle.state.texts_total)
        self.recording = True
        result = self._mission_start()
        if result != mavlink.MAV_RESULT_ACCEPTED and self.backend.vehicle.flavour is Flavour.PX4:
            # PX4 also starts a mission in its AUTO.MISSION mode (from the current item, 0 after an upload).
            mode = link.command_long(self.sysid, mavlink.MAV_CMD_DO_SET_MODE, mission_mode_params(Flavour.PX4),
                                     self.deadline,
                                     other=self.vehicle.take)
            if mode == mavlink.MAV_RESULT_ACCEPTED:
                rec.add_note(f"{refused('MISSION_START', result)}; started in AUTO.MISSION mode")
                result = mavlink.MAV_RESULT_ACCEPTED
        if result != mavlink.MAV_RESULT_ACCEPTED:
            what = refused("mission start", result)
            self.problem(unanswered(what, link, self.sysid) if result is None else what)
            return False
        now = time.time()
        rec.set(started=True, t_start=now)
        rec.last_heard = now
        self.heard_at = time.monotonic()
        if self.bar is not None:
            self.bar.reset(total=max(len(rec.wire) - 1, 1))
        return True

    def _mission_start(self) -> int | None:
        """MAV_CMD_MISSION_START; its MAV_RESULT. PX4 takes a new mission only after its own checks (its
        navigator's, then commander's), so a start right after the upload may be DENIED ("Mission start
        denied! No valid mission") for a moment: retried for PX4_START_RETRY_S, within which PX4 does not
        yet disarm an armed vehicle that has not taken off (COM_DISARM_PRFLT, 10 s)."""
        assert self.vehicle is not None and self.backend is not None
        rec, link = self.record, self.backend.link
        px4 = self.backend.vehicle.flavour is Flavour.PX4
        until = min(self.deadline, time.monotonic() + (PX4_START_RETRY_S if px4 else 0.0))
        wait_s = self._start_wait_s()
        sends = math.ceil(COMMAND_TRIES * COMMAND_WAIT_S / wait_s)  # as long in all as any other command
        tries = 0
        while True:
            tries += 1
            result = link.command_long(self.sysid, mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], self.deadline,
                                       other=self.vehicle.take,
                                       done=lambda: rec.mission_state == mavlink.MISSION_STATE_ACTIVE,
                                       tries=sends, wait_s=wait_s)
            if result not in (mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED) or \
                    time.monotonic() + START_RETRY_WAIT_S >= until:
                break
            self.vehicle.listen(time.monotonic() + START_RETRY_WAIT_S)
        if tries > 1 and result == mavlink.MAV_RESULT_ACCEPTED:
            rec.add_note(f"MISSION_START accepted after {tries} tries (the vehicle had not yet taken the "
                         f"new mission: {self.vehicle.state.reasons(1)})")
        return result

    def _start_wait_s(self) -> float:
        """How long a MISSION_START waits for its acknowledgement before it is sent again: START_ACK_RTTS of
        the slowest round trip this vehicle's link has shown (its mode and arming commands were acknowledged
        just before), never under START_WAIT_MIN_S nor over the usual COMMAND_WAIT_S."""
        rtt = self.backend.link.ack_rtt_s.get(self.sysid)
        if rtt is None:
            return COMMAND_WAIT_S
        return min(COMMAND_WAIT_S, max(START_WAIT_MIN_S, START_ACK_RTTS * rtt))

    # ------------------------------------------------------------------ a resumed flight
    def _attach(self) -> bool:
        """Take up this flight's vehicle again (fly --resume): only if it holds the mission this flight
        uploaded; commands nothing. Whether there is anything to follow."""
        assert self.vehicle is not None and self.backend is not None
        rec = self.record
        if rec.finished or rec.ended_early:
            self.fleet.say(f"uav{self.sysid}: its flight had already ended; nothing to follow")
            return False
        if not (rec.started or rec.arming) or not rec.wire:
            rec.add_note("not started by the run that was stopped; left alone (`missionplan fly` starts it)")
            self.fleet.say(f"uav{self.sysid}: was not started by the stopped run; left alone")
            return False
        try:
            differences = read_back_differences(self.backend, 0, rec.wire)
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
        state = self.vehicle.state
        self.armed = bool(state.armed)
        self.last_reached = max((seq for _, seq in rec.reached), default=-1)
        if not self.armed:  # landed while nobody followed: how far did its mission get?
            until = min(self.deadline, time.monotonic() + HEARTBEAT_WAIT_S)
            while (msg := self.vehicle.link.recv(until)) is not None:
                self.vehicle.take(msg)
                if msg.get_type() == "MISSION_CURRENT":
                    self.mission_heard_at = time.monotonic()
                    rec.set(current=int(msg.seq), mission_state=int(getattr(msg, "mission_state", 0) or 0))
                    break
        self.said = (None, None, None, self.vehicle.state.texts_total)
        self.recording = True
        self.heard_at = time.monotonic()
        rec.last_heard = time.time()
        rec.add_event(time.time(), f"re-attached by fly --resume ({'armed' if state.armed else 'disarmed'}, "
                                   f"{state.mode_name()})")
        self.fleet.say(f"uav{self.sysid}: re-attached, {'armed' if state.armed else 'disarmed'} in {state.mode_name()}")
        if self.bar is not None:
            self.bar.reset(total=max(len(rec.wire) - 1, 1))
        return True

    # ------------------------------------------------------------------ following
    def _follow_to_the_end(self) -> None:
        self._follow()
        rec = self.record
        if self.stop.is_set() and not (rec.finished or rec.ended_early):
            return  # Ctrl-C: the vehicle flies on; nothing is asked of it
        if self._disarmed_on_ground():
            self._recover_photos()
        if rec.finished:
            self._check_still_held()

    def _follow(self) -> None:
        rec, link = self.record, self.backend.link
        last_seq = len(rec.wire) - 1
        reboots = link.reboots.get(self.sysid, 0)  # the link notices reboots (boot heartbeat, clock restart)
        lost_since: float | None = None  # our monotonic clock
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= self.deadline:
                self.problem(f"mission not finished within the time-out (item {rec.current} of {last_seq})")
                return
            if lost_since is None and now - self.heard_at > LINK_LOST_S:
                lost_since = self.heard_at
                self._link_lost(last_seq)
            if lost_since is not None and now > self._give_up_at():
                self.problem(f"link lost for {now - lost_since:.0f} s since item {rec.current} of {last_seq}; its "
                             "mission should have ended by now: last known position in flight.json")
                return
            msg = link.recv(min(self.deadline, now + 0.5))
            if msg is None or msg.get_srcSystem() != self.sysid:
                continue
            if lost_since is not None:
                self.alert(f"link back after {time.monotonic() - lost_since:.1f} s, at item {rec.current} of "
                           f"{last_seq}")
                lost_since = None
                self.gaps += 1
                self.back_at = time.monotonic()
                if self.given_away and self.armed:
                    self._send_home()
            self.heard_at = time.monotonic()
            if link.reboots.get(self.sysid, 0) > reboots:
                self.problem(f"rebooted in flight at item {rec.current} of {last_seq} (mission lost)")
                self.alert(f"rebooted in flight at item {rec.current} of {last_seq}")
                return
            self.vehicle.take(msg)  # readiness state and STATUSTEXT, then _take records it
            if self._disarmed_on_ground():
                self._end(last_seq)
                return
            if not self.requests.empty():
                self._run_requests()
                last_seq = len(rec.wire) - 1

    # ------------------------------------------------------------------ fly --replan
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
            self.heard_at = time.monotonic()  # heard meanwhile (the action's reads go to vehicle.take)

    def hold(self) -> tuple[float, float, float]:
        """Stop where it is (ArduPilot GUIDED, PX4 AUTO.LOITER: the autopilot brakes and hovers) until a
        re-task or a release; returns where it hovers (lat, lon, m up) once its speed is under HOLD_SPEED.
        Raises BridgeError when the vehicle refuses or does not stop in time."""
        assert self.backend is not None and self.vehicle is not None
        flavour = self.backend.vehicle.flavour
        mode, params = (("GUIDED", mode_params(ARDUPILOT_GUIDED)) if flavour is Flavour.ARDUPILOT else
                        ("HOLD", mode_params(PX4_AUTO_MAIN, PX4_LOITER_SUB)))
        self.commanded.add(mode)
        deadline = min(self.deadline, time.monotonic() + HOLD_S)
        result = self.backend.link.command_long(self.sysid, mavlink.MAV_CMD_DO_SET_MODE, params, deadline,
                                                other=self.vehicle.take)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise BridgeError(refused(f"{mode} (to hold it for the re-task)", result))
        rec = self.record
        while time.monotonic() < deadline:
            if rec.samples and rec.samples[-1][4] < HOLD_SPEED and self.vehicle.state.mode_name() == mode:
                t, lat, lon, up = rec.samples[-1][:4]
                rec.add_event(time.time(), f"held for a re-task ({mode})")
                return float(lat), float(lon), float(up)
            msg = self.backend.link.recv(deadline)
            if msg is not None and msg.get_srcSystem() == self.sysid:
                self.vehicle.take(msg)
        # What it was doing is said, so a vehicle still braking can be told from one in another mode.
        seen = (f"still at {rec.samples[-1][4]:.1f} m/s" if rec.samples else "no position heard") \
            + f", in {self.vehicle.state.mode_name()}"
        raise BridgeError(f"did not stop in {HOLD_S:g} s after {mode} ({seen})")

    def release(self) -> None:
        """Back to its mission mode: its new mission from the item set current (after a re-task), or its
        old one where it was (a re-task refused after the hold)."""
        assert self.backend is not None and self.vehicle is not None
        flavour = self.backend.vehicle.flavour
        result = self.backend.link.command_long(self.sysid, mavlink.MAV_CMD_DO_SET_MODE, mission_mode_params(flavour),
                                                min(self.deadline, time.monotonic() + HOLD_S),
                                                other=self.vehicle.take)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise BridgeError(refused("its mission mode (released after a refused re-task)", result))

    def retask(self, request: RetaskRequest) -> str:
        """Put a re-task's mission and fence on the held vehicle, current at its first item after the
        take-off, and leave it holding (missionplan.bridge.transfer.retask: the way each autopilot takes it, confirmed
        by the vehicle; what it says meanwhile is recorded): release() then starts it, with the others. The record's
        mission becomes the new one, so its end and its photos are judged against it. Returns what to say; raises
        BridgeError when it is not confirmed."""
        assert self.backend is not None and self.vehicle is not None
        rec = self.record
        flavour = self.backend.vehicle.flavour
        wire = to_wire(request.mission, flavour)
        resume = request.resume_index + (len(wire) - len(request.mission.items))  # ArduPilot's home is seq 0
        fence = to_wire(request.fence, flavour) if request.fence is not None and request.fence.items else None
        try:
            report = replace_mission_in_flight(self.backend, self.backend.link, self.sysid, flavour, wire, resume,
                                               min(self.deadline, time.monotonic() + RETASK_UPLOAD_S), fence=fence,
                                               observe=self.vehicle.take, held=True, resume=False)
        except (BridgeError, ValueError) as err:
            self.problem(f"re-task failed: the new mission is not on board ({err})")
            raise BridgeError(f"the new mission is not on board ({err})") from None
        rec.set(wire=wire, planned_photos=request.photos)  # what the vehicle holds now
        self.last_reached = -1
        if not report.confirmed:
            self.problem(f"re-task failed: the new mission is on board but not confirmed: {report.problem}")
            raise BridgeError(f"the new mission is on board but not confirmed: {report.problem}")
        rec.set(current=report.continued_at or resume, mission_state=mavlink.MISSION_STATE_ACTIVE)
        rec.add_note(f"re-tasked in flight: {len(wire)} items, continued at item {report.continued_at} "
                     f"({report.strategy}, upload {report.upload_s:.2f} s)")
        if self.bar is not None:
            self.bar.reset(total=max(len(wire) - 1, 1))
        return (f"re-tasked: new mission of {len(wire)} items on board, continuing at item {report.continued_at} "
                f"(upload {report.upload_s:.2f} s)")

    def _send_home(self) -> None:
        """A drone whose share fly --replan gave to others is heard again: it would fly their streets, so
        it returns to launch (what --replan asks for), once."""
        assert self.backend is not None
        self.given_away = False
        result = self.backend.link.command_long(self.sysid, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, [],
                                                min(self.deadline, time.monotonic() + 5.0), other=self.vehicle.take)
        self.alert("heard again after its share was re-tasked to the others: sent home (RTL)"
                   if result == mavlink.MAV_RESULT_ACCEPTED else
                   f"heard again after its share was re-tasked: {refused('RTL', result)}; bring it home by hand")

    def _disarmed_on_ground(self) -> bool:
        on_ground = self.vehicle.state.on_ground  # PX4's landed state: its altitude drifts on the ground
        return not self.armed and (on_ground if on_ground is not None else self.rel_alt < ON_GROUND_M)

    def _end(self, last_seq: int) -> None:
        """The vehicle is on the ground and disarmed: finished, or ended early and why."""
        rec = self.record
        complete = (rec.mission_state == mavlink.MISSION_STATE_COMPLETE or self.last_reached >= last_seq
                    or self._at_final_return(last_seq))
        if not complete and self.gaps and self.mission_heard_at <= self.back_at:
            # Found landed after a silence (it may have finished its mission meanwhile): what we know of its
            # mission is from before the silence. Judge it from its own word after it, bounded.
            until = min(self.deadline, time.monotonic() + MISSION_STATE_WAIT_S)
            while self.mission_heard_at <= self.back_at and (msg := self.backend.link.recv(until)) is not None:
                if msg.get_srcSystem() == self.sysid:
                    self.vehicle.take(msg)
            complete = (rec.mission_state == mavlink.MISSION_STATE_COMPLETE or self.last_reached >= last_seq
                        or self._at_final_return(last_seq))
        if complete:
            rec.set(finished=True, t_end=rec.last_heard)
            if self.bar is not None:
                self.bar.n = self.bar.total
                self.bar.refresh()
            return
        why = "; ".join(self.warnings[-2:]) or (f"switched to {self.left_mission}, not by fly" if self.left_mission
                                                 else "landed and disarmed")
        reason = f"{why} (at item {rec.current} of {last_seq})"
        rec.set(ended_early=reason, t_end=rec.last_heard)
        self.problem(f"ended its mission early: {reason}")
        self.alert(f"landed and disarmed before the end of its mission: {reason}")

    def _at_final_return(self, last_seq: int) -> bool:
        """At the mission's last item, an RTL or a LAND: PX4 reports no MISSION_ITEM_REACHED for it
        (nor a mission_state), it lands and disarms there."""
        rec = self.record
        if not (0 <= last_seq < len(rec.wire)
                and int(rec.wire[last_seq].command) in (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                        mavlink.MAV_CMD_NAV_LAND)):
            return False
        # At it, or only DO_ items left before it (PX4 may switch to RTL while it still reports the
        # DO_SET_CAM_TRIGG_DIST after the last waypoint as its current item).
        return all(int(item.command) > mavlink.MAV_CMD_NAV_LAST for item in rec.wire[max(rec.current, 0) + 1:last_seq])

    def _give_up_at(self) -> float:
        """Our monotonic time after which a silent vehicle's mission is surely over: its planned time
        (vehicle seconds) LINK_WAIT_FACTOR times over plus LINK_MARGIN_S, at its clock's rate, from its start."""
        rec = self.record
        planned = self.fleet.planned_s.get(self.sysid, 0.0)
        rate = self.fleet.time_scale
        if rate is None and len(rec.samples) >= 10:
            rate = vehicle_rate(np.array(rec.samples))
        rate = rate or 1.0
        started_ago = time.time() - (rec.t_start if rec.t_start is not None else time.time())
        left = (planned * LINK_WAIT_FACTOR + LINK_MARGIN_S) / rate - started_ago
        # Not clamped at 0: once `left` is negative the moment is past (clamped, it was always "now", and
        # `now > _give_up_at()` in _follow never held: a silent vehicle was waited for until --timeout).
        return min(self.deadline, time.monotonic() + left)

    def _link_lost(self, last_seq: int) -> None:
        rec = self.record
        where = ""
        if rec.last_position is not None:
            lat, lon, up, _ = rec.last_position
            where = f", last at {lat:.6f}, {lon:.6f}, {up:.1f} m up"
        self.alert(f"link lost: nothing heard for {LINK_LOST_S:g} s at item {rec.current} of {last_seq}{where}; "
                   "still waiting for it")

    def _take_if_started(self, msg: Any) -> None:
        if self.recording:
            self._take(msg)

    def _take(self, msg: Any) -> None:
        """Record one message of our vehicle."""
        rec = self.record
        t = rec.last_heard = time.time()
        kind = msg.get_type()
        if kind == "STATUSTEXT":  # a chunked text is keyed by its last chunk: close enough for its severity
            self.severity[str(msg.text).strip()] = int(msg.severity)
        if kind in ("HEARTBEAT", "EXTENDED_SYS_STATE", "STATUSTEXT"):
            self._note_changes(t)
        if kind == "GLOBAL_POSITION_INT":
            self.rel_alt = msg.relative_alt / 1000.0
            lat, lon = msg.lat / 1e7, msg.lon / 1e7
            rec.add_sample((t, lat, lon, self.rel_alt, float(np.hypot(msg.vx, msg.vy)) / 100.0,
                            msg.time_boot_ms / 1000.0, -msg.vz / 100.0))
            if not rec.last_position or t - rec.last_position[3] >= 1.0:  # journaled once a second
                rec.set(last_position=[lat, lon, self.rel_alt, t])
        elif kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS:
            self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "MISSION_CURRENT":
            self.mission_heard_at = time.monotonic()
            rec.set(current=int(msg.seq), mission_state=int(getattr(msg, "mission_state", 0) or 0))
            if self.bar is not None:
                self.bar.n = min(max(rec.current, self.bar.n), self.bar.total)
                self.bar.refresh()
        elif kind == "MISSION_ITEM_REACHED":
            rec.add_reached(t, int(msg.seq))
            self.last_reached = max(self.last_reached, int(msg.seq))
        elif kind == "CAMERA_FEEDBACK":
            rec.add_photo(int(msg.img_idx), t, msg.lat / 1e7, msg.lng / 1e7, float(msg.alt_rel),
                          attitude=(float(msg.roll), float(msg.pitch), float(msg.yaw)), amsl=float(msg.alt_msl))
            rec.set(captures=max(rec.captures, int(msg.completed_captures), int(msg.img_idx) + 1))
        elif kind == "CAMERA_IMAGE_CAPTURED":
            # PX4's photo report (its camera_feedback module, one per trigger, image_index from 0 after
            # boot), or a MAVLink camera's: from one component only, their indices are separate counts.
            if self.camera_component is None:
                self.camera_component = msg.get_srcComponent()
            index = int(msg.image_index)
            if msg.get_srcComponent() == self.camera_component and index >= 0:
                if int(msg.capture_result) == CAPTURE_OK:
                    rec.add_photo(index, t, msg.lat / 1e7, msg.lon / 1e7, self.rel_alt, amsl=msg.alt / 1000.0,
                                  attitude=euler_degrees(list(msg.q)))
                rec.set(captures=max(rec.captures, index + 1))

    def _note_changes(self, t: float) -> None:
        """Mode, arming and landed-state changes and new STATUSTEXT lines into the record's events;
        the ones a crew must hear at once also said as alerts."""
        assert self.vehicle is not None
        state, rec = self.vehicle.state, self.record
        mode, armed, landed, texts = self.said
        if state.custom_mode is not None and state.mode_name() != mode:
            rec.add_event(t, f"mode {state.mode_name()}")
            self._mode_changed(state.mode_name(), mode)
        if state.armed is not None and state.armed != armed:
            rec.add_event(t, "armed" if state.armed else "disarmed")
        if state.landed_state is not None and state.landed_state != landed:
            rec.add_landed(t, state.landed_state)
            rec.add_event(t, f"landed state {LANDED_STATE_NAMES.get(state.landed_state, state.landed_state)}")
        fresh = min(state.texts_total - texts, len(state.texts))
        for text in state.texts[len(state.texts) - fresh:]:
            rec.add_event(t, f"says: {text}")
            if any(word in text.lower() for word in ALERT_WORDS) and \
                    self.severity.get(text, ALERT_SEVERITY) <= ALERT_SEVERITY:
                self.warnings.append(text)
                self.alert(f"says: {text}")
        self.said = (state.mode_name() if state.custom_mode is not None else None, state.armed,
                     state.landed_state, state.texts_total)

    def _mode_changed(self, new: str, old: str | None) -> None:
        """A mode nobody in this run asked for, mid-mission: RC, another ground station, a failsafe."""
        if old is None or new in MISSION_MODES[self.vehicle.info.flavour] or new in self.commanded:
            return
        rec = self.record
        last_seq = len(rec.wire) - 1
        if new in RETURN_MODES and self._at_final_return(last_seq):
            return  # PX4 flies a mission's final RTL / LAND item in its own mode
        if not self.armed and self._disarmed_on_ground():
            return  # after landing
        self.left_mission = new
        self.alert(f"mode changed to {new} at item {rec.current} of {last_seq}, not by fly (RC, another ground "
                   "station or a failsafe)")

    # ------------------------------------------------------------------ after landing
    def _recover_photos(self) -> None:
        """The photos whose reports were lost (a gap in the indices, or fewer reports than the camera
        counted), read from the vehicle's own log where its autopilot keeps one
        (missionplan.bridge.transfer.onboard_log: ArduPilot's DataFlash log, served once the vehicle is disarmed). The
        logs read are kept in DIR/logs/uavK/ with the flight."""
        rec = self.record
        if self.backend is None or not (rec.camera or self.gaps):
            return
        first = min(rec.camera) if rec.camera else 1
        missing = set(range(first, max(rec.captures, max(rec.camera, default=0) + 1))) - set(rec.camera)
        if not missing and not self.gaps:
            return
        # After a silence nobody knows how many photos it took in it (the vehicle may have landed before it
        # was heard again): every photo of its flight's log is read, and those not yet recorded are added.
        wanted = None if self.gaps else missing
        lost = "photo reports lost on the link" if not self.gaps else "photo reports not heard in a link gap"
        self.fleet.say(f"uav{self.sysid}: {len(missing) if missing else 'some'} {lost}; reading its log")
        lock = self.fleet.log_lock(self.url)
        while not lock.acquire(timeout=0.5):  # another vehicle's log is being read on this link
            if self.stop.is_set() or time.monotonic() >= self.deadline:
                rec.add_note(f"{lost}; its log was not read (fly was stopped or timed out first)")
                return
        try:
            found = recover_photos(self.backend.link, self.sysid, self.backend.vehicle.flavour,
                                   min(self.deadline, time.monotonic() + LOG_READ_S), wanted=wanted,
                                   since_utc=rec.t_start, save_dir=self._log_folder())
        except (BridgeError, OSError) as err:
            if not missing:  # after a gap: nothing known to be missing, but what it took in the gap is unknown
                rec.add_note(f"{lost}: its log could not be read: {err}")
                self.alert(f"photos taken while it was not heard not confirmed (its log could not be read: {err})")
                return
            rec.add_note(f"{len(missing)} {lost}; not read from the vehicle's log: {err}")
            self.alert(f"{len(missing)} photos not confirmed (their reports were lost and its log could not be "
                       f"read: {err})")
            return
        finally:
            lock.release()
        samples = np.array(rec.samples) if rec.samples else np.zeros((0, 7))
        got = 0
        for photo in found:
            # When it was taken, on our clock: through the samples' vehicle clock (time since boot).
            t = float(np.interp(photo.time_boot_s, samples[:, 5], samples[:, 0])) if len(samples) else time.time()
            up = photo.alt_rel if photo.alt_rel is not None else self.rel_alt
            attitude = None if photo.roll is None else (photo.roll, photo.pitch, photo.yaw)
            got += rec.add_photo(photo.img_idx, t, photo.lat, photo.lon, up, source="log", attitude=attitude,
                                 amsl=photo.alt_amsl)
        rec.add_note(f"{len(missing) if missing else 'some'} {lost}; {got} read back from the vehicle's log")
        unconfirmed = len(missing - set(rec.camera))
        if unconfirmed:
            self.alert(f"{unconfirmed} photos not confirmed: neither reported nor in its log")

    def _log_folder(self) -> Path:
        folder = self.plan_path.parent / "logs" / f"uav{self.sysid}"
        folder.mkdir(parents=True, exist_ok=True)
        return folder

    def _check_still_held(self) -> None:
        """After landing: does the vehicle still hold exactly the mission that was uploaded?"""
        rec = self.record
        try:
            differences = read_back_differences(self.backend, 0, rec.wire)
        except BridgeError as err:
            self.problem(f"could not read the mission back after landing: {err}")
            return
        rec.set(held_after_flight=not differences)
        if differences:
            self.problem("holds another mission after the flight: " + "; ".join(differences))
