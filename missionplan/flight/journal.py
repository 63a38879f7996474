"""The flight journal written: everything `fly` learns about a flight, written as it happens, in DIR/journal.sqlite.

Owns opening the journal for a run (a new flight, or a resumed one) and writing it. One writer thread takes
the drones' changes (record.DroneRecord's sink) from a queue and commits at least every COMMIT_S, so SIGKILL,
a power cut, Ctrl-C or an exception lose at most that much. Readers (flight.json, `fly --resume`) open it
beside a running writer (journal_read.py). The tables and connections are journal_db.py's.

A *flight* is one `fly DIR` (one sortie flown once) with the `fly --resume DIR` runs that continue it;
a *run* is one process.

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
  and what SQLite can still read of it is copied, row by row (journal_repair.py), into a new journal, saying
  what was recovered and what was lost; a read-only one cannot be continued, said in one line.
"""

from __future__ import annotations

import json
import os
import queue
import sqlite3
import tempfile
import threading
import time
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from missionplan.base.atomic import write_text_atomic

from .journal_db import COUNTER_NAME, JOURNAL_NAME, JournalError, connect, entry_row, migrate, not_a_journal
from .journal_read import read_records
from .journal_repair import salvage_journal
from .record import DroneRecord, Sink
from .salvage import fault_kind, has_sqlite_header, integrity_problem

COMMIT_S = 0.25  # the most a crash can lose
RETRY_S = 1.0  # a paused journal tries to write again this often
CLOSE_S = 30.0  # at most this long for the last writes when the journal closes
# A flight a resume can continue: a vehicle was started, or fly was about to arm one (its `arming` fact
# is committed before the arm command is sent, drone_flight.DroneFlight._arm).
RESUMABLE = ("started", "arming")
Item = tuple[str, tuple[Any, ...]]  # (kind, (drone, *row)) from a sink, or ("sql", (statement, args)) of our own


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
def _open_writable(plan_dir: Path) -> tuple[sqlite3.Connection, list[str], str | None]:
    """plan_dir's journal open for writing: (connection, what was repaired (one line each), why the
    journal was cut or None). A damaged journal is salvaged into a new one; one that cannot be written,
    or is no SQLite file, is a JournalError."""
    path = Path(plan_dir) / JOURNAL_NAME
    existed = path.exists()
    if existed and not has_sqlite_header(path):
        raise not_a_journal(path, "no SQLite header: another kind of file, or its first bytes were overwritten")
    counted = read_counter(plan_dir) if existed else None  # before the database (see _cut)
    repairs: list[str] = []
    damage = None
    try:
        db = connect(path)
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
            db = connect(path)
        except sqlite3.Error as err:
            raise JournalError(f"{path}: cannot be written ({err})") from None
    try:
        migrate(db)
        cut = _cut(db, path, counted)
    except sqlite3.Error as err:
        db.close()
        raise not_a_journal(path, err) from None
    return db, repairs, cut


# ------------------------------------------------------------------------------------------- the journal
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
                tables["entries"].append(entry_row(kind, row))
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
            drone, entry_kind, text = entry_row(kind, row)
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

