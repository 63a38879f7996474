"""Live re-tasking on a PX4 SIH fleet: three vehicles as sitl_tests/test_fleet_px4.py wires them (every GCS
link into one udpin port, the camera set at boot), vehicle 2's PX4 process SIGKILLed half-way through
its mission, and `fly --replan` must re-task the two others in flight so that the same run ends at 99 %
or more of the reachable targets, from their own CAMERA_IMAGE_CAPTURED, with the separation kept.

fly runs as a child process; when vehicle 2 is half-way is read from fly's own journal (journal.sqlite,
readable while fly writes it: SQLite WAL). Skipped with a reason when ../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from test_fleet_px4 import AREA, CAMERA, LAUNCHES, TELEMETRY_HZ, _home, _plan

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.flight.journal_db import JournalError
from missionplan.flight.journal_read import read_flight
from missionplan.testing.loopback import free_udp_port, wait_until

pytestmark = pytest.mark.sitl

ROOT = Path(__file__).resolve().parent.parent
SYSIDS = (1, 2, 3)
LOST = 2
SURVIVORS = (1, 3)
FLY_TIMEOUT_S = 600.0
START_S = 240.0  # wall seconds from boot to the lost vehicle half-way (readiness ~40 s, then half its flight)
REPLAN_AFTER_S = 4.0


def _current(plan_dir: Path, sysid: int) -> int:
    """The mission item fly's journal last recorded for `sysid` (-1 before any)."""
    try:
        _, _, records = read_flight(plan_dir)
    except (JournalError, OSError, ValueError):
        return -1
    return next((rec.current for rec in records if rec.id == sysid and rec.started), -1)


def test_fly_replan_re_tasks_a_px4_fleet_in_flight(px4, tmp_path: Path) -> None:
    plan_dir = _plan(tmp_path, "milan", AREA, LAUNCHES)
    port = free_udp_port()
    vehicles = {k: px4(sysid=k, gcs_port=port, home=_home(plan_dir, k), params=CAMERA) for k in SYSIDS}
    half = len(read_mission_file(plan_dir / f"uav{LOST}.plan").mission.items) // 2
    proc = subprocess.Popen([sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--connect",
                             f"udpin:127.0.0.1:{port}", "--timeout", str(FLY_TIMEOUT_S), "--telemetry-hz",
                             str(TELEMETRY_HZ), "--quiet", "--replan", "--replan-after", str(REPLAN_AFTER_S)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert wait_until(lambda: _current(plan_dir, LOST) >= half or proc.poll() is not None, START_S), \
            "vehicle 2 never got half-way"
        assert proc.poll() is None, proc.communicate()[0]
        lost = vehicles[LOST].proc
        assert lost is not None
        os.killpg(lost.pid, signal.SIGKILL)  # the autopilot gone at once, in the air
        out, _ = proc.communicate(timeout=FLY_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10.0)
    doc = json.loads((plan_dir / "flight.json").read_text())
    rows = {int(d["id"]): d for d in doc["drones"]}
    print(out, json.dumps(doc.get("retasks"), indent=1))
    assert proc.returncode == 1, (out, doc["problems"])  # the lost drone is a problem of the flight
    (retask,) = doc["retasks"]
    assert retask["gone"] == [LOST] and sorted(retask["survivors"]) == list(SURVIVORS), retask
    assert retask["outcome"] == "re-tasked" and not retask["failed"], (retask, out)
    assert all(rows[k]["finished"] for k in SURVIVORS), doc["problems"]
    assert doc["photos_from"] == "camera"
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    assert doc["min_separation_m"]["kept"] is True, doc["min_separation_m"]
    assert [p for p in doc["problems"] if not p.startswith(f"uav{LOST}:")] == [], doc["problems"]
