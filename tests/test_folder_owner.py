"""One owner per survey folder, no plan over a flight, and a plan written whole or not at all.

- Two `fly` on one folder and one link (child processes against the in-process mock fleet, which is the
  ground truth: every arming and every upload it took is counted here): the second is refused in one
  line naming the first, each vehicle is armed once and takes each mission once, the photos are
  counted once (ledger, photos.csv).
- A lock left by a SIGKILLed holder is taken over with one line; another thread of the same process is
  refused; `demo` plans and flies in one process.
- `plan --out` / `replan --out` into a flown folder, into another survey's flown folder, `/` and the
  home folder: one line, exit 2, the folder unchanged (every file's hash before and after). A re-plan
  keeps a file the crew changed, and a report.json copied in from elsewhere deletes nothing.
- A full disk in `plan` (a 2 MiB tmpfs mounted here when the machine allows it, else ENOSPC injected
  at the writes): exit 2, one line on stderr naming the folder, the file and the cause, no
  traceback, the earlier plan's files unchanged, and no folder left where the run made one.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from missionplan.bridge.folder_lock import LOCK_NAME, FolderBusy, hold_folder
from missionplan.bridge.link.connection import mavlink
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.ledger import Ledger
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.planning.plan_folder import STAGING_PREFIX, flight_record

ROOT = Path(__file__).resolve().parent.parent
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
SPEEDUP = 5.0  # Leonardo's 2-drone missions, about 75 s planned: 15 s of wall time
FAST = 10.0
SYSIDS = (1, 2)


def _plan_args(out: Path, uavs: int = 2, *extra: str) -> list[str]:
    return ["plan", "--map", "leonardo", "--uavs", str(uavs), "--out", str(out), "--quiet", *extra]


@pytest.fixture(scope="module")
def leonardo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leonardo-2") / "plan"
    assert main(_plan_args(out)) == 0
    return out


@pytest.fixture(scope="module")
def flown(leonardo: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A survey folder that has been flown (against the mock fleet) and judged: journal, ledger, record."""
    plan_dir = _copy(leonardo, tmp_path_factory.mktemp("flown"))
    mock = start_mock_fleet(plan_dir, FAST)
    try:
        assert fly(plan_dir, mock.client_url, timeout_s=120, progress=False, time_scale=FAST).ok
    finally:
        mock.stop()
    return plan_dir


def _copy(folder: Path, into: Path) -> Path:
    copy = into / folder.name
    shutil.copytree(folder, copy)
    return copy


def _hashes(folder: Path) -> dict[str, str]:
    """Every entry of the folder, hidden ones too: a file by its content's sha256, a folder by its name."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
            for p in folder.iterdir()}


def _one_line(err: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------------------------------ two fly, one folder
def _count_arms_and_uploads(mock) -> tuple[Counter, Counter]:
    """Count, on the mock vehicles themselves, every arming they accepted and every upload they completed
    (by sysid, and by (sysid, mission type))."""
    arms: Counter = Counter()
    uploads: Counter = Counter()
    for sysid, vehicle in mock.vehicles.items():
        handler, server = vehicle.command_handler, vehicle.mission_server

        def command(cmd: int, p: list[float], now: float, sysid: int = sysid, original=handler._command) -> int:
            result = original(cmd, p, now)
            if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM and p[0] >= 0.5 and result == mavlink.MAV_RESULT_ACCEPTED:
                arms[sysid] += 1
            return result

        def commit(mission_type: int, *args, sysid: int = sysid, original=server._commit) -> None:
            uploads[(sysid, mission_type)] += 1
            original(mission_type, *args)

        handler._command = command
        server._commit = commit
    return arms, uploads


def _fly_process(plan_dir: Path, url: str, **popen) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--connect", url,
                             "--time-scale", str(SPEEDUP), "--timeout", "120", "--quiet"],
                            cwd=ROOT, text=True, env=ENV, **popen)


@pytest.mark.flight
def test_a_second_fly_on_the_same_folder_is_refused_and_each_vehicle_is_armed_once(
        leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    arms, uploads = _count_arms_and_uploads(mock)
    first = _fly_process(plan_dir, mock.client_url, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        # The second starts once the first is talking to the vehicles: well before they are armed.
        assert mock.wait_until(lambda m: m.stats["in"] > 0, 30.0), "the first fly never reached the mock"
        second = subprocess.run([sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--connect",
                                 mock.client_url, "--time-scale", str(SPEEDUP), "--timeout", "120", "--quiet"],
                                cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=60)
        out, _ = first.communicate(timeout=150)
    finally:
        if first.poll() is None:
            first.kill()
        mock.stop()
    assert second.returncode == 2 and second.stdout == "", (second.stdout, second.stderr)
    line = _one_line(second.stderr)
    assert line.startswith(f"missionplan: {plan_dir} is in use by pid {first.pid} on ") and " fly " in line, line
    assert first.returncode == 0, out
    assert dict(arms) == {k: 1 for k in SYSIDS}, arms
    assert uploads and set(uploads.values()) == {1}, uploads  # each vehicle took each of its missions once
    doc = json.loads((plan_dir / "flight.json").read_text())
    with Ledger.of(plan_dir) as ledger:
        flights, photos = ledger.flights(), len(ledger.photos())
    assert len(flights) == 1 and photos == sum(d["photos"] for d in doc["drones"]) > 0, (flights, photos)
    assert len((plan_dir / "photos.csv").read_text().splitlines()) == photos + 1  # a header, then each photo once
    taken = sum(v.flight.state.photos for v in mock.vehicles.values())
    assert photos <= taken, (photos, taken)
    assert not (plan_dir / LOCK_NAME).exists()


# ------------------------------------------------------------------------------------------ the lock itself
HOLDER = ("import sys\n"
          "from missionplan.bridge.folder_lock import hold_folder\n"
          "with hold_folder(sys.argv[1]):\n"
          "    print('held', flush=True)\n"
          "    sys.stdin.read()\n")


def test_a_lock_left_by_a_killed_holder_is_taken_over_with_a_word(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _copy(leonardo, tmp_path)
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        before = _hashes(folder)
        assert main(_plan_args(folder)) == 2  # held: refused, nothing written
        line = _one_line(capsys.readouterr().err)
        assert f"is in use by pid {holder.pid} on " in line and "-c " in line, line
        assert _hashes(folder) == before
    finally:
        holder.send_signal(signal.SIGKILL)  # a crash: the lock file stays, naming a process that is gone
        holder.wait(10)
    assert json.loads((folder / LOCK_NAME).read_text())["pid"] == holder.pid
    assert main(_plan_args(folder)) == 0
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"missionplan: {folder}: took over the lock left by pid {holder.pid} on ") \
        and line.endswith(", which no longer runs"), line
    assert not (folder / LOCK_NAME).exists()


def test_the_lock_is_the_holding_threads_alone(tmp_path: Path) -> None:
    outcome: list[BaseException | None] = []

    def other_thread() -> None:
        try:
            with hold_folder(tmp_path):
                outcome.append(None)
        except FolderBusy as err:
            outcome.append(err)

    with hold_folder(tmp_path, say=pytest.fail):
        with hold_folder(tmp_path):  # the same thread again (replan holds --out, then plans into it)
            thread = threading.Thread(target=other_thread)
            thread.start()
            thread.join(10)
    assert len(outcome) == 1 and isinstance(outcome[0], FolderBusy), outcome
    assert "in use by another thread of this process, pid" in str(outcome[0])
    assert not (tmp_path / LOCK_NAME).exists()
    with hold_folder(tmp_path, say=pytest.fail):  # released: free again, and no stale lock to take over
        pass


def test_a_lock_files_text_is_printed_escaped_in_one_line(tmp_path: Path) -> None:
    import fcntl

    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": 7, "host": "evil\nhost", "command": "fly \x1b[2Jx",
                                                  "started": "2025-06-02T09:14:03+0200"}))
    fd = os.open(tmp_path / LOCK_NAME, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH)  # as its holder would
        with pytest.raises(FolderBusy) as busy:
            with hold_folder(tmp_path):
                pass
    finally:
        os.close(fd)
    assert str(busy.value).startswith(f"{tmp_path} is in use by pid 7 on evil\\nhost (`fly \\x1b[2Jx`, "
                                      f"started 2025-06-02T09:14:03+0200): "), str(busy.value)
    said: list[str] = []
    with hold_folder(tmp_path, say=said.append):  # no holder any more: taken over, said escaped
        pass
    assert said == [f"{tmp_path}: took over the lock left by pid 7 on evil\\nhost (`fly \\x1b[2Jx`, started "
                    f"2025-06-02T09:14:03+0200), which no longer runs"]


@pytest.mark.flight
def test_demo_plans_then_flies_in_one_process_and_a_second_demo_there_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--uavs", "2", "--speedup", str(FAST), "--quiet"]) == 0
    assert (out / "flight.json").is_file() and not (out / LOCK_NAME).exists()
    capsys.readouterr()
    before = _hashes(out)
    assert main(["demo", "--out", str(out), "--uavs", "2", "--speedup", str(FAST), "--quiet"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "holds a survey's record" in _one_line(captured.err)
    assert _hashes(out) == before


# ------------------------------------------------------------------------------------------ no plan over a flight
@pytest.mark.flight
def test_every_file_fly_writes_tells_a_flight(flown: Path) -> None:
    planned = set(json.loads((flown / "report.json").read_text())["files"])
    record = set(flight_record(flown))
    assert {p.name for p in flown.iterdir()} - planned <= record, sorted({p.name for p in flown.iterdir()} - planned)
    assert {"journal.sqlite", "ledger.sqlite", "flight.json", "photos.csv"} <= record


@pytest.mark.flight
def test_plan_into_a_flown_folder_is_refused_and_changes_nothing(
        flown: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _copy(flown, tmp_path)
    before = _hashes(folder)
    assert main(_plan_args(folder, 1)) == 2
    captured = capsys.readouterr()
    line = _one_line(captured.err)
    assert captured.out == ""
    assert line == (f"missionplan: --out {folder}: holds a survey's record (journal.sqlite, ledger.sqlite, "
                    f"flight.json and {len(flight_record(folder)) - 3} more): a plan here would replace the plan it "
                    f"belongs to; plan into a new folder, e.g. --out {folder}-2"), line
    assert _hashes(folder) == before
    assert main(["status", str(folder)]) == 0  # the survey reads as it did


@pytest.mark.flight
def test_replan_into_another_surveys_flown_folder_is_refused(
        flown: Path, leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = _copy(flown, tmp_path / "other-survey")
    survey = _copy(leonardo, tmp_path)
    before = _hashes(other)
    assert main(["replan", str(survey), "--out", str(other), "--drones", "1"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "holds a survey's record (journal.sqlite, ledger.sqlite" in _one_line(captured.err)
    assert _hashes(other) == before


def test_a_replan_keeps_a_file_the_crew_changed(leonardo: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "plan"
    assert main(_plan_args(folder, 3)) == 0
    doc = json.loads((folder / "uav3.plan").read_text())
    doc["mission"]["cruiseSpeed"] = 3.0  # the crew slowed uav3 down
    edited = json.dumps(doc, indent=4) + "\n"
    (folder / "uav3.plan").write_text(edited)
    capsys.readouterr()
    assert main(_plan_args(folder, 2)) == 0
    err = capsys.readouterr().err
    assert (folder / "uav3.plan").read_text() == edited  # kept, and said
    assert not (folder / "uav3.waypoints").exists()  # unchanged since the plan wrote it: stale, removed
    assert f"missionplan: warning: kept {folder / 'uav3.plan'}: " in err and "not removed" in err, err


def test_a_report_copied_in_from_elsewhere_deletes_nothing(leonardo: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "crew"
    folder.mkdir()
    shutil.copy(leonardo / "report.json", folder)  # lists uav1.* and uav2.*, with the other folder's checksums
    (folder / "uav2.plan").write_text("the crew's own mission\n")
    (folder / "uav2.waypoints").write_text("QGC WPL 110\n")
    assert main(_plan_args(folder, 1)) == 0
    assert (folder / "uav2.plan").read_text() == "the crew's own mission\n"
    assert (folder / "uav2.waypoints").read_text() == "QGC WPL 110\n"
    err = capsys.readouterr().err
    assert err.count("missionplan: warning: kept ") == 2, err


PLAN_NAMES = {"report.json", "plan.png", "plan.html", "plan.gpkg", "plan.kmz", "tracks.geojson", "uav1.plan",
              "uav1.waypoints", "uav2.plan", "uav2.waypoints", LOCK_NAME}


def test_out_root_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    root = Path("/")
    before = {p.name for p in root.iterdir()}
    try:
        assert main(_plan_args(root)) == 2
    finally:  # whatever happened, leave nothing of a plan in /
        for name in PLAN_NAMES - before:
            (root / name).unlink(missing_ok=True)
    assert _one_line(capsys.readouterr().err) == (
        "missionplan: --out /: the root folder is no plan folder (a plan writes and replaces files in --out); "
        "give a folder of its own, e.g. --out /survey-1")
    assert {p.name for p in root.iterdir()} == before


def test_out_home_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                             capsys: pytest.CaptureFixture[str]) -> None:
    home = tmp_path / "home"
    home.mkdir()
    (home / "notes.txt").write_text("the user's own")
    monkeypatch.setenv("HOME", str(home))
    before = _hashes(home)
    assert main(_plan_args(home)) == 2
    assert _one_line(capsys.readouterr().err).startswith(f"missionplan: --out {home}: your home folder is no plan "
                                                         f"folder")
    assert _hashes(home) == before


# ------------------------------------------------------------------------------------------ a full disk
class SmallDisk:
    """A 2 MiB tmpfs (mounted when the machine allows it), or, where mount is refused, a disk whose
    fullness is injected: an ENOSPC when the file named is about to be put in the plan's staging folder."""

    SIZE = "2m"

    def __init__(self, root: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        self.root, self.monkeypatch = root, monkeypatch
        try:
            done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={self.SIZE}", "tmpfs", str(root)],
                                  capture_output=True, text=True, timeout=30)
            self.mounted, self.why_not = done.returncode == 0, done.stderr.strip()
        except OSError as err:  # no mount command at all
            self.mounted, self.why_not = False, str(err)

    def fill_until(self, target: str, sizes: list[tuple[str, int]]) -> None:
        """Leave room for the files written before `target` (in write order) and half of `target`."""
        if not self.mounted:
            self._inject(target)
            return
        page = os.statvfs(self.root).f_frsize
        pages = lambda size: -(-size // page)  # noqa: E731
        before = [size for name, size in sizes[:[n for n, _ in sizes].index(target)]]
        free = page * (1 + sum(map(pages, before)) + pages(dict(sizes)[target]) // 2)  # 1: the lock file
        stat = os.statvfs(self.root)
        with open(self.root / "filler", "wb") as f:
            f.write(b"\0" * (stat.f_bavail * stat.f_frsize - free))

    def _inject(self, target: str) -> None:
        real_replace = os.replace

        def replace(src, dst) -> None:
            dst = Path(dst)
            if dst.name == target and dst.parent.name.startswith(STAGING_PREFIX):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            real_replace(src, dst)

        self.monkeypatch.setattr(os, "replace", replace)

    def unmount(self) -> None:
        if self.mounted:
            subprocess.run(["umount", str(self.root)], check=True)


@pytest.fixture()
def small_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[SmallDisk]:
    root = tmp_path / "disk"
    root.mkdir()
    disk = SmallDisk(root, monkeypatch)
    if not disk.mounted:
        print(f"no tmpfs ({disk.why_not}): ENOSPC is injected at the writes instead")
    try:
        yield disk
    finally:
        disk.unmount()


@pytest.fixture(scope="module")
def new_plan_sizes(tmp_path_factory: pytest.TempPathFactory) -> list[tuple[str, int]]:
    """The sizes of the files `plan --uavs 2` writes, in the order write_plan_folder writes them: the
    missions, the map files, plan.png, and report.json last."""
    out = tmp_path_factory.mktemp("sizes") / "plan"
    assert main(_plan_args(out)) == 0
    order = ["uav1.plan", "uav1.waypoints", "uav2.plan", "uav2.waypoints", "plan.html", "plan.gpkg", "plan.kmz",
             "tracks.geojson", "plan.png", "report.json"]
    assert sorted(order) == sorted(json.loads((out / "report.json").read_text())["files"])
    return [(name, (out / name).stat().st_size) for name in order]


@pytest.mark.parametrize("target", ["uav1.plan", "plan.html", "plan.gpkg", "plan.png", "report.json"])
def test_a_full_disk_in_plan_leaves_the_earlier_plan_as_it_was(
        small_disk: SmallDisk, new_plan_sizes: list[tuple[str, int]], target: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    folder = small_disk.root / "plan"
    assert main(_plan_args(folder, 3)) == 0  # the earlier plan: 3 drones
    capsys.readouterr()
    before = _hashes(folder)
    small_disk.fill_until(target, new_plan_sizes)
    assert main(_plan_args(folder, 2)) == 2  # the new one, 2 drones, does not fit
    captured = capsys.readouterr()
    assert captured.out == ""
    assert _one_line(captured.err) == (f"missionplan: --out {folder}: cannot write {target} (No space left on "
                                       f"device); nothing of this plan was kept, and the folder's earlier files "
                                       f"are as they were")
    assert _hashes(folder) == before


def test_a_full_disk_in_plan_leaves_no_folder_where_it_made_one(
        small_disk: SmallDisk, new_plan_sizes: list[tuple[str, int]], capsys: pytest.CaptureFixture[str]) -> None:
    small_disk.fill_until("plan.html", new_plan_sizes)
    folder = small_disk.root / "new" / "plan"
    assert main(_plan_args(folder)) == 2
    assert "cannot write plan.html (No space left on device)" in _one_line(capsys.readouterr().err)
    assert not (small_disk.root / "new").exists()
