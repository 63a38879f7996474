"""`fly --replan`: watch the fleet for a drone that is lost or ends early, and re-task the others in flight.

fly's main thread calls Retasker.look() every WATCH_S. The re-tasker knows the fleet from the events its
followers publish (events.py, on a queue read here), not from their threads' state: a drone counts as
gone when it ended its mission early (a landing), was switched to a return by someone else than fly (a
failsafe's RTL or LAND), or has been silent mid-mission for --replan-after seconds (link_silence decides).
Then, once per gone drone:
1. the drones still flying their missions are held where they are (ArduPilot GUIDED, PX4 HOLD: the
   autopilot brakes and hovers), so the plan starts where they really are and their new tracks start
   together;
2. the planner fly was handed (a retask_planner.RetaskPlanner: missionplan.planning.retask.retask_planner, through
   the CLI; this layer plans nothing itself) plans what no confirmed photo (events.PhotoTaken) has covered
   yet for them, from there, checked for endurance, separation and fences;
3. each survivor's own thread puts its new mission on its vehicle (retask_actions, through its vehicle
   session: missionplan.bridge.transfer.retask), the main thread waiting, bounded, for all of them; then all are released to their mission mode at
   once, so the new tracks start together. One whose upload failed keeps holding, and the crew is told.
A refusal (a survivor that cannot be held, a plan that fails a check) is said with its reason and the
held survivors are released to their old missions where they were.

A gone drone that is heard again after its share was given away would fly the same streets as the
drones that took it over: its follower is told (events.ShareGivenAway) and sends it home (RTL), which is
what --replan asks for, and says so.
Every step is journaled in the drones' records (events and notes) and so reaches flight.json.
"""

from __future__ import annotations

import queue
import time
from collections.abc import Callable
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.bridge.formats.missionfile import read_mission_file

from ..mission.plan_record import PlanRecord
from .drone_flight import DroneFlight
from .events import FlightEvent, ShareGivenAway, drain
from .fleet_view import DroneView, confirmed_photos
from .follower_mail import RecordNote
from .flight_report import vehicle_rate
from .link_silence import SilenceRule
from .retask_actions import HOLD_S, RETASK_UPLOAD_S, RetaskActions
from .retask_planner import RetaskPlanner, RetaskPlanningError, Survivor


def _actions(flight: DroneFlight) -> RetaskActions:
    """A survivor's re-task actions (it is flying its mission: its follower has its session)."""
    assert flight.retasking is not None
    return flight.retasking


@dataclass
class Retasker:
    plan_dir: Path
    record: PlanRecord  # the plan as this flight is judged (fly.flight_view)
    flights: list[DroneFlight]
    planner: RetaskPlanner  # missionplan.planning.retask.retask_planner
    alert: Callable[[str], None]
    events: queue.SimpleQueue[FlightEvent]  # every follower's events (FlightEvents.new_queue, made before they start)
    silence: SilenceRule = field(default_factory=SilenceRule)  # when a silent drone is gone (--replan-after)
    time_scale: float | None = None
    handled: set[int] = field(default_factory=set)  # drones whose share was re-planned already
    retasks: list[dict[str, Any]] = field(default_factory=list)
    views: dict[int, DroneView] = field(init=False)  # what the events said of each drone

    def __post_init__(self) -> None:
        self.views = {f.sysid: DroneView(f.sysid) for f in self.flights}

    def _read_events(self) -> None:
        for event in drain(self.events):
            self.views[event.sysid].take(event)

    def look(self) -> None:
        self._read_events()
        now = time.monotonic()
        gone = [f for f in self.flights if f.sysid not in self.handled and self.views[f.sysid].gone(now, self.silence)]
        if not gone:
            return
        self.handled.update(f.sysid for f in gone)
        for f in gone:
            f.tell(ShareGivenAway())
        survivors = [f for f in self.flights if f not in gone and self.views[f.sysid].flying(now, self.silence)]
        names = ", ".join(f"uav{f.sysid}" for f in gone)
        if not survivors:
            self.alert(f"re-plan: {names} gone and no drone still flying its mission to take its share; "
                       "`missionplan replan` plans it after landing")
            return
        self._retask(gone, survivors)

    def _retask(self, gone: list[DroneFlight], survivors: list[DroneFlight]) -> None:
        """Hold the survivors where they are, plan from there, put the new missions on board (released
        together by the uploads); a refusal releases them to their old missions."""
        names = ", ".join(f"uav{f.sysid}" for f in gone)
        now = time.monotonic()
        lost_at = min(heard_at if (heard_at := self.views[f.sysid].heard_at) is not None else now for f in gone)
        entry: dict[str, Any] = {"gone": [f.sysid for f in gone], "survivors": [f.sysid for f in survivors],
                                 "why": {f.sysid: self.views[f.sysid].why_gone() for f in gone}}
        self.alert(f"re-plan: {names} gone; holding {', '.join(f'uav{f.sysid}' for f in survivors)} to plan what "
                   "is left from where they are")
        # Held first: planned from where they hover, the new tracks start where the plan says, together.
        held = self._all(survivors, lambda f: _actions(f).hold, HOLD_S + 5.0)
        failed = {k: v for k, v in held.items() if isinstance(v, str)}
        if failed:
            self._refused(survivors, entry, "could not hold " + "; ".join(f"uav{k}: {v}" for k, v in failed.items()))
            return
        self._read_events()  # the photos confirmed until now
        photos = confirmed_photos(list(self.views.values()))
        states = [self._survivor(f, held[f.sysid]) for f in survivors]
        planning = time.monotonic()
        try:
            plan = self.planner(self.plan_dir, self.record, states, photos)
        except RetaskPlanningError as err:  # the reason, for the crew
            self._refused(survivors, entry, str(err))
            return
        if plan is None:
            self._refused(survivors, entry, "every target is already photographed")
            return
        planned_at = time.monotonic()
        requests = {f.sysid: plan.request(f.sysid) for f in survivors}
        said = self._all(survivors, lambda f: (lambda: _actions(f).retask(requests[f.sysid])), RETASK_UPLOAD_S + 5.0)
        failed = {k: v for k, v in said.items() if not v.startswith("re-tasked")}
        # Released together: the new tracks start at one moment, as the separation check assumed. A survivor
        # whose upload failed keeps holding (ArduPilot may hold half of the new mission): the crew takes it.
        go = [f for f in survivors if f.sysid not in failed]
        released = self._all(go, lambda f: _actions(f).release, HOLD_S + 5.0)
        failed.update({k: f"not released: {v}" for k, v in released.items() if v is not None})
        for f in survivors:
            self.alert(f"uav{f.sysid}: {said[f.sysid]}" if f.sysid not in failed
                       else f"uav{f.sysid}: re-task failed: {said[f.sysid]}")
        in_air = time.monotonic()
        entry.update({"targets_left": plan.targets_left, "plan_s": round(planned_at - planning, 2),
                      "separation_m": plan.separation_m, "flight_s": {k: round(v, 1) for k, v in plan.flight_s.items()},
                      "loss_to_missions_s": round(in_air - lost_at, 2), "failed": failed,
                      "outcome": "re-tasked" if not failed else "re-tasked in part"})
        self.retasks.append(entry)
        self._note(survivors + gone, entry)
        self.alert(f"re-plan: {plan.targets_left} target cells left re-tasked to "
                   f"{len(survivors) - len(failed)} drones, {in_air - lost_at:.1f} s after {names} was last heard"
                   + (f"; not on {', '.join(f'uav{k}' for k in failed)}" if failed else ""))

    def _all(self, flights: list[DroneFlight], action: Callable[[DroneFlight], Callable[[], Any]],
             timeout_s: float) -> dict[int, Any]:
        """Run action(f)() in each drone's own thread at once; per drone its result, or why not (a str)."""
        asked = {f.sysid: f.ask(action(f)) for f in flights}
        until = time.monotonic() + timeout_s
        out: dict[int, Any] = {}
        for sysid, done in asked.items():
            try:
                out[sysid] = done.result(timeout=max(0.0, until - time.monotonic()))
            except FutureTimeout:
                out[sysid] = "no answer (its thread did not get to it: not heard?)"
            except Exception as err:  # noqa: BLE001 - BridgeError and the like: the reason
                out[sysid] = str(err)
        return out

    def _refused(self, survivors: list[DroneFlight], entry: dict[str, Any], why: str) -> None:
        """The re-task will not be flown: the held survivors go back to their missions, and it is said."""
        released = self._all(survivors, lambda f: _actions(f).release, HOLD_S + 5.0)
        stuck = {k: v for k, v in released.items() if v is not None}
        entry["outcome"] = f"not re-tasked: {why}"
        if stuck:
            entry["not_released"] = stuck
        self.retasks.append(entry)
        self._note(survivors, entry)
        self.alert(f"re-plan refused: {why}; the others fly on with their missions"
                   + (f" (NOT back in their mission mode: {stuck}; take them over)" if stuck else ""))

    def _survivor(self, f: DroneFlight, where: tuple[float, float, float]) -> Survivor:
        """What the planner needs of a survivor, held at `where`."""
        rec = f.record
        lat, lon, up = where
        home = read_mission_file(f.plan_path).mission.home
        rate = self.time_scale or (vehicle_rate(np.array(rec.samples)) if len(rec.samples) >= 10 else None) or 1.0
        flown = (time.time() - (rec.t_start or time.time())) * rate
        return Survivor(f.sysid, float(lat), float(lon), float(up),
                        (float(home[0]), float(home[1])) if home is not None else (float(lat), float(lon)), float(flown))

    def _note(self, flights: list[DroneFlight], entry: dict[str, Any]) -> None:
        text = "re-plan: " + ", ".join(f"{k} {v}" for k, v in entry.items())
        for f in flights:
            f.tell(RecordNote(text))  # written by its follower (follower_mail)
