"""Fly a planned fleet over MAVLink and record it: `missionplan fly DIR --connect URL`.

Owns the ground-station side of a flight. One connection per --connect URL, shared by every vehicle
on it (bridge.shared_link: one udpin port all vehicles send to, a TCP port, a radio); one thread per
drone on its vehicle's view of that link:

1. ask for every stream fly reads (bridge.readiness: ArduPilot sends nothing until asked) and wait,
   bounded by --ready-timeout, until the vehicle has a GPS fix, an EKF solution, a home position and
   passing pre-arm checks, saying what it waits for and what the vehicle says (STATUSTEXT);
2. site check: the vehicle's home must lie within --max-launch-offset (plus its GPS error) of the
   plan's plannedHomePosition; if any drone fails it (a plan for another site, swapped system ids)
   nothing is uploaded to that one and no drone arms at all;
3. upload DIR/uavK.plan to system id K and prove by read-back that the vehicle holds it exactly
   (or, with --upload-with mavsdk, let MAVSDK's QGroundControl importer read the file and upload it,
   and prove the vehicle then holds exactly what our reader makes of the same file). Nobody arms
   until every drone got this far;
4. set GUIDED (ArduPilot; PX4 arms in its own HOLD and starts by MISSION_START, or AUTO.MISSION if
   that is refused), arm (retried while the vehicle says it is still getting ready), wait for
   every other drone to be armed, then MAV_CMD_MISSION_START: all start together, as the plan's
   separation assumes. A drone that cannot fly is left disarmed and out of AUTO, and fly says so;
5. record GLOBAL_POSITION_INT, MISSION_CURRENT, MISSION_ITEM_REACHED and the photo reports
   (ArduPilot's CAMERA_FEEDBACK, PX4's CAMERA_IMAGE_CAPTURED), with one progress bar per drone on a
   terminal (elsewhere, a log: plain lines at the start and every quarter of each mission), until
   the vehicle has landed (PX4: its EXTENDED_SYS_STATE landed state) and disarmed with its mission
   complete (PX4: at its final RTL / LAND item, which it never reports as reached), or
   it reboots, stops answering, or the time-out passes (each a problem, the others fly on);
6. after landing, read the mission back once more: the vehicle must still hold what was uploaded.

The recordings go to flight_report.judge (coverage from the photo positions, separation, times),
which writes DIR/flight.json and DIR/flight.png. Every link fly opens signs with --signing-key when
given and speaks as ground station --gcs-sysid / --gcs-compid (bridge.commands.add_gcs_arguments).
Also here: start_mock_fleet(), the in-process mock autopilots `missionplan demo` and the integration
tests fly against.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bridge.commands import CONNECT_HELP, DEFAULT_CONNECT, add_gcs_arguments, gcs_identity, signing_key
from bridge.copter_model import PARAMETERS as COPTER_PARAMETERS
from bridge.errors import BridgeError, BridgeUsageError
from bridge.link import GCS_COMPONENT_ID, GCS_SYSTEM_ID, parse_gcs_sysid
from bridge.mission import Flavour, to_wire
from bridge.missionfile import check_firmware, read_mission_file
from bridge.params import ParamClient, read_params
from bridge.protocol import Timeouts
from bridge.px4_model import FLOAT_PARAMETERS as PX4_PARAMETERS
from bridge.readiness import (DEFAULT_LAUNCH_OFFSET_M, PX4_AUTO_MAIN, PX4_MISSION_SUB, Vehicle, request_streams,
                              site_problem, stream_rates)
from bridge.shared_link import LinkPool
from bridge.signing import SigningKey
from bridge.uploader import (MissionBackend, check_gcs_identity, open_backend, read_back_differences, set_plan_params,
                             upload_plan)

from ..mission.sorties import sortie_file
from .flight_report import DroneRecord, FlightResult, judge, sortie_view
from .phases import slow_phase

CMD_DO_SET_MODE, CMD_MISSION_START = 176, 300
CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_LAND = 20, 21
CAPTURE_OK = 1  # CAMERA_IMAGE_CAPTURED capture_result: 1 success
MODE_FLAG_ARMED = 128
MAV_TYPE_GCS = 6
MISSION_STATE_ACTIVE, MISSION_STATE_COMPLETE = 3, 5
LANDED_STATE_NAMES = {1: "on ground", 2: "in air", 3: "taking off", 4: "landing"}  # EXTENDED_SYS_STATE
ARDUPILOT_GUIDED = 4
SILENCE_S = 5.0        # a vehicle that says nothing for this long has stopped answering
MAV_RESULT_TEMPORARILY_REJECTED, MAV_RESULT_DENIED = 1, 2
PX4_START_RETRY_S = 5.0   # MISSION_START retried this long while PX4 checks a new mission (see _mission_start)
START_RETRY_WAIT_S = 0.5
ON_GROUND_M = 0.3      # relative altitude under which a disarmed vehicle counts as landed
DEFAULT_TELEMETRY_HZ = 25.0
DEFAULT_READY_S = 120.0  # a real vehicle's GPS and EKF may take a minute or two after power-on
UPLOADERS = ("missionplan", "mavsdk")  # who reads the .plan files and uploads them


def _refused(what: str, result: int | None) -> str:
    return f"{what} {'not acknowledged' if result is None else f'refused (MAV_RESULT {result})'}"


def _unanswered(text: str, link: Any, sysid: int) -> str:
    """text, with MAVLink 2 signing named when it is the likely reason the vehicle did not answer
    (bridge.link.Link.signing_hint decides)."""
    hint = link.signing_hint(sysid)
    return f"{text}: {hint}" if hint else text


class _LineProgress:
    """A drone's progress where no bar can be drawn (stderr is a file or a pipe): the few attributes
    of a tqdm bar that _DroneFlight uses, said as plain lines, at the mission's start and at each
    quarter of it, so a log gets no cursor codes."""

    def __init__(self, label: str, say: Callable[[str], None]) -> None:
        self.label, self.say = label, say
        self.n, self.total = 0, 1
        self._quarter = 4  # nothing to say before the mission starts (reset)

    def reset(self, total: int) -> None:
        self.n, self.total, self._quarter = 0, total, 0
        self.say(f"{self.label}: mission started")

    def refresh(self) -> None:
        quarter = 4 * self.n // max(self.total, 1)
        if quarter > self._quarter:
            self._quarter = quarter
            self.say(f"{self.label}: at item {self.n} of {self.total}")

    def close(self) -> None:
        pass


def _progress_display(labels: dict[int, str], progress: bool) -> tuple[dict[int, Any], Callable[[str], None]]:
    """(one progress display per drone, how to say a line). Bars only when stderr is a terminal, as
    `plan` and `upload` do; in a log, plain lines (_LineProgress). progress False: neither."""
    if not progress:
        return {}, lambda text: None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bars = {sysid: tqdm(total=1, desc=label, position=pos, unit="item", leave=True, file=sys.stderr)
                for pos, (sysid, label) in enumerate(labels.items())}
        return bars, lambda text: tqdm.write(text, file=sys.stderr)  # above the bars, not through them

    def say(text: str) -> None:
        sys.stderr.write(text + "\n")  # one write per line: the drones' threads say things at once
        sys.stderr.flush()

    return {sysid: _LineProgress(label, say) for sysid, label in labels.items()}, say


class _StartGate:
    """Drones start their missions together. Every drone's thread checks in once: a ready one
    waits there for all the others; one that failed (upload refused, arming denied) checks in
    without waiting, so the rest are not held up by it."""

    def __init__(self, parties: int) -> None:
        self._waiting_for = parties
        self._all_in = threading.Condition()

    def check_in(self, wait_s: float) -> None:
        with self._all_in:
            self._waiting_for -= 1
            if self._waiting_for <= 0:
                self._all_in.notify_all()
            elif wait_s > 0:
                self._all_in.wait_for(lambda: self._waiting_for <= 0, timeout=wait_s)


class _ArmGate:
    """Nobody arms before every drone has checked in here (ready, uploaded, site checked, or failed).
    A drone that failed the site check vetoes arming for all: a wrong site or swapped system ids is
    a fleet problem, and the fleet starts together or not at all."""

    def __init__(self, parties: int) -> None:
        self._waiting_for = parties
        self.vetoes: list[str] = []
        self._all_in = threading.Condition()

    def check_in(self, wait_s: float, veto: str = "") -> list[str]:
        """Check in (waiting up to wait_s for the others); the vetoes heard, [] when arming may go on."""
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
class _FleetStart:
    """What the drones' threads share: the links, both gates, the stop flag, how to say things."""

    pool: LinkPool
    arm_gate: _ArmGate
    gate: _StartGate
    stop: threading.Event
    key: SigningKey | None = None  # for the links fly opens beside the pool (MAVSDK's upload)
    ready_s: float = DEFAULT_READY_S
    max_offset_m: float = DEFAULT_LAUNCH_OFFSET_M
    say: Callable[[str], None] = lambda text: None


class _DroneFlight:
    """One drone's thread: readiness, upload, site check, arm, start, follow. What it learns goes into
    `record`."""

    def __init__(self, fleet: _FleetStart, record: DroneRecord, plan_path: Path, deadline: float,
                 telemetry_hz: float, bar: Any, upload_with: str = "missionplan") -> None:
        self.fleet, self.record, self.plan_path, self.deadline = fleet, record, plan_path, deadline
        self.upload_with = upload_with
        self.telemetry_hz, self.gate, self.stop, self.bar = telemetry_hz, fleet.gate, fleet.stop, bar
        self.backend: MissionBackend | None = None
        self.vehicle: Vehicle | None = None
        self.url = ""
        self.armed, self.rel_alt, self.last_reached = True, 0.0, -1  # as last reported
        self.checked_in = self.arm_checked_in = False  # at the start gate, at the arm gate
        self.recording = False  # from the mission start on: what came before is not this flight
        self.camera_component: int | None = None  # who sends this vehicle's CAMERA_IMAGE_CAPTURED: the first heard
        self.said = (None, None, None, 0)  # mode, armed, landed state, STATUSTEXT count already in record.events

    def problem(self, text: str) -> None:
        self.record.problems.append(f"uav{self.record.id}: {text}")

    def run(self) -> None:
        try:
            if self._connect() and self._ready() and self._site() and self._upload() and self._arm() and self._start():
                self._follow()
                if self.record.finished:
                    self._check_still_held()
        except Exception as err:  # noqa: BLE001 - one drone's failure must not hide the others'
            self.problem(f"{type(err).__name__}: {err}")
        finally:
            if not self.arm_checked_in:  # failed before the arm gate: the others need not wait for us
                self.fleet.arm_gate.check_in(0.0)
            if not self.checked_in:  # failed before the start: let the others go without us
                self.gate.check_in(0.0)
            if not self.record.started and self.vehicle is not None:
                self._leave_safe()
            if self.backend is not None:
                self.backend.close()

    def _connect(self) -> bool:
        """Find the vehicle on its link and learn its flavour; ask for every stream fly reads."""
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
        refused = request_streams(view, rec.id, stream_rates(self.telemetry_hz, self.backend.vehicle.flavour),
                                  self.deadline, other=self.vehicle.take)
        if refused:
            rec.notes.append(_unanswered(f"streams not accepted (SET_MESSAGE_INTERVAL): {', '.join(refused)}; "
                                         "the vehicle's own rates", view, rec.id))
        return True

    def _ready(self) -> bool:
        """Bounded wait for GPS, EKF, home and pre-arm checks (bridge.readiness)."""
        assert self.vehicle is not None
        missing = self.vehicle.wait_ready(min(self.deadline, time.monotonic() + self.fleet.ready_s))
        if missing:
            reasons = self.vehicle.state.reasons()
            # A vehicle that ignores us (signing) never sends what it sends only when asked (its home).
            self.problem(_unanswered(f"not ready to fly within {self.fleet.ready_s:g} s: still waiting for "
                                     f"{', '.join(missing)}" + (f"; the vehicle said: {reasons}" if reasons else ""),
                                     self.vehicle.link, self.record.id))
            return False
        return True

    def _leave_safe(self) -> None:
        """A vehicle that will not fly: disarmed and out of AUTO, and say how it was left."""
        assert self.vehicle is not None
        try:
            how = self.vehicle.make_safe(time.monotonic() + 5.0)
        except BridgeError as err:
            how = f"could not be made safe: {err}"
        self.record.notes.append(how)
        self.fleet.say(f"uav{self.record.id}: {how}")

    def _upload(self) -> bool:
        rec = self.record
        try:
            plan = read_mission_file(self.plan_path)
            check_firmware(plan, self.plan_path, self.backend.vehicle.flavour if self.backend else None, rec.id)
            if self.upload_with == "mavsdk":
                self._upload_by_mavsdk()
            assert self.backend is not None
            rec.wire = to_wire(plan.mission, self.backend.vehicle.flavour)
            if self.upload_with == "mavsdk":
                # What MAVSDK made of the file must be exactly what our reader makes of it.
                differences = read_back_differences(self.backend, 0, rec.wire)
                if differences:
                    raise BridgeError("the mission MAVSDK read from the .plan and uploaded differs from ours: "
                                      + "; ".join(differences))
                set_plan_params(self.backend, plan.mission)  # WPNAV_RADIUS: MAVSDK sets no parameters
            else:
                upload_plan(self.backend, plan.parts(), verify=True)
            rec.uploaded = True
            rec.flavour = self.backend.vehicle.flavour.value
            names = {Flavour.ARDUPILOT: list(COPTER_PARAMETERS), Flavour.PX4: PX4_PARAMETERS}
            if self.backend.vehicle.flavour in names:  # what it will fly with: re-times the plan (its autopilot's model)
                rec.params = read_params(ParamClient(self.backend.link, self.backend.vehicle),
                                         names[self.backend.vehicle.flavour])
            return True
        except (BridgeError, OSError) as err:
            self.problem(f"upload failed: {err}")
            return False

    def _connect_s(self) -> float:
        return max(1.0, min(10.0, self.deadline - time.monotonic()))

    def _upload_by_mavsdk(self) -> None:
        """MAVSDK's own QGroundControl importer opens the .plan and MAVSDK uploads what it read."""
        mavsdk = open_backend("mavsdk", self.url, self.record.id, key=self.fleet.key,
                              timeouts=Timeouts(item_timeout=0.5, retries=10), connect_timeout=self._connect_s())
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
        self.fleet.arm_gate.check_in(0.0, veto=f"uav{self.record.id} failed the site check")
        return False

    def _arm(self) -> bool:
        """The arm gate (nobody arms while a drone is still getting ready, none if any failed the site
        check), then GUIDED (ArduPilot) and arming, retried while not ready."""
        assert self.vehicle is not None and self.backend is not None
        sysid = self.record.id
        self.arm_checked_in = True
        vetoes = self.fleet.arm_gate.check_in(self.deadline - time.monotonic())
        if vetoes:
            self.problem(f"not armed: {'; '.join(vetoes)} (no drone arms when one is at the wrong site)")
            return False
        link = self.backend.link
        if self.backend.vehicle.flavour is Flavour.ARDUPILOT:  # arms in GUIDED, starts AUTO by MISSION_START
            link.command_long(sysid, CMD_DO_SET_MODE, [1.0, float(ARDUPILOT_GUIDED)], self.deadline,
                              other=self.vehicle.take)
        armed, why = self.vehicle.arm(min(self.deadline, time.monotonic() + self.fleet.ready_s))
        if not armed:
            self.problem(_unanswered(why, link, sysid) if "not acknowledged" in why else why)
            return False
        return True

    def _start(self) -> bool:
        rec, link, sysid = self.record, self.backend.link, self.record.id
        self.checked_in = True
        self.gate.check_in(self.deadline - time.monotonic())
        # The first positions may come before the acknowledgement: keep them (and what the vehicle says
        # from now on, not before).
        self.said = (None, None, None, self.vehicle.state.texts_total)
        self.recording = True
        result = self._mission_start()
        if result != 0 and self.backend.vehicle.flavour is Flavour.PX4:
            # PX4 also starts a mission in its AUTO.MISSION mode (from the current item, 0 after an upload).
            mode = link.command_long(sysid, CMD_DO_SET_MODE, [1.0, float(PX4_AUTO_MAIN), float(PX4_MISSION_SUB)],
                                     self.deadline, other=self.vehicle.take)
            if mode == 0:
                rec.notes.append(f"{_refused('MISSION_START', result)}; started in AUTO.MISSION mode")
                result = 0
        if result != 0:
            what = _refused("mission start", result)
            self.problem(_unanswered(what, link, sysid) if result is None else what)
            return False
        rec.started = True
        rec.t_start = rec.last_heard = time.monotonic()
        if self.bar is not None:
            self.bar.reset(total=max(len(rec.wire) - 1, 1))
        return True

    def _mission_start(self) -> int | None:
        """MAV_CMD_MISSION_START; its MAV_RESULT. PX4 takes a new mission only after its own checks (its
        navigator's, then commander's), so a start right after the upload may be DENIED ("Mission start
        denied! No valid mission") for a moment: retried for PX4_START_RETRY_S, within which PX4 does not
        yet disarm an armed vehicle that has not taken off (COM_DISARM_PRFLT, 10 s)."""
        assert self.vehicle is not None and self.backend is not None
        rec, link, sysid = self.record, self.backend.link, self.record.id
        px4 = self.backend.vehicle.flavour is Flavour.PX4
        until = min(self.deadline, time.monotonic() + (PX4_START_RETRY_S if px4 else 0.0))
        tries = 0
        while True:
            tries += 1
            result = link.command_long(sysid, CMD_MISSION_START, [0.0, 0.0], self.deadline, other=self.vehicle.take,
                                       done=lambda: rec.mission_state == MISSION_STATE_ACTIVE)
            if result not in (MAV_RESULT_DENIED, MAV_RESULT_TEMPORARILY_REJECTED) or \
                    time.monotonic() + START_RETRY_WAIT_S >= until:
                break
            self.vehicle.listen(time.monotonic() + START_RETRY_WAIT_S)
        if tries > 1 and result == 0:
            rec.notes.append(f"MISSION_START accepted after {tries} tries (the vehicle had not yet taken the "
                             f"new mission: {self.vehicle.state.reasons(1)})")
        return result

    def _follow(self) -> None:
        rec, link, sysid = self.record, self.backend.link, self.record.id
        last_seq = len(rec.wire) - 1
        reboots = link.reboots.get(sysid, 0)  # the link notices reboots (boot heartbeat, clock restart)
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= self.deadline:
                self.problem(f"mission not finished within the time-out (item {rec.current} of {last_seq})")
                return
            if now - rec.last_heard > SILENCE_S:
                self.problem(f"stopped answering at item {rec.current} of {last_seq} "
                             f"({SILENCE_S:g} s without a message)")
                return
            msg = link.recv(min(self.deadline, now + 0.5))
            if msg is None or msg.get_srcSystem() != sysid:
                continue
            if link.reboots.get(sysid, 0) > reboots:
                self.problem(f"rebooted in flight at item {rec.current} of {last_seq} (mission lost)")
                return
            self.vehicle.take(msg)  # readiness state and STATUSTEXT, then _take records it
            complete = (rec.mission_state == MISSION_STATE_COMPLETE or self.last_reached >= last_seq
                        or self._at_final_return(last_seq))
            on_ground = self.vehicle.state.on_ground  # PX4's landed state: its altitude drifts on the ground
            if not self.armed and complete and (on_ground if on_ground is not None else self.rel_alt < ON_GROUND_M):
                rec.finished, rec.t_end = True, rec.last_heard
                if self.bar is not None:
                    self.bar.n = self.bar.total
                    self.bar.refresh()
                return

    def _at_final_return(self, last_seq: int) -> bool:
        """At the mission's last item, an RTL or a LAND: PX4 reports no MISSION_ITEM_REACHED for it
        (nor a mission_state), it lands and disarms there."""
        rec = self.record
        return (rec.current >= last_seq and 0 <= last_seq < len(rec.wire)
                and int(rec.wire[last_seq].command) in (CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_LAND))

    def _take_if_started(self, msg: Any) -> None:
        if self.recording:
            self._take(msg)

    def _take(self, msg: Any) -> None:
        """Record one message of our vehicle."""
        rec = self.record
        t = rec.last_heard = time.monotonic()
        kind = msg.get_type()
        if kind in ("HEARTBEAT", "EXTENDED_SYS_STATE", "STATUSTEXT"):
            self._note_changes(t)
        if kind == "GLOBAL_POSITION_INT":
            self.rel_alt = msg.relative_alt / 1000.0
            rec.samples.append((t, msg.lat / 1e7, msg.lon / 1e7, self.rel_alt, float(np.hypot(msg.vx, msg.vy)) / 100.0,
                                msg.time_boot_ms / 1000.0, -msg.vz / 100.0))
        elif kind == "HEARTBEAT" and msg.type != MAV_TYPE_GCS:
            self.armed = bool(msg.base_mode & MODE_FLAG_ARMED)
        elif kind == "MISSION_CURRENT":
            rec.current = int(msg.seq)
            rec.mission_state = int(getattr(msg, "mission_state", 0) or 0)
            if self.bar is not None:
                self.bar.n = min(max(rec.current, self.bar.n), self.bar.total)
                self.bar.refresh()
        elif kind == "MISSION_ITEM_REACHED":
            if not rec.reached or rec.reached[-1][1] != int(msg.seq):  # PX4 repeats its last one every second
                rec.reached.append((t, int(msg.seq)))
            self.last_reached = max(self.last_reached, int(msg.seq))
        elif kind == "CAMERA_FEEDBACK":
            rec.camera.setdefault(int(msg.img_idx), (t, msg.lat / 1e7, msg.lng / 1e7, float(msg.alt_rel)))
            rec.captures = max(rec.captures, int(msg.completed_captures), int(msg.img_idx) + 1)
        elif kind == "CAMERA_IMAGE_CAPTURED":
            # PX4's photo report (its camera_feedback module, one per trigger, image_index from 0 after
            # boot), or a MAVLink camera's: from one component only, their indices are separate counts.
            if self.camera_component is None:
                self.camera_component = msg.get_srcComponent()
            index = int(msg.image_index)
            if msg.get_srcComponent() == self.camera_component and index >= 0:
                if int(msg.capture_result) == CAPTURE_OK:
                    rec.camera.setdefault(index, (t, msg.lat / 1e7, msg.lon / 1e7, self.rel_alt))
                rec.captures = max(rec.captures, index + 1)

    def _note_changes(self, t: float) -> None:
        """Mode, arming and landed-state changes and new STATUSTEXT lines into record.events (where the
        flight's time went: flight.json's phases and events)."""
        assert self.vehicle is not None
        state, rec = self.vehicle.state, self.record
        mode, armed, landed, texts = self.said
        if state.custom_mode is not None and state.mode_name() != mode:
            rec.events.append((t, f"mode {state.mode_name()}"))
        if state.armed is not None and state.armed != armed:
            rec.events.append((t, "armed" if state.armed else "disarmed"))
        if state.landed_state is not None and state.landed_state != landed:
            rec.landed.append((t, state.landed_state))
            rec.events.append((t, f"landed state {LANDED_STATE_NAMES.get(state.landed_state, state.landed_state)}"))
        fresh = min(state.texts_total - texts, len(state.texts))
        rec.events.extend((t, f"says: {text}") for text in state.texts[len(state.texts) - fresh:])
        self.said = (state.mode_name() if state.custom_mode is not None else None, state.armed,
                     state.landed_state, state.texts_total)

    def _check_still_held(self) -> None:
        """After landing: does the vehicle still hold exactly the mission that was uploaded?"""
        rec = self.record
        try:
            differences = read_back_differences(self.backend, 0, rec.wire)
        except BridgeError as err:
            self.problem(f"could not read the mission back after landing: {err}")
            return
        rec.held_after_flight = not differences
        if differences:
            self.problem("holds another mission after the flight: " + "; ".join(differences))


def flight_view(plan_dir: Path, report: dict[str, Any], sortie: int) -> dict[str, Any]:
    """report.json as a flight of `sortie` is judged (flight_report.sortie_view): with several sorties,
    every sortie's planned photos (read from its files) decide which cells are this one's duty."""
    count = max(len(d.get("sorties") or [1]) for d in report["drones"])
    missions = {j: {int(d["id"]): read_mission_file(path).mission.items for d in report["drones"]
                    if (path := plan_dir / sortie_file(int(d["id"]), j)).is_file()}
                for j in range(1, count + 1)} if count > 1 else {}
    return sortie_view(report, sortie, missions)


def fly(plan_dir: Path, connect: str | list[str], timeout_s: float = 600.0, progress: bool = True,
        time_scale: float | None = None, telemetry_hz: float = DEFAULT_TELEMETRY_HZ,
        upload_with: str = "missionplan", sortie: int = 1, ready_s: float = DEFAULT_READY_S,
        max_launch_offset_m: float = DEFAULT_LAUNCH_OFFSET_M, photos_from_track: bool = False,
        key: SigningKey | None = None, source_system: int = GCS_SYSTEM_ID,
        source_component: int = GCS_COMPONENT_ID) -> FlightResult:
    """Wait until ready, upload, verify, site-check, arm, start and follow every drone of plan_dir at
    once; write flight.json/.png.

    connect: one URL or several (each URL, or SYSID=URL; bridge.shared_link.parse_connects): one
    connection per URL, shared by the vehicles on it, signed with `key` when given, and speaking as
    ground station (source_system, source_component).

    progress: one bar per drone on stderr when it is a terminal, else plain lines (a log); False: none.
    sortie=J flies battery sortie J (uavK-sJ.plan, J >= 2) of every drone that has one, judged on the
    targets that sortie's plan photographs.

    photos_from_track: count a photo every trigger distance along the track of a vehicle that reports
    none (no CAMERA_FEEDBACK); without it such a flight is judged a failure (flight_report.judge).

    upload_with="mavsdk": MAVSDK's QGroundControl importer reads each .plan and MAVSDK uploads it;
    the read-back must then equal what our own reader makes of the same file."""
    if upload_with not in UPLOADERS:
        raise BridgeUsageError(f"--upload-with {upload_with}: choose {' or '.join(UPLOADERS)}")
    check_gcs_identity(upload_with, source_system, source_component, "--upload-with")
    plan_dir = Path(plan_dir)
    report = json.loads((plan_dir / "report.json").read_text())
    if "georeference" not in report or "drones" not in report:
        raise BridgeUsageError(f"{plan_dir / 'report.json'}: not a georeferenced plan (no missions to fly)")
    # Bad URLs: exit 2, before anything.
    pool = LinkPool([connect] if isinstance(connect, str) else list(connect), key, source_system, source_component)
    if sortie < 1:
        raise BridgeUsageError(f"--sortie must be 1 or more, got {sortie}")
    files = {int(d["id"]): plan_dir / sortie_file(int(d["id"]), sortie) for d in report["drones"]}
    report = flight_view(plan_dir, report, sortie)
    if not report["drones"]:
        raise BridgeUsageError(f"{plan_dir}: no drone has a sortie {sortie}")
    records = [DroneRecord(id=int(d["id"]), planned_photos=int(d.get("photos", 0))) for d in report["drones"]]
    parse_gcs_sysid(source_system, [rec.id for rec in records])  # not a drone's own id
    plans = {rec.id: files[rec.id] for rec in records}
    start = time.monotonic()
    deadline = start + timeout_s
    for rec in records:
        if not plans[rec.id].exists():
            rec.problems.append(f"uav{rec.id}: {plans[rec.id]} is missing")
    runnable = [rec for rec in records if plans[rec.id].exists()]
    bars, say = _progress_display({rec.id: f"uav{rec.id}" for rec in runnable}, progress)
    try:
        pool.open_all()
        pool.register(rec.id for rec in runnable)
        fleet = _FleetStart(pool, _ArmGate(len(runnable)), _StartGate(len(runnable)), threading.Event(), key=key,
                            ready_s=ready_s, max_offset_m=max_launch_offset_m, say=say)
        threads = [threading.Thread(target=_DroneFlight(fleet, rec, plans[rec.id], deadline, telemetry_hz,
                                                        bars.get(rec.id), upload_with).run,
                                    name=f"fly-uav{rec.id}", daemon=True)
                   for rec in runnable]
        for thread in threads:
            thread.start()
        try:
            for thread in threads:
                thread.join(max(0.0, deadline - time.monotonic()) + 5.0)
        finally:
            fleet.stop.set()
            for thread in threads:
                thread.join(2.0)
    finally:
        pool.close()
        for bar in bars.values():
            bar.close()
    return judge(plan_dir, report, records, time_scale, wall_s=time.monotonic() - start, telemetry_hz=telemetry_hz,
                 photos_from_track=photos_from_track)


def start_mock_fleet(plan_dir: Path, speedup: float, flavour: str = "ardupilot", faults: Any = None,
                     sitl_like: bool = True, cameras: bool = True, **options: Any) -> Any:
    """In-process mock autopilots on 127.0.0.1, one per uavK.plan of plan_dir (system id K, home at
    its launch point). Returns the started MockAutopilot; fly against mock.client_url, then mock.stop().
    sitl_like: they fly like ArduCopter SITL (the plan's timeline); cameras: each has its camera
    configured (CAM1_TYPE and a reboot, as a team does once), else it reports no photos; options go
    to MockAutopilot (gps_fix_after, streams_until_asked: SITL-like readiness and streams; homes)."""
    from bridge.mock import MockAutopilot

    homes: dict[int, tuple[float, float, float]] = {}
    for path in sorted(Path(plan_dir).glob("uav*.plan")):
        if not path.stem[3:].isdigit():  # uavK-sJ.plan: a later sortie of drone K, same home
            continue
        home = read_mission_file(path).mission.home
        if home is not None:
            homes[int(path.stem[3:])] = (float(home[0]), float(home[1]), float(home[2]))
    if not homes:
        raise BridgeUsageError(f"{plan_dir}: no uavK.plan files to fly")
    homes = {**homes, **options.pop("homes", {})}
    mock = MockAutopilot("udpin:127.0.0.1:0", sysids=sorted(homes), flavour=flavour, speedup=speedup,
                         faults=faults, homes=homes, sitl_like=sitl_like, **options)
    mock.start()
    if sitl_like and cameras:
        for sysid in homes:
            mock.configure_camera(sysid)
    return mock


# ------------------------------------------------------------------------------------------- CLI
def print_flight(result: FlightResult) -> None:
    """The lines `fly` and `demo` print about a flight."""
    sep = result.separation
    print(f"flown coverage {result.coverage:.2f} % of {result.targets} target cells "
          f"(photos from {result.photo_source}); {len(result.drones)} drones, {result.wall_s:.1f} s wall")
    if sep["kept"] is None:
        print(f"separation not measured: {sep.get('tracks', 0)} drone(s) flew, it takes two"
              + (f" (the plan promised {sep['planned_3d']} m 3-D)" if sep["planned_3d"] is not None else ""))
    else:
        print(f"closest approach {sep['horizontal']} m horizontal / {sep['3d']} m 3-D; "
              f"the plan promised {sep['planned_3d']} m 3-D (tolerance {sep['tolerance']} m): "
              f"{'kept' if sep['kept'] else 'BROKEN'}")
    for d in result.drones:
        state = "finished" if d["finished"] else "NOT finished"
        held = {True: "holds the uploaded mission", False: "LOST its mission", None: "mission not re-read"}
        retimed = d.get("planned_flight_s_vehicle")
        vehicle = (f"; {retimed:.1f} s with the vehicle's parameters"
                   if retimed is not None and abs(retimed - d["planned_flight_s"]) >= 0.05 else "")
        print(f"  uav{d['id']}: {state}, {d['flight_s']:.1f} s flown (planned {d['planned_flight_s']:.1f} s{vehicle}), "
              f"{d['photos']} photos, {held[d['held_after_flight']]}"
              + "".join(f"; {note}" for note in d.get("notes", []) if note.startswith("left "))
              + (f"; {slow}" if (slow := slow_phase(d.get("phases") or [])) else ""))
    for problem in result.problems:
        print(f"  problem: {problem}")
    print(f"wrote {result.json_path} and {result.png_path}")


def cmd_fly(args: Any) -> int:
    if args.timeout <= 0:
        raise BridgeUsageError(f"--timeout must be positive, got {args.timeout}")
    if args.telemetry_hz <= 0:
        raise BridgeUsageError(f"--telemetry-hz must be positive, got {args.telemetry_hz}")
    if not (Path(args.dir) / "report.json").is_file():
        raise BridgeUsageError(f"{args.dir}: no report.json (run `missionplan plan --out {args.dir}` first)")
    if args.ready_timeout <= 0:
        raise BridgeUsageError(f"--ready-timeout must be positive, got {args.ready_timeout}")
    if not args.max_launch_offset >= 0:
        raise BridgeUsageError(f"--max-launch-offset must be a distance in metres (0 or more), "
                               f"got {args.max_launch_offset}")
    gcs = gcs_identity(args, [])  # the drones' own ids are checked by fly(), once report.json is read
    # --connect appends; its default applies only when none is given (an argparse append default
    # would be appended to, not replaced).
    connect = args.connect or [DEFAULT_CONNECT]
    try:
        result = fly(Path(args.dir), connect, timeout_s=args.timeout, progress=not args.quiet,
                     time_scale=args.time_scale, telemetry_hz=args.telemetry_hz, upload_with=args.upload_with,
                     sortie=args.sortie, ready_s=args.ready_timeout, max_launch_offset_m=args.max_launch_offset,
                     photos_from_track=args.photos_from_track, key=signing_key(args), source_system=gcs[0],
                     source_component=gcs[1])
    except BridgeUsageError:
        raise
    except BridgeError as err:  # a link that cannot be opened: one line, exit 1
        print(f"missionplan fly: {err}", file=sys.stderr)
        return 1
    print_flight(result)
    return 0 if result.ok else 1


def register(subparsers: Any) -> None:
    """Add `fly DIR [--connect URL ...] [--ready-timeout S] [--max-launch-offset M] [--timeout S]
    [--telemetry-hz HZ] [--time-scale X] [--upload-with W] [--sortie J] [--photos-from-track]
    [--signing-key FILE] [--gcs-sysid N] [--gcs-compid N] [--quiet]`."""
    p = subparsers.add_parser("fly", help="upload a planned fleet, fly it over MAVLink and judge the flight "
                                          "(flight.json, flight.png)", allow_abbrev=False)
    p.add_argument("dir", help="plan folder written by `missionplan plan` (report.json, uavK.plan)")
    p.add_argument("--connect", action="append", default=None, metavar="URL",
                   help=f"{CONNECT_HELP}; the vehicles share it, told apart by system id; repeat it for vehicles on "
                        "several links (each found on its link by its heartbeat), or give SYSID=URL (1,2=URL) to "
                        "say which")
    p.add_argument("--ready-timeout", type=float, default=DEFAULT_READY_S,
                   help=f"wait this many seconds at most for each vehicle's GPS fix, EKF, home position and pre-arm "
                        f"checks (default {DEFAULT_READY_S:g})")
    p.add_argument("--max-launch-offset", type=float, default=DEFAULT_LAUNCH_OFFSET_M, metavar="M",
                   help=f"refuse to arm any vehicle when one's home is more than M metres plus its reported GPS "
                        f"error from its plan's launch point (default {DEFAULT_LAUNCH_OFFSET_M:g})")
    p.add_argument("--timeout", type=float, default=600.0, help="give up after this many seconds (default 600)")
    p.add_argument("--telemetry-hz", type=float, default=DEFAULT_TELEMETRY_HZ,
                   help=f"position stream rate to ask each vehicle for (default {DEFAULT_TELEMETRY_HZ:g})")
    p.add_argument("--time-scale", type=float, default=None,
                   help="simulated seconds per wall second of a sped-up simulator (default: estimated from the "
                        "reported velocities; 1 for real vehicles)")
    p.add_argument("--upload-with", choices=UPLOADERS, default="missionplan",
                   help="who reads the .plan files and uploads them: our reader and uploader (default), or "
                        "MAVSDK's QGroundControl importer and MissionRaw (checked against ours by read-back)")
    p.add_argument("--sortie", type=int, default=1, metavar="J",
                   help="battery sortie to fly: 1 (uavK.plan, default) or J (uavK-sJ.plan, drones that have one)")
    p.add_argument("--photos-from-track", action="store_true",
                   help="a vehicle that reports no photos (no CAMERA_FEEDBACK: no camera configured) gets one every "
                        "trigger distance along its flown track; without this flag such a flight fails")
    add_gcs_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bars or progress lines")
    p.set_defaults(handler=cmd_fly)
