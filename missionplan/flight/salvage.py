"""The SQLite files of a flight (the journal, the survey ledger) when the disk does not play along:
a damaged file read row by row, a read-only one read without writing, a failed write told apart.

Python's sqlite3 has no binding for SQLite's recovery extension, so a damaged file (bytes overwritten,
the file cut short) is read through SQLite itself, one table at a time, in rowid order: a range read
stops at the first damaged page, and the reader skips ahead (doubling the jump, then narrowing it
down) to the first rowid that reads again; then it reads the table backwards from its end down to the
damage (a table cut short), and looks up each rowid of a gap on its own (a row that a range read cannot
step to may still be found from the root). What lies on a damaged page is lost; everything else is
returned, with the rowid ranges that could not be read. The damaged file itself is never written.

`integrity_problem` is the check that tells a damaged file from a sound one (SQLite's quick_check:
every page of every b-tree, not the values inside the rows). `fault_kind` sorts a failed write: a full
disk, a read-only file or folder, damage, or anything else.
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

SQLITE_MAGIC = b"SQLite format 3\x00"
BATCH = 512  # rows per range read
MAX_ROWID = 2 ** 62  # past any rowid a table of ours reaches
POINT_LOOKUPS = 100_000  # a gap of at most this many rowids is looked up rowid by rowid


FaultKind = Literal["full", "read-only", "damaged", "other"]


def fault_kind(err: BaseException) -> FaultKind:
    """What a failed SQLite call says of the file: a full disk (SQLite's SQLITE_FULL, its word for ENOSPC),
    a file or folder that cannot be written, a damaged file, or something else (an I/O error, a quota)."""
    code = getattr(err, "sqlite_errorcode", None)
    primary = code & 0xFF if isinstance(code, int) else None
    if primary == sqlite3.SQLITE_FULL:
        return "full"
    if primary in (sqlite3.SQLITE_READONLY, sqlite3.SQLITE_CANTOPEN, sqlite3.SQLITE_PERM):
        return "read-only"
    if primary in (sqlite3.SQLITE_CORRUPT, sqlite3.SQLITE_NOTADB):
        return "damaged"
    return "other"


def connect_read_only(path: Path) -> sqlite3.Connection:
    """A connection that never writes `path` nor creates a file beside it (a folder on a read-only disk):
    SQLite's read-only mode when a -wal file is there to be read, else the file taken as immutable."""
    wal = path.with_name(path.name + "-wal")
    mode = "mode=ro" if wal.exists() else "immutable=1"
    return sqlite3.connect(f"{path.resolve().as_uri()}?{mode}", uri=True, check_same_thread=False)


def move_aside(path: Path, suffix: str = ".damaged") -> Path:
    """Rename a damaged database (and its -wal, which SQLite reads under the new name) out of the way,
    to PATH.damaged (PATH.damaged-2... when taken); its -shm, an index rebuilt from the -wal, is removed."""
    target = path.with_name(path.name + suffix)
    k = 2
    while target.exists():
        target = path.with_name(f"{path.name}{suffix}-{k}")
        k += 1
    path.rename(target)
    wal = path.with_name(path.name + "-wal")
    if wal.exists():
        wal.rename(target.with_name(target.name + "-wal"))
    path.with_name(path.name + "-shm").unlink(missing_ok=True)
    return target


def has_sqlite_header(path: Path) -> bool:
    """Whether the file starts as every SQLite database does (an empty file is a database not yet written)."""
    with open(path, "rb") as f:
        head = f.read(len(SQLITE_MAGIC))
    return not head or head == SQLITE_MAGIC


def integrity_problem(db: sqlite3.Connection) -> str | None:
    """What SQLite's quick_check finds wrong with the open database (its first complaint), None when sound."""
    try:
        rows = db.execute("PRAGMA quick_check").fetchall()
    except sqlite3.DatabaseError as err:
        return str(err)
    lines = [line for row in rows for line in str(row[0]).splitlines()
             if line not in ("ok", "") and not line.startswith("*** in database")]
    if not lines:
        return None
    return lines[0] if len(lines) == 1 else f"{lines[0]} (and {len(lines) - 1} more)"


@dataclass
class TableSalvage:
    """The rows of one table that could be read (rowid first), and the rowid ranges that could not."""

    table: str
    rows: list[tuple[Any, ...]] = field(default_factory=list)
    lost: list[tuple[int, int | None]] = field(default_factory=list)  # (first, last) rowids; last None: to the end
    unreadable: bool = False  # not even its first page could be read

    @property
    def lost_rows(self) -> int | None:
        """How many rows were lost, counting the rowids skipped (None when the table's end was lost)."""
        if any(last is None for _, last in self.lost):
            return None
        return sum(last - first + 1 for first, last in self.lost)  # type: ignore[operator]


def _read(db: sqlite3.Connection, sql: str, after: int, limit: int) -> tuple[list[tuple[Any, ...]], bool]:
    """(the rows past rowid `after`, up to `limit`, in order; whether the read ran into damage: an error, or a
    rowid not past the one before it, which a damaged page read as garbage gives)."""
    try:
        rows = db.execute(sql, (after, limit)).fetchall()
    except sqlite3.DatabaseError:
        return [], True
    good: list[tuple[Any, ...]] = []
    for row in rows:
        if not isinstance(row[0], int) or row[0] <= after:
            return good, True
        good.append(row)
        after = row[0]
    return good, False


def _readable(db: sqlite3.Connection, sql: str, after: int) -> bool:
    return not _read(db, sql, after, 1)[1]


def _forward(db: sqlite3.Connection, sql: str) -> tuple[list[tuple[Any, ...]], list[tuple[int, int | None]]]:
    """The rows a forward read gets, skipping each damaged stretch; and the rowid ranges skipped."""
    out: list[tuple[Any, ...]] = []
    lost: list[tuple[int, int | None]] = []
    after = -MAX_ROWID
    while True:
        rows, damaged = _read(db, sql, after, BATCH)
        out.extend(rows)
        after = int(rows[-1][0]) if rows else after
        if not damaged:
            if len(rows) < BATCH:
                return out, lost  # the end of the table
            continue
        # Damage past `after`: the rows before it one at a time (a batch read fails as a whole)...
        while True:
            one, damaged = _read(db, sql, after, 1)
            if damaged:
                break
            if not one:
                return out, lost
            out.append(one[0])
            after = int(one[0][0])
        # ...then the first rowid past it that reads again: jumps doubling, then halving back.
        start = max(after, 0)
        jump = 1
        while start + jump < MAX_ROWID and not _readable(db, sql, start + jump):
            jump *= 2
        if start + jump >= MAX_ROWID:  # nothing reads past the damage going forward
            lost.append((start + 1, None))
            return out, lost
        low, high = start + jump // 2, start + jump  # reading past `low` fails (or low is start), past `high` works
        while high - low > 1:
            middle = (low + high) // 2
            if _readable(db, sql, middle):
                high = middle
            else:
                low = middle
        nxt, _ = _read(db, sql, high, 1)
        if not nxt:
            lost.append((start + 1, None))
            return out, lost
        lost.append((start + 1, int(nxt[0][0]) - 1))
        after = high


def _backward(db: sqlite3.Connection, table: str, columns: str, above: int) -> list[tuple[Any, ...]]:
    """The rows past rowid `above` read from the table's end down, until the first damage."""
    sql = f"SELECT rowid, {columns} FROM {table} WHERE rowid > ? AND rowid < ? ORDER BY rowid DESC LIMIT ?"
    out: list[tuple[Any, ...]] = []
    below = MAX_ROWID
    for limit in (BATCH, 1):  # in batches, then one at a time up to the damage
        while True:
            try:
                rows = db.execute(sql, (above, below, limit)).fetchall()
            except sqlite3.DatabaseError:
                break
            good = []
            for row in rows:
                if not isinstance(row[0], int) or not above < row[0] < below:
                    break
                good.append(row)
                below = row[0]
            out.extend(good)
            if len(good) < len(rows):
                break
            if len(rows) < limit:
                return out
    return out


def _looked_up(db: sqlite3.Connection, table: str, columns: str, first: int, last: int) -> list[tuple[Any, ...]]:
    """The rows of rowids first..last that a lookup from the table's root still finds."""
    sql = f"SELECT rowid, {columns} FROM {table} WHERE rowid = ?"
    out = []
    for rowid in range(first, last + 1):
        try:
            row = db.execute(sql, (rowid,)).fetchone()
        except sqlite3.DatabaseError:
            continue
        if row is not None and row[0] == rowid:
            out.append(row)
    return out


def _gaps(kept: set[int], lost: list[tuple[int, int | None]]) -> list[tuple[int, int | None]]:
    """The runs of rowids in the ranges `lost` that are not in `kept`."""
    runs: list[tuple[int, int | None]] = []
    for first, last in lost:
        end = last if last is not None else max((r for r in kept if r >= first), default=first - 1)
        run_start = None
        for rowid in range(first, end + 1):
            if rowid in kept:
                if run_start is not None:
                    runs.append((run_start, rowid - 1))
                    run_start = None
            elif run_start is None:
                run_start = rowid
        if last is None:
            runs.append((run_start if run_start is not None else end + 1, None))
        elif run_start is not None:
            runs.append((run_start, end))
    return runs


def salvage_table(db: sqlite3.Connection, table: str, columns: str) -> TableSalvage:
    """Every row of `table` SQLite can still read (rowid, then `columns`), in rowid order."""
    out = TableSalvage(table)
    rows, lost = _forward(db, f"SELECT rowid, {columns} FROM {table} WHERE rowid > ? ORDER BY rowid LIMIT ?")
    found = {int(row[0]): row for row in rows}
    if lost:  # from the table's end down to the first damage: what a forward read cannot step to
        for row in _backward(db, table, columns, lost[0][0] - 1):
            found.setdefault(int(row[0]), row)
        if lost[-1][1] is None and any(r >= lost[-1][0] for r in found):
            # The end was read backwards: the gap before it is bounded (past the highest rowid is the end).
            lost[-1] = (lost[-1][0], max(found))
    for first, last in list(lost):
        if last is not None and last - first < POINT_LOOKUPS:
            for row in _looked_up(db, table, columns, first, last):
                found.setdefault(int(row[0]), row)
    out.rows = [found[r] for r in sorted(found)]
    out.lost = _gaps(set(found), lost)
    out.unreadable = not out.rows and bool(out.lost)
    return out


def table_columns(db: sqlite3.Connection, table: str) -> list[str] | None:
    """The columns of `table` as its schema says, None when the schema cannot be read or has no such table."""
    try:
        rows = db.execute(f"PRAGMA table_info({table})").fetchall()
    except sqlite3.DatabaseError:
        return None
    return [str(r[1]) for r in rows] or None
