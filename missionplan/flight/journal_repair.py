"""A damaged flight journal repaired: moved aside, and what SQLite can still read of it copied into a new one.

The rows are read table by table, past the damaged pages (flight/salvage.py); a row that does not read as
one of ours (a damaged page, or a page cut short, can yield garbage) is dropped and counted as lost.
`salvage_journal` says, in one line, what was recovered and what was lost.
"""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path
from typing import Any

from .journal_db import COUNTER_NAME, ENTRY_KINDS, TABLES, JournalError, column_names, connect, migrate
from .record import PHOTO_SOURCES
from .salvage import TableSalvage, move_aside, salvage_table, table_columns


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
        db = connect(path)
        migrate(db)
        db.execute("BEGIN")
        for table in TABLES:
            got = salvaged[table]
            if got is None:
                lost.append(f"the whole {table} table")
                continue
            columns, rows = got
            ours = column_names(db, table)
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

