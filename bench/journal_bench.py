"""The disk a flight's record takes: what missionplan/flight/disk_space.py's terms are, measured.

Run by hand: `.venv/bin/python bench/journal_bench.py [--write-doc FILE]` (about two minutes).

1. Bytes per row of the journal, written through its real writer (journal.Journal, a sink per drone) into
   a fresh journal.sqlite and read off the file's growth once it is closed: a position sample; a photo
   with the `captures` fact that comes with it; another change (the drone's position, journaled once a
   second, the commonest). And the largest the -wal file grew while samples of five drones at 25 Hz were
   written at their real pace (SQLite copies it into the database at 1000 pages).
2. Flights of the Leonardo map (3 drones, about 60 s each) on the mock fleet at a speed-up, with two
   telemetry rates: the journal's rows (samples, photos, other entries) and bytes, the folder's peak disk
   use while fly ran (every file's allocated blocks, sampled every 20 ms), the files fly writes after the
   flight, and disk_space's estimate for the same flight, which must be above the peak.
3. The files written after the flight fitted on the two flights: bytes per sample (the tracks in
   flight.html / .gpkg / .kmz), per photo (the ledger's rows and covered cells, photos.csv / .geojson,
   geo.txt), and the rest.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sqlite3
import tempfile
import threading
import time
from pathlib import Path

import doctable

from missionplan.cli import main
from missionplan.flight import disk_space
from missionplan.flight.journal import Journal
from missionplan.flight.journal_db import JOURNAL_NAME
from missionplan.flight.record import DroneRecord
from missionplan.mission.plan_record import read_plan_record

ROOT = Path(__file__).resolve().parent.parent


ROWS = 30_000
JOURNAL_FILES = (JOURNAL_NAME, JOURNAL_NAME + "-wal", JOURNAL_NAME + "-shm", "journal.commits")


def _grown(folder: Path, fill) -> float:
    """Bytes journal.sqlite grows by per row when `fill(records)` hands ROWS rows to 3 drones' records."""
    journal = Journal.start_flight(folder, 1, "bench")
    journal.close()
    before = (folder / JOURNAL_NAME).stat().st_size
    journal = Journal.start_flight(folder, 1, "bench")
    records = [DroneRecord(id=k, sink=journal.sink(k)) for k in (1, 2, 3)]
    fill(records)
    journal.close()
    return ((folder / JOURNAL_NAME).stat().st_size - before) / ROWS


def _samples(records: list[DroneRecord]) -> None:
    t0 = time.time()
    for i in range(ROWS):
        rec = records[i % 3]
        t = t0 + i * 0.04 / 3
        rec.add_sample((t, 45.4784123 + i * 1.3e-7, 9.2270456 + i * 1.1e-7, 20.012 + (i % 7) * 0.01, 5.03, 312.5 + i
                        * 0.04 / 3, -0.02))


def _photos(records: list[DroneRecord]) -> None:
    t0 = time.time()
    for i in range(ROWS):
        rec = records[i % 3]
        idx = i // 3 + 1
        rec.add_photo(idx, t0 + i * 0.3, 45.4784123 + i * 1.3e-7, 9.2270456 + i * 1.1e-7, 20.01,
                      attitude=(0.12, -1.3, 87.25), amsl=142.31)
        rec.set(captures=idx + 1)


def _entries(records: list[DroneRecord]) -> None:
    t0 = time.time()
    for i in range(ROWS):
        records[i % 3].set(last_position=[45.4784123 + i * 1.3e-7, 9.2270456 + i * 1.1e-7, 20.012, t0 + i])


def wal_peak(folder: Path, drones: int = 5, hz: float = 25.0, seconds: float = 45.0) -> int:
    """The largest the -wal file grows while `drones` records get samples at `hz` at their real pace."""
    journal = Journal.start_flight(folder, 1, "bench")
    records = [DroneRecord(id=k, sink=journal.sink(k)) for k in range(1, drones + 1)]
    wal = folder / (JOURNAL_NAME + "-wal")
    peak, start = 0, time.monotonic()
    tick = 0
    while time.monotonic() - start < seconds:
        now = time.time()
        for rec in records:
            rec.add_sample((now, 45.47841 + tick * 1e-6, 9.22704, 20.0, 5.0, tick / hz, 0.0))
        if tick % int(hz) == 0:
            for rec in records:
                rec.set(last_position=[45.47841 + tick * 1e-6, 9.22704, 20.0, now])
        tick += 1
        peak = max(peak, wal.stat().st_size if wal.exists() else 0)
        time.sleep(max(0.0, start + tick / hz - time.monotonic()))
    journal.close()
    return peak


def _allocated(folder: Path) -> int:
    total = 0
    for path in folder.rglob("*"):
        try:
            if path.is_file():
                total += path.stat().st_blocks * 512
        except OSError:
            pass
    return total


def fly_once(plan: Path, work: Path, speedup: float, hz: float) -> dict:
    """Fly a copy of `plan` on the mock fleet; what it wrote and the folder's peak disk use."""
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet

    folder = work / f"fly-{speedup:g}x-{hz:g}hz"
    folder.mkdir()
    for path in plan.iterdir():
        (folder / path.name).write_bytes(path.read_bytes())
    planned = _allocated(folder)
    names_before = {p.name for p in folder.iterdir()}
    peak = [0]
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            peak[0] = max(peak[0], _allocated(folder) - planned)
            done.wait(0.02)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    mock = start_mock_fleet(folder, speedup)
    try:
        result = fly(folder, mock.client_url, timeout_s=300, progress=False, time_scale=speedup, telemetry_hz=hz)
    finally:
        mock.stop()
        done.set()
        watcher.join()
    peak[0] = max(peak[0], _allocated(folder) - planned)
    db = sqlite3.connect(folder / JOURNAL_NAME)
    counts = {t: db.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0] for t in ("samples", "photos", "entries")}
    db.close()
    outputs = sum(p.stat().st_blocks * 512 for p in folder.iterdir()
                  if p.is_file() and p.name not in names_before and p.name not in JOURNAL_FILES)
    estimate, _ = disk_space.flight_bytes(read_plan_record(folder), hz, 1)
    ledger = sum((folder / name).stat().st_blocks * 512 for name in ("ledger.sqlite", "photos.csv", "photos.geojson",
                                                                     "geo.txt"))
    return {"speedup": speedup, "hz": hz, "ok": result.ok, **counts,
            "journal": (folder / JOURNAL_NAME).stat().st_size, "outputs": outputs, "per_photo_files": ledger,
            "peak": peak[0], "estimate": estimate}


def table() -> int:
    with tempfile.TemporaryDirectory(prefix="journal-bench-") as tmp:
        work = Path(tmp)
        measured = {}
        for name, fill in (("sample", _samples), ("photo", _photos), ("entry", _entries)):
            folder = work / name
            folder.mkdir()
            measured[name] = _grown(folder, fill)
        (work / "wal").mkdir()
        wal = wal_peak(work / "wal")
        plan = work / "plan"
        with contextlib.redirect_stdout(io.StringIO()):  # the plan's own summary is not this table
            assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(plan), "--quiet"]) == 0
        flights = [fly_once(plan, work, 2.0, 25.0), fly_once(plan, work, 2.0, 10.0)]
    a, b = flights
    per_sample = (a["outputs"] - b["outputs"]) / max(a["samples"] - b["samples"], 1)
    per_photo = max(f["per_photo_files"] / f["photos"] for f in flights)
    fixed = max(f["outputs"] - per_sample * f["samples"] - per_photo * f["photos"] for f in flights)
    print(f"{'journal.sqlite, bytes per row':<44}{'measured':>10}{'disk_space':>12}")
    print("-" * 66)
    rows = (("a position sample", measured["sample"], disk_space.SAMPLE_BYTES),
            ("a photo, with its captures fact", measured["photo"], disk_space.PHOTO_BYTES),
            ("another change (a position fact)", measured["entry"], disk_space.ENTRY_BYTES),
            ("the -wal file at its largest (5 x 25 Hz)", wal, disk_space.WAL_BYTES),
            ("files after the flight: per sample", per_sample, disk_space.OUTPUT_SAMPLE_BYTES),
            ("files after the flight: per photo", per_photo, disk_space.OUTPUT_PHOTO_BYTES),
            ("files after the flight: the rest", fixed, disk_space.OUTPUT_BYTES))
    for what, value, constant in rows:
        print(f"{what:<44}{value:>10,.0f}{constant:>12,}")
    print()
    print(f"{'Leonardo x3':<12}{'Hz':>4}{'samples':>9}{'photos':>8}{'entries':>9}{'journal kB':>12}{'after kB':>10}"
          f"{'peak kB':>9}{'estimate kB':>13}")
    print("-" * 86)
    for f in flights:
        label = f"{f['speedup']:g}x speed-up"
        print(f"{label:<12}{f['hz']:>4g}{f['samples']:>9}{f['photos']:>8}{f['entries']:>9}"
              f"{f['journal'] / 1e3:>12.0f}{f['outputs'] / 1e3:>10.0f}{f['peak'] / 1e3:>9.0f}"
              f"{f['estimate'] / 1e3:>13.0f}")
    low = [f for f in flights if f["estimate"] < f["peak"]]
    return 1 if low else 0


def main_() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table()


if __name__ == "__main__":
    raise SystemExit(main_())
