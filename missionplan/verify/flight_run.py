"""One verification run: a copy of the plan folder flown by `fly`'s own logic (its journal, alerts, live re-tasking
and judge: missionplan.flight.fly.fly) on a fresh mock fleet in the run's wind and faults, read back as one row.

The copy lives in OUT/runs/NNNN/ (the plan folder itself is never written to). After the run only flight.json (the
judge's whole record) and run.log (what fly said) are kept there, unless the crew asks to keep the flights.
Every row names its conditions, so a run can be flown again alone: `verify --runs 1 --first N`.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .conditions import Conditions

KEEP_AFTER = ("flight.json", "run.log")
# What a flight leaves in a plan folder: never copied into a run (each run is a first flight of the plan).
FLIGHT_LEFTOVERS = ("journal.*", "ledger.sqlite*", "flight.*", "missed.geojson", "photos.*", ".missionplan.lock",
                    "verify", "runs", "*.damaged")
MOCK_MARGIN_S = 120.0  # wall seconds on top of fly's makespan bound (fleet_flight): readiness, uploads, a re-task


@dataclass(frozen=True)
class RunJob:
    """Everything one run needs, picklable for a process or a Ray task: the plan folder, where the run flies,
    its conditions, the simulator and its speed-up, live re-tasking or not, and whether to keep the flight."""

    plan_dir: str
    run_dir: str
    conditions: Conditions
    sim: str  # "mock" or "sitl"
    time_scale: float
    replan: bool
    keep_flight: bool = False
    sitl_dir: str | None = None  # --sim sitl: the folder of the arducopter binary and its copter.parm


def copy_plan(plan_dir: Path, run_dir: Path) -> Path:
    """A fresh copy of the plan folder's plan (no earlier flight's record) in run_dir/plan."""
    if run_dir.exists():  # a run that was stopped or whose worker died: start it again from nothing
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True)
    copy = run_dir / "plan"
    shutil.copytree(plan_dir, copy, ignore=shutil.ignore_patterns(*FLIGHT_LEFTOVERS))
    return copy


def fly_run(job: RunJob) -> dict[str, Any]:
    """Fly one run and return its row (row_of); an error of the run itself (not of the flight) is the row's
    `error`, with the run's own traceback in run.log."""
    run_dir = Path(job.run_dir)
    started = time.monotonic()
    copy = copy_plan(Path(job.plan_dir), run_dir)
    (run_dir / "worker.pid").write_text(f"{os.getpid()}\n")  # who flies it: what a test kills to kill a worker
    log = run_dir / "run.log"
    extra: dict[str, Any] = {}
    try:
        with open(log, "w", encoding="utf-8") as out, contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            if job.sim == "sitl":
                from .sitl_run import fly_on_sitl

                doc, extra = fly_on_sitl(copy, job)
            else:
                doc, extra = fly_on_mock(copy, job)
    except Exception as err:  # noqa: BLE001 - the run failed to fly at all: its row says why, the others go on
        with open(log, "a", encoding="utf-8") as out:
            out.write(traceback.format_exc())
        return {"run": job.conditions.run, "seed": job.conditions.seed, "conditions": job.conditions.to_json(),
                "error": f"{type(err).__name__}: {err}", "wall_s": round(time.monotonic() - started, 2),
                "worker": worker_identity()}
    row = row_of(job.conditions, doc, extra, copy)
    row["wall_s"] = round(time.monotonic() - started, 2)
    row["worker"] = worker_identity()
    if (copy / "flight.json").is_file():
        shutil.copy2(copy / "flight.json", run_dir / "flight.json")
    if not job.keep_flight:
        shutil.rmtree(copy, ignore_errors=True)
    (run_dir / "worker.pid").unlink(missing_ok=True)
    return row


def worker_identity() -> dict[str, Any]:
    return {"host": socket.gethostname(), "pid": os.getpid()}


def fly_on_mock(copy: Path, job: RunJob) -> tuple[dict[str, Any], dict[str, Any]]:
    """The run on in-process mock autopilots (SITL-like, cameras configured): fly's judgement (flight.json's
    content) and the simulator's own truth (battery used per drone, the faults as they struck)."""
    from missionplan.bridge.sim.mock_vehicle import BATTERY_CURRENT_A
    from missionplan.flight.mock_fleet import start_mock_fleet

    from .fleet_flight import fly_fleet
    from .sim_faults import MockFaults

    speedup = job.time_scale
    mock = start_mock_fleet(copy, speedup)
    faults = MockFaults(mock, job.conditions, speedup)
    try:
        faults.start()
        result = fly_fleet(copy, mock.client_url, speedup, job.replan, MOCK_MARGIN_S)
    finally:
        faults.stop()
        mock.stop()
    used = {sysid: float(mock.vehicle(sysid).consumed_mah) for sysid in mock.vehicles}
    return result.doc, {"battery_mah": used, "calm_current_a": BATTERY_CURRENT_A, "struck": faults.struck}


def row_of(conditions: Conditions, doc: dict[str, Any], extra: dict[str, Any], plan_dir: Path) -> dict[str, Any]:
    """One run's row: its conditions and seed, coverage (%), makespan (s, flown and planned), closest approach (m,
    flown and promised), drones lost or ended early, the re-task outcome, battery left (share of each drone's
    battery, from what the simulator says it used against the plan's endurance), problems."""
    from missionplan.mission.plan_record import read_plan_record

    record = read_plan_record(plan_dir)
    safety = record.settings.safety if record.settings is not None else None
    endurance = safety.endurance_s if safety is not None else None
    drones = doc.get("drones", [])
    lost = [d["id"] for d in drones if not d.get("finished") and not d.get("ended_early")]
    early = {str(d["id"]): d["ended_early"] for d in drones if d.get("ended_early")}
    separation = doc.get("min_separation_m") or {}
    battery_left: dict[str, float] = {}
    if endurance and extra.get("battery_mah"):
        capacity = extra["calm_current_a"] * endurance / 3.6  # mAh the plan's endurance is worth in calm air
        battery_left = {str(k): round(1.0 - v / capacity, 4) for k, v in extra["battery_mah"].items()}
    retasks = doc.get("retasks") or []
    return {
        "run": conditions.run, "seed": conditions.seed, "conditions": conditions.to_json(),
        "coverage": doc.get("coverage"),
        # The fleet's end: the last drone down of those that came back (a lost drone's clock runs until fly gives
        # it up, which is not a flight time).
        "makespan_s": max((float(d.get("flight_s") or 0.0) for d in drones if d["id"] not in lost), default=None),
        "planned_makespan_s": max((float(d.get("planned_flight_s") or 0.0) for d in drones), default=None),
        "closest_m": separation.get("3d"), "promised_m": separation.get("planned_3d"),
        "separation_tolerance_m": separation.get("tolerance"), "separation_kept": separation.get("kept"),
        "drones_lost": lost, "ended_early": early,
        "retask": [r.get("outcome") for r in retasks],
        "battery_left": battery_left, "reserve": safety.reserve if safety is not None else None,
        "problems": list(doc.get("problems", [])), "struck": extra.get("struck", []),
    }
