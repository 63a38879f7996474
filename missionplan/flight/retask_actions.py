"""A survivor's part in a live re-task (fly --replan), run by its follower's thread: held where it is, its
new mission put on board, released.

The re-tasker (live_replan.Retasker) asks each survivor's follower (DroneFlight.ask) to run these between
two of its vehicle's messages, since that thread owns the vehicle's link; each answers through its
Future. Every command goes through the vehicle's session (missionplan.bridge.session).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from missionplan.bridge.errors import BridgeError
from missionplan.bridge.formats.mission_items import to_wire
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.session.vehicle_session import VehicleSession

from .event_journal import refused
from .record import DroneRecord
from .retask_planner import RetaskRequest
from .telemetry_record import TelemetryRecorder

RETASK_UPLOAD_S = 30.0  # at most this long to put a re-task's mission on a flying vehicle
HOLD_S, HOLD_SPEED = 10.0, 0.5  # a vehicle held for a re-task stops (m/s) within this long (wall s)


class RetaskActions:
    """One survivor's vehicle, for a re-task: hold(), retask(request), release()."""

    def __init__(self, session: VehicleSession, record: DroneRecord, recorder: TelemetryRecorder, deadline: float,
                 problem: Callable[[str], None], bar: Any = None) -> None:
        self.session, self.record, self.recorder, self.deadline = session, record, recorder, deadline
        self.problem, self.bar = problem, bar

    def hold(self) -> tuple[float, float, float]:
        """Stop where it is (ArduPilot GUIDED, PX4 AUTO.LOITER: the autopilot brakes and hovers) until a
        re-task or a release; returns where it hovers (lat, lon, m up) once its speed is under HOLD_SPEED.
        Raises BridgeError when the vehicle refuses or does not stop in time."""
        session = self.session
        mode = session.action.hold_mode()
        deadline = min(self.deadline, time.monotonic() + HOLD_S)
        result = session.action.hold(deadline)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise BridgeError(refused(f"{mode} (to hold it for the re-task)", result))
        rec = self.record
        while time.monotonic() < deadline:
            if rec.samples and rec.samples[-1][4] < HOLD_SPEED and session.state.mode_name() == mode:
                t, lat, lon, up = rec.samples[-1][:4]
                rec.add_event(time.time(), f"held for a re-task ({mode})")
                return float(lat), float(lon), float(up)
            msg = session.recv(deadline)
            if msg is not None and msg.get_srcSystem() == session.sysid:
                session.take(msg)
        # What it was doing is said, so a vehicle still braking can be told from one in another mode.
        seen = (f"still at {rec.samples[-1][4]:.1f} m/s" if rec.samples else "no position heard") \
            + f", in {session.state.mode_name()}"
        raise BridgeError(f"did not stop in {HOLD_S:g} s after {mode} ({seen})")

    def release(self) -> None:
        """Back to its mission mode: its new mission from the item set current (after a re-task), or its
        old one where it was (a re-task refused after the hold)."""
        result = self.session.action.mission_mode(min(self.deadline, time.monotonic() + HOLD_S))
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise BridgeError(refused("its mission mode (released after a refused re-task)", result))

    def retask(self, request: RetaskRequest) -> str:
        """Put a re-task's mission and fence on the held vehicle, current at its first item after the
        take-off, and leave it holding (missionplan.bridge.transfer.retask: the way each autopilot takes it, confirmed
        by the vehicle; what it says meanwhile is recorded): release() then starts it, with the others. The record's
        mission becomes the new one, so its end and its photos are judged against it. Returns what to say; raises
        BridgeError when it is not confirmed."""
        rec = self.record
        flavour = self.session.flavour
        wire = to_wire(request.mission, flavour)
        resume = request.resume_index + (len(wire) - len(request.mission.items))  # ArduPilot's home is seq 0
        fence = to_wire(request.fence, flavour) if request.fence is not None and request.fence.items else None
        try:
            report = self.session.mission.replace_in_flight(wire, resume,
                                                            min(self.deadline, time.monotonic() + RETASK_UPLOAD_S),
                                                            fence)
        except (BridgeError, ValueError) as err:
            self.problem(f"re-task failed: the new mission is not on board ({err})")
            raise BridgeError(f"the new mission is not on board ({err})") from None
        rec.set(wire=wire, planned_photos=request.photos)  # what the vehicle holds now
        self.recorder.last_reached = -1
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
