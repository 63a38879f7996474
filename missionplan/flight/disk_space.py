"""How much disk a flight's record takes in its plan folder, checked before `fly` opens any link.

The record is the journal (journal.py: a row per position sample, per photo, per other change of a
drone's record), its write-ahead log, and the files fly writes once the flight is judged (flight.json,
flight.png, flight.html / .gpkg / .kmz, missed.geojson, the ledger's rows, photos.csv / .geojson and
geo.txt). Each term below is a size measured by bench/journal_bench.py (which prints them, and the
estimate next to what real mock flights wrote), never a guess; the estimate is an upper bound:
- every drone is followed for as long as fly would wait for it at most (link_silence's LINK_WAIT_FACTOR
  times its planned flight plus LINK_MARGIN_S, vehicle seconds), at the telemetry rate asked, in
  vehicle seconds (a sped-up simulator sends fewer samples per vehicle second, a real vehicle as many);
- every planned photo is taken PHOTO_MARGIN times over (repeated reports, a log read after a gap);
- the -wal file reaches its largest (SQLite copies it into the database at 1000 pages);
- the ledger is in the same folder (a survey's first plan) or on the same disk.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ..mission.plan_blocks import SortiePlan
from ..mission.plan_record import PlanRecord
from .link_silence import LINK_MARGIN_S, LINK_WAIT_FACTOR
from .journal_db import JournalError

# Bytes in journal.sqlite (rows, their index entries, the pages' slack), as bench/journal_bench.py measured
# them (86, 152, 106 bytes; the -wal file 4.13 MB at most), rounded up.
SAMPLE_BYTES = 90  # one position sample
PHOTO_BYTES = 160  # one photo, with the `captures` fact that comes with it
ENTRY_BYTES = 110  # one other change (a fact, an event, an item reached)
ENTRIES_PER_S = 2.0  # other changes a followed drone makes per second (its position once a second...; 1.7 measured)
WAL_BYTES = 4_200_000  # the -wal file at its largest: 1000 pages of 4 KiB and their headers, and one transaction
# The files written after the flight (measured: 0.89 MB, 55 bytes a sample, 1,889 a photo): a fixed part,
# and parts growing with the samples (the tracks of flight.html / .gpkg / .kmz) and the photos (the
# ledger's photo and covered-cell rows, photos.csv / .geojson, geo.txt).
OUTPUT_BYTES = 1_000_000
OUTPUT_SAMPLE_BYTES = 60
OUTPUT_PHOTO_BYTES = 2_000
PHOTO_MARGIN = 1.5


def _drone_entries(record: PlanRecord, sortie: int | None) -> list[SortiePlan]:
    """Each drone's planned flight for `sortie` (None: the largest of its sorties, for a resume)."""
    out = []
    for drone in record.drones or ():
        sorties = drone.planned_sorties
        if sortie is None:
            out.append(max(sorties, key=lambda s: float(s.flight_s or 0.0)))
        elif sortie <= len(sorties):
            out.append(sorties[sortie - 1])
    return out


def flight_bytes(record: PlanRecord, telemetry_hz: float, sortie: int | None = 1) -> tuple[int, str]:
    """(bytes the flight's record may take at most, what that assumes in words)."""
    drones = _drone_entries(record, sortie)
    seconds = [float(d.flight_s or 0.0) * LINK_WAIT_FACTOR + LINK_MARGIN_S for d in drones]
    samples = sum(seconds) * telemetry_hz
    photos = sum(float(d.photos or 0) for d in drones) * PHOTO_MARGIN
    entries = sum(seconds) * ENTRIES_PER_S
    journal = samples * SAMPLE_BYTES + photos * PHOTO_BYTES + entries * ENTRY_BYTES + WAL_BYTES
    outputs = OUTPUT_BYTES + samples * OUTPUT_SAMPLE_BYTES + photos * OUTPUT_PHOTO_BYTES
    how = (f"{len(drones)} drone{'' if len(drones) == 1 else 's'} followed for up to {max(seconds, default=0):.0f} s "
           f"at {telemetry_hz:g} Hz, the journal and the files written after the flight")
    return int(journal + outputs), how


def size_text(n: float) -> str:
    return f"{n / 1e3:.0f} kB" if n < 1e6 else f"{n / 1e6:.1f} MB"


def check_space(plan_dir: Path, record: PlanRecord, telemetry_hz: float, sortie: int | None = 1) -> None:
    """Raise JournalError (one line: the folder, the space free and needed) when plan_dir's disk has too
    little room for the flight's record."""
    need, how = flight_bytes(record, telemetry_hz, sortie)
    try:
        free = shutil.disk_usage(plan_dir).free
    except OSError:
        return  # a disk that does not say: the journal's own checks in flight will tell
    if free < need:
        raise JournalError(f"{plan_dir}: too little free space for the flight's record: {size_text(free)} free on "
                           f"its disk, about {size_text(need)} needed ({how}); free some space or fly from a "
                           "folder on another disk")
