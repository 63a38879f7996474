"""The flight journal on a disk that does not play along (missionplan/flight/journal.py, salvage.py):
a full disk pauses it and loses nothing, a damaged file is salvaged row by row (checked against the
sqlite3 shell's own .dump), a read-only one is refused in one line, a -wal file lost after a kill is
proven, and a vehicle fly was about to arm is found by a resume even when its start was never written."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from small_disk import read_only, small_disk

from missionplan.flight.journal import Journal, write_fallback
from missionplan.flight.journal_db import COUNTER_NAME, JOURNAL_NAME, JournalError
from missionplan.flight.journal_read import read_flight
from missionplan.flight.record import DroneRecord
from missionplan.testing.loopback import wait_until

ROOT = Path(__file__).resolve().parent.parent


def _sample(k: int) -> tuple[float, float, float, float, float, float, float]:
    return (1000.0 + k * 0.04, 45.4784 + k * 1e-6, 9.2270 + k * 1e-6, 20.0, 5.0, k * 0.04, 0.0)


def _hashes(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def test_a_full_disk_pauses_the_journal_says_so_once_and_every_record_is_written_when_space_returns(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with small_disk(tmp_path / "disk", 2048, monkeypatch) as disk:
        journal = Journal.start_flight(disk.path, 1, "fly test")
        said: list[str] = []
        journal.set_alert(said.append)
        rec = DroneRecord(id=1, sink=journal.sink(1))
        for k in range(50):
            rec.add_sample(_sample(k))
        assert journal.flush()
        disk.fill()
        for k in range(50, 3000):  # never raises: the sinks hand over, the journal holds
            rec.add_sample(_sample(k))
        rec.add_event(1200.0, "mode AUTO")
        assert wait_until(lambda: len(said) == 1, 10.0), said
        assert re.fullmatch(r"disk full: journal writes paused, \d+ records held in memory \(database or disk is "
                            r"full\); trying again every 1 s", said[0]), said
        assert not journal.flush() and journal.paused is not None
        for k in range(3000, 3100):
            rec.add_sample(_sample(k))
        assert len(said) == 1  # one alert for the pause, however long it lasts
        disk.free()
        assert journal.flush(through_pause_s=5.0)
        assert wait_until(lambda: len(said) == 2, 5.0), said  # said once the held records are committed
        assert re.fullmatch(r"journal writes resumed: \d+ records written", said[1]), said
        journal.close()
        assert journal.unwritten == []
        back = read_flight(disk.path)[2][0]
        assert [s[0] for s in back.samples] == [_sample(k)[0] for k in range(3100)]
        assert back.events == [(1200.0, "mode AUTO")]


def test_a_journal_still_paused_when_it_closes_leaves_its_records_to_the_fallback_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "elsewhere"))
    (tmp_path / "elsewhere").mkdir()
    with small_disk(tmp_path / "disk", 2048, monkeypatch) as disk:
        journal = Journal.start_flight(disk.path, 1, "fly test")
        rec = DroneRecord(id=2, sink=journal.sink(2))
        rec.add_sample(_sample(0))
        assert journal.flush()
        disk.fill()
        for k in range(1, 400):
            rec.add_sample(_sample(k))
        rec.add_photo(7, 1010.0, 45.47, 9.22, 20.0, attitude=(1.0, 2.0, 3.0), amsl=140.0)
        journal.close()  # the final try fails too
        assert len(journal.unwritten) == 400
        path = write_fallback(journal, {"coverage": 12.5}, "disk full")
        assert path.parent == tmp_path / "elsewhere"
        doc = json.loads(path.read_text())
        assert doc["flight"] == journal.flight and doc["flight_json"] == {"coverage": 12.5}
        rows = doc["journal_rows"]
        assert [r["row"][0] for r in rows if r["kind"] == "sample"] == [_sample(k)[0] for k in range(1, 400)]
        assert [r for r in rows if r["kind"] == "photo"] == [
            {"kind": "photo", "drone": 2, "row": [7, 1010.0, 45.47, 9.22, 20.0, "camera", 1.0, 2.0, 3.0, 140.0,
                                                 None]}]
        disk.free()


# ------------------------------------------------------------------------------------------- damage
def _journal_of_one_flight(folder: Path, samples: int = 20000) -> None:
    """A journal whose entries come first and whose samples fill the rest of the file."""
    journal = Journal.start_flight(folder, 1, "fly test")
    rec = DroneRecord(id=1, sink=journal.sink(1))
    rec.set(uploaded=True, started=True, t_start=1000.0)
    for k in range(100):
        rec.add_event(1000.0 + k, f"mode AUTO {k}")
    assert journal.flush()
    for k in range(samples):
        rec.add_sample(_sample(k))
    journal.close()


def _page_of_sample(path: Path, k: int) -> int:
    """The offset of the page of journal.sqlite that holds sample k (found by its latitude, a float SQLite
    stores big-endian): a page of the samples table, to damage."""
    import struct

    data = path.read_bytes()
    at = data.index(struct.pack(">d", _sample(k)[1]))
    return at - at % 4096


def _dumped_latitudes(path: Path) -> set[float]:
    """The latitudes of the sample rows the sqlite3 shell's .dump gets out of a damaged file that are real
    samples (it also prints rows of a damaged page as garbage): an independent view of what is readable."""
    truth = {_sample(k)[1] for k in range(20000)}
    out = subprocess.run(["sqlite3", str(path), ".dump"], capture_output=True, text=True, timeout=60).stdout
    rows = [line[len("INSERT INTO samples VALUES("):].split(",") for line in out.splitlines()
            if line.startswith("INSERT INTO samples VALUES(")]
    return {lat for row in rows if row[3] != "NULL" and (lat := float(row[3])) in truth}


@pytest.mark.parametrize("damage", ["overwritten", "truncated"])
def test_a_damaged_journal_is_salvaged_row_by_row_in_one_line(tmp_path: Path, damage: str) -> None:
    if shutil.which("sqlite3") is None:
        pytest.skip("the sqlite3 shell (apt-get install sqlite3) is the independent check; CI installs it")
    _journal_of_one_flight(tmp_path)
    path = tmp_path / JOURNAL_NAME
    size = path.stat().st_size
    with open(path, "r+b") as f:
        if damage == "overwritten":  # a page of samples in the middle of the table
            f.seek(_page_of_sample(path, 10000))
            f.write(b"\xa5" * 4096)
        else:
            f.truncate(size * 2 // 3)
    copy = tmp_path / "copy.sqlite"
    shutil.copy(path, copy)
    dumped = _dumped_latitudes(copy)
    journal = Journal.continue_flight(tmp_path, "fly --resume")
    journal.close()
    (line,) = journal.repairs
    assert line.startswith(f"{path}: damaged (") and "kept as journal.sqlite.damaged" in line, line
    assert "\n" not in line and "lost: " in line and "samples" in line.split("lost: ")[1], line
    recovered = read_flight(tmp_path)[2][0]
    # Every real sample the shell's .dump reads we read too; nothing made up.
    assert dumped <= {s[1] for s in recovered.samples} and len(recovered.samples) < 20000, len(dumped)
    assert set(recovered.samples) <= {_sample(k) for k in range(20000)}
    assert f"{len(recovered.samples):,} samples" in line
    assert recovered.started and recovered.t_start == 1000.0
    assert (tmp_path / "journal.sqlite.damaged").read_bytes()[:100] == copy.read_bytes()[:100]
    assert sqlite3.connect(path).execute("PRAGMA quick_check").fetchone() == ("ok",)


def test_a_journal_that_is_no_database_or_lost_its_flights_is_refused_in_one_line(tmp_path: Path) -> None:
    _journal_of_one_flight(tmp_path, samples=100)
    path = tmp_path / JOURNAL_NAME
    with open(path, "r+b") as f:  # its first page: the schema
        f.seek(100)
        f.write(b"\xa5" * 3996)
    with pytest.raises(JournalError, match=r"damaged beyond repair .*kept as journal.sqlite.damaged"):
        Journal.continue_flight(tmp_path, "fly --resume")
    assert not path.exists() and (tmp_path / "journal.sqlite.damaged").exists()


def test_a_read_only_journal_cannot_be_continued_and_is_left_as_it_was(tmp_path: Path) -> None:
    folder = tmp_path / "plan"
    folder.mkdir()
    _journal_of_one_flight(folder, samples=100)
    before = _hashes(folder)
    with read_only(folder):
        with pytest.raises(JournalError) as raised:
            Journal.continue_flight(folder, "fly --resume")
        # A reader still reads it (status, a rebuilt ledger), writing nothing.
        assert len(read_flight(folder)[2][0].samples) == 100
    text = str(raised.value)
    assert text.startswith(f"{folder / JOURNAL_NAME}: read-only (") and "cannot be written here" in text, text
    assert _hashes(folder) == before


# ------------------------------------------------------------------------------------------- a lost -wal file
WRITER = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from missionplan.flight.journal import Journal
    from missionplan.flight.record import DroneRecord
    journal = Journal.start_flight(Path(sys.argv[1]), 1, "fly child")
    rec = DroneRecord(id=1, sink=journal.sink(1))
    rec.set(uploaded=True, arming=1000.0, started=True, t_start=1000.0)
    for k in range(int(sys.argv[2])):
        rec.add_sample((1000.0 + k, 45.0, 9.0, 20.0, 5.0, float(k), 0.0))
        if k % 50 == 0:
            journal.flush()
    journal.flush()
    os.kill(os.getpid(), signal.SIGKILL)
""")


def _killed_writer(folder: Path, samples: int) -> None:
    done = subprocess.run([sys.executable, "-c", WRITER, str(folder), str(samples)], capture_output=True, text=True,
                          timeout=120, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == -signal.SIGKILL, done.stderr
    assert (folder / (JOURNAL_NAME + "-wal")).exists()


def test_a_journal_whose_wal_file_was_lost_after_a_kill_says_it_was_cut(tmp_path: Path) -> None:
    _killed_writer(tmp_path, 500)
    (tmp_path / (JOURNAL_NAME + "-wal")).unlink()
    with pytest.raises(JournalError) as raised:
        Journal.continue_flight(tmp_path, "fly --resume")
    text = str(raised.value)
    assert "the journal was cut: run 1 of fly" in text and "no run of fly started a vehicle" not in text, text
    assert re.search(r"committed (\d+) transactions and the file holds 0 of them", text), text
    assert "journal.sqlite-wal) was lost" in text and "\n" not in text


def test_a_clean_close_after_a_kill_is_no_cut(tmp_path: Path) -> None:
    """`status` or any reader opening and closing the journal after the kill copies the -wal into it and
    deletes it, as SQLite does: the counts agree and the flight resumes."""
    _killed_writer(tmp_path, 500)
    reader = sqlite3.connect(tmp_path / JOURNAL_NAME)
    assert reader.execute("SELECT COUNT(*) FROM samples").fetchone() == (500,)
    reader.close()
    assert not (tmp_path / (JOURNAL_NAME + "-wal")).exists() and (tmp_path / COUNTER_NAME).exists()
    journal = Journal.continue_flight(tmp_path, "fly --resume")
    journal.close()
    assert journal.repairs == [] and len(read_flight(tmp_path)[2][0].samples) == 500


def test_a_vehicle_fly_was_about_to_arm_is_resumed_though_its_start_was_never_written(tmp_path: Path) -> None:
    journal = Journal.start_flight(tmp_path, 1, "fly")
    rec = DroneRecord(id=1, sink=journal.sink(1))
    rec.set(uploaded=True, arming=1000.0)  # killed after the arm command: `started` never came
    assert journal.flush()
    other = Journal.start_flight(tmp_path, 1, "fly (found the fleet flying)")  # a later flight that started nothing
    other.close()
    resumed = Journal.continue_flight(tmp_path, "fly --resume")
    assert resumed.flight == journal.flight and resumed.records([1])[0].arming == 1000.0
    resumed.close()
    journal.close()


def test_a_journal_from_before_the_counter_and_the_commits_column_is_continued(tmp_path: Path) -> None:
    db = sqlite3.connect(tmp_path / JOURNAL_NAME)
    db.executescript("""
        CREATE TABLE flights (flight INTEGER PRIMARY KEY, sortie INTEGER NOT NULL, started REAL NOT NULL, judged REAL);
        CREATE TABLE runs (run INTEGER PRIMARY KEY, flight INTEGER NOT NULL, started REAL NOT NULL, ended REAL,
                           how TEXT NOT NULL, command TEXT NOT NULL);
        CREATE TABLE entries (flight INTEGER NOT NULL, drone INTEGER NOT NULL, kind TEXT NOT NULL, row TEXT NOT NULL);
        INSERT INTO flights VALUES (1, 1, 0.0, NULL);
        INSERT INTO runs VALUES (1, 1, 0.0, NULL, 'fly', 'fly x');
        INSERT INTO entries VALUES (1, 1, 'fact', '["started", true]');
    """)
    db.commit()
    db.close()
    journal = Journal.continue_flight(tmp_path, "fly --resume")
    assert journal.flight == 1 and journal.repairs == []
    journal.close()
    assert [r["how"] for r in Journal.continue_flight(tmp_path, "x").runs()] == ["fly", "resume", "resume"]
