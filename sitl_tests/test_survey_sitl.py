"""Finishing the survey when a drone is lost, against three real ArduCopter SITL vehicles (the mock-based
versions are in tests/test_survey.py): `fly --replan` re-tasks the two survivors in flight and the same
run ends at 99 % or more; without it, `replan` + a second `fly` of the two finish the survey, and
`status` says so from the ledger.

The fleet, the relay that is the ground truth of what the vehicles did, the camera set-up and the fly
child process are those of sitl_tests/test_fly_faults_sitl.py (a block in Milan, 3 drones, SPEEDUP 5:
missionplan/testing/sitl_fleet.py, the `fleet` fixture of sitl_tests/conftest.py).
The vehicle lost is SITL process 2, SIGKILLed once it is half-way through its mission items: silent for
good, as a drone that went down.

Skipped with a reason when ../shared/sitl/arducopter is absent.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.testing.sitl_fleet import FLY_TIMEOUT_S, Fleet, configure, flight_doc, in_flight, summary

pytestmark = pytest.mark.sitl

LOST = 2
SURVIVORS = (1, 3)
REPLAN_AFTER_S = 4.0  # wall seconds of silence (20 s of the vehicles' time at SPEEDUP 5)


def _half_way(fleet: Fleet) -> int:
    """The mission item half-way through the lost drone's survey (its uploaded plan)."""
    items = read_mission_file(fleet.plan_dir / f"uav{LOST}.plan").mission.items
    return len(items) // 2


def _kill(fleet: Fleet, sysid: int) -> None:
    proc = fleet.vehicle(sysid).proc
    assert proc is not None
    os.killpg(proc.pid, signal.SIGKILL)  # the process, at once: no goodbye on the link
    proc.wait(10.0)


def test_fly_replan_re_tasks_the_survivors_in_flight_and_the_same_run_ends_at_99_percent(
        fleet: Fleet, fly_runs) -> None:
    configure(fleet)
    relay, plan_dir = fleet.relay, fleet.plan_dir
    run = fly_runs(plan_dir, fleet.url, "--replan", "--replan-after", str(REPLAN_AFTER_S))
    assert in_flight(relay, _half_way(fleet), sysids=(LOST,)), summary(fleet, run)
    _kill(fleet, LOST)
    code = run.finish(FLY_TIMEOUT_S)
    doc, rows = flight_doc(plan_dir)
    print(run.out, json.dumps(doc.get("retasks"), indent=1))
    assert code == 1, (run.out, doc["problems"])  # a drone was lost: said, and the exit says it
    (retask,) = doc["retasks"]
    assert retask["gone"] == [LOST] and sorted(retask["survivors"]) == list(SURVIVORS), retask
    assert retask["outcome"] == "re-tasked" and not retask["failed"], retask
    assert all(rows[k]["finished"] for k in SURVIVORS), doc["problems"]
    assert all(any(n.startswith("re-tasked in flight") for n in rows[k]["notes"]) for k in SURVIVORS)
    # The vehicles' own photo reports (and logs) cover the survey; the separation promise held.
    assert doc["photos_from"] == "camera"
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    assert doc["min_separation_m"]["kept"] is True, doc["min_separation_m"]
    assert [p for p in doc["problems"] if not p.startswith(f"uav{LOST}:")] == [], doc["problems"]


def test_without_replan_a_replan_and_a_second_flight_finish_the_survey(fleet: Fleet, fly_runs, tmp_path: Path) -> None:
    configure(fleet)
    relay, plan_dir = fleet.relay, fleet.plan_dir
    run = fly_runs(plan_dir, fleet.url)
    assert in_flight(relay, _half_way(fleet), sysids=(LOST,)), summary(fleet, run)
    _kill(fleet, LOST)
    assert run.finish(FLY_TIMEOUT_S) == 1
    first, _ = flight_doc(plan_dir)
    assert first["coverage"] < 99.0 and "retasks" not in first

    rest = plan_dir.parent / "rest"
    planned = subprocess.run([sys.executable, "-m", "missionplan", "replan", str(plan_dir), "--out", str(rest),
                              "--drones", ",".join(map(str, SURVIVORS)), "--quiet"],
                             capture_output=True, text=True, timeout=120)
    assert planned.returncode == 0, planned.stdout + planned.stderr
    report = json.loads((rest / "report.json").read_text())
    assert sorted(d["id"] for d in report["drones"]) == list(SURVIVORS)

    second = fly_runs(rest, fleet.url)
    code = second.finish(FLY_TIMEOUT_S)
    doc, rows = flight_doc(rest)
    print(second.out)
    assert code == 0, (second.out, doc["problems"])
    assert doc["survey"]["flights"] == 2 and doc["survey"]["coverage"] >= 99.0, doc["survey"]
    status = subprocess.run([sys.executable, "-m", "missionplan", "status", str(plan_dir)],
                            capture_output=True, text=True, timeout=60)
    assert status.returncode == 0, status.stderr
    line = next(text for text in status.stdout.splitlines() if text.startswith("covered "))
    assert float(line.split(": ")[1].split(" %")[0]) >= 99.0, status.stdout
    assert (plan_dir / "missing.geojson").exists() and (plan_dir / "status.png").exists()
