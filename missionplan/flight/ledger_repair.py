"""A survey ledger whatever state its file is in: `open_ledger`, for `status`, `replan` and the judge.

Every row of the ledger (ledger.py) was put there by the judge from a flight's journal, so the ledger
can be made again: for every flight a journal says was judged, the judge's own photo rule
(photo_positions.flight_photos) gives the same rows. Hence:
- a missing ledger is rebuilt from the journals of the folder given, of the survey's root and of the
  re-plans beside the root (`replan --out ../NEW`: their report.json points back to it);
- a damaged one (quick_check fails) is moved aside to ledger.sqlite.damaged and rebuilt the same way,
  from the journals of every folder it names too, its own readable rows (salvage.py, row by row)
  standing in for the flights whose journals are not at hand;
- one in a folder that cannot be written (a read-only disk) is read without writing anything, and
  when it must be rebuilt, is rebuilt in memory.
A ledger rebuilt is built in memory and written whole in place (Ledger.copy_to). Each repair is said in
one line through `say`: the file, the damage, what was rebuilt from where, what was lost.
"""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import Any

from missionplan.base.atomic import probe_writable

from .photo_positions import flight_photos
from .journal_db import JOURNAL_NAME, JournalError
from .journal_read import judged_flights
from .ledger import LEDGER_NAME, PHOTO_COLUMNS, Ledger, LedgerError, Survey, open_survey, read_plan, survey_root
from .salvage import (connect_read_only, fault_kind, has_sqlite_header, integrity_problem, move_aside,
                      salvage_table, table_columns)

Say = Callable[[str], None]


def _writable(folder: Path) -> bool:
    try:
        probe_writable(folder)
        return True
    except OSError:
        return False


def _in_memory(survey: Survey) -> Ledger:
    return Ledger(survey, sqlite3.connect(":memory:", isolation_level=None))


def _folder_name(survey: Survey, key: str) -> str:
    return str(survey.root) if key == "." else str(Path(os.path.normpath(survey.root / key)))


def _from_journals(ledger: Ledger, survey: Survey,
                   keys: list[str]) -> tuple[set[tuple[str, int]], list[str], list[str]]:
    """Record every judged flight of the journals of the folders `keys` (relative to the root) into the
    ledger, as the judge did: ((key, flight) recorded, the folders whose journals gave flights, the
    journals that could not be read, one line each)."""
    done: set[tuple[str, int]] = set()
    used: list[str] = []
    unread: list[str] = []
    for key in keys:
        folder = Path(os.path.normpath(survey.root / key))
        try:
            judged = judged_flights(folder)
            record = read_plan(folder) if judged else None
        except (JournalError, LedgerError) as err:
            unread.append(str(err))
            continue
        for flight in judged:
            assert record is not None  # read above, since a flight was judged
            ledger.record_flight(key, flight.flight, flight.sortie,
                                 flight_photos(record, flight.records, flight.photos_from_track),
                                 recorded=flight.judged)
            done.add((key, flight.flight))
        if judged:
            used.append(_folder_name(survey, key))
    return done, used, unread


def _replans(survey: Survey) -> list[Path]:
    """The re-plan folders of the survey found beside its root or inside it (where `replan --out` puts them:
    a folder whose report.json names the root as its survey's). A re-plan elsewhere is found only through
    the folder given or the damaged ledger's own rows."""
    root = survey.root.resolve()
    found = []
    for parent in (root.parent, root):
        try:
            children = sorted(p for p in parent.iterdir() if p.is_dir() and p.resolve() != root)
        except OSError:
            continue
        for folder in children:
            try:
                if (folder / "report.json").is_file() and survey_root(folder).resolve() == root:
                    found.append(folder)
            except LedgerError:
                continue
    return found


def _keys(ledger: Ledger, plan_dir: Path, more: list[str] | None = None) -> list[str]:
    """The folders whose journals a rebuild reads, as ledger keys: the root, the folder given, the re-plans
    beside the root, and `more`."""
    keys: list[str] = []
    for key in [".", ledger.plan_key(plan_dir), *(ledger.plan_key(f) for f in _replans(ledger.survey)), *(more or [])]:
        if key not in keys:
            keys.append(key)
    return keys


def _settle(ledger: Ledger, survey: Survey, writable: bool) -> tuple[Ledger, str]:
    """The rebuilt ledger (in memory) written in place when the folder takes it: (the ledger to use, what
    to add to the line that says so)."""
    if not writable:
        return ledger, "; kept in memory only: the folder cannot be written"
    try:
        ledger.copy_to(ledger.path)
    except (OSError, sqlite3.Error) as err:
        return ledger, f"; kept in memory only: it could not be written ({err})"
    ledger.close()
    return Ledger(survey), ""


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _rebuild_missing(survey: Survey, plan_dir: Path, writable: bool, say: Say) -> Ledger:
    ledger = _in_memory(survey)
    done, used, unread = _from_journals(ledger, survey, _keys(ledger, plan_dir))
    if not done and not unread:  # never flown (or never judged): an empty ledger, as a new survey has
        ledger.close()
        return Ledger(survey) if writable else _in_memory(survey)
    ledger, where = _settle(ledger, survey, writable)
    photos = sum(f["photos"] for f in ledger.flights())
    text = (f"{ledger.path}: missing; rebuilt from the {JOURNAL_NAME} of {', '.join(used) or 'no folder'}: "
            f"{_plural(len(done), 'flight')}, {_plural(photos, 'photo')}{where}")
    if unread:
        text += "; not read: " + "; ".join(unread)
    say(text)
    return ledger


def _rows(n: int | None, what: str) -> str:
    return f"the {what} rows after the damage" if n is None else _plural(n, f"{what} row")


def _lost(flights: Any, photos: Any, from_rows: int, orphans: int) -> str:
    """What a damaged ledger's rebuild could not bring back. A flight in a journal is never lost; the rows
    that could not be read are lost only for the flights no journal holds."""
    if flights is None or photos is None:
        return "whatever it held of flights no journal here holds (its tables cannot be read)"
    parts = []
    if flights.lost_rows != 0:
        parts.append(f"{_rows(flights.lost_rows, 'flight')} unreadable (with {_plural(orphans, 'photo')}): "
                     "their flights, unless a journal here holds them")
    if from_rows and photos.lost_rows != 0:
        parts.append(f"{_rows(photos.lost_rows, 'photo')} unreadable, of the flights rebuilt from its rows")
    return "; ".join(parts) or "nothing"


def _rebuild_damaged(survey: Survey, plan_dir: Path, writable: bool, damage: str, say: Say) -> Ledger:
    path = survey.root / LEDGER_NAME
    aside = move_aside(path) if writable else None
    src = sqlite3.connect(aside, isolation_level=None) if aside is not None else connect_read_only(path)
    try:
        src.execute("PRAGMA writable_schema=ON")  # read the tables even when an index's pages are gone
        flights = salvage_table(src, "flights", "plan, flight, sortie, recorded")
        have = table_columns(src, "photos")  # a ledger from before a column: NULL for it
        if have is None:
            raise sqlite3.DatabaseError("the photos table's schema cannot be read")
        photos = salvage_table(src, "photos", "flight_id, " + ", ".join(c if c in have else "NULL"
                                                                        for c in PHOTO_COLUMNS))
    except sqlite3.DatabaseError:  # not even its schema: the journals alone
        flights = photos = None
    finally:
        src.close()
    ledger = _in_memory(survey)
    named = sorted({str(row[1]) for row in flights.rows}) if flights is not None else []
    done, used, unread = _from_journals(ledger, survey, _keys(ledger, plan_dir, named))
    from_rows, rows_used, orphans = 0, 0, 0
    if flights is not None and photos is not None:
        by_flight: dict[int, list[dict[str, Any]]] = {}
        for row in photos.rows:
            by_flight.setdefault(int(row[1]), []).append(dict(zip(PHOTO_COLUMNS, row[2:])))
        known = {int(row[0]) for row in flights.rows}
        orphans = sum(len(rows) for flight_id, rows in by_flight.items() if flight_id not in known)
        for flight_id, key, flight, sortie, recorded in flights.rows:
            if (str(key), int(flight)) in done:
                continue
            kept = by_flight.get(int(flight_id), [])
            ledger.record_flight(str(key), int(flight), int(sortie), kept, recorded=float(recorded))
            from_rows += 1
            rows_used += len(kept)
    ledger, where = _settle(ledger, survey, writable)
    kept_as = f"kept as {aside.name}" if aside is not None else "left as it is (the folder cannot be written)"
    parts = [f"{_plural(len(done), 'flight')} from the {JOURNAL_NAME} of {', '.join(used)}" if done else "",
             f"{_plural(from_rows, 'flight')} ({_plural(rows_used, 'photo')}) from its readable rows"
             if from_rows else ""]
    rebuilt = " and ".join(p for p in parts if p) or "nothing (no flight could be read)"
    lost = _lost(flights, photos, from_rows, orphans)
    text = f"{path}: damaged ({damage}); {kept_as}; rebuilt: {rebuilt}{where}; lost: {lost}"
    if unread:
        text += "; not read: " + "; ".join(unread)
    say(text)
    return ledger


def open_ledger(plan_dir: Path, say: Say) -> Ledger:
    """The ledger of the survey plan_dir belongs to, repaired or rebuilt when it has to be (said through
    `say`, one line). Raises LedgerError for a folder that is no plan, or a file that is no SQLite file."""
    plan_dir = Path(plan_dir)
    survey = open_survey(plan_dir)
    path = survey.root / LEDGER_NAME
    writable = _writable(survey.root)
    if not path.exists():
        return _rebuild_missing(survey, plan_dir, writable, say)
    if not has_sqlite_header(path):
        raise LedgerError(f"{path}: not a missionplan survey ledger (no SQLite header: another kind of file, or its "
                          "first bytes were overwritten)")
    damage = None
    try:
        check = sqlite3.connect(path, isolation_level=None) if writable else connect_read_only(path)
        try:
            damage = integrity_problem(check)
        finally:
            check.close()
    except sqlite3.Error as err:
        if fault_kind(err) != "damaged":
            raise LedgerError(f"{path}: cannot be opened ({err})") from None
        damage = str(err)
    if damage:
        return _rebuild_damaged(survey, plan_dir, writable, damage, say)
    if writable:
        return Ledger(survey)
    try:
        return Ledger(survey, connect_read_only(path))
    except sqlite3.Error as err:
        raise LedgerError(f"{path}: cannot be read ({err})") from None
