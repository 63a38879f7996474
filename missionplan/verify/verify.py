"""`missionplan verify PLAN_DIR`, the library call: the plan flown `runs` times on simulated fleets, each run in
the wind and with the faults drawn for it, on the engine asked; verify.json / .png / .html in the output folder.

The output folder (PLAN_DIR/verify by default) is held for the whole run (bridge.folder_lock: a second verify on
it gets one line). verify.json is rewritten after every finished run; Ctrl-C stops the runs and keeps what finished;
`resume` flies only the runs it lacks, with the same settings (checked).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from missionplan.base.naming import Named
from missionplan.bridge.folder_lock import hold_folder
from missionplan.bridge.formats.missionfile import read_mission_file

from .conditions import draw_conditions
from .engines import EngineInfo, choose_engine, run_jobs
from .flight_run import RunJob
from .summary import summarise, verdict
from .verify_files import (JSON_NAME, SCHEMA, VerifyFolderError, draw, plan_fingerprint, read_for_resume,
                           write_html, write_json)

DEFAULT_TIME_SCALE = 20.0  # mock autopilots at 20x: a leonardo-3 run in ~5 s of wall time, telemetry still dense


@dataclass(frozen=True)
class VerifySettings:
    """What the runs meet and how they fly: the number of runs, the base seed, the wind range (m/s), the fault
    kinds, live re-tasking as `fly --replan`, the simulator and its speed-up."""

    runs: int
    seed: int = 0
    wind: tuple[float, float] = (0.0, 0.0)
    faults: tuple[str, ...] = ()
    replan: bool = False
    sim: str = "mock"
    time_scale: float = DEFAULT_TIME_SCALE

    def to_json(self) -> dict[str, Any]:
        doc = asdict(self)
        doc["wind"], doc["faults"] = list(self.wind), list(self.faults)
        return doc


@dataclass
class VerifyResult:
    out: Path
    rows: list[dict[str, Any]]
    summary: dict[str, Any]
    verdict: str
    engine: EngineInfo | None
    complete: bool
    files: list[Path] = field(default_factory=list)


def mission_items(plan_dir: Path) -> dict[int, int]:
    """Each drone's system id -> the number of items of its (first sortie's) mission."""
    items = {int(p.stem[3:]): len(read_mission_file(p).mission.items)
             for p in sorted(plan_dir.glob("uav*.plan")) if p.stem[3:].isdigit()}
    if not items:
        raise VerifyFolderError(f"{plan_dir}: no uavK.plan files to fly (run `missionplan plan --out {plan_dir}`)")
    return items


def verify_plan(plan_dir: Path, settings: VerifySettings, out: Path | None = None, engine: str = "auto",
                workers: int | None = None, address: str | None = None, resume: bool = False,
                keep_flights: bool = False, progress: bool = True, sitl_dir: str | None = None,
                say: Callable[[str], None] = print) -> VerifyResult:
    plan_dir = Path(plan_dir)
    if not (plan_dir / "report.json").is_file():
        raise VerifyFolderError(f"{plan_dir}: no report.json (run `missionplan plan --out {plan_dir}` first)")
    out = Path(out) if out is not None else plan_dir / "verify"
    items = mission_items(plan_dir)
    chosen, why = choose_engine(engine, address)
    workers = workers or os.cpu_count() or 1
    out.mkdir(parents=True, exist_ok=True)
    with hold_folder(out):
        fingerprint = plan_fingerprint(plan_dir)
        if (out / JSON_NAME).exists() and not resume:
            raise VerifyFolderError(Named("{0}: an earlier verify is there; {resume} continues it, or choose another "
                                          "{out}", out / JSON_NAME))
        done = read_for_resume(out, fingerprint, settings.to_json()) if resume else []
        rows = {r["run"]: r for r in done if r["run"] < settings.runs}
        jobs = [RunJob(str(plan_dir.resolve()), str((out / "runs" / f"{i:04d}").resolve()),
                       draw_conditions(i, settings.seed, settings.wind, settings.faults, items), settings.sim,
                       settings.time_scale, settings.replan, keep_flights, sitl_dir)
                for i in range(settings.runs) if i not in rows]
        if why:
            say(why)
        if rows:
            say(f"resuming: {len(rows)} of {settings.runs} runs already flown, {len(jobs)} to fly")
        doc: dict[str, Any] = {"schema": SCHEMA, "plan": {"dir": str(plan_dir), "missions_sha256": fingerprint},
                               "settings": settings.to_json(), "engine": None, "complete": False}
        info: list[EngineInfo] = []

        def save() -> None:
            doc["rows"] = [rows[k] for k in sorted(rows)]
            doc["summary"] = summarise(doc["rows"])
            doc["verdict"] = verdict(doc["summary"])
            write_json(out, doc)

        def started(engine_info: EngineInfo) -> None:
            info.append(engine_info)
            doc["engine"] = engine_info.to_json()
            say(f"{len(jobs)} runs on {engine_info.engine} {engine_info.version}: {engine_info.nodes} node"
                f"{'s' if engine_info.nodes != 1 else ''}, {engine_info.workers} workers")

        bar = _bar(len(rows), settings.runs, progress)
        complete = False
        try:
            for row in run_jobs(chosen, jobs, workers, plan_dir, on_start=started, address=address):
                rows[row["run"]] = row
                save()
                if bar is not None:
                    bar.update(1)
            complete = True
        except KeyboardInterrupt:
            say(f"stopped: {len(rows)} of {settings.runs} runs kept in {out / JSON_NAME}; "
                f"`missionplan verify {plan_dir} --resume` flies the rest")
        finally:
            if bar is not None:
                bar.close()
        doc["complete"] = complete and len(rows) == settings.runs
        save()
        title = f"{plan_dir}: {len(rows)} runs; {doc['verdict']}"
        png = draw(out, doc["rows"], doc["summary"], title)
        page = write_html(out, doc, png)
        return VerifyResult(out, doc["rows"], doc["summary"], doc["verdict"], info[0] if info else None,
                            doc["complete"], [out / JSON_NAME, png, page])


def _bar(done: int, total: int, progress: bool) -> Any:
    """A progress bar on a terminal only."""
    if not progress or not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit="run", desc="verify", file=sys.stderr)
