"""A flight journal read back: a flight's DroneRecords, rebuilt by replaying its rows in order.

Entries are replayed through DroneRecord.replay, so the record read back is the record that was kept. Read
beside a running writer, or read-only where the folder cannot be written, and never altered: a journal
written by an older fly may lack a table or a column. `read_flight`: the latest flight (or one asked for),
for flight.json and `fly --resume`; `judged_flights`: every flight fly judged, for a rebuilt survey ledger.
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass
from pathlib import Path

from .journal_db import JOURNAL_NAME, JournalError, column_names, decode, not_a_journal
from .record import DroneRecord
from .salvage import connect_read_only, fault_kind, has_sqlite_header, integrity_problem


def read_records(db: sqlite3.Connection, flight: int, ids: list[int] | None = None) -> list[DroneRecord]:
    """The DroneRecords of a flight, rebuilt by replaying its entries, samples and photos in order.
    `ids`: the drones to return, in that order (a drone with nothing journaled gets an empty record)."""
    records: dict[int, DroneRecord] = {}

    def record(drone: int) -> DroneRecord:
        if drone not in records:
            records[drone] = DroneRecord(id=drone)
        return records[drone]

    # Read as it is, never altered: a journal written by an older fly may lack a table or a column.
    have = {table: column_names(db, table) for table in ("entries", "samples", "photos")}
    if have["entries"]:
        for drone, kind, row in db.execute("SELECT drone, kind, row FROM entries WHERE flight = ? ORDER BY rowid",
                                           (flight,)):
            values = json.loads(row)
            if kind == "fact":
                values = [values[0], decode(values[0], values[1])]
            record(drone).replay(kind, tuple(values))
    if have["samples"]:
        for drone, *sample in db.execute("SELECT drone, t, lat, lon, up, speed, boot_s, climb FROM samples "
                                         "WHERE flight = ? ORDER BY rowid", (flight,)):
            record(drone).samples.append(tuple(sample))  # type: ignore[arg-type]
    if have["photos"]:
        amsl, url = (name if name in have["photos"] else "NULL" for name in ("amsl", "file_url"))
        for drone, *photo in db.execute(f"SELECT drone, idx, t, lat, lon, up, source, roll, pitch, yaw, {amsl}, {url} "
                                        "FROM photos WHERE flight = ? ORDER BY rowid", (flight,)):
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
            raise not_a_journal(path, err) from None
    return connect_read_only(path)


def read_flight(plan_dir: Path, flight: int | None = None) -> tuple[int, int, list[DroneRecord]]:
    """(flight, sortie, records) of plan_dir's journal: the latest flight, or the one asked for."""
    path = Path(plan_dir) / JOURNAL_NAME
    if not path.is_file():
        raise JournalError(f"{plan_dir}: no {JOURNAL_NAME}")
    if not has_sqlite_header(path):
        raise not_a_journal(path, "no SQLite header")
    db = _open_to_read(path)
    try:
        where = "" if flight is None else f" WHERE flight = {int(flight)}"
        row = db.execute(f"SELECT flight, sortie FROM flights{where} ORDER BY flight DESC LIMIT 1").fetchone()
        if row is None:
            raise JournalError(f"{path}: no such flight")
        return int(row[0]), int(row[1]), read_records(db, int(row[0]))
    except sqlite3.DatabaseError as err:
        raise not_a_journal(path, err) from None
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
        raise not_a_journal(path, "no SQLite header")
    db = _open_to_read(path)
    try:
        damage = integrity_problem(db)
        if damage:
            raise JournalError(f"{path}: damaged ({damage})")
        track = "photos_from_track" if "photos_from_track" in column_names(db, "flights") else "NULL"
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

