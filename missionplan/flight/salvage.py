"""The SQLite files of a flight (the journal, the survey ledger) when the disk does not play along:
a damaged file read row by row, a read-only one read without writing, a failed write told apart.

Python's sqlite3 has no binding for SQLite's recovery extension, so a damaged file (bytes overwritten,
the file cut short) is read through SQLite itself, one table at a time, in rowid order: a range read
stops at the first damaged page, and the reader skips ahead (doubling the jump, then narrowing it
down) to the first rowid that reads again. What lies on a damaged page is lost; everything else is
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


def _reads_from(db: sqlite3.Connection, sql: str, after: int) -> bool:
    try:
        db.execute(sql, (after, 1)).fetchall()
        return True
    except sqlite3.DatabaseError:
        return False


def salvage_table(db: sqlite3.Connection, table: str, columns: str) -> TableSalvage:
    """Every row of `table` SQLite can still read (rowid, then `columns`), in rowid order."""
    out = TableSalvage(table)
    sql = f"SELECT rowid, {columns} FROM {table} WHERE rowid > ? ORDER BY rowid LIMIT ?"
    after = -MAX_ROWID
    while True:
        try:
            batch = db.execute(sql, (after, BATCH)).fetchall()
        except sqlite3.DatabaseError:
            batch = None
        if batch:
            out.rows.extend(batch)
            after = int(batch[-1][0])
            continue
        if batch is not None:
            return out  # the end of the table
        # A damaged page after `after`: rows one at a time up to it, then the first rowid past it that reads.
        while True:
            try:
                row = db.execute(sql, (after, 1)).fetchall()
            except sqlite3.DatabaseError:
                break
            if not row:
                return out
            out.rows.append(row[0])
            after = int(row[0][0])
        start = max(after, 0)
        jump = 1
        while start + jump < MAX_ROWID and not _reads_from(db, sql, start + jump):
            jump *= 2
        if start + jump >= MAX_ROWID:  # nothing reads past the damage: the rest of the table is lost
            if not out.rows and after < 0:
                out.unreadable = True
            out.lost.append((start + 1, None))
            return out
        low, high = start + jump // 2, start + jump  # low does not read (or is start), high does
        while high - low > 1:
            middle = (low + high) // 2
            if _reads_from(db, sql, middle):
                high = middle
            else:
                low = middle
        # Reading from `high` works: the rows after it are readable; those in (start, first row after high) are lost.
        nxt = db.execute(sql, (high, 1)).fetchall()
        first_after = int(nxt[0][0]) if nxt else None
        out.lost.append((start + 1, (first_after - 1) if first_after is not None else None))
        if first_after is None:
            return out
        after = high


def table_columns(db: sqlite3.Connection, table: str) -> list[str] | None:
    """The columns of `table` as its schema says, None when the schema cannot be read or has no such table."""
    try:
        rows = db.execute(f"PRAGMA table_info({table})").fetchall()
    except sqlite3.DatabaseError:
        return None
    return [str(r[1]) for r in rows] or None
