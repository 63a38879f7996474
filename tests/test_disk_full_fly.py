"""`fly` on a disk that does not play along, against the in-process mock fleet (the ground truth: what the
vehicles sent and did): a full disk in flight is a pause of the journal and not an end, a disk full to
the end leaves the record in a named fallback file, too little room refuses the flight before any link
is opened, a vehicle whose start cannot be recorded is not armed, and a damaged, read-only or cut
journal is one line on `fly --resume`.

The small disk is a real tmpfs where the machine allows it (tests/small_disk.py), filled once the
fleet is past an item and freed later; fly runs in this process (`main`), in a thread, its stderr
captured whole."""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from small_disk import read_only, small_disk

from missionplan.cli import main
from missionplan.flight.journal_db import JOURNAL_NAME
from missionplan.flight.journal_read import read_flight
from missionplan.flight.mock_fleet import start_mock_fleet

pytestmark = pytest.mark.flight  # flies mock autopilots: `pytest -m "not flight"` leaves it out

ROOT = Path(__file__).resolve().parent.parent
SPEEDUP = 4.0  # Leonardo's 3 drones, about 60 s planned each: 15 s of wall time
SYSIDS = (1, 2, 3)
PAUSED = re.compile(r"disk full: journal writes paused, \d+ records held in memory \(database or disk is full\); "
                    r"trying again every 1 s")
RESUMED = re.compile(r"journal writes resumed: \d+ records written")


@pytest.fixture(scope="module")
def leonardo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leonardo-3")
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    return out


def _copy(plan: Path, to: Path) -> Path:
    to.mkdir(parents=True)
    for path in plan.iterdir():
        (to / path.name).write_bytes(path.read_bytes())
    return to


def _hashes(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def _fly(plan: Path, url: str, *extra: str, speedup: float = SPEEDUP) -> list[str]:
    return ["fly", str(plan), "--connect", url, "--time-scale", str(speedup), "--timeout", "120", "--quiet", *extra]


def _in_thread(target: Any) -> tuple[threading.Thread, list[Any]]:
    out: list[Any] = []
    thread = threading.Thread(target=lambda: out.append(target()), daemon=True)
    thread.start()
    return thread, out


def _in_flight(mock: Any, item: int, timeout: float = 60.0) -> bool:
    return mock.wait_until(lambda m: all(v.flight.state.armed and v.flight.state.mode == "AUTO"
                                         and v.flight.state.current >= item for v in m.vehicles.values()), timeout)


def _positions_sent(mock: Any) -> dict[int, list[int]]:
    """Every GLOBAL_POSITION_INT each vehicle sends from now on, by its time_boot_ms (the mock's truth)."""
    sent: dict[int, list[int]] = {k: [] for k in SYSIDS}
    for k in SYSIDS:
        vehicle = mock.vehicle(k)
        original = vehicle.telemetry._send_position

        def send(now: float, k: int = k, vehicle: Any = vehicle, original: Any = original) -> None:
            sent[k].append(vehicle.time_boot_ms(now))
            original(now)
        vehicle.telemetry._send_position = send
    return sent


def _missing_samples(sent: dict[int, list[int]], journaled: dict[int, set[int]]) -> dict[int, int]:
    """Per vehicle: the positions it sent between the first and the last the journal holds that the journal
    lacks (what a record lost in a pause would be)."""
    missing = {}
    for k, times in journaled.items():
        low, high = min(times), max(times)
        missing[k] = sum(1 for t in sent[k] if low <= t <= high and t not in times)
    return missing


def _journaled_times(plan: Path) -> dict[int, set[int]]:
    return {rec.id: {round(s[5] * 1000) for s in rec.samples} for rec in read_flight(plan)[2]}


def test_a_full_disk_in_flight_pauses_the_journal_and_loses_nothing(
        leonardo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    with small_disk(tmp_path / "disk", 12 * 1024, monkeypatch) as disk:
        plan = _copy(leonardo, disk.path / "plan")
        mock = start_mock_fleet(plan, SPEEDUP)
        try:
            sent = _positions_sent(mock)
            flying, code = _in_thread(lambda: main(_fly(plan, mock.client_url)))
            assert _in_flight(mock, 3), "the fleet never got going"
            disk.fill()
            # The fleet flies on while the journal is paused...
            assert mock.wait_until(lambda m: all(v.flight.state.current >= 8 for v in m.vehicles.values()), 60.0)
            disk.free()  # ...and the space comes back before it lands
            flying.join(120)
            taken = {k: mock.vehicle(k).flight.state.photos for k in SYSIDS}
            err = capsys.readouterr().err
            assert code == [0], err
            lines = err.splitlines()
            assert len(lines) == 2 and PAUSED.fullmatch(lines[0]) and RESUMED.fullmatch(lines[1]), err
            doc = json.loads((plan / "flight.json").read_text())
            assert all(d["finished"] for d in doc["drones"]) and "record_faults" not in doc, doc["problems"]
            assert all(any(PAUSED.fullmatch(text[len("alert: "):]) for _, text in d["events"]) for d in doc["drones"])
            # Every position the vehicles sent while the journal was paused is in it, and every photo.
            assert _missing_samples(sent, _journaled_times(plan)) == {k: 0 for k in SYSIDS}
            assert all(abs(d["photos"] - taken[d["id"]]) <= 1 for d in doc["drones"]), (taken, doc["drones"])
            # fly --resume works after: the flight had ended, it is judged again, nothing is sent.
            uploads = {k: mock.vehicle(k).uploads_completed for k in SYSIDS}
            assert main(_fly(plan, mock.client_url, "--resume")) == 0
            assert {k: mock.vehicle(k).uploads_completed for k in SYSIDS} == uploads
            assert "Traceback" not in capsys.readouterr().err
        finally:
            mock.stop()


def test_a_disk_full_to_the_end_leaves_the_record_in_a_named_fallback_file(
        leonardo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    elsewhere = tmp_path / "elsewhere"  # the temp folder: another filesystem than the small disk
    elsewhere.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(elsewhere))
    with small_disk(tmp_path / "disk", 12 * 1024, monkeypatch) as disk:
        plan = _copy(leonardo, disk.path / "plan")
        mock = start_mock_fleet(plan, SPEEDUP)
        try:
            sent = _positions_sent(mock)
            flying, code = _in_thread(lambda: main(_fly(plan, mock.client_url)))
            assert _in_flight(mock, 3), "the fleet never got going"
            disk.fill()
            flying.join(120)
            landed = all(not v.flight.state.armed and v.flight.state.mission_done for v in mock.vehicles.values())
        finally:
            mock.stop()
        err = capsys.readouterr().err
        assert code == [3] and landed, err  # followed to the end; not fully recorded
        lines = err.splitlines()
        assert len(lines) == 2 and PAUSED.fullmatch(lines[0]) and "Traceback" not in err, err
        kept = re.fullmatch(rf"missionplan fly: {re.escape(str(plan))}: the flight's record is not whole there: \d+ "
                            r"journal records not written \(disk full \(database or disk is full\)\)(?:; not written: "
                            r"(?P<files>.+))?; kept instead in (?P<path>\S+\.json)", lines[1])
        assert kept, lines[1]
        fallback = json.loads(Path(kept["path"]).read_text())
        assert Path(kept["path"]).parent == elsewhere and fallback["plan_dir"] == str(plan.resolve())
        if disk.mounted:  # the judge's files could not be written either: flight.json's content is in the file
            assert kept["files"] == ("ledger.sqlite (cannot be written (database or disk is full)), photos.csv, "
                                     "photos.geojson, geo.txt (written from the survey ledger), flight.json, "
                                     "missed.geojson, flight.png, flight.html, flight.gpkg, flight.kmz (No space left "
                                     "on device)"), kept["files"]
            assert not (plan / "flight.json").exists()
            assert all(d["finished"] for d in fallback["flight_json"]["drones"])
        # The journal and the fallback file together hold every position the vehicles sent.
        journaled = _journaled_times(plan)
        for row in fallback["journal_rows"]:
            if row["kind"] == "sample":
                journaled[row["drone"]].add(round(row["row"][5] * 1000))
        assert _missing_samples(sent, journaled) == {k: 0 for k in SYSIDS}


def _bytes(text: str) -> float:
    number, unit = text.split()
    return float(number) * {"kB": 1e3, "MB": 1e6}[unit]


@pytest.mark.parametrize("resume", [False, True], ids=["fly", "resume"])
def test_too_little_room_for_the_record_refuses_the_flight_before_any_link(
        leonardo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        resume: bool) -> None:
    with small_disk(tmp_path / "disk", 4 * 1024, monkeypatch) as disk:
        plan = _copy(leonardo, disk.path / "plan")
        if not disk.mounted:
            from shutil import _ntuple_diskusage  # type: ignore[attr-defined]

            monkeypatch.setattr("missionplan.flight.disk_space.shutil.disk_usage",
                                lambda path: _ntuple_diskusage(4 << 20, 1 << 20, 3 << 20))
        before = _hashes(plan)
        mock = start_mock_fleet(plan, SPEEDUP)
        try:
            code = main(_fly(plan, mock.client_url, *(["--resume"] if resume else [])))
            heard = dict(mock.stats)
        finally:
            mock.stop()
        err = capsys.readouterr().err
        assert code == 2, err
        line = re.fullmatch(rf"missionplan: {re.escape(str(plan))}: too little free space for the flight's record: "
                            r"([\d.]+ [kM]B) free on its disk, about ([\d.]+ [kM]B) needed \(3 drones followed for up "
                            r"to \d+ s at "
                            r"25 Hz, the journal and the files written after the flight\); free some space or fly from "
                            r"a folder on another disk\n", err)
        assert line and _bytes(line[1]) < _bytes(line[2]), err
        assert heard["in"] == 0 and heard["clients"] == 0  # no link was opened, nothing sent
        assert _hashes(plan) == before


def test_a_vehicle_whose_start_cannot_be_recorded_is_not_armed(
        leonardo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The arming fact is committed before the arm command; a journal that cannot commit it (paused) arms
    nothing: a flight that cannot be recorded is not started."""
    import missionplan.flight.fly as fly_module

    real = fly_module.FleetStart
    monkeypatch.setattr(fly_module, "FleetStart", lambda *a, **k: real(*a, **{**k, "commit": lambda: False}))
    from missionplan.bridge.link.connection import mavlink

    plan = _copy(leonardo, tmp_path / "plan")
    mock = start_mock_fleet(plan, 10.0)
    commands: list[tuple[int, int, float]] = []  # (vehicle, command, param1) as each vehicle got them
    for k in SYSIDS:
        handler = mock.vehicle(k).command_handler
        real_command = handler._command

        def command(number: int, p: list[float], now: float, k: int = k, real_command: Any = real_command) -> int:
            commands.append((k, number, p[0]))
            return real_command(number, p, now)
        handler._command = command
    try:
        code = main(_fly(plan, mock.client_url, speedup=10.0))
    finally:
        mock.stop()
    out = capsys.readouterr()
    armed = [k for k, number, p1 in commands if number == mavlink.MAV_CMD_COMPONENT_ARM_DISARM and p1 >= 0.5]
    started = [k for k, number, _ in commands if number == mavlink.MAV_CMD_MISSION_START]
    assert code == 1 and armed == [] and started == [], out.out + out.err
    doc = json.loads((plan / "flight.json").read_text())
    assert sorted(doc["problems"]) == [f"uav{k}: not armed: its start could not be written to the flight journal (a "
                                       "flight that cannot be recorded is not started)" for k in SYSIDS]
    assert out.err == ""


# ------------------------------------------------------------------------------------------- fly --resume
@pytest.fixture(scope="module")
def flown(leonardo: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Leonardo flown once to the end at 10x: a folder with a whole journal."""
    plan = _copy(leonardo, tmp_path_factory.mktemp("flown") / "plan")
    mock = start_mock_fleet(plan, 10.0)
    try:
        assert main(_fly(plan, mock.client_url, speedup=10.0)) == 0
    finally:
        mock.stop()
    return plan


def _page_of_a_sample(path: Path) -> int:
    """The offset of a page of journal.sqlite in the middle of the samples table, found by a sample's own
    clock (boot_s: no other table holds it; a float SQLite stores big-endian)."""
    import sqlite3
    import struct

    db = sqlite3.connect(path)
    count = db.execute("SELECT COUNT(*) FROM samples").fetchone()[0]
    boot_s = db.execute("SELECT boot_s FROM samples WHERE boot_s != CAST(boot_s AS INTEGER) ORDER BY rowid "
                        "LIMIT 1 OFFSET ?", (count // 3,)).fetchone()[0]
    db.close()
    data = path.read_bytes()
    at = data.index(struct.pack(">d", boot_s))
    return at - at % 4096


def test_a_damaged_journal_on_resume_is_salvaged_in_one_line_and_the_flight_judged_again(
        flown: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = _copy(flown, tmp_path / "plan")
    path = plan / JOURNAL_NAME
    samples = sum(len(rec.samples) for rec in read_flight(plan)[2])
    with open(path, "r+b") as f:
        f.seek(_page_of_a_sample(path))
        f.write(b"\xa5" * 4096)
    mock = start_mock_fleet(plan, 10.0)
    try:
        code = main(_fly(plan, mock.client_url, "--resume", speedup=10.0))
    finally:
        mock.stop()
    err = capsys.readouterr().err
    assert code == 3, err  # judged again, from a journal that lost rows: not fully recorded
    (line,) = err.splitlines()
    assert line.startswith(f"missionplan fly: {path}: damaged (") and "kept as journal.sqlite.damaged" in line, line
    lost = re.search(r"lost: (\d+) samples$", line)
    assert lost and 0 < int(lost[1]) < samples / 2, line
    doc = json.loads((plan / "flight.json").read_text())
    assert doc["record_faults"] == [line[len("missionplan fly: "):]]
    assert sum(d["samples"] for d in doc["drones"]) == samples - int(lost[1])


def test_a_read_only_journal_on_resume_is_one_line_before_any_link(
        flown: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = _copy(flown, tmp_path / "plan")
    before = _hashes(plan)
    mock = start_mock_fleet(plan, 10.0)
    try:
        with read_only(plan):
            code = main(_fly(plan, mock.client_url, "--resume", speedup=10.0))
        heard = dict(mock.stats)
    finally:
        mock.stop()
    err = capsys.readouterr().err
    # The folder's lock is the first thing fly would write (missionplan.bridge.folder_lock), so a read-only
    # folder is said there; a read-only journal in a writable folder: tests/test_journal_faults.py.
    assert code == 2 and re.fullmatch(rf"missionplan: {re.escape(str(plan))}: cannot write in this folder \([^)]+\): "
                                      r"a run of fly, plan or replan keeps its record there; copy the folder to a "
                                      r"writable disk and run it there\n", err), err
    assert heard["in"] == 0 and heard["clients"] == 0
    assert _hashes(plan) == before


def test_a_journal_cut_by_a_lost_wal_file_says_so_on_resume(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = _copy(leonardo, tmp_path / "plan")
    mock = start_mock_fleet(plan, SPEEDUP / 2)
    try:
        crashed = subprocess.Popen([sys.executable, "-m", "missionplan", *_fly(plan, mock.client_url)[:-1]],
                                   cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                   env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert _in_flight(mock, 3), "the fleet never got going"
        crashed.send_signal(signal.SIGKILL)
        crashed.wait(10)
        (plan / (JOURNAL_NAME + "-wal")).unlink()  # lost: a copy of journal.sqlite alone, a careless clean-up
        code = main(_fly(plan, mock.client_url, "--resume"))
    finally:
        mock.stop()
    err = capsys.readouterr().err
    assert code == 2, err
    # The killed run's lock is taken over with a word (missionplan.bridge.folder_lock), then the cut is said.
    took_over, _, err = err.partition("\n")
    assert took_over.startswith(f"missionplan: {plan}: took over the lock left by pid {crashed.pid} "), took_over
    assert re.fullmatch(rf"missionplan: {re.escape(str(plan / JOURNAL_NAME))}: the journal was cut: run 1 of "
                        r"fly(?:, started [^;]+)? committed \d+ transactions and the file holds \d+ of them; its "
                        r"write-ahead log \(journal.sqlite-wal\) was lost after that run was killed, and with it "
                        r"everything written since SQLite last copied the log into the file: no flight left in it to "
                        r"resume\n", err), err


def test_a_fleet_armed_by_a_fly_killed_before_its_start_was_written_is_resumed(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """fly commits each vehicle's `arming` fact before the arm command: killed after arming, before any
    mission start was acknowledged (so before `started` was journaled), its flight is still found by
    `fly --resume`, which follows the vehicles the crew then started, to the end."""
    from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle

    plan = _copy(leonardo, tmp_path / "plan")
    mock = start_mock_fleet(plan, SPEEDUP)
    handlers = {k: mock.vehicle(k).command_handler for k in SYSIDS}
    answer = {k: handler._on_command for k, handler in handlers.items()}
    for k, handler in handlers.items():  # MISSION_START goes unanswered, and so fly never journals `started`
        handler._on_command = (lambda msg, peer, now, k=k: None if int(msg.command) == mavlink.MAV_CMD_MISSION_START
                               else answer[k](msg, peer, now))
    try:
        crashed = subprocess.Popen([sys.executable, "-m", "missionplan", *_fly(plan, mock.client_url)],
                                   cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                   env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert mock.wait_until(lambda m: all(v.flight.state.armed for v in m.vehicles.values()), 60.0)
        crashed.send_signal(signal.SIGKILL)
        crashed.wait(10)
        kept = read_flight(plan)[2]
        assert all(rec.arming and not rec.started for rec in kept), [(r.arming, r.started) for r in kept]
        for k, handler in handlers.items():
            handler._on_command = answer[k]
        with Link(mock.client_url, source_system=250) as crew:  # the crew starts them from its own station
            for k in SYSIDS:
                wait_vehicle(crew, k, timeout=5)
                crew.mav.command_long_send(k, 1, mavlink.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
            assert _in_flight(mock, 1, timeout=20.0)
        code = main(_fly(plan, mock.client_url, "--resume"))
        landed = all(v.flight.state.mission_done and not v.flight.state.armed for v in mock.vehicles.values())
    finally:
        mock.stop()
    out = capsys.readouterr()
    assert code == 0 and landed, out.out + out.err
    doc = json.loads((plan / "flight.json").read_text())
    assert all(d["finished"] for d in doc["drones"]), doc["problems"]
    assert all(any(n.startswith("its start was not in the journal") for n in d["notes"]) for d in doc["drones"])
