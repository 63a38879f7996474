"""Live re-tasking measured on ArduCopter SITL: a drone lost half-way, `fly --replan`, against the ideal.

Run by hand: `.venv/bin/python bench/survey_bench.py [--runs N] [--replan-after S] [--write-doc FILE]`
(needs ../shared/sitl/arducopter). Each run: the fleet of sitl_tests/test_fly_faults_sitl.py
(missionplan/testing/sitl_fleet.py: three ArduCopter SITL vehicles at 5x through a loopback relay, the
200 x 140 m Milan block from 20 m, fly as a child process with --replan), vehicle 2's SITL SIGKILLed once it is half-way through its mission items.

Each row, times in the vehicles' seconds (simulated) unless named wall:
- `lost at`: when vehicle 2 was last heard, from the mission start;
- `on board`: from then to the survivors' new missions confirmed on board (wall, and vehicle s): the
  --replan-after wait, the planning, the uploads;
- `flown end`: when the last survivor landed, from the mission start (flight.json, the vehicles' clocks);
- `ideal end`: the loss moment plus the makespan of a fresh plan for the survivors made at that very
  moment from where they were, with the photos confirmed until then (missionplan.planning.retask.plan_retask on
  the journal's records cut at the loss, no waiting, no upload): what re-tasking could at best give;
- `extra`: flown end less ideal end (s, and % of the ideal end); `flying s`: the part of it not spent
  before the new missions were on board (`veh s`), i.e. the survivors flying their new plans slower
  than the flight model times them; `cover`: the flight's coverage (%),
  `sep`: the flown closest approach against the re-task's promise (kept or not).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import doctable

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.cli import main
from missionplan.mission.plan_record import read_plan_record

ROOT = Path(__file__).resolve().parent.parent


LOST = 2
HEADER = (f"{'run':>3}{'lost at':>9}{'on board wall':>15}{'veh s':>7}{'left':>6}{'flown end':>11}{'ideal end':>11}"
          f"{'extra s':>9}{'extra %':>9}{'flying s':>10}{'cover':>8}  sep")


def _plan(out: Path) -> Path:
    from missionplan.testing.sitl_fleet import AREA, LAUNCHES

    area = out / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    argv = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(out / "plan"), "--quiet"]
    for launch in LAUNCHES:
        argv += ["--launch", launch]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    return out / "plan"


def _at(rec: Any, t: float) -> tuple[float, float, float]:
    """A record's position (lat, lon, up) at our time t, interpolated between its samples."""
    s = np.array(rec.samples)
    return tuple(float(np.interp(t, s[:, 0], s[:, k])) for k in (1, 2, 3))  # type: ignore[return-value]


def ideal_end(plan_dir: Path, scale: float) -> tuple[float, float]:
    """(the loss moment, the ideal end), vehicle seconds from the survivors' mission start."""
    from missionplan.flight.journal_read import read_flight
    from missionplan.planning.retask import Survivor, plan_retask

    _, _, records = read_flight(plan_dir)
    lost = next(r for r in records if r.id == LOST)
    t_loss = lost.samples[-1][0]
    survivors = [r for r in records if r.id != LOST]
    t0 = min(r.t_start for r in survivors)
    photos = np.array([[lat, lon] for r in records for (t, lat, lon, _) in r.camera.values() if t <= t_loss])
    states = []
    for r in survivors:
        lat, lon, up = _at(r, t_loss)
        home = read_mission_file(plan_dir / f"uav{r.id}.plan").mission.home
        states.append(Survivor(r.id, lat, lon, up, (float(home[0]), float(home[1])), (t_loss - r.t_start) * scale))
    with tempfile.TemporaryDirectory() as tmp:  # the plan alone: no ledger, so only these photos count
        clean = Path(tmp)
        for path in plan_dir.iterdir():
            if path.name == "report.json" or path.suffix == ".plan":
                shutil.copy(path, clean / path.name)
        plan = plan_retask(clean, read_plan_record(clean), states, photos.reshape(-1, 2))
    loss = (t_loss - t0) * scale
    return loss, loss + (max(plan.flight_s.values()) if plan is not None else 0.0)


def run_once(index: int, replan_after: float) -> str:
    from missionplan.testing.sitl_fleet import SYSIDS, FlyRun, configure, in_flight, sitl_fleet

    with tempfile.TemporaryDirectory() as tmp:
        plan_dir = _plan(Path(tmp))
        half = len(read_mission_file(plan_dir / f"uav{LOST}.plan").mission.items) // 2
        with sitl_fleet(plan_dir, SYSIDS) as fleet:
            configure(fleet)
            run = FlyRun(plan_dir, fleet.url, "--replan", "--replan-after", str(replan_after))
            try:
                if not in_flight(fleet.relay, half, sysids=(LOST,)):
                    return f"{index:>3}  vehicle {LOST} never got half-way"
                os.killpg(fleet.vehicle(LOST).proc.pid, signal.SIGKILL)
                run.finish(600.0)
            finally:
                run.kill()
        doc = json.loads((plan_dir / "flight.json").read_text())
        retask = (doc.get("retasks") or [{}])[0]
        if retask.get("outcome") != "re-tasked":
            return f"{index:>3}  not re-tasked: {retask.get('outcome')}"
        scale = float(doc["time_scale"])
        loss, ideal = ideal_end(plan_dir, scale)
        flown = max(d["flight_s"] for d in doc["drones"] if d["id"] != LOST)
        on_board = float(retask["loss_to_missions_s"])
        sep = doc["min_separation_m"]
    extra = flown - ideal
    return (f"{index:>3}{loss:>9.1f}{on_board:>15.2f}{on_board * scale:>7.1f}{retask['targets_left']:>6}"
            f"{flown:>11.1f}{ideal:>11.1f}{extra:>9.1f}{100.0 * extra / ideal:>9.1f}{extra - on_board * scale:>10.1f}"
            f"{doc['coverage']:>8.2f}  "
            f"{sep['3d']} m vs {sep['planned_3d']} m: {'kept' if sep['kept'] else 'BROKEN'}")


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1, help="lost-drone flights to measure (default 1)")
    parser.add_argument("--replan-after", type=float, default=4.0,
                        help="fly --replan-after, wall seconds (default 4: 20 s of the vehicles' time at 5x)")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        print(HEADER)
        print("-" * len(HEADER))
        for index in range(1, args.runs + 1):
            started = time.monotonic()
            row = run_once(index, args.replan_after)
            print(row, flush=True)
            print(f"    ({time.monotonic() - started:.0f} s wall)", file=sys.stderr)


if __name__ == "__main__":
    main_bench()
