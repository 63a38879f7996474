"""The flight journal's database: its file names, tables and columns, its connections, and a change of a
DroneRecord as a row.

One SQLite database per plan folder, DIR/journal.sqlite, in WAL mode with synchronous=FULL: a committed
transaction survives the process being killed and the machine losing power. Tables:
  flights(flight, sortie, started, judged, photos_from_track)   judged: when a run last wrote flight.json
                                             from it; photos_from_track: judged with --photos-from-track
  runs(run, flight, started, ended, how, command, commits)   how: "fly" or "resume"; ended NULL: it was
                                             killed; commits: the transactions it committed
  entries(flight, drone, kind, row)          every change of a DroneRecord, in order; row as JSON
  samples(flight, drone, t, lat, lon, up, speed, boot_s, climb)   the positions, the bulk, in columns
  photos(flight, drone, idx, t, lat, lon, up, source, roll, pitch, yaw, amsl, file_url)   file_url: a MAVLink
                                             camera's record names its file ('' none); NULL for other reports
Columns added since the first journals are added when an older journal is opened for writing (`migrate`).
journal.py writes it, journal_read.py reads it back, journal_repair.py salvages a damaged one.
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import asdict
from pathlib import Path
from typing import Any

from missionplan.bridge.formats.mission_items import WireItem

JOURNAL_NAME = "journal.sqlite"
COUNTER_NAME = "journal.commits"
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
                                   yaw REAL, amsl REAL, file_url TEXT);
CREATE INDEX IF NOT EXISTS entries_by_drone ON entries (flight, drone);
CREATE INDEX IF NOT EXISTS samples_by_drone ON samples (flight, drone);
CREATE INDEX IF NOT EXISTS photos_by_drone ON photos (flight, drone);
"""
# Columns added since the first journals: (table, column, its declaration). Added when an older journal is
# opened for writing; readers select NULL for them.
ADDED_COLUMNS = (("photos", "amsl", "REAL"), ("runs", "commits", "INTEGER NOT NULL DEFAULT 0"),
                 ("flights", "photos_from_track", "INTEGER"), ("photos", "file_url", "TEXT"))
TABLES = ("flights", "runs", "entries", "samples", "photos")
ENTRY_KINDS = ("fact", "event", "reached", "landed", "problem", "note", "gimbal")


class JournalError(Exception):
    """A journal that cannot be used as asked (none to resume, not ours, damaged beyond repair, read-only):
    one line for the user."""


def connect(path: Path) -> sqlite3.Connection:
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


def migrate(db: sqlite3.Connection) -> None:
    db.executescript(SCHEMA)
    for table, column, declaration in ADDED_COLUMNS:
        if column not in column_names(db, table):  # a journal from before it
            db.execute(f"ALTER TABLE {table} ADD COLUMN {column} {declaration}")


def column_names(db: sqlite3.Connection, table: str) -> set[str]:
    return {row[1] for row in db.execute(f"PRAGMA table_info({table})")}


def not_a_journal(path: Path, err: Any) -> JournalError:
    return JournalError(f"{path}: not a missionplan flight journal ({err})")


def encode(name: str, value: Any) -> Any:
    if name == "wire":
        return [asdict(item) for item in value]
    return value


def decode(name: str, value: Any) -> Any:
    if name == "wire":
        return [WireItem(**item) for item in value]
    return value


def entry_row(kind: str, row: tuple[Any, ...]) -> list[Any]:
    drone, *rest = row
    if kind == "fact":
        rest = [rest[0], encode(rest[0], rest[1])]
    return [drone, kind, json.dumps(rest)]

