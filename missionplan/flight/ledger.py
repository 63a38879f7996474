"""The survey ledger: every photo of a survey and the target cells each one covered, across flights,
sorties, re-plans and days, in ROOT/ledger.sqlite.

A *survey* is a plan folder (its root) and the re-plans made from it (`missionplan replan ROOT --out NEW`
writes `survey: {"root": ...}` into NEW/report.json, so NEW's flights land in ROOT's ledger). Every
re-plan keeps the root's grid and georeference, so a cell means the same ground in every folder.

`fly` records each flight it judges (flight_report.judge) and records it again when a `--resume` judges
it anew: a flight's rows are replaced, never added twice. Every coverage figure of the survey is a
query of this file; flight.json's figure for one flight uses the same rule (covered_cells).

The photos table gets a column added since the first ledgers (ADDED_COLUMNS: a MAVLink camera's) when a flight
that has it is first recorded, every row kept (NULL in it), so a survey that never needs it keeps the table as it
was; a ledger without it reads NULL for it.

Tables:
  flights(id, plan, flight, sortie, recorded)   plan: the folder, relative to the root; flight: its
                                                journal's flight number (journal.sqlite)
  photos(id, flight_id, vehicle, img_idx, time, lat, lon, alt_amsl, alt_rel, roll, pitch, yaw, source,
         image_index, file_url)                 image_index, file_url: a MAVLink camera's record (plan --capture
                                                camera*): its image_index (img_idx then is that) and the file it
                                                named; NULL for the autopilot's reports, the log's, the track's
  covered(photo, row, col)                      the root's target cells the photo holds (its footprint
                                                with plan_report.SLACK_CELLS of slack on a side)
"""

from __future__ import annotations

import os
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.geo.frame import GridFrame

from ..maps.gridmap import MapError
from ..mission.plan_record import PlanRecord, PlanRecordError, read_plan_record
from .plan_report import SLACK_CELLS, target_cells  # the judge's rule, one place
from .salvage import fault_kind

LEDGER_NAME = "ledger.sqlite"
MAX_POINTERS = 16  # re-plans of re-plans: a chain longer than this is a loop
SCHEMA = """
CREATE TABLE IF NOT EXISTS flights (id INTEGER PRIMARY KEY, plan TEXT NOT NULL, flight INTEGER NOT NULL,
                                    sortie INTEGER NOT NULL, recorded REAL NOT NULL, UNIQUE (plan, flight));
CREATE TABLE IF NOT EXISTS photos (id INTEGER PRIMARY KEY, flight_id INTEGER NOT NULL, vehicle INTEGER NOT NULL,
                                   img_idx INTEGER NOT NULL, time REAL, lat REAL NOT NULL, lon REAL NOT NULL,
                                   alt_amsl REAL, alt_rel REAL, roll REAL, pitch REAL, yaw REAL,
                                   source TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS covered (photo INTEGER NOT NULL, row INTEGER NOT NULL, col INTEGER NOT NULL);
CREATE INDEX IF NOT EXISTS photos_by_flight ON photos (flight_id);
CREATE INDEX IF NOT EXISTS covered_by_photo ON covered (photo);
"""

# Columns of the photos table added since the first ledgers: (column, its declaration), added by Ledger.add_columns.
ADDED_COLUMNS = (("image_index", "INTEGER"), ("file_url", "TEXT"))
# The photos table's columns as record_flight writes them and photos() reads them (after flight_id).
PHOTO_COLUMNS = ("vehicle", "img_idx", "time", "lat", "lon", "alt_amsl", "alt_rel", "roll", "pitch", "yaw", "source",
                 *(column for column, _ in ADDED_COLUMNS))


class LedgerError(MapError):
    """A survey that cannot be read (no plan, a broken re-plan pointer): one line for the user."""


@dataclass(frozen=True)
class LedgerPhoto:
    """One photo as the ledger keeps it: who took it, when (our clock, UTC seconds), where, how."""

    plan: str  # the plan folder, relative to the survey root ("." for the root)
    flight: int
    vehicle: int  # MAVLink system id
    img_idx: int
    time: float | None
    lat: float
    lon: float
    alt_amsl: float | None
    alt_rel: float | None
    roll: float | None
    pitch: float | None
    yaw: float | None
    source: str  # camera (its report over the link), log (the vehicle's log), track (fly --photos-from-track)
    image_index: int | None = None  # a MAVLink camera's record: its image_index
    file_url: str | None = None  # ... and the file it named on its card


@dataclass(frozen=True)
class Survey:
    """A survey's root plan: its grid, frame and coverage rule, which every folder of the survey shares."""

    root: Path
    record: PlanRecord
    frame: GridFrame
    targets: np.ndarray  # (n, 2) the root plan's reachable target cells: what the survey must photograph
    reach_m: float  # a cell is covered when a photo lies within this Chebyshev distance of its centre

    @property
    def shape(self) -> tuple[int, int]:
        return self.record.shape

    def target_mask(self) -> np.ndarray:
        mask = np.zeros(self.shape, dtype=bool)
        mask[self.targets[:, 0], self.targets[:, 1]] = True
        return mask


def read_plan(plan_dir: Path) -> PlanRecord:
    """The plan record of a folder of the survey; LedgerError (one line) when it cannot be read."""
    try:
        return read_plan_record(plan_dir)
    except PlanRecordError as err:
        raise LedgerError(str(err)) from None


def survey_root(plan_dir: Path) -> Path:
    """The root plan folder of the survey plan_dir belongs to (plan_dir itself unless it is a re-plan)."""
    here = Path(plan_dir)
    for _ in range(MAX_POINTERS):
        survey = read_plan(here).survey
        pointer = survey.root if survey is not None else None
        if not pointer:
            return here
        parent = Path(os.path.normpath(here / pointer))
        if not (parent / "report.json").is_file():
            raise LedgerError(f"{here / 'report.json'}: its survey root {parent} has no report.json (moved? "
                              "keep re-plan folders where they were made relative to the survey's first plan)")
        here = parent
    raise LedgerError(f"{plan_dir}: its survey pointers (report.json `survey`) go round in a loop")


def open_survey(plan_dir: Path) -> Survey:
    """The survey plan_dir belongs to, read from its root's report.json."""
    root = survey_root(Path(plan_dir))
    record = read_plan(root)
    if record.georeference is None:
        raise LedgerError(f"{root}: the plan has no georeference (a map without origin): nothing to fly or survey")
    frame = record.georeference.frame
    footprint = record.georeference.footprint_m
    reach = footprint / 2.0 - frame.cell_m / 2.0 + SLACK_CELLS * frame.cell_m + 1e-6
    return Survey(root=root, record=record, frame=frame, targets=target_cells(record), reach_m=reach)


def covered_cells(survey: Survey, lat: np.ndarray, lon: np.ndarray, mask: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(photo index, cell (row, col)) pairs: the cells of `mask` (default: the survey's targets) that
    the photo at (lat, lon) covers. Cell centres lie at integer grid coordinates times cell_m; a cell
    is covered when the photo lies within reach_m of its centre on both axes."""
    mask = survey.target_mask() if mask is None else mask
    lat, lon = np.atleast_1d(np.asarray(lat, float)), np.atleast_1d(np.asarray(lon, float))
    if len(lat) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2), dtype=np.int64)
    r, c = survey.frame.latlon_to_grid(lat, lon)
    pos = np.column_stack([np.atleast_1d(r), np.atleast_1d(c)]) * survey.frame.cell_m
    span = int(np.ceil(survey.reach_m / survey.frame.cell_m)) + 1
    offsets = np.arange(-span, span + 1)
    base = np.rint(pos / survey.frame.cell_m).astype(np.int64)  # (n, 2) nearest cell
    rows = base[:, 0:1, None] + offsets[None, :, None]  # (n, w, 1)
    cols = base[:, 1:2, None] + offsets[None, None, :]  # (n, 1, w)
    rows, cols = np.broadcast_arrays(rows, cols)
    photo = np.broadcast_to(np.arange(len(lat))[:, None, None], rows.shape)
    near_r = np.abs(rows * survey.frame.cell_m - pos[:, 0, None, None]) <= survey.reach_m
    near_c = np.abs(cols * survey.frame.cell_m - pos[:, 1, None, None]) <= survey.reach_m
    inside = (rows >= 0) & (rows < mask.shape[0]) & (cols >= 0) & (cols < mask.shape[1])
    keep = near_r & near_c & inside
    keep[keep] = mask[rows[keep], cols[keep]]
    return photo[keep], np.column_stack([rows[keep], cols[keep]])


class Ledger:
    """ROOT/ledger.sqlite, open. Use as a context manager, or close().

    db: an open connection to use instead (ledger_repair: a read-only one, or one in memory for a ledger
    rebuilt where the folder cannot be written); its tables are made when missing."""

    def __init__(self, survey: Survey, db: sqlite3.Connection | None = None) -> None:
        self.survey = survey
        self.path = survey.root / LEDGER_NAME
        try:
            if db is None:
                db = sqlite3.connect(self.path, isolation_level=None, timeout=10.0)
                db.execute("PRAGMA journal_mode=WAL")
                db.execute("PRAGMA synchronous=FULL")
            self._db = db
            if {"flights", "photos", "covered"} - {r[0] for r in db.execute("SELECT name FROM sqlite_master")}:
                db.executescript(SCHEMA)
            have = {row[1] for row in db.execute("PRAGMA table_info(photos)")}
            self.missing = {column for column, _ in ADDED_COLUMNS if column not in have}  # read as NULL
        except sqlite3.DatabaseError as err:
            if fault_kind(err) in ("full", "read-only"):
                raise LedgerError(f"{self.path}: cannot be written ({err})") from None
            raise LedgerError(f"{self.path}: not a missionplan survey ledger ({err})") from None

    def add_columns(self) -> None:
        """Add the columns this ledger lacks (ADDED_COLUMNS); ALTER TABLE keeps every row, NULL in them."""
        for column, declaration in ADDED_COLUMNS:
            if column in self.missing:
                self._db.execute(f"ALTER TABLE photos ADD COLUMN {column} {declaration}")
                self.missing.discard(column)

    @classmethod
    def of(cls, plan_dir: Path) -> Ledger:
        """The ledger of the survey plan_dir belongs to."""
        return cls(open_survey(plan_dir))

    def __enter__(self) -> Ledger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._db.close()

    def copy_to(self, path: Path) -> None:
        """Write this ledger, whole, as the SQLite file `path` (a temp file beside it first, then renamed), in
        place of a ledger file that is missing or was moved aside: nobody else may have `path` open."""
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            target = sqlite3.connect(tmp)
            try:
                self._db.backup(target)
            finally:
                target.close()
            for leftover in ("-wal", "-shm"):  # of a file no longer there: SQLite would apply them to this one
                path.with_name(path.name + leftover).unlink(missing_ok=True)
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)

    def plan_key(self, plan_dir: Path) -> str:
        return os.path.relpath(Path(plan_dir).resolve(), self.survey.root.resolve())

    # -- writing
    def record_flight(self, plan_dir: Path | str, flight: int, sortie: int, photos: list[dict[str, Any]],
                      recorded: float | None = None) -> int:
        """Put one flight's photos (dicts with LedgerPhoto's fields but plan and flight) and the cells they
        cover into the ledger, replacing what an earlier judgement of the same flight put there. One
        transaction: a crash leaves the flight's old rows or its new ones, never half. plan_dir: the folder,
        or its key (plan_key) as a string; recorded: when it was judged (default now)."""
        plan = plan_dir if isinstance(plan_dir, str) else self.plan_key(plan_dir)
        recorded = time.time() if recorded is None else recorded
        lat = np.array([p["lat"] for p in photos], dtype=float)
        lon = np.array([p["lon"] for p in photos], dtype=float)
        which, cells = covered_cells(self.survey, lat, lon)
        if any(p.get(column) is not None for p in photos for column, _ in ADDED_COLUMNS):
            self.add_columns()  # a MAVLink camera's photos: the ledger keeps its image_index and file_url from now on
        columns = [c for c in PHOTO_COLUMNS if c not in self.missing]
        insert = f"INSERT INTO photos (flight_id, {', '.join(columns)}) VALUES (?{', ?' * len(columns)})"
        with self._db:
            self._db.execute("BEGIN")
            old = self._db.execute("SELECT id FROM flights WHERE plan = ? AND flight = ?", (plan, flight)).fetchone()
            if old is not None:
                self._db.execute("DELETE FROM covered WHERE photo IN (SELECT id FROM photos WHERE flight_id = ?)",
                                 (old[0],))
                self._db.execute("DELETE FROM photos WHERE flight_id = ?", (old[0],))
                self._db.execute("UPDATE flights SET sortie = ?, recorded = ? WHERE id = ?", (sortie, recorded, old[0]))
                flight_id = int(old[0])
            else:
                flight_id = int(self._db.execute("INSERT INTO flights (plan, flight, sortie, recorded) VALUES (?, ?, ?, ?)",
                                                 (plan, flight, sortie, recorded)).lastrowid)
            ids = []
            for p in photos:
                image_index = p.get("image_index")
                values = dict(zip(PHOTO_COLUMNS, (
                    int(p["vehicle"]), int(p["img_idx"]), p.get("time"), float(p["lat"]), float(p["lon"]),
                    p.get("alt_amsl"), p.get("alt_rel"), p.get("roll"), p.get("pitch"), p.get("yaw"), str(p["source"]),
                    None if image_index is None else int(image_index), p.get("file_url") or None)))
                ids.append(self._db.execute(insert, (flight_id, *(values[c] for c in columns))).lastrowid)
            photo_ids = np.array(ids, dtype=np.int64)
            self._db.executemany("INSERT INTO covered (photo, row, col) VALUES (?, ?, ?)",
                                 zip(photo_ids[which].tolist(), cells[:, 0].tolist(), cells[:, 1].tolist()))
        return len(photos)

    # -- reading
    def _which(self, plan_dir: Path | None, flight: int | None) -> tuple[str, list[Any]]:
        """A WHERE clause on the flights table `f` (one folder, one of its flights, or all) and its values."""
        where, args = [], []
        if plan_dir is not None:
            where.append("f.plan = ?")
            args.append(self.plan_key(plan_dir))
        if flight is not None:
            where.append("f.flight = ?")
            args.append(int(flight))
        return (" WHERE " + " AND ".join(where) if where else ""), args

    def flights(self) -> list[dict[str, Any]]:
        rows = self._db.execute("SELECT f.plan, f.flight, f.sortie, f.recorded, COUNT(p.id) FROM flights f LEFT JOIN "
                                "photos p ON p.flight_id = f.id GROUP BY f.id ORDER BY f.recorded").fetchall()
        return [{"plan": r[0], "flight": r[1], "sortie": r[2], "recorded": r[3], "photos": r[4]} for r in rows]

    def photos(self, plan_dir: Path | None = None, flight: int | None = None) -> list[LedgerPhoto]:
        """The photos of the survey, or of one folder, or of one of its flights, in the order taken."""
        where, args = self._which(plan_dir, flight)
        columns = ", ".join("NULL" if c in self.missing else f"p.{c}" for c in PHOTO_COLUMNS)
        sql = (f"SELECT f.plan, f.flight, {columns} FROM photos p JOIN flights f ON f.id = p.flight_id"
               + where + " ORDER BY f.id, p.vehicle, p.img_idx")
        return [LedgerPhoto(*row) for row in self._db.execute(sql, args)]

    def covered_mask(self, plan_dir: Path | None = None, flight: int | None = None) -> np.ndarray:
        """The survey's target cells some photo covered (of one folder / flight when asked), as a grid mask."""
        where, args = self._which(plan_dir, flight)
        sql = ("SELECT DISTINCT c.row, c.col FROM covered c JOIN photos p ON p.id = c.photo JOIN flights f ON "
               "f.id = p.flight_id" + where)
        cells = np.array(self._db.execute(sql, args).fetchall(), dtype=np.int64).reshape(-1, 2)
        mask = np.zeros(self.survey.shape, dtype=bool)
        mask[cells[:, 0], cells[:, 1]] = True
        return mask & self.survey.target_mask()

    def missing_cells(self) -> np.ndarray:
        """(n, 2) the survey's reachable target cells no photo of the ledger covered yet."""
        covered = self.covered_mask()
        t = self.survey.targets
        return t[~covered[t[:, 0], t[:, 1]]]

