"""The flight journal (missionplan/flight/journal.py): every change of a drone record is written as it
happens and read back as the same record; a killed process loses at most the last fraction of a second;
a resumed run continues the same flight."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    MissionType,
    WireItem,
)
from missionplan.flight.journal import COMMIT_S, Journal
from missionplan.flight.journal_db import JournalError
from missionplan.flight.journal_read import read_flight
from missionplan.flight.record import DroneRecord

ROOT = Path(__file__).resolve().parent.parent


def _wire() -> list[WireItem]:
    return [WireItem(0, FRAME_GLOBAL_RELATIVE_ALT, CMD_NAV_TAKEOFF, 1, 1, 0.0, 0.0, 0.0, math.nan, 454641000, 91891000,
                     20.0, MissionType.MISSION),
            WireItem(1, FRAME_GLOBAL_RELATIVE_ALT, CMD_NAV_WAYPOINT, 0, 1, 0.0, 0.06, 0.0, math.nan, 454642000,
                     91892000, 20.0, MissionType.MISSION)]


def _fill(rec: DroneRecord) -> None:
    rec.set(uploaded=True, flavour="ardupilot", wire=_wire(), params={"WPNAV_SPEED": 500.0}, started=True,
            t_start=100.0)
    for k in range(5):
        rec.add_sample((100.0 + k, 45.4641 + 1e-5 * k, 9.1891, 20.0, 5.0, 40.0 + k, 0.0))
    rec.add_photo(3, 101.5, 45.46412, 9.1891, 20.0)
    rec.add_photo(3, 101.6, 45.0, 9.0, 1.0)  # a repeated report: the first word stands
    rec.add_photo(4, 102.5, 45.46413, 9.1891, 20.0, source="log", attitude=(1.0, -2.0, 90.0))
    rec.add_reached(101.0, 1)
    rec.add_reached(101.2, 1)  # PX4 repeats: kept once
    rec.add_landed(104.0, 4)
    rec.add_event(104.0, "mode RTL")
    rec.add_problem("uav1: a problem")
    rec.add_note("a note")
    rec.set(current=1, mission_state=5, finished=True, t_end=104.5, ended_early="battery failsafe",
            last_position=[45.4641, 9.1891, 0.1, 104.5])


def _same(a: DroneRecord, b: DroneRecord) -> None:
    for name in ("id", "uploaded", "started", "finished", "flavour", "params", "t_start", "t_end", "current",
                 "mission_state", "samples", "camera", "photo_source", "attitude", "reached", "landed", "events",
                 "problems", "notes", "ended_early", "last_position"):
        assert getattr(a, name) == getattr(b, name), name
    assert [(w.seq, w.command, w.x, w.y, w.z) for w in a.wire] == [(w.seq, w.command, w.x, w.y, w.z) for w in b.wire]
    assert math.isnan(b.wire[0].param4)


def test_a_record_reads_back_as_it_was_kept(tmp_path: Path) -> None:
    journal = Journal.start_flight(tmp_path, sortie=1, command="fly test")
    kept = DroneRecord(id=1, sink=journal.sink(1))
    _fill(kept)
    back = journal.records([1, 2])
    _same(kept, back[0])
    assert back[1] == DroneRecord(id=2)  # a drone with nothing journaled: an empty record
    journal.close()
    flight, sortie, records = read_flight(tmp_path)
    assert (flight, sortie) == (1, 1)
    _same(kept, records[0])


def test_a_resumed_run_continues_the_same_flight(tmp_path: Path) -> None:
    first = Journal.start_flight(tmp_path, sortie=2, command="fly a")
    rec = DroneRecord(id=3, sink=first.sink(3))
    rec.set(started=True)
    rec.add_sample((1.0, 45.0, 9.0, 10.0, 5.0, 1.0, 0.0))
    first.flush()  # killed here: never closed
    second = Journal.continue_flight(tmp_path, command="fly --resume a")
    assert (second.flight, second.sortie) == (first.flight, 2)
    again = second.records([3])[0]
    again.sink = second.sink(3)
    again.add_sample((2.0, 45.0, 9.0, 10.0, 5.0, 2.0, 0.0))
    second.close()
    assert [s[0] for s in read_flight(tmp_path)[2][0].samples] == [1.0, 2.0]
    assert [(r["how"], r["ended"] is None) for r in Journal.continue_flight(tmp_path, "x").runs()] == \
        [("fly", True), ("resume", False), ("resume", True)]
    third = Journal.start_flight(tmp_path, sortie=1, command="fly b")  # a new flight starts empty
    assert third.flight == first.flight + 1 and third.records() == []
    third.close()
    # A run that started nothing (it found the fleet flying) is not what a resume continues.
    assert Journal.continue_flight(tmp_path, "fly --resume b").flight == first.flight


def test_nothing_to_resume_or_not_a_journal_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(JournalError, match="no flight to resume"):
        Journal.continue_flight(tmp_path, "fly --resume")
    (tmp_path / "journal.sqlite").write_bytes(b"this is not a database, it is far too plain a text" * 20)
    with pytest.raises(JournalError, match="not a missionplan flight journal"):
        Journal.continue_flight(tmp_path, "fly --resume")


CHILD = textwrap.dedent("""
    import os, signal, sys, time
    from pathlib import Path
    from missionplan.flight.journal import Journal
    from missionplan.flight.record import DroneRecord
    journal = Journal.start_flight(Path(sys.argv[1]), 1, "child")
    rec = DroneRecord(id=1, sink=journal.sink(1))
    start = time.time()
    while time.time() - start < 1.5:
        now = time.time()
        rec.add_sample((now, 45.0, 9.0, 10.0, 5.0, now - start, 0.0))
        deadline = now + 0.005
        while time.time() < deadline:
            pass
    print(repr(time.time()), flush=True)
    os.kill(os.getpid(), signal.SIGKILL)
""")


def test_a_killed_process_loses_at_most_the_last_commit_interval(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path)], capture_output=True, text=True, timeout=60,
                          cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == -signal.SIGKILL, done.stderr
    killed_at = float(done.stdout.strip())
    samples = read_flight(tmp_path)[2][0].samples
    assert len(samples) > 50
    # What was handed over up to COMMIT_S (plus the writer's scheduling) before the kill is on disk.
    assert killed_at - samples[-1][0] <= COMMIT_S + 0.25, (killed_at, samples[-1][0])
    assert [s[0] for s in samples] == sorted(s[0] for s in samples)


def test_a_journal_from_before_the_amsl_column_is_read_and_extended(tmp_path: Path) -> None:
    """A plan folder flown by an older missionplan: its photos table lacks `amsl`; the journal adds the
    column, the old photos read back without it, new ones keep it."""
    import sqlite3

    db = sqlite3.connect(tmp_path / "journal.sqlite")
    db.executescript("""
        CREATE TABLE flights (flight INTEGER PRIMARY KEY, sortie INTEGER NOT NULL, started REAL NOT NULL, judged REAL);
        CREATE TABLE photos (flight INTEGER NOT NULL, drone INTEGER NOT NULL, idx INTEGER NOT NULL, t REAL,
                             lat REAL, lon REAL, up REAL, source TEXT NOT NULL, roll REAL, pitch REAL, yaw REAL);
        INSERT INTO flights VALUES (1, 1, 0.0, NULL);
        INSERT INTO photos VALUES (1, 1, 1, 10.0, 45.0, 9.0, 20.0, 'camera', NULL, NULL, NULL);
    """)
    db.commit()
    db.close()
    _, _, (old,) = read_flight(tmp_path)
    assert old.camera == {1: (10.0, 45.0, 9.0, 20.0)} and old.amsl == {}
    journal = Journal.start_flight(tmp_path, 1, "test")
    rec = DroneRecord(id=1, sink=journal.sink(1))
    rec.add_photo(1, 11.0, 45.1, 9.1, 20.0, attitude=(1.0, 2.0, 3.0), amsl=140.5)
    journal.close()
    _, _, (new,) = read_flight(tmp_path)
    assert new.amsl == {1: 140.5} and new.attitude == {1: (1.0, 2.0, 3.0)}
