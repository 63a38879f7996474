"""A drone's record is written by its follower's thread alone while it runs: what other threads have for
it waits in its mailbox (missionplan.flight.follower_mail) and is written when the follower takes it; once
the follower has ended, posts are written by their posters."""

from __future__ import annotations

import threading
from typing import Any

from missionplan.flight.events import ShareGivenAway
from missionplan.flight.fly import SeparationWatch
from missionplan.flight.follower_mail import Mailbox, RecordEvent, RecordNote, RecordProblem
from missionplan.flight.record import DroneRecord


def writers(rec: DroneRecord) -> list[tuple[str, str]]:
    """Give `rec` a sink that notes, per change, its kind and the thread that wrote it."""
    seen: list[tuple[str, str]] = []
    rec.sink = lambda kind, row: seen.append((kind, threading.current_thread().name))
    return seen


def test_posts_wait_for_the_follower_which_writes_them_in_its_own_thread() -> None:
    rec = DroneRecord(id=2)
    seen = writers(rec)
    box = Mailbox(rec)
    box.post(RecordEvent(10.0, "alert: uav1 and uav2: separation breach"))
    box.post(ShareGivenAway())
    box.post(RecordNote("re-plan: outcome re-tasked"))
    assert rec.events == [] and rec.notes == [] and seen == []  # nothing written by the poster

    orders: list[Any] = []
    follower = threading.Thread(target=lambda: orders.extend(box.take()), name="fly-uav2")
    follower.start()
    follower.join(5.0)
    assert orders == [ShareGivenAway()]
    assert rec.events == [(10.0, "alert: uav1 and uav2: separation breach")]
    assert rec.notes == ["re-plan: outcome re-tasked"]
    assert seen == [("event", "fly-uav2"), ("note", "fly-uav2")]
    assert box.take() == []  # taken once


def test_after_its_follower_ends_a_post_is_written_by_the_poster_and_an_order_is_dropped() -> None:
    rec = DroneRecord(id=3)
    seen = writers(rec)
    box = Mailbox(rec)
    box.post(RecordNote("waiting when the follower ended"))
    follower = threading.Thread(target=box.close, name="fly-uav3")
    follower.start()
    follower.join(5.0)
    assert box.closed and rec.notes == ["waiting when the follower ended"] and seen == [("note", "fly-uav3")]
    box.post(RecordProblem("uav3: not followed to the end"))
    box.post(ShareGivenAway())
    assert rec.problems == ["uav3: not followed to the end"]
    assert seen[-1] == ("problem", threading.current_thread().name)
    box.close()  # the main thread closing it again (a follower past its bound) changes nothing
    assert box.take() == [] and len(seen) == 2


def test_a_drone_without_a_follower_is_written_at_once() -> None:
    rec = DroneRecord(id=4)
    box = Mailbox(rec, followed=False)
    box.post(RecordEvent(1.0, "alert: disk full: journal writes paused"))
    assert rec.events == [(1.0, "alert: disk full: journal writes paused")]


def test_a_separation_breach_goes_to_both_followers_not_into_their_records() -> None:
    near = [DroneRecord(id=k, started=True) for k in (1, 2, 3)]
    for rec, east_m in zip(near, (0.0, 3.0, 200.0)):
        rec.samples.append((100.0, 45.0, 7.0 + east_m / 78_700.0, 30.0, 5.0, 10.0, 0.0))
    mail = {rec.id: Mailbox(rec) for rec in near}
    said: list[str] = []
    watch = SeparationWatch(near, 12.0, 1.0, said.append, mail)
    watch.look()
    assert len(said) == 1 and said[0].startswith("uav1 and uav2: separation breach, 3.0 m apart")
    assert all(rec.events == [] for rec in near)  # the main thread wrote no record
    for rec in near:
        mail[rec.id].take()
    assert [len(rec.events) for rec in near] == [1, 1, 0]
    assert near[0].events[0][1] == f"alert: {said[0]}"
    watch.look()
    assert len(said) == 1  # said once while they stay close
