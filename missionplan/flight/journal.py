"""The flight journal: everything `fly` learns about a flight, written as it happens, in DIR/journal.sqlite.

One SQLite database per plan folder, in WAL mode with synchronous=FULL: a committed transaction
survives the process being killed and the machine losing power. One writer thread takes the drones'
changes (record.DroneRecord's sink) from a queue and commits at least every COMMIT_S, so SIGKILL, a
power cut, Ctrl-C or an exception lose at most that much. Readers (flight.json, `fly --resume`) open
it beside a running writer.

A *flight* is one `fly DIR` (one sortie flown once) with the `fly --resume DIR` runs that continue it;
a *run* is one process. Tables:
  flights(flight, sortie, started, judged, photos_from_track)   judged: when a run last wrote flight.json
                                             from it; photos_from_track: judged with --photos-from-track
  runs(run, flight, started, ended, how, command, commits)   how: "fly" or "resume"; ended NULL: it was
                                             killed; commits: the transactions it committed
  entries(flight, drone, kind, row)          every change of a DroneRecord, in order; row as JSON
  samples(flight, drone, t, lat, lon, up, speed, boot_s, climb)   the positions, the bulk, in columns
  photos(flight, drone, idx, t, lat, lon, up, source, roll, pitch, yaw, amsl)
Entries are replayed through DroneRecord.replay, so the record read back is the record that was kept.

When the disk does not play along:
- a write that fails (a full disk, an I/O error, a quota, a read-only remount) pauses the journal: the
  sinks go on taking changes, held in memory, the writer says so once (`set_alert`) and tries again
  every RETRY_S; once a write goes through, everything held is written and it says so. Nothing handed
  to a sink is dropped: what is still held when the journal closes is `unwritten`, for the caller's
  fallback file (write_fallback);
- DIR/journal.commits, beside the database and outside SQLite's files, counts the transactions the
  running run committed. A run killed and its -wal file lost afterwards leaves a database holding fewer
  of that run's commits than the counter says: the journal was cut, and opening it says so. A clean
  close of the database by anyone copies the -wal into it first, so the counts then agree;
- a damaged database (bytes overwritten, the file cut short) is moved aside to journal.sqlite.damaged
  and what SQLite can still read of it is copied, row by row (salvage.py), into a new journal, saying
  what was recovered and what was lost; a read-only one cannot be continued, said in one line.
"""

from __future__ import annotations

import json
import math
import os
import queue
import sqlite3
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from missionplan.base.atomic import write_text_atomic
from missionplan.bridge.formats.mission_items import WireItem

from .record import PHOTO_SOURCES, DroneRecord, Sink
from .salvage import (TableSalvage, connect_read_only, fault_kind, has_sqlite_header, integrity_problem, move_aside,
                      salvage_table, table_columns)

JOURNAL_NAME = "journal.sqlite"
COUNTER_NAME = "journal.commits"
COMMIT_S = 0.25  # the most a crash can lose
RETRY_S = 1.0  # a paused journal tries to write again this often
CLOSE_S = 30.0  # at most this long for the last writes when the journal closes
SCHEMA = """
CREATE TABLE IF NOT EXISTS flights (flight INTEGER PRIMARY KEY, sortie INTEGER NOT NULL, started REAL NOT NULL,
                                    judged REAL, photos_from_track INTEGER);
CREATE TABLE IF NOT EXISTS runs (run INTEGER PRIMARY KEY, flight INTEGER NOT NULL, started REAL NOT NULL,
                                 ended REAL, how TEXT NOT NULL, command TEXT NOT NULL,
                                 commits INTEGER NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS entries (flight INTEGER NOT NULL, drone INTEGER NOT NULL, kind TEXT NOT NULL,
                                    row TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS samples (flight INTEGER NOT NULL, drone INTEGER NOT NULL, t REAL, lat REAL, lon REAL,
                                    up REAL, speed REAL, boot_s REAL, climb REAL);
CREATE TABLE IF NOT EXISTS photos (flight INTEGER NOT NULL, drone INTEGER NOT NULL, idx INTEGER NOT NULL, t REAL,
                                   lat REAL, lon REAL, up REAL, source TEXT NOT NULL, roll REAL, pitch REAL,
                                   yaw REAL, amsl REAL);
CREATE INDEX IF NOT EXISTS entries_by_drone ON entries (flight, drone);
CREATE INDEX IF NOT EXISTS samples_by_drone ON samples (flight, drone);
CREATE INDEX IF NOT EXISTS photos_by_drone ON photos (flight, drone);
"""
# Columns added since the first journals: (table, column, its declaration). Added when an older journal is
# opened for writing; readers select NULL for them.
ADDED_COLUMNS = (("photos", "amsl", "REAL"), ("runs", "commits", "INTEGER NOT NULL DEFAULT 0"),
                 ("flights", "photos_from_track", "INTEGER"))
TABLES = ("flights", "runs", "entries", "samples", "photos")
ENTRY_KINDS = ("fact", "event", "reached", "landed", "problem", "note")
# A flight a resume can continue: a vehicle was started, or fly was about to arm one (its `arming` fact
# is committed before the arm command is sent, drone_flight.DroneFlight._arm).
RESUMABLE = ("started", "arming")
Item = tuple[str, tuple[Any, ...]]  # (kind, (drone, *row)) from a sink, or ("sql", (statement, args)) of our own


class JournalError(Exception):
    """A journal that cannot be used as asked (none to resume, not ours, damaged beyond repair, read-only):
    one line for the user."""


# ------------------------------------------------------------------------------------------- the commit counter
class CommitCounter:
    """DIR/journal.commits: `run R commits N`, rewritten in place after each commit of run R. Kept outside
    SQLite's files so that losing the -wal file does not lose it too; one pwrite of a fixed-size line a
    commit (no fsync: it must outlive the process, which the page cache does)."""

    LINE = "run {run:>12} commits {commits:>12}\n"

    def __init__(self, plan_dir: Path, run: int, commits: int) -> None:
        self.run = run
        self._fd: int | None
        try:
            self._fd = os.open(Path(plan_dir) / COUNTER_NAME, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o666)
        except OSError:
            self._fd = None  # no counter, no proof of a lost -wal file: the journal itself is unaffected
        self.set(commits)

    def set(self, commits: int) -> None:
        if self._fd is None:
            return
        try:
            os.pwrite(self._fd, self.LINE.format(run=self.run, commits=commits).encode(), 0)
        except OSError:
            pass  # overwriting a line already on disk needs no new space; an odd disk: the proof only is lost

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def read_counter(plan_dir: Path) -> tuple[int, int] | None:
    """(run, commits) of DIR/journal.commits, None when there is none (or it is not ours)."""
    try:
        words = (Path(plan_dir) / COUNTER_NAME).read_text(encoding="ascii").split()
        if len(words) == 4 and words[0] == "run" and words[2] == "commits":
            return int(words[1]), int(words[3])
    except (OSError, ValueError):
        pass
    return None


def _cut(db: sqlite3.Connection, path: Path, counted: tuple[int, int] | None) -> str | None:
    """The journal was cut when it holds fewer of the last run's commits than its counter says (read
    the counter before the database: a commit is counted only after it is in the database)."""
    if counted is None:
        return None
    run, commits = counted
    row = db.execute("SELECT commits, how, started FROM runs WHERE run = ?", (run,)).fetchone()
    held = 0 if row is None else int(row[0] or 0)
    if held >= commits:
        return None
    when = "" if row is None else f", started {_utc(row[2])}"
    return (f"{path}: the journal was cut: run {run} of fly{when} committed {commits} transactions and the file "
            f"holds {held} of them; its write-ahead log ({path.name}-wal) was lost after that run was killed, "
            "and with it everything written since SQLite last copied the log into the file")


def _utc(t: float) -> str:
    return datetime.fromtimestamp(float(t), timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


# ------------------------------------------------------------------------------------------- opening
def _connect(path: Path) -> sqlite3.Connection:
    """A writable connection to path (created if missing); raises sqlite3.Error when it cannot be written."""
    db = sqlite3.connect(path, check_same_thread=False, isolation_level=None, timeout=10.0)
    try:
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.execute("BEGIN IMMEDIATE")  # a file this process can write, or the error now, before any flight
        db.execute("ROLLBACK")
    except sqlite3.Error:
        db.close()
        raise
    return db


def _migrate(db: sqlite3.Connection) -> None:
    db.executescript(SCHEMA)
    for table, column, declaration in ADDED_COLUMNS:
        if column not in _columns(db, table):  # a journal from before it
            db.execute(f"ALTER TABLE {table} ADD COLUMN {column} {declaration}")


def _columns(db: sqlite3.Connection, table: str) -> set[str]:
    return {row[1] for row in db.execute(f"PRAGMA table_info({table})")}


def _not_a_journal(path: Path, err: Any) -> JournalError:
    return JournalError(f"{path}: not a missionplan flight journal ({err})")


def _open_writable(plan_dir: Path) -> tuple[sqlite3.Connection, list[str], str | None]:
    """plan_dir's journal open for writing: (connection, what was repaired (one line each), why the
    journal was cut or None). A damaged journal is salvaged into a new one; one that cannot be written,
    or is no SQLite file, is a JournalError."""
    path = Path(plan_dir) / JOURNAL_NAME
    existed = path.exists()
    if existed and not has_sqlite_header(path):
        raise _not_a_journal(path, "no SQLite header: another kind of file, or its first bytes were overwritten")
    counted = read_counter(plan_dir) if existed else None  # before the database (see _cut)
    repairs: list[str] = []
    damage = None
    try:
        db = _connect(path)
    except sqlite3.Error as err:
        kind = fault_kind(err)
        if kind == "read-only":
            raise JournalError(f"{path}: read-only ({err}): this flight's journal cannot be written here; copy the "
                               "plan folder to a writable disk and run fly there") from None
        if kind != "damaged":
            raise JournalError(f"{path}: cannot be written ({err})") from None
        damage = str(err)
    else:
        damage = integrity_problem(db) if existed else None
        if damage:
            db.close()
    if damage:
        repairs.append(salvage_journal(path, damage))
        counted = None  # the counter spoke of the damaged file
        try:
            db = _connect(path)
        except sqlite3.Error as err:
            raise JournalError(f"{path}: cannot be written ({err})") from None
    try:
        _migrate(db)
        cut = _cut(db, path, counted)
    except sqlite3.Error as err:
        db.close()
        raise _not_a_journal(path, err) from None
    return db, repairs, cut


# ------------------------------------------------------------------------------------------- salvage
def _salvage_rows(db: sqlite3.Connection) -> dict[str, tuple[list[str], TableSalvage] | None]:
    out: dict[str, tuple[list[str], TableSalvage] | None] = {}
    for table in TABLES:
        columns = table_columns(db, table)
        out[table] = None if columns is None else (columns, salvage_table(db, table, ", ".join(columns)))
    return out


def _position(values: dict[str, Any]) -> bool:
    lat, lon = values.get("lat"), values.get("lon")
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (lat, lon, values.get("t"))):
        return False
    # (0, 0): what a page cut short reads as; fly records no position before a vehicle has its GPS fix.
    return -90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and (lat, lon) != (0.0, 0.0)


def _usable(table: str, row: tuple[Any, ...], columns: list[str]) -> bool:
    """Whether a salvaged row reads as one of ours: a damaged page (or a page cut short, read as zeros)
    can yield rows of garbage, which are dropped and counted as lost."""
    values = dict(zip(columns, row[1:]))
    if table == "entries":
        if values.get("kind") not in ENTRY_KINDS:
            return False
        try:
            return isinstance(json.loads(values.get("row") or ""), list)
        except (TypeError, ValueError):
            return False
    if table == "samples":
        return _position(values)
    if table == "photos":
        return _position(values) and isinstance(values.get("idx"), int) and values.get("source") in PHOTO_SOURCES
    return True


def _plural(n: int, word: str) -> str:
    if n == 1:
        return f"1 {word[:-1] if word.endswith('s') else word}"
    return f"{n:,} {word}"


def salvage_journal(path: Path, damage: str) -> str:
    """Move the damaged journal aside (journal.sqlite.damaged) and copy what can be read of it into a new
    journal at path; returns the one line that says so (what was recovered, what was lost). Raises
    JournalError when nothing can be read (the damaged file stays aside) or the new one cannot be written
    (then the damaged one is put back)."""
    aside = move_aside(path)
    src = sqlite3.connect(aside, isolation_level=None)
    try:
        src.execute("PRAGMA writable_schema=ON")  # read the tables even when an index's pages are gone
        salvaged = _salvage_rows(src)
    finally:
        src.close()
    if salvaged["flights"] is None or salvaged["runs"] is None or salvaged["flights"][1].unreadable:
        raise JournalError(f"{path}: damaged beyond repair ({damage}): not even its flights can be read; "
                           f"kept as {aside.name}")
    kept: dict[str, int] = {}
    lost: list[str] = []
    try:
        db = _connect(path)
        _migrate(db)
        db.execute("BEGIN")
        for table in TABLES:
            got = salvaged[table]
            if got is None:
                lost.append(f"the whole {table} table")
                continue
            columns, rows = got
            ours = _columns(db, table)
            use = [i for i, c in enumerate(columns) if c in ours]
            names = ", ".join(["rowid"] + [columns[i] for i in use])
            good = [row for row in rows.rows if _usable(table, row, columns)]
            db.executemany(f"INSERT INTO {table} ({names}) VALUES ({', '.join('?' * (len(use) + 1))})",
                           [(row[0], *(row[i + 1] for i in use)) for row in good])
            kept[table] = len(good)
            garbled = len(rows.rows) - len(good)
            if rows.lost_rows is None:
                last = rows.lost[-1][0] - 1
                lost.append((f"the {table} after row {last:,}" if last > 0 else f"all the {table}")
                            + (f" and {garbled} unreadable" if garbled else ""))
            elif rows.lost_rows or garbled:
                lost.append(_plural(rows.lost_rows + garbled, table))
        db.execute("COMMIT")
        db.close()
    except sqlite3.Error as err:
        for name in (path.name, path.name + "-wal", path.name + "-shm"):
            path.with_name(name).unlink(missing_ok=True)
        aside.rename(path)
        aside_wal = aside.with_name(aside.name + "-wal")
        if aside_wal.exists():
            aside_wal.rename(path.with_name(path.name + "-wal"))
        raise JournalError(f"{path}: damaged ({damage}) and no repaired copy could be written ({err})") from None
    (Path(path).parent / COUNTER_NAME).unlink(missing_ok=True)  # it counted the damaged file's commits
    recovered = ", ".join(_plural(kept.get(t, 0), t) for t in TABLES)
    return (f"{path}: damaged ({damage}); kept as {aside.name}, and what could be read copied into a new "
            f"{path.name}: {recovered}; lost: {', '.join(lost) if lost else 'nothing'}")


# ------------------------------------------------------------------------------------------- the journal
def _encode(name: str, value: Any) -> Any:
    if name == "wire":
        return [asdict(item) for item in value]
    return value


def _decode(name: str, value: Any) -> Any:
    if name == "wire":
        return [WireItem(**item) for item in value]
    return value


def _fault_label(err: BaseException) -> str:
    return {"full": "disk full", "read-only": "journal read-only", "damaged": "journal damaged"}.get(
        fault_kind(err), "journal write failed")


class Journal:
    """The journal of one flight, open for this run: sinks for the drones' records, a writer thread."""

    def __init__(self, path: Path, flight: int, run: int, sortie: int, db: sqlite3.Connection,
                 repairs: list[str] | None = None) -> None:
        self.path, self.flight, self.run, self.sortie = path, flight, run, sortie
        self.repairs = list(repairs or [])  # what opening it found and repaired (a damaged file, a cut), one line each
        self.unwritten: list[Item] = []  # after close(): what could not be written (write_fallback keeps it)
        self._db = db
        self._queue: queue.SimpleQueue[Item | None] = queue.SimpleQueue()
        self._counts = threading.Condition()
        self._handed = self._committed = 0  # items handed over (sinks and our own), and committed of those
        self._held: list[Item] = []  # the writer's, while paused: everything not yet written
        self._paused_by: sqlite3.Error | None = None
        self._alert: Callable[[str], None] | None = None
        self._unsaid: list[str] = []  # said before anyone listened
        # This run's row was its first commit (counted in it); the counter file says so from now on.
        self._commits = int(db.execute("SELECT commits FROM runs WHERE run = ?", (run,)).fetchone()[0])
        self._counter = CommitCounter(path.parent, run, self._commits)
        self._thread = threading.Thread(target=self._write, name="journal", daemon=True)
        self._thread.start()

    # -- opening
    @classmethod
    def start_flight(cls, plan_dir: Path, sortie: int, command: str) -> Journal:
        """A new flight of `sortie` in plan_dir's journal (created if missing), with this run as its first."""
        db, repairs, cut = _open_writable(Path(plan_dir))
        now = time.time()
        try:
            with db:
                flight = db.execute("INSERT INTO flights (sortie, started) VALUES (?, ?)", (sortie, now)).lastrowid
                run = db.execute("INSERT INTO runs (flight, started, how, command, commits) VALUES "
                                 "(?, ?, 'fly', ?, 1)", (flight, now, command)).lastrowid
        except sqlite3.Error as err:
            db.close()
            raise JournalError(f"{Path(plan_dir) / JOURNAL_NAME}: cannot be written ({err})") from None
        # A cut of an earlier flight is said; this flight starts whole.
        return cls(Path(plan_dir) / JOURNAL_NAME, int(flight), int(run), sortie, db, repairs + ([cut] if cut else []))

    @classmethod
    def continue_flight(cls, plan_dir: Path, command: str) -> Journal:
        """The latest flight of plan_dir's journal that started a vehicle, continued by a new run ("resume")."""
        path = Path(plan_dir) / JOURNAL_NAME
        if not path.is_file():
            raise JournalError(f"{plan_dir}: no flight to resume (no {JOURNAL_NAME}: `missionplan fly {plan_dir}` "
                               "starts one)")
        db, repairs, cut = _open_writable(Path(plan_dir))
        # The latest flight that started a vehicle (or was about to arm one): a run that only found the fleet
        # already flying (and sent it nothing) left a flight of its own, with nothing to resume.
        row = db.execute("SELECT flight, sortie FROM flights WHERE EXISTS (SELECT 1 FROM entries WHERE "
                         "entries.flight = flights.flight AND kind = 'fact' AND (row = ? OR "
                         "json_extract(row, '$[0]') = ?)) ORDER BY flight DESC LIMIT 1",
                         (json.dumps(["started", True]), "arming")).fetchone()
        if row is None:
            db.close()
            if cut:
                raise JournalError(f"{cut}: no flight left in it to resume")
            raise JournalError(f"{path}: no flight to resume: no run of fly started a vehicle here "
                               f"(`missionplan fly {plan_dir}` starts one)")
        try:
            with db:
                run = db.execute("INSERT INTO runs (flight, started, how, command, commits) VALUES "
                                 "(?, ?, 'resume', ?, 1)", (row[0], time.time(), command)).lastrowid
        except sqlite3.Error as err:
            db.close()
            raise JournalError(f"{path}: cannot be written ({err})") from None
        return cls(path, int(row[0]), int(run), int(row[1]), db, repairs + ([cut] if cut else []))

    # -- writing
    def set_alert(self, alert: Callable[[str], None]) -> None:
        """Who hears the journal pause and resume (fly's in-flight alerts); what was said before, at once."""
        self._alert = alert
        unsaid, self._unsaid = self._unsaid, []
        for text in unsaid:
            alert(text)

    def _say(self, text: str) -> None:
        if self._alert is None:
            self._unsaid.append(text)
        else:
            self._alert(text)

    def _put(self, item: Item) -> None:
        with self._counts:
            self._handed += 1
        self._queue.put(item)

    def sink(self, drone: int) -> Sink:
        """Where drone's record writes its changes. Never raises: a paused journal holds them."""
        def write(kind: str, row: tuple[Any, ...]) -> None:
            self._put((kind, (drone, *row)))
        return write

    def _take(self, wait: float) -> list[Item | None]:
        """What is queued: the first item waited for up to `wait` s, then everything already there (so a busy
        producer, holding the GIL between switches, cannot outpace the writer)."""
        items: list[Item | None] = []
        try:
            items.append(self._queue.get(timeout=wait))
            while items[-1] is not None and len(items) < 5000:
                items.append(self._queue.get_nowait())
        except queue.Empty:
            pass
        return items

    def _write(self) -> None:
        """The writer thread: one transaction per COMMIT_S at most, committed when it is that old, when the
        sinks go quiet, or when the journal closes. A failed write pauses it (_pause): then it holds
        everything and tries again every RETRY_S, and once more when the journal closes."""
        batch: list[Item] = []  # in the open transaction
        began = retry_at = 0.0
        while True:
            now = time.monotonic()
            if self._paused_by is not None:
                wait = max(0.0, retry_at - now)
            else:
                wait = COMMIT_S if not batch else max(0.0, began + COMMIT_S - now)
            items = self._take(wait)
            closing = bool(items) and items[-1] is None
            rows: list[Item] = [item for item in items if item is not None]
            if self._paused_by is not None:
                self._held.extend(rows)
                if closing or time.monotonic() >= retry_at:
                    self._retry()
                    retry_at = time.monotonic() + RETRY_S
                if closing:
                    return
                continue
            try:
                if rows:
                    if not batch:
                        self._db.execute("BEGIN")
                        began = time.monotonic()
                    self._insert(rows)
                    batch.extend(rows)
                    rows = []
                if batch and (closing or not items or time.monotonic() - began >= COMMIT_S):
                    self._commit(len(batch))
                    batch = []
            except sqlite3.Error as err:  # a full disk, an I/O error, a read-only remount: hold on to everything
                self._rollback()
                self._held = batch + rows
                batch = []
                self._pause(err)
                retry_at = time.monotonic() + RETRY_S
                if closing:
                    self._retry()  # the final try
                    return
                continue
            if closing:
                return

    def _commit(self, count: int) -> None:
        self._db.execute("UPDATE runs SET commits = commits + 1 WHERE run = ?", (self.run,))
        self._db.execute("COMMIT")
        self._commits += 1
        with self._counts:
            self._committed += count
            self._counts.notify_all()
        self._counter.set(self._commits)  # after the commit: the counter never runs ahead of the database

    def _rollback(self) -> None:
        try:
            if self._db.in_transaction:
                self._db.execute("ROLLBACK")
        except sqlite3.Error:
            pass  # SQLite rolled it back itself (it does on a full disk)

    def _pause(self, err: sqlite3.Error) -> None:
        self._paused_by = err
        with self._counts:
            self._counts.notify_all()  # flush() waits no longer
        self._say(f"{_fault_label(err)}: journal writes paused, {len(self._held)} records held in memory ({err}); "
                  f"trying again every {RETRY_S:g} s")

    def _retry(self) -> bool:
        """Write everything held in one transaction; whether it went through (then said once)."""
        held = self._held
        try:
            self._db.execute("BEGIN")
            self._insert(held)
            self._commit(len(held))
        except sqlite3.Error as err:
            self._rollback()
            self._paused_by = err
            return False
        self._held, self._paused_by = [], None
        self._say(f"journal writes resumed: {len(held)} records written")
        return True

    def _insert(self, rows: list[Item]) -> None:
        """One statement per table for the whole batch (INSERT ... SELECT over a JSON array): sqlite3
        lets go of the GIL for every step, and taking it back from a busy thread costs a switch
        interval (5 ms), so a step per row would fall behind a busy flight."""
        tables: dict[str, list[Any]] = {"samples": [], "photos": [], "entries": []}
        statements = []
        for kind, row in rows:
            if kind == "sql":
                statements.append(row)
            elif kind in ("sample", "photo"):
                tables[kind + "s"].append(list(row))
            else:
                tables["entries"].append(_entry(kind, row))
        for table, values in tables.items():
            if values:
                columns = ", ".join(f"json_extract(value, '$[{i}]')" for i in range(len(values[0])))
                self._db.execute(f"INSERT INTO {table} SELECT ?, {columns} FROM json_each(?) ORDER BY key",
                                 (self.flight, json.dumps(values)))
        for statement, args in statements:
            self._db.execute(statement, args)

    @property
    def paused(self) -> str | None:
        """Why writes are paused (the last error), None while they go through."""
        err = self._paused_by
        return None if err is None else f"{_fault_label(err)} ({err})"

    @property
    def held(self) -> int:
        """How many records a paused journal holds in memory."""
        return len(self._held)

    def flush(self, timeout: float = 10.0, through_pause_s: float = 0.0) -> bool:
        """Wait until everything handed over so far is committed (bounded: at most COMMIT_S after the last);
        whether it is. While the journal is paused, False at once, or after waiting up to through_pause_s
        for its tries to go through."""
        with self._counts:
            target = self._handed
            self._counts.wait_for(lambda: self._committed >= target or self._paused_by is not None, timeout)
            if self._committed < target and through_pause_s > 0:
                self._counts.wait_for(lambda: self._committed >= target, through_pause_s)
            return self._committed >= target

    def mark_judged(self, photos_from_track: bool = False) -> bool:
        """Record that flight.json was written from this flight (and how its photos were counted, which a
        rebuilt survey ledger needs); whether that is committed."""
        self._put(("sql", ("UPDATE flights SET judged = ?, photos_from_track = ? WHERE flight = ?",
                           (time.time(), int(photos_from_track), self.flight))))
        return self.flush()

    def close(self) -> None:
        """Commit what is left and record that this run ended (a killed run never gets here), then close.
        Never raises: what could not be written stays in `unwritten`."""
        self._put(("sql", ("UPDATE runs SET ended = ? WHERE run = ?", (time.time(), self.run))))
        self._queue.put(None)
        self._thread.join(CLOSE_S)
        if self._thread.is_alive():  # a disk that hangs: what it has not written is not known to be there
            self.unwritten = list(self._held)
        else:
            self.unwritten = [item for item in self._held if item[0] != "sql"]
        self._counter.close()
        try:
            self._db.close()
        except sqlite3.Error:
            pass

    # -- reading
    def records(self, ids: list[int] | None = None) -> list[DroneRecord]:
        """This flight's records as journaled so far (everything handed over is committed first)."""
        if not self.flush():
            raise JournalError(f"{self.path}: the journal cannot be written ({self.paused or 'too slow a disk'})")
        return read_records(self._db, self.flight, ids)

    def runs(self) -> list[dict[str, Any]]:
        rows = self._db.execute("SELECT run, started, ended, how, command FROM runs WHERE flight = ? ORDER BY run",
                                (self.flight,)).fetchall()
        return [{"run": r[0], "started": r[1], "ended": r[2], "how": r[3], "command": r[4]} for r in rows]


def _entry(kind: str, row: tuple[Any, ...]) -> list[Any]:
    drone, *rest = row
    if kind == "fact":
        rest = [rest[0], _encode(rest[0], rest[1])]
    return [drone, kind, json.dumps(rest)]


# ------------------------------------------------------------------------------------------- the fallback file
def fallback_folder(plan_dir: Path) -> list[Path]:
    """Where a record that cannot be written into plan_dir goes: the temp folder and the home folder, those
    on another filesystem than plan_dir first (a full disk there is usually the reason)."""
    try:
        device = os.stat(plan_dir).st_dev
    except OSError:
        device = None
    candidates = [Path(tempfile.gettempdir()), Path.home()]

    def elsewhere(folder: Path) -> bool:
        try:
            return os.stat(folder).st_dev != device
        except OSError:
            return False
    return sorted(candidates, key=lambda folder: not elsewhere(folder))


def write_fallback(journal: Journal, flight_doc: dict[str, Any] | None, why: str) -> Path:
    """The part of the flight's record that could not be written into its plan folder, as one JSON file in
    fallback_folder: the journal rows still held (each {kind, drone, row}, the journal's own columns, in
    the order they were handed over) and flight.json's content when flight.json could not be written.
    Returns its path; raises OSError when no folder takes it."""
    plan_dir = journal.path.parent
    rows = []
    for kind, row in journal.unwritten:
        if kind == "sql":
            continue
        if kind in ("sample", "photo"):
            rows.append({"kind": kind, "drone": row[0], "row": list(row[1:])})
        else:
            drone, entry_kind, text = _entry(kind, row)
            rows.append({"kind": entry_kind, "drone": drone, "row": json.loads(text)})
    doc = {"what": "the part of a flight's record fly could not write into its plan folder",
           "plan_dir": str(plan_dir.resolve()), "journal": str(journal.path.resolve()), "flight": journal.flight,
           "run": journal.run, "sortie": journal.sortie, "why": why, "journal_rows": rows, "flight_json": flight_doc}
    text = json.dumps(doc) + "\n"
    name = f"missionplan-{plan_dir.resolve().name}-flight{journal.flight}-run{journal.run}-" \
           f"{datetime.now(timezone.utc).strftime('%Y%m%dT%H%M%SZ')}.json"
    errors = []
    for folder in fallback_folder(plan_dir):
        try:
            write_text_atomic(folder / name, text)
            return folder / name
        except OSError as err:
            errors.append(f"{folder}: {err.strerror or err}")
    raise OSError(f"no folder took it ({'; '.join(errors)})")


# ------------------------------------------------------------------------------------------- reading
def read_records(db: sqlite3.Connection, flight: int, ids: list[int] | None = None) -> list[DroneRecord]:
    """The DroneRecords of a flight, rebuilt by replaying its entries, samples and photos in order.
    `ids`: the drones to return, in that order (a drone with nothing journaled gets an empty record)."""
    records: dict[int, DroneRecord] = {}

    def record(drone: int) -> DroneRecord:
        if drone not in records:
            records[drone] = DroneRecord(id=drone)
        return records[drone]

    # Read as it is, never altered: a journal written by an older fly may lack a table or a column.
    have = {table: _columns(db, table) for table in ("entries", "samples", "photos")}
    if have["entries"]:
        for drone, kind, row in db.execute("SELECT drone, kind, row FROM entries WHERE flight = ? ORDER BY rowid",
                                           (flight,)):
            values = json.loads(row)
            if kind == "fact":
                values = [values[0], _decode(values[0], values[1])]
            record(drone).replay(kind, tuple(values))
    if have["samples"]:
        for drone, *sample in db.execute("SELECT drone, t, lat, lon, up, speed, boot_s, climb FROM samples "
                                         "WHERE flight = ? ORDER BY rowid", (flight,)):
            record(drone).samples.append(tuple(sample))  # type: ignore[arg-type]
    if have["photos"]:
        amsl = "amsl" if "amsl" in have["photos"] else "NULL"
        for drone, *photo in db.execute(f"SELECT drone, idx, t, lat, lon, up, source, roll, pitch, yaw, {amsl} FROM "
                                        "photos WHERE flight = ? ORDER BY rowid", (flight,)):
            record(drone).replay("photo", tuple(photo))
    if ids is None:
        return [records[k] for k in sorted(records)]
    return [record(k) for k in ids]


def _open_to_read(path: Path) -> sqlite3.Connection:
    """A journal open for reading: as any reader beside a running writer, or, where the folder cannot
    be written (a read-only disk), without writing anything."""
    try:
        db = sqlite3.connect(path, check_same_thread=False, timeout=10.0)
        db.execute("SELECT 1 FROM sqlite_master").fetchall()
        return db
    except sqlite3.Error as err:
        if fault_kind(err) != "read-only":
            raise _not_a_journal(path, err) from None
    return connect_read_only(path)


def read_flight(plan_dir: Path, flight: int | None = None) -> tuple[int, int, list[DroneRecord]]:
    """(flight, sortie, records) of plan_dir's journal: the latest flight, or the one asked for."""
    path = Path(plan_dir) / JOURNAL_NAME
    if not path.is_file():
        raise JournalError(f"{plan_dir}: no {JOURNAL_NAME}")
    if not has_sqlite_header(path):
        raise _not_a_journal(path, "no SQLite header")
    db = _open_to_read(path)
    try:
        where = "" if flight is None else f" WHERE flight = {int(flight)}"
        row = db.execute(f"SELECT flight, sortie FROM flights{where} ORDER BY flight DESC LIMIT 1").fetchone()
        if row is None:
            raise JournalError(f"{path}: no such flight")
        return int(row[0]), int(row[1]), read_records(db, int(row[0]))
    except sqlite3.DatabaseError as err:
        raise _not_a_journal(path, err) from None
    finally:
        db.close()


@dataclass
class JudgedFlight:
    """A flight of a journal that fly judged (wrote flight.json from): what the survey ledger recorded of it."""

    flight: int
    sortie: int
    judged: float  # when
    photos_from_track: bool
    records: list[DroneRecord]


def judged_flights(plan_dir: Path) -> list[JudgedFlight]:
    """Every judged flight of plan_dir's journal, oldest judgement first ([] without a journal). Raises
    JournalError when the journal cannot be read (damaged: `fly --resume` repairs it)."""
    path = Path(plan_dir) / JOURNAL_NAME
    if not path.is_file():
        return []
    if not has_sqlite_header(path):
        raise _not_a_journal(path, "no SQLite header")
    db = _open_to_read(path)
    try:
        damage = integrity_problem(db)
        if damage:
            raise JournalError(f"{path}: damaged ({damage})")
        track = "photos_from_track" if "photos_from_track" in _columns(db, "flights") else "NULL"
        rows = db.execute(f"SELECT flight, sortie, judged, {track} FROM flights WHERE judged IS NOT NULL "
                          "ORDER BY judged").fetchall()
        out = []
        for flight, sortie, judged, from_track in rows:
            if from_track is None:  # judged by a fly from before the column: its command line says
                commands = [r[0] for r in db.execute("SELECT command FROM runs WHERE flight = ?", (flight,))]
                from_track = any("--photos-from-track" in command for command in commands)
            out.append(JudgedFlight(int(flight), int(sortie), float(judged), bool(from_track),
                                    read_records(db, int(flight))))
        return out
    except sqlite3.DatabaseError as err:
        raise JournalError(f"{path}: cannot be read ({err})") from None
    finally:
        db.close()
