"""Where verification runs fly: in this process one after the other (`inline`), on a local process pool (`pool`:
one worker process per run, at most N at once), or as Ray tasks (`ray`: a local Ray started here, or a running
cluster joined by address).

Each engine takes the runs' jobs (flight_run.RunJob) and hands back each run's row as it finishes, so the caller
writes it at once. A worker that dies mid-run (killed, out of memory, its node lost) is retried once, and its row
says so (`attempts`: 2, `retried`: why); one that dies twice gives a row with `error`, counted apart, never dropped.

Ray: tasks ask for one CPU each; the plan folder travels as bytes in Ray's object store, so a node that does not
share this machine's disk flies it too (each task writes it into a temporary folder of its own node and returns
the judge's flight.json and the run's log). Ray on Linux talks over the machine's own network address, never
127.0.0.1 (ray-project/ray#26293); a local Ray reaches no other machine.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from missionplan.base.naming import Named
from .flight_run import RunJob, fly_run

ENGINES = ("auto", "ray", "pool", "inline")
WAIT_S = 0.5  # how often the pool looks at its workers


@dataclass
class EngineInfo:
    """What flew the runs, for verify.json: the engine, its version, nodes and workers used."""

    engine: str
    version: str
    nodes: int
    workers: int
    address: str | None = None
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        doc = {"engine": self.engine, "version": self.version, "nodes": self.nodes, "workers": self.workers}
        if self.address:
            doc["address"] = self.address
        return doc


def ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


def choose_engine(asked: str, address: str | None) -> tuple[str, str]:
    """(engine, the one line saying why, or "") for the engine asked: auto is Ray when installed, else the pool."""
    if asked in ("ray", "auto") and ray_available():
        return "ray", ""
    if asked == "ray" or address:
        raise EngineError(Named("Ray is not installed: pip install 'missionplan[cluster]' (or use {engine} pool)"))
    if asked == "auto":
        return "pool", "Ray is not installed (pip install 'missionplan[cluster]'): the runs go to a local process pool"
    return asked, ""


class EngineError(RuntimeError):
    """An engine that cannot start (Ray missing, a cluster address that does not answer): one line."""


def finished_row(row: dict[str, Any], retried: str | None) -> dict[str, Any]:
    """A run's row as its engine hands it back: flown at the first attempt, or at the second after a worker died."""
    return {**row, "attempts": 1} if retried is None else {**row, "attempts": 2, "retried": retried}


def died_twice_row(job: RunJob, why: str) -> dict[str, Any]:
    """The row of a run whose worker died at both attempts: its conditions and why, counted apart."""
    return {"run": job.conditions.run, "seed": job.conditions.seed, "conditions": job.conditions.to_json(),
            "error": f"worker died twice: {why}", "attempts": 2, "retried": why}


# ------------------------------------------------------------------------------------------ inline
def run_inline(jobs: list[RunJob]) -> Iterator[dict[str, Any]]:
    for job in jobs:
        yield finished_row(fly_run(job), None)


# ------------------------------------------------------------------------------------------ pool
def _start_worker(job: RunJob) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, "-m", "missionplan.verify.worker"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    assert proc.stdin is not None
    proc.stdin.write(json.dumps(job_to_json(job)))
    proc.stdin.close()
    return proc


def run_pool(jobs: list[RunJob], workers: int) -> Iterator[dict[str, Any]]:
    """One process per run, at most `workers` at once; a process that ends without a row died."""
    queue = list(jobs)
    running: dict[int, tuple[subprocess.Popen[str], RunJob, str | None]] = {}  # pid -> worker, job, why retried
    try:
        while queue or running:
            while queue and len(running) < workers:
                job = queue.pop(0)
                proc = _start_worker(job)
                running[proc.pid] = (proc, job, None)
            finished = [pid for pid, (proc, _, _) in running.items() if proc.poll() is not None]
            if not finished:
                try:  # the oldest worker's end, or WAIT_S: then every worker is looked at again
                    next(iter(running.values()))[0].wait(timeout=WAIT_S)
                except subprocess.TimeoutExpired:
                    pass
                continue
            for pid in finished:
                proc, job, retried = running.pop(pid)
                assert proc.stdout is not None
                out = proc.stdout.read().strip().splitlines()
                if proc.returncode == 0 and out:
                    yield finished_row(json.loads(out[-1]), retried)
                    continue
                why = f"worker process {pid} ended with {_exit_text(proc.returncode)}"
                if retried is not None:
                    yield died_twice_row(job, why)
                    continue
                retry = _start_worker(job)
                running[retry.pid] = (retry, job, why)
    finally:
        for proc, _, _ in running.values():
            proc.kill()


def _exit_text(code: int | None) -> str:
    if code is not None and code < 0:
        import signal

        return f"signal {signal.Signals(-code).name}"
    return f"exit code {code}"


def job_to_json(job: RunJob) -> dict[str, Any]:
    return {"plan_dir": job.plan_dir, "run_dir": job.run_dir, "conditions": job.conditions.to_json(), "sim": job.sim,
            "time_scale": job.time_scale, "replan": job.replan, "keep_flight": job.keep_flight,
            "sitl_dir": job.sitl_dir}


def job_from_json(doc: dict[str, Any]) -> RunJob:
    from .conditions import Conditions

    return RunJob(**{**doc, "conditions": Conditions.from_json(doc["conditions"])})


# ------------------------------------------------------------------------------------------ Ray
def plan_bytes(plan_dir: Path) -> dict[str, bytes]:
    """The plan folder's files (what a run copies), by path inside it."""
    from .flight_run import copy_plan

    with tempfile.TemporaryDirectory() as tmp:
        copy = copy_plan(plan_dir, Path(tmp) / "run")
        return {str(p.relative_to(copy)): p.read_bytes() for p in copy.rglob("*") if p.is_file()}


def ray_task(job_doc: dict[str, Any], files: dict[str, bytes]) -> dict[str, Any]:
    """One run in a Ray worker, on a node that may not share this machine's disk: the plan written into a
    temporary folder of the node, flown, and the row returned with the judge's flight.json and the run's log."""
    import ray

    job = job_from_json(job_doc)
    with tempfile.TemporaryDirectory(prefix="missionplan-verify-") as tmp:
        plan = Path(tmp) / "plan-in"
        for name, data in files.items():
            (plan / name).parent.mkdir(parents=True, exist_ok=True)
            (plan / name).write_bytes(data)
        run_dir = Path(tmp) / "run"
        row = fly_run(replace(job, plan_dir=str(plan), run_dir=str(run_dir), keep_flight=False))
        kept = {name: (run_dir / name).read_text(encoding="utf-8", errors="replace")
                for name in ("flight.json", "run.log") if (run_dir / name).is_file()}
    context = ray.get_runtime_context()
    row["worker"] = {**row.get("worker", {}), "node": context.get_node_id(), "ip": ray.util.get_node_ip_address()}
    return {"row": row, "files": kept}


def start_ray(workers: int, address: str | None) -> EngineInfo:
    import ray

    if address:
        try:
            ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)
        except (ConnectionError, RuntimeError) as err:
            raise EngineError(Named("{address} {0}: no Ray cluster answers there ({1})", address,
                                    str(err).splitlines()[0]))
    else:
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
    alive = [n for n in ray.nodes() if n.get("Alive")]
    cpus = int(sum(n.get("Resources", {}).get("CPU", 0) for n in alive))
    return EngineInfo("ray", ray.__version__, len(alive), cpus if address else workers, address)


def run_ray(jobs: list[RunJob], plan_dir: Path) -> Iterator[dict[str, Any]]:
    """Every run as a Ray task (one CPU each, no automatic retry: a dead worker is retried here once, counted)."""
    import ray
    from ray.exceptions import NodeDiedError, RayTaskError, WorkerCrashedError

    task = ray.remote(num_cpus=1, max_retries=0)(ray_task)
    files = ray.put(plan_bytes(plan_dir))
    pending: dict[Any, tuple[RunJob, str | None]] = {}  # task -> its job, why it is a retry
    for job in jobs:
        pending[task.remote(job_to_json(job), files)] = (job, None)
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        ref = done[0]
        job, retried = pending.pop(ref)
        try:
            result = ray.get(ref)
        except (WorkerCrashedError, NodeDiedError) as err:
            why = f"Ray worker died: {type(err).__name__}"
            if retried is not None:
                yield died_twice_row(job, why)
            else:
                pending[task.remote(job_to_json(job), files)] = (job, why)
            continue
        except RayTaskError as err:  # the run raised past fly_run's own catch: its row says so
            yield {"run": job.conditions.run, "seed": job.conditions.seed, "conditions": job.conditions.to_json(),
                   "error": str(err).splitlines()[0], "attempts": 1}
            continue
        run_dir = Path(job.run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        for name, text in result["files"].items():
            (run_dir / name).write_text(text, encoding="utf-8")
        yield finished_row(result["row"], retried)


def run_jobs(engine: str, jobs: list[RunJob], workers: int, plan_dir: Path,
             on_start: Callable[[EngineInfo], None] | None = None,
             address: str | None = None) -> Iterator[dict[str, Any]]:
    """Every job's row, as runs finish, from `engine` (after choose_engine). on_start gets what flies them."""
    if engine == "ray":
        import ray

        info = start_ray(workers, address)
        if on_start:
            on_start(info)
        try:
            yield from run_ray(jobs, plan_dir)
        finally:
            ray.shutdown()
        return
    info = EngineInfo(engine, "python " + sys.version.split()[0], 1, 1 if engine == "inline" else workers)
    if on_start:
        on_start(info)
    yield from (run_inline(jobs) if engine == "inline" else run_pool(jobs, workers))
