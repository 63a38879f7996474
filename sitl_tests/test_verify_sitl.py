"""`missionplan verify --sim sitl`: a plan flown by `fly`'s own logic on real ArduCopter SITL with a drawn fault
(missionplan/verify/sitl_run.py), end to end through the command line.

The plan is the Milan block of missionplan/testing/sitl_fleet.py (AREA) for its first two launch points: two SITL
vehicles (system ids 1 and 2), started by verify itself on free instance numbers behind a loopback relay on
127.0.0.1, set up as a team does (camera, wind) and stopped at the end of the run. One run, drawn with a lost drone:
its vehicle's process is SIGKILLed when the relay sees it reach the drawn mission item.

Required: verify exits, verify.json holds one row with no error, coverage and makespan present, the drawn drone
listed in drones_lost, the fault recorded as struck at its item, and no SITL process of the run left behind.
Skipped with a reason when the ArduCopter SITL binary is absent.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from missionplan.cli import main
from missionplan.testing.arducopter import sitl_or_skip
from missionplan.testing.plans import plan_area
from missionplan.testing.sitl_fleet import AREA, LAUNCHES

pytestmark = pytest.mark.sitl  # starts real autopilots (verify --sim sitl): `pytest -m "not sitl"` leaves it out


def _our_arducopters() -> list[int]:
    """Pids of arducopter processes this test process started and that still exist (zombies included)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            stat = (proc / "stat").read_text() if proc.name.isdigit() else ""
        except OSError:
            continue
        if not stat:
            continue
        comm, fields = stat[stat.index("(") + 1:stat.rindex(")")], stat[stat.rindex(")") + 2:].split()
        if comm == "arducopter" and int(fields[1]) == os.getpid():
            found.append(int(proc.name))
    return found


def test_verify_on_sitl_with_a_lost_drone(tmp_path: Path) -> None:
    sitl_dir = sitl_or_skip().parent
    plan = plan_area(tmp_path, AREA, LAUNCHES[:2])
    out = tmp_path / "verify"
    code = main(["verify", str(plan), "--sim", "sitl", "--sitl-dir", str(sitl_dir), "--runs", "1", "--engine",
                 "inline", "--faults", "lost-drone", "--time-scale", "10", "--out", str(out), "--quiet"])
    doc = json.loads((out / "verify.json").read_text())
    log = "\n".join(p.read_text(errors="replace") for p in sorted(out.glob("runs/*/run.log")))
    assert len(doc["rows"]) == 1, doc
    row = doc["rows"][0]
    assert "error" not in row, f"{row.get('error')}\n{log}"
    assert code in (0, 1), log  # the verdict may fail the plan (a lost drone); the command itself did not fail
    assert row["coverage"] is not None and row["makespan_s"] is not None and row["makespan_s"] > 0, row
    (fault,) = row["conditions"]["faults"]
    assert fault["kind"] == "lost-drone"
    assert row["drones_lost"] == [fault["drone"]], row
    assert [(s["kind"], s["drone"], s["at_item"]) for s in row["struck"]] == [
        ("lost-drone", fault["drone"], fault["at_item"])], row["struck"]
    assert _our_arducopters() == [], "a SITL process of the run is still there"
