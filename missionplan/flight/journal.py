"""The flight journal: everything `fly` learns about a flight, written as it happens, in DIR/journal.sqlite.

One SQLite database per plan folder, in WAL mode with synchronous=FULL: a committed transaction
survives the process being killed and the machine losing power. One writer thread takes the drones'
changes (record.DroneRecord's sink) from a queue and commits at least every COMMIT_S, so SIGKILL, a
power cut, Ctrl-C or an exception lose at most that much. Readers (flight.json, `fly --resume`) open
it beside a running writer.

A *flight* is one `fly DIR` (one sortie flown once) with the `fly --resume DIR` runs that continue it;
a *run* is one process. Tables:
  flights(flight, sortie, started, judged)   judged: when a run last wrote flight.json from it
  runs(run, flight, started, ended, how, command)   how: "fly" or "resume"; ended NULL: it was killed
  entries(flight, drone, kind, row)          every change of a DroneRecord, in order; row as JSON
  samples(flight, drone, t, lat, lon, up, speed, boot_s, climb)   the positions, the bulk, in columns
  photos(flight, drone, idx, t, lat, lon, up, source, roll, pitch, yaw, amsl)
Entries are replayed through DroneRecord.replay, so the record read back is the record that was kept.
"""

from __future__ import annotations

import json
import queue
import sqlite3
import threading
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from missionplan.bridge.formats.mission_items import WireItem

from .record import DroneRecord, Sink

JOURNAL_NAME = "journal.sqlite"
COMMIT_S = 0.25  # the most a crash can lose
SCHEMA = """
CREATE TABLE IF NOT EXISTS flights (flight INTEGER PRIMARY KEY, sortie INTEGER NOT NULL, started REAL NOT NULL,
                                    judged REAL);
CREATE TABLE IF NOT EXISTS runs (run INTEGER PRIMARY KEY, flight INTEGER NOT NULL, started REAL NOT NULL,
                                 ended REAL, how TEXT NOT NULL, command TEXT NOT NULL);
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


class JournalError(Exception):
    """A journal that cannot be used as asked (none to resume, not ours): one line for the user."""


def _connect(path: Path) -> sqlite3.Connection:
    try:
        db = sqlite3.connect(path, check_same_thread=False, isolation_level=None, timeout=10.0)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.executescript(SCHEMA)
        if "amsl" not in {row[1] for row in db.execute("PRAGMA table_info(photos)")}:  # a journal from before it
            db.execute("ALTER TABLE photos ADD COLUMN amsl REAL")
    except sqlite3.DatabaseError as err:
        raise JournalError(f"{path}: not a missionplan flight journal ({err})") from None
    return db


def _encode(name: str, value: Any) -> Any:
    if name == "wire":
        return [asdict(item) for item in value]
    return value


def _decode(name: str, value: Any) -> Any:
    if name == "wire":
        return [WireItem(**item) for item in value]
    return value


class Journal:
    """The journal of one flight, open for this run: sinks for the drones' records, a writer thread."""

    def __init__(self, path: Path, flight: int, run: int, sortie: int, db: sqlite3.Connection) -> None:
        self.path, self.flight, self.run, self.sortie = path, flight, run, sortie
        self._db = db
        self._queue: queue.SimpleQueue[tuple[str, tuple[Any, ...]] | None] = queue.SimpleQueue()
        self._counts = threading.Condition()
        self._handed = self._committed = 0  # changes handed over by the sinks, and committed of those
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._write, name="journal", daemon=True)
        self._thread.start()

    # -- opening
    @classmethod
    def start_flight(cls, plan_dir: Path, sortie: int, command: str) -> Journal:
        """A new flight of `sortie` in plan_dir's journal (created if missing), with this run as its first."""
        path = Path(plan_dir) / JOURNAL_NAME
        db = _connect(path)
        now = time.time()
        with db:
            flight = db.execute("INSERT INTO flights (sortie, started) VALUES (?, ?)", (sortie, now)).lastrowid
            run = db.execute("INSERT INTO runs (flight, started, how, command) VALUES (?, ?, 'fly', ?)",
                             (flight, now, command)).lastrowid
        return cls(path, int(flight), int(run), sortie, db)

    @classmethod
    def continue_flight(cls, plan_dir: Path, command: str) -> Journal:
        """The latest flight of plan_dir's journal that started a vehicle, continued by a new run ("resume")."""
        path = Path(plan_dir) / JOURNAL_NAME
        if not path.is_file():
            raise JournalError(f"{plan_dir}: no flight to resume (no {JOURNAL_NAME}: `missionplan fly {plan_dir}` "
                               "starts one)")
        db = _connect(path)
        # The latest flight that started a vehicle: a run that only found the fleet already flying (and
        # sent it nothing) left a flight of its own, with nothing to resume.
        row = db.execute("SELECT flight, sortie FROM flights WHERE EXISTS (SELECT 1 FROM entries WHERE "
                         "entries.flight = flights.flight AND kind = 'fact' AND row = ?) ORDER BY flight DESC LIMIT 1",
                         (json.dumps(["started", True]),)).fetchone()
        if row is None:
            db.close()
            raise JournalError(f"{path}: no flight to resume: no run of fly started a vehicle here "
                               f"(`missionplan fly {plan_dir}` starts one)")
        with db:
            run = db.execute("INSERT INTO runs (flight, started, how, command) VALUES (?, ?, 'resume', ?)",
                             (row[0], time.time(), command)).lastrowid
        return cls(path, int(row[0]), int(run), int(row[1]), db)

    # -- writing
    def sink(self, drone: int) -> Sink:
        """Where drone's record writes its changes."""
        def write(kind: str, row: tuple[Any, ...]) -> None:
            if self._error is not None:
                raise JournalError(f"{self.path}: the journal cannot be written ({self._error})")
            with self._counts:
                self._handed += 1
            self._queue.put((kind, (drone, *row)))
        return write

    def _write(self) -> None:
        """The writer thread: one transaction per COMMIT_S at most, committed when it is that old, when
        the sinks go quiet, or when the journal closes. It takes everything queued at each wake-up, so a
        busy producer (holding the GIL between switches) cannot outpace it."""
        pending, began = 0, 0.0
        while True:
            wait = COMMIT_S if not pending else max(0.0, began + COMMIT_S - time.monotonic())
            items: list[Any] = []
            try:
                items.append(self._queue.get(timeout=wait))
                while items[-1] is not None and len(items) < 5000:
                    items.append(self._queue.get_nowait())
            except queue.Empty:
                pass
            closing = bool(items) and items[-1] is None
            rows = [item for item in items if item is not None]
            try:
                if rows:
                    if not pending:
                        self._db.execute("BEGIN")
                        began = time.monotonic()
                    self._insert(rows)
                    pending += len(rows)
                if pending and (closing or not rows or time.monotonic() - began >= COMMIT_S):
                    self._db.execute("COMMIT")
                    with self._counts:
                        self._committed += pending
                        self._counts.notify_all()
                    pending = 0
            except sqlite3.Error as err:  # a full disk, a removed folder: said by the next sink call
                self._error = err
                with self._counts:
                    self._counts.notify_all()
                return
            if closing:
                return

    def _insert(self, rows: list[tuple[str, tuple[Any, ...]]]) -> None:
        """One statement per table for the whole batch (INSERT ... SELECT over a JSON array): sqlite3
        lets go of the GIL for every step, and taking it back from a busy thread costs a switch
        interval (5 ms), so a step per row would fall behind a busy flight."""
        tables: dict[str, list[Any]] = {"samples": [], "photos": [], "entries": []}
        for kind, (drone, *rest) in rows:
            if kind in ("sample", "photo"):
                tables[kind + "s"].append([drone, *rest])
            else:
                if kind == "fact":
                    rest = [rest[0], _encode(rest[0], rest[1])]
                tables["entries"].append([drone, kind, json.dumps(rest)])
        for table, values in tables.items():
            if values:
                columns = ", ".join(f"json_extract(value, '$[{i}]')" for i in range(len(values[0])))
                self._db.execute(f"INSERT INTO {table} SELECT ?, {columns} FROM json_each(?) ORDER BY key",
                                 (self.flight, json.dumps(values)))

    def flush(self, timeout: float = 10.0) -> None:
        """Until everything handed over so far is committed (bounded: at most COMMIT_S after the last)."""
        with self._counts:
            target = self._handed
            self._counts.wait_for(lambda: self._committed >= target or self._error is not None, timeout)
        if self._error is not None:
            raise JournalError(f"{self.path}: the journal cannot be written ({self._error})")

    def mark_judged(self) -> None:
        self.flush()
        with self._db:
            self._db.execute("UPDATE flights SET judged = ? WHERE flight = ?", (time.time(), self.flight))

    def close(self) -> None:
        """Commit what is left, record that this run ended (a killed run never gets here), close."""
        self._queue.put(None)
        self._thread.join(10.0)
        try:
            with self._db:
                self._db.execute("UPDATE runs SET ended = ? WHERE run = ?", (time.time(), self.run))
        finally:
            self._db.close()

    # -- reading
    def records(self, ids: list[int] | None = None) -> list[DroneRecord]:
        """This flight's records as journaled so far (everything handed over is committed first)."""
        self.flush()
        return read_records(self._db, self.flight, ids)

    def runs(self) -> list[dict[str, Any]]:
        rows = self._db.execute("SELECT run, started, ended, how, command FROM runs WHERE flight = ? ORDER BY run",
                                (self.flight,)).fetchall()
        return [{"run": r[0], "started": r[1], "ended": r[2], "how": r[3], "command": r[4]} for r in rows]


def read_records(db: sqlite3.Connection, flight: int, ids: list[int] | None = None) -> list[DroneRecord]:
    """The DroneRecords of a flight, rebuilt by replaying its entries, samples and photos in order.
    `ids`: the drones to return, in that order (a drone with nothing journaled gets an empty record)."""
    records: dict[int, DroneRecord] = {}

    def record(drone: int) -> DroneRecord:
        if drone not in records:
            records[drone] = DroneRecord(id=drone)
        return records[drone]

    for drone, kind, row in db.execute("SELECT drone, kind, row FROM entries WHERE flight = ? ORDER BY rowid",
                                       (flight,)):
        values = json.loads(row)
        if kind == "fact":
            values = [values[0], _decode(values[0], values[1])]
        record(drone).replay(kind, tuple(values))
    for drone, *sample in db.execute("SELECT drone, t, lat, lon, up, speed, boot_s, climb FROM samples "
                                     "WHERE flight = ? ORDER BY rowid", (flight,)):
        record(drone).samples.append(tuple(sample))  # type: ignore[arg-type]
    for drone, *photo in db.execute("SELECT drone, idx, t, lat, lon, up, source, roll, pitch, yaw, amsl FROM photos "
                                    "WHERE flight = ? ORDER BY rowid", (flight,)):
        record(drone).replay("photo", tuple(photo))
    if ids is None:
        return [records[k] for k in sorted(records)]
    return [record(k) for k in ids]


def read_flight(plan_dir: Path, flight: int | None = None) -> tuple[int, int, list[DroneRecord]]:
    """(flight, sortie, records) of plan_dir's journal: the latest flight, or the one asked for."""
    path = Path(plan_dir) / JOURNAL_NAME
    if not path.is_file():
        raise JournalError(f"{plan_dir}: no {JOURNAL_NAME}")
    db = _connect(path)
    try:
        where = "" if flight is None else f" WHERE flight = {int(flight)}"
        row = db.execute(f"SELECT flight, sortie FROM flights{where} ORDER BY flight DESC LIMIT 1").fetchone()
        if row is None:
            raise JournalError(f"{path}: no such flight")
        return int(row[0]), int(row[1]), read_records(db, int(row[0]))
    finally:
        db.close()
