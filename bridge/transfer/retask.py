"""Live re-tasking: replace the mission of a vehicle that is flying it, and have it carry on.

Owns replace_mission_in_flight, what the product calls when a drone of a flying fleet is lost and a
survivor takes over its work: the survivor's mission is replaced in flight by `items` (wire items as
formats.mission_items.to_wire makes them: ArduPilot's seq 0 is home) and it continues at `resume_seq`,
without landing, disarming or flying back to its first item. Per autopilot it uses the strategy
measured best on ArduCopter SITL and PX4 SIH (docs/live-retasking.md, bench/retask_bench.py):

- ArduPilot: pause in GUIDED, upload the whole mission, MISSION_SET_CURRENT resume_seq, AUTO again.
  ArduPilot writes each uploaded item into its live mission as it arrives (MISSION_COUNT truncates it
  first: GCS_MAVLink/MissionItemProtocol.cpp, replace_item / append_item), and in AUTO restarts whatever
  then sits at its current index (AP_Mission_ChangeDetector, ModeAuto::run: "Auto mission changed,
  restarted command"): an upload in AUTO is flown while half written, and one that fails halfway
  leaves the half. In GUIDED the mission is stopped; AUTO resumes it at the item set current
  (AP_Mission::resume). On SITL the pause lasted 0.1-0.2 vehicle seconds and the copter kept 2 m/s.
- PX4: upload the whole mission in mission mode with `current` = 1 on resume_seq; MISSION_SET_CURRENT
  resume_seq only if MISSION_CURRENT does not say it is there within 1.5 s. PX4 receives an upload into
  its inactive mission slot and switches at the last item, taking the item flagged current as its
  current one (mavlink/mavlink_mission.cpp, update_active_mission); its navigator goes on from there
  at once (navigator/mission_base.cpp, onMissionUpdate). With the flag on seq 0, as to_wire sets it,
  PX4 first turns back to item 0 (measured on SIH).

Neither uses MISSION_WRITE_PARTIAL_LIST: PX4 has no handler for it (no answer at all), and ArduPilot's
writes in place like the full upload, cannot shorten a mission nor lengthen it by more than one item.

Verification: the vehicle's MISSION_CURRENT must say resume_seq (or later), its HEARTBEAT armed and in
mission mode again, and a read-back must equal `items` by the flavour's rule (formats.readback.compare_wire).
A vehicle that is not flying its mission (not armed, or in another mode: RTL after a failsafe, say)
is not touched: re-tasking must never override what the pilot or a failsafe chose.

In `fly` each vehicle's link is a view of a shared link read by that drone's thread
(link.shared_link.VehicleLink): call this from that thread with its backend and view (its vehicle session,
missionplan.bridge.session, does), and pass `observe` (the session's `take`) to keep every message of the
vehicle that arrives meanwhile (positions, MISSION_ITEM_REACHED, STATUSTEXT) in the flight's record. A new geofence (`fence`) goes
up before the mission (ArduPilot: during the pause), so the vehicle never flies the new mission inside
the old fence; a fence or mission refused raises RetaskError with what was left on the vehicle.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from ..errors import BridgeError
from ..link.connection import AUTOPILOT_COMPONENT_ID, mavlink
from ..formats.mission_items import Flavour, MissionType, WireItem
from ..formats.readback import compare_wire
from .protocol import MissionClient, MissionTransferError
from ..link.readiness import ARDUPILOT_GUIDED, VehicleState, mission_mode_params, mode_params
from .uploader import MissionBackend

HEARTBEAT_WAIT_S = 2.5  # a HEARTBEAT comes every second: this long to learn the vehicle's mode
CONFIRM_S = 5.0         # after the change: this long for MISSION_CURRENT and a HEARTBEAT that confirm it
SET_CURRENT_TRIES, SET_CURRENT_WAIT_S = 3, 1.5  # PX4 says MISSION_CURRENT once a second when nothing changes
STRATEGIES = {
    Flavour.ARDUPILOT: "pause in GUIDED, full upload, MISSION_SET_CURRENT, AUTO",
    Flavour.PX4: "full upload in mission mode with resume_seq flagged current",
}

Observe = Callable[[Any], None]


@dataclass
class RetaskReport:
    """What replace_mission_in_flight did and what the vehicle confirmed."""

    sysid: int
    strategy: str
    accepted: bool = False          # the upload was acknowledged with MAV_MISSION_ACCEPTED
    upload_s: float = 0.0           # wall seconds from MISSION_COUNT to its final ACK
    continued_at: int | None = None  # the seq MISSION_CURRENT reported once the change was made
    mode: str = ""                  # the vehicle's mode after the change, as its HEARTBEAT says
    read_back: bool = False         # the vehicle holds exactly `items` (flavour's rule)
    confirmed: bool = False         # accepted, continued at resume_seq or later, armed in mission mode, read back
    texts: list[str] = field(default_factory=list)  # the vehicle's STATUSTEXT meanwhile
    problem: str = ""               # why not confirmed, and how the vehicle was left

    def summary(self) -> str:
        state = "confirmed" if self.confirmed else f"NOT confirmed: {self.problem}"
        said = f"; it said: {'; '.join(self.texts)}" if self.texts else ""
        return (f"vehicle {self.sysid}: mission replaced in flight ({self.strategy}) in {self.upload_s:.2f} s, "
                f"continued at item {self.continued_at} in {self.mode}; {state}{said}")


class _Tee:
    """The vehicle's link as protocol code sees it, each message of it also handed to `other` (the
    mission client drops what it does not need: positions, MISSION_ITEM_REACHED, STATUSTEXT)."""

    def __init__(self, link: Any, sysid: int, other: Observe) -> None:
        self._link, self._sysid, self._other = link, sysid, other

    def recv(self, deadline: float) -> Any | None:
        msg = self._link.recv(deadline)
        if msg is not None and msg.get_srcSystem() == self._sysid:
            self._other(msg)
        return msg

    def __getattr__(self, name: str) -> Any:
        return getattr(self._link, name)


class _Watch:
    """The vehicle's messages read here: its state (mode, armed), MISSION_CURRENT and what it says."""

    def __init__(self, link: Any, sysid: int, flavour: Flavour, other: Observe | None) -> None:
        self.link, self.sysid, self.other = link, sysid, other
        self.state = VehicleState(flavour)
        self.currents: list[int] = []  # MISSION_CURRENT seqs, in order
        self.heartbeats = 0
        self.texts: list[str] = []

    def take(self, msg: Any) -> None:
        if msg.get_srcSystem() != self.sysid:
            return
        kind = msg.get_type()
        if kind != "HEARTBEAT" or msg.get_srcComponent() == AUTOPILOT_COMPONENT_ID:  # not a camera's or gimbal's
            self.state.take(msg)
            self.heartbeats += kind == "HEARTBEAT"
        if kind == "MISSION_CURRENT":
            self.currents.append(int(msg.seq))
        self.texts += self.state.new_texts  # STATUSTEXT, long ones joined from their chunks
        self.state.new_texts.clear()
        if self.other is not None:
            self.other(msg)

    def until(self, done: Callable[[], bool], deadline: float) -> bool:
        """Read until done() or the deadline; whether done."""
        while not done():
            if time.monotonic() >= deadline:
                return False
            msg = self.link.recv(deadline)
            if msg is not None:
                self.take(msg)
        return True

    def flying_mission(self) -> bool:
        return bool(self.state.armed) and self.state.in_auto


def _check(items: list[WireItem], resume_seq: int, flavour: Flavour) -> None:
    if flavour not in STRATEGIES:
        raise ValueError(f"live re-tasking is measured for ArduPilot and PX4 only, not {flavour.value}")
    if [it.seq for it in items] != list(range(len(items))) or any(it.mission_type != MissionType.MISSION
                                                                    for it in items):
        raise ValueError("items must be mission items with seq 0..n-1")
    first = 1 if flavour.has_home_item(MissionType.MISSION) else 0  # ArduPilot's item 0 is home, not flown
    if not first <= resume_seq < len(items):
        raise ValueError(f"resume_seq {resume_seq} is not a mission item to fly ({first}..{len(items) - 1})")


class RetaskError(BridgeError):
    """The new mission is not on the vehicle; `report` says what was done and how the vehicle was left."""

    def __init__(self, message: str, report: RetaskReport) -> None:
        super().__init__(message)
        self.report = report


def replace_mission_in_flight(backend: MissionBackend, link: Any, sysid: int, flavour: Flavour,
                              items: list[WireItem], resume_seq: int, deadline: float, *,
                              fence: list[WireItem] | None = None, observe: Observe | None = None,
                              held: bool = False, resume: bool = True) -> RetaskReport:
    """Replace the mission of vehicle `sysid`, flying it in AUTO (ArduPilot) / mission mode (PX4), by
    `items` and have it continue at `resume_seq`; `deadline` (time.monotonic()) bounds it all.

    backend: the vehicle's mission backend (transfer.uploader) over `link` (a Link or, in fly, the
    vehicle's view of a shared link). fence: a new geofence (wire items of mission_type 1) to put up
    first; None leaves the fence as it is. observe: gets every message of the vehicle read meanwhile.
    held: the caller has already stopped the vehicle (ArduPilot GUIDED, PX4 HOLD, to plan from where it
    hovers): armed in that mode is accepted, and PX4 is switched back to its mission mode at the end too.
    resume=False (with held): leave it holding with the new mission on board, current at resume_seq; the
    caller switches it to its mission mode (a fleet released together, so the new tracks start together).
    Raises ValueError for items or a resume_seq that cannot be flown; RetaskError (a BridgeError) when
    the new mission is not on board: the vehicle not flying its mission (nothing is sent then), a mode,
    fence or mission refused (ArduPilot: left hovering in GUIDED when its mission may be half written).
    Otherwise the report: confirmed, or what the vehicle says that differs."""
    _check(items, resume_seq, flavour)
    watch = _Watch(link, sysid, flavour, observe)
    report = RetaskReport(sysid=sysid, strategy=STRATEGIES[flavour])

    def fail(why: str) -> RetaskError:
        report.problem, report.texts = why, watch.texts
        return RetaskError(f"vehicle {sysid}: {why}", report)

    seen_from = watch.heartbeats
    watch.until(lambda: watch.heartbeats > seen_from, min(deadline, time.monotonic() + HEARTBEAT_WAIT_S))
    if not (watch.flying_mission() or (held and watch.state.armed)):
        state = "no HEARTBEAT" if watch.heartbeats == seen_from else (
            f"{'armed' if watch.state.armed else 'disarmed'} in {watch.state.mode_name()}")
        raise fail(f"not flying its mission ({state}): nothing was sent to it")
    # The transfers go through transfer.protocol's client (the pymavlink backend's own protocol, its time-outs)
    # on a tee of the link: what the vehicle says meanwhile (STATUSTEXT, MISSION_ITEM_REACHED, positions) is
    # read here and handed to `observe`, not dropped. Another backend (MAVSDK) does its own transfers.
    transfers: Any = backend
    if hasattr(backend, "client"):
        transfers = MissionClient(_Tee(link, sysid, watch.take), backend.vehicle, backend.client.timeouts)

    ardupilot = flavour is Flavour.ARDUPILOT
    if ardupilot:
        # Stop the mission before touching it: GUIDED holds position (LOITER would follow the sticks).
        result = link.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline,
                                   other=watch.take)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise fail(f"GUIDED {_refused(result)}: nothing was changed, it flies on in AUTO")
        wire = items
    else:
        # PX4 makes the item flagged current its current one when the upload completes.
        wire = [replace(it, current=int(it.seq == resume_seq)) for it in items]

    def back_to_auto() -> str:
        result = link.command_long(sysid, mavlink.MAV_CMD_DO_SET_MODE, mission_mode_params(flavour), deadline,
                                   other=watch.take)
        return "" if result == mavlink.MAV_RESULT_ACCEPTED else f"its mission mode {_refused(result)}: left in " \
            f"{watch.state.mode_name()}"

    if fence is not None:
        try:
            if fence:
                transfers.upload(MissionType.FENCE, fence)
            else:
                transfers.clear(MissionType.FENCE)
        except MissionTransferError as err:
            left = back_to_auto() if ardupilot else ""
            raise fail(f"fence refused ({err}); the mission was not touched, it flies on with its old one"
                       + (f"; {left}" if left else "")) from None

    started = time.monotonic()
    try:
        transfers.upload(MissionType.MISSION, wire)
    except MissionTransferError as err:
        report.upload_s = time.monotonic() - started
        left = ("left hovering in GUIDED: its mission may be half written (ArduPilot stores items as they come)"
                if ardupilot else "it flies on with its previous mission (PX4 switches only at the last item)")
        raise fail(f"mission upload failed ({err}); {left}") from None
    report.upload_s = time.monotonic() - started
    report.accepted = True
    heard = len(watch.currents)  # what MISSION_CURRENT says from the final ACK on is about the new mission

    problems: list[str] = []
    nav_seq = _first_nav(items, resume_seq)
    # PX4 is there already when the upload completes (the flag): MISSION_SET_CURRENT only if it does not
    # say so within SET_CURRENT_WAIT_S (sent once it had moved on to the item after, it would go back).
    there = not ardupilot and watch.until(lambda: any(resume_seq <= k <= nav_seq for k in watch.currents[heard:]),
                                          min(deadline, time.monotonic() + SET_CURRENT_WAIT_S))
    if not there and not _set_current(watch, resume_seq, nav_seq, deadline):
        problems.append(f"MISSION_SET_CURRENT {resume_seq}: no MISSION_CURRENT said so")
    # Confirm from what the vehicle itself says: its item (the first MISSION_CURRENT once the change is
    # made: from the final ACK on for PX4 in its mission mode, from the mode change on otherwise; it may
    # fly on quickly), its mode and arming (a HEARTBEAT from now on).
    currents = heard if not ardupilot and not held else len(watch.currents)
    if there and not held:
        # PX4 may say its old mission's item once more right after the final ACK (a report from before the switch:
        # 6 then 2 on SIH); the first report in the new mission's range is where it continued.
        currents = next(i for i in range(heard, len(watch.currents)) if resume_seq <= watch.currents[i] <= nav_seq)
    if resume and (ardupilot or held) and (refusal := back_to_auto()):  # a held PX4 resumes at its flagged item
        problems.append(refusal)
    beats = watch.heartbeats
    # ArduPilot streams MISSION_CURRENT only when asked
    link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                               float(mavlink.MAVLINK_MSG_ID_MISSION_CURRENT), 0, 0, 0, 0, 0, 0)
    watch.until(lambda: len(watch.currents) > currents and watch.heartbeats > beats,
                min(deadline, time.monotonic() + CONFIRM_S))
    report.continued_at = watch.currents[currents] if len(watch.currents) > currents else None
    report.mode = watch.state.mode_name()
    try:
        differences = compare_wire(items, transfers.download(MissionType.MISSION),
                                   skip_home=flavour.has_home_item(MissionType.MISSION), flavour=flavour)
    except MissionTransferError as err:
        differences = [f"read-back failed: {err}"]
    report.read_back = not differences
    report.texts = watch.texts
    if report.continued_at is None or report.continued_at < resume_seq:
        problems.append(f"MISSION_CURRENT says {report.continued_at}, not {resume_seq}")
    if not (watch.flying_mission() if resume else watch.state.armed):
        problems.append(f"{'armed' if watch.state.armed else 'DISARMED'} in {report.mode}")
    if differences:
        problems.append("holds another mission: " + "; ".join(differences[:3]))
    report.problem = "; ".join(problems)
    report.confirmed = not problems
    return report


def _first_nav(items: list[WireItem], seq: int) -> int:
    """The first navigation item at or after `seq` (seq itself when there is none): what MISSION_CURRENT
    reports once a DO_ item was made current (ArduPilot loads the next navigation item at once)."""
    return next((it.seq for it in items[seq:] if it.command <= mavlink.MAV_CMD_NAV_LAST), seq)


def _set_current(watch: _Watch, seq: int, nav_seq: int, deadline: float) -> bool:
    """MISSION_SET_CURRENT seq until MISSION_CURRENT says seq (or nav_seq, the navigation item it leads
    to); sent again only while no such MISSION_CURRENT came (it is not repeated once taken: a vehicle
    already past seq would be sent back). transfer.protocol's set_current waits for seq exactly, which a
    DO_ item at seq (fly resumes at the DO_CHANGE_SPEED after the take-off) is never reported as."""
    for _ in range(SET_CURRENT_TRIES):
        heard = len(watch.currents)
        watch.link.mav.mission_set_current_send(watch.sysid, AUTOPILOT_COMPONENT_ID, seq)
        until = min(deadline, time.monotonic() + SET_CURRENT_WAIT_S)
        if watch.until(lambda: any(seq <= k <= nav_seq for k in watch.currents[heard:]), until):
            return True
        if time.monotonic() >= deadline:
            break
    return False


def _refused(result: int | None) -> str:
    return "not acknowledged" if result is None else f"refused (MAV_RESULT {result})"


__all__ = ["RetaskError", "RetaskReport", "replace_mission_in_flight", "STRATEGIES"]
