"""The flight loop's events and its one decision of what a silence means, without threads: events in,
decisions out (missionplan/flight/events.py, link_silence.py, fleet_view.py, event_journal.py, and the
re-tasker's choice of who is gone and who takes over, live_replan.Retasker)."""

from __future__ import annotations

import queue
import threading
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import pytest

from missionplan.bridge.errors import BridgeError
from missionplan.flight.event_journal import EventJournal
from missionplan.flight.events import (ArmingChanged, EndedEarly, Finished, FlightEvent, FlightEvents,
                                       FollowingStopped, LeftMission, LinkBack, LinkLost, LinkQuiet, MissionStarted,
                                       ModeChanged, PhotoTaken, SentHome, ShareGivenAway, VehicleSaid, drain)
from missionplan.flight.fleet_view import DroneView, confirmed_photos
from missionplan.flight.follower_mail import RecordNote
from missionplan.flight.link_silence import (GONE_SILENT_S, LINK_LOST_S, MIN_WALL_S, UPLOAD_HEARD_S, LinkWatch,
                                             SilenceOver, SilenceRule, SilenceStep, give_up_at)
from missionplan.flight.live_replan import Retasker
from missionplan.flight.record import DroneRecord


def test_each_meaning_of_a_silence_has_its_own_threshold() -> None:
    rule = SilenceRule()
    assert (UPLOAD_HEARD_S, LINK_LOST_S, GONE_SILENT_S) == (2.0, 5.0, 15.0)
    assert rule.takes_uploads(2.0) and not rule.takes_uploads(2.01)
    assert not rule.link_lost(5.0) and rule.link_lost(5.01)
    assert not rule.gone(15.0) and rule.gone(15.01)
    assert SilenceRule(3.0).gone(3.01) and not SilenceRule(3.0).link_lost(3.01)  # fly --replan-after 3
    assert rule.matters_after_s == 2.0 and SilenceRule(1.0).matters_after_s == 1.0


def test_a_watched_link_is_quiet_then_lost_then_back_each_said_once() -> None:
    watch = LinkWatch(SilenceRule(), heard_at=100.0)
    assert watch.look(101.9) == []
    assert watch.look(102.1) == [SilenceStep.MATTERS]
    assert watch.look(104.0) == []  # said once
    assert watch.look(105.1) == [SilenceStep.LOST] and watch.lost_since == 100.0
    assert watch.look(130.0) == []
    assert watch.heard(131.0) == SilenceOver(silent_s=31.0, was_lost=True)
    assert watch.lost_since is None and watch.look(132.0) == []
    assert watch.look(133.5) == [SilenceStep.MATTERS]
    assert watch.heard(134.0) == SilenceOver(silent_s=3.0, was_lost=False)  # quiet, never lost
    assert watch.heard(134.5) is None  # heard lately: no silence ended


def test_a_short_replan_after_makes_a_silence_matter_sooner() -> None:
    watch = LinkWatch(SilenceRule(1.0), heard_at=0.0)
    assert watch.look(1.05) == [SilenceStep.MATTERS]  # the re-tasker must time it from 1 s, not 2


def test_silences_in_vehicle_time_scale_every_threshold_down_to_a_floor() -> None:
    rule = SilenceRule(vehicle_scale=10.0)  # a simulator at 10x: 15 vehicle s gone, 5 lost, 2 to take an upload
    assert rule.gone(1.51) and not rule.gone(1.49)
    assert rule.link_lost(0.51) and not rule.link_lost(0.49)
    assert rule.takes_uploads(0.49) and not rule.takes_uploads(0.51)  # 0.2 s, floored at MIN_WALL_S
    assert rule.matters_after_s == MIN_WALL_S
    calm = SilenceRule()  # fly's own: our seconds
    assert calm.takes_uploads(1.9) and not calm.link_lost(4.9) and calm.gone(15.1)


def test_a_silent_vehicle_is_given_up_when_its_mission_would_be_long_over() -> None:
    # 100 vehicle seconds planned, at 2 vehicle seconds per ours, started 40 s ago: (150 + 60) / 2 - 40 = 65 s left
    assert give_up_at(100.0, 2.0, 40.0, now=1000.0, deadline=5000.0) == pytest.approx(1065.0)
    assert give_up_at(100.0, 2.0, 200.0, now=1000.0, deadline=5000.0) == pytest.approx(905.0)  # already past
    assert give_up_at(100.0, 1.0, 0.0, now=1000.0, deadline=1100.0) == 1100.0


def _started(sysid: int = 1) -> DroneView:
    view = DroneView(sysid)
    for event in (MissionStarted(sysid, 0.0), ModeChanged(sysid, 0.0, "AUTO", True), ArmingChanged(sysid, 0.0, True)):
        view.take(event)
    return view


def test_a_silent_drone_is_gone_after_the_replan_wait_and_takes_no_upload_after_two_seconds() -> None:
    rule = SilenceRule()
    view = _started()
    assert view.flying(50.0, rule) and not view.gone(50.0, rule)
    view.take(LinkQuiet(1, 0.0, heard_at=40.0))
    assert view.flying(42.0, rule) and not view.flying(42.1, rule)
    assert not view.gone(55.0, rule) and view.gone(55.1, rule) and view.why_gone() == "not heard"
    view.take(LinkLost(1, 0.0, 40.0, 3, 9, None))
    assert view.silent_since == 40.0  # the silence began when it was last heard, not when it counted as lost
    view.take(LinkBack(1, 0.0, 20.0, True, 3, 9))
    assert view.flying(100.0, rule) and not view.gone(100.0, rule)


def test_a_drone_is_gone_when_it_ends_early_or_leaves_for_a_return_and_never_once_finished() -> None:
    rule = SilenceRule()
    landed = _started()
    landed.take(EndedEarly(1, 0.0, "Battery failsafe (at item 4 of 9)", heard_at=7.0))
    assert landed.gone(8.0, rule) and not landed.flying(8.0, rule)
    assert landed.why_gone() == "Battery failsafe (at item 4 of 9)" and landed.heard_at == 7.0
    returning = _started()
    returning.take(ModeChanged(1, 0.0, "RTL", False))
    returning.take(LeftMission(1, 0.0, "RTL", 5.0, 4, 9))
    assert returning.gone(6.0, rule) and returning.why_gone() == "switched to RTL"
    loitering = _started()
    loitering.take(ModeChanged(1, 0.0, "LOITER", False))
    loitering.take(LeftMission(1, 0.0, "LOITER", 5.0, 4, 9))
    assert not loitering.gone(6.0, rule) and not loitering.flying(6.0, rule)  # a pilot's mode: neither
    done = _started()
    done.take(Finished(1, 0.0))
    done.take(FollowingStopped(1, 0.0, heard_at=1.0))
    assert not done.gone(100.0, rule) and not done.flying(100.0, rule)
    never = DroneView(1)
    never.take(FollowingStopped(1, 0.0, heard_at=1.0))
    assert not never.gone(100.0, rule)  # never started: nothing of its mission to give away


def test_a_follower_that_stopped_hearing_its_drone_counts_as_silent_from_then() -> None:
    view = _started()
    view.take(FollowingStopped(1, 0.0, heard_at=10.0))  # it rebooted in flight, say
    assert not view.gone(25.0, SilenceRule()) and view.gone(25.1, SilenceRule())


def test_photos_are_counted_once_each_the_first_word_standing() -> None:
    a, b = DroneView(1), DroneView(2)
    a.take(PhotoTaken(1, 1.0, 0, 45.0, 7.0, 30.0))
    a.take(PhotoTaken(1, 2.0, 0, 46.0, 8.0, 30.0, source="log"))
    b.take(PhotoTaken(2, 1.0, 0, 45.5, 7.5, 30.0))
    assert confirmed_photos([a, b]).tolist() == [[45.0, 7.0], [45.5, 7.5]]
    assert confirmed_photos([]).shape == (0, 2)


def test_events_reach_every_consumer_in_order_in_the_publishing_thread_and_every_queue() -> None:
    events = FlightEvents()
    seen: list[tuple[str, FlightEvent, str]] = []
    events.subscribe(lambda e: seen.append(("first", e, threading.current_thread().name)))
    events.subscribe(lambda e: seen.append(("second", e, threading.current_thread().name)))
    waiting = events.new_queue()
    published = [MissionStarted(1, 1.0), LinkQuiet(1, 2.0, 3.0)]
    follower = threading.Thread(target=lambda: [events.publish(e) for e in published], name="fly-uav1")
    follower.start()
    follower.join(5.0)
    assert [(who, e) for who, e, _ in seen] == [("first", published[0]), ("second", published[0]),
                                               ("first", published[1]), ("second", published[1])]
    assert {thread for _, _, thread in seen} == {"fly-uav1"}
    assert drain(waiting) == published and drain(waiting) == []


def test_the_journal_writes_each_event_into_its_own_drones_record_and_says_what_a_crew_must_hear() -> None:
    records = {1: DroneRecord(id=1), 2: DroneRecord(id=2)}
    said: list[str] = []
    journal = EventJournal(records, said.append)
    journal(MissionStarted(1, 100.0))
    journal(ModeChanged(1, 101.0, "AUTO", True))
    journal(VehicleSaid(1, 102.0, "PreArm: all good", False))
    journal(VehicleSaid(1, 103.0, "Battery failsafe", True))
    journal(PhotoTaken(1, 104.0, 3, 45.0, 7.0, 30.0, attitude=(1.0, 2.0, 3.0), amsl_m=270.0))
    journal(LinkLost(1, 105.0, 50.0, 4, 9, (45.0, 7.0, 30.0)))
    journal(LinkBack(1, 106.0, 6.25, True, 4, 9))
    journal(LinkBack(1, 107.0, 2.5, False, 4, 9))  # quiet, never lost: nothing said
    journal(EndedEarly(1, 108.0, "Battery failsafe (at item 4 of 9)", 60.0))
    journal(SentHome(2, 109.0, False, None))
    rec = records[1]
    assert rec.started and rec.t_start == 100.0 and rec.ended_early == "Battery failsafe (at item 4 of 9)"
    assert rec.t_end == 108.0 and rec.camera[3] == (104.0, 45.0, 7.0, 30.0) and rec.amsl[3] == 270.0
    assert [text for _, text in rec.events] == [
        "mode AUTO", "says: PreArm: all good", "says: Battery failsafe", "alert: says: Battery failsafe",
        "alert: link lost: nothing heard for 5 s at item 4 of 9, last at 45.000000, 7.000000, 30.0 m up; still "
        "waiting for it", "alert: link back after 6.2 s, at item 4 of 9",
        "alert: landed and disarmed before the end of its mission: Battery failsafe (at item 4 of 9)"]
    assert rec.problems == ["uav1: ended its mission early: Battery failsafe (at item 4 of 9)"]
    assert said[-1] == ("uav2: heard again after its share was re-tasked: RTL not acknowledged; bring it home by "
                        "hand")
    assert len(said) == 5 and records[2].events[0][1].startswith("alert: heard again")


class _Follower:
    """What the re-tasker asks of a drone's follower, answered at once (no thread)."""

    def __init__(self, sysid: int, hold_fails: str = "") -> None:
        self.sysid, self.record, self.plan_path = sysid, DroneRecord(id=sysid), Path("unused")
        self.told: list[Any] = []
        self.asked: list[str] = []
        self.retasking = self
        self.hold_fails = hold_fails

    def tell(self, message: Any) -> None:
        self.told.append(message)

    def ask(self, action: Any) -> Future[Any]:
        done: Future[Any] = Future()
        try:
            done.set_result(action())
        except BridgeError as err:
            done.set_exception(err)
        return done

    def hold(self) -> tuple[float, float, float]:
        self.asked.append("hold")
        if self.hold_fails:
            raise BridgeError(self.hold_fails)
        return 45.0, 7.0, 30.0

    def release(self) -> None:
        self.asked.append("release")


def _retasker(flights: list[_Follower], events: queue.SimpleQueue[FlightEvent], said: list[str]) -> Retasker:
    def planner(*args: Any) -> None:
        raise AssertionError("not planned: the hold failed")

    return Retasker(Path("unused"), {}, flights, planner, said.append, events,  # type: ignore[arg-type]
                    SilenceRule(3.0))


def test_the_retasker_decides_from_events_alone_who_is_gone_and_who_takes_over() -> None:
    events = FlightEvents()
    waiting = events.new_queue()
    flights = [_Follower(1, hold_fails="GUIDED refused"), _Follower(2), _Follower(3)]
    said: list[str] = []
    retasker = _retasker(flights, waiting, said)
    for sysid in (1, 2, 3):
        for event in (MissionStarted(sysid, 0.0), ModeChanged(sysid, 0.0, "AUTO", True)):
            events.publish(event)
    retasker.look()
    assert said == [] and all(not f.told for f in flights)
    now = time.monotonic()
    events.publish(LinkQuiet(2, 0.0, heard_at=now - 3.5))  # silent past --replan-after 3
    events.publish(LinkQuiet(3, 0.0, heard_at=now - 2.5))  # quiet: neither gone nor able to take an upload
    retasker.look()
    assert flights[1].told == [ShareGivenAway()] and flights[2].told == []
    # The refused re-task's note goes to the survivor's follower, which writes it into its record.
    assert [type(m) for m in flights[0].told] == [RecordNote] and flights[0].record.notes == []
    assert flights[0].told[0].text.startswith("re-plan: gone [2], survivors [1]")
    assert retasker.handled == {2}
    assert said[0] == "re-plan: uav2 gone; holding uav1 to plan what is left from where they are"
    assert flights[0].asked == ["hold", "release"] and flights[2].asked == []  # refused: released again
    assert said[-1].startswith("re-plan refused: could not hold uav1: GUIDED refused")
    assert retasker.retasks[0]["why"] == {2: "not heard"} and retasker.retasks[0]["survivors"] == [1]
    retasker.look()
    assert flights[1].told == [ShareGivenAway()]  # handled once
