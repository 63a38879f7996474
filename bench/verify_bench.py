"""`missionplan verify`'s speed by engine: runs per minute of a small plan (Leonardo, 3 drones, mock autopilots at
the default 20x) in this process one after the other, on the local process pool, on a local Ray, and on a two-node
Ray cluster started on this machine (two `ray start` processes, one CPU each); then one bigger plan (--big, a
shipped map and a number of drones) flown in this process, to see how a run grows with the drones and the flight.

    python bench/verify_bench.py [--runs 6] [--workers 2] [--big grid-city:6] [--write-doc FILE]

Each engine row is one `verify` of --runs runs, its wall time including the engine's start (a local Ray's start-up
and stop, the pool's process start per run; the cluster was started before) and its stop. Printed: runs per
minute, the wall seconds per run, each run's own wall time in its worker (copy, mock fleet, fly, judge), and the
share the engine added on top over all workers. The last table: per run of each plan in this process, the
busiest drone's simulated flight, the wall time and the CPU time (every thread of this process: the mock's
vehicles, fly's followers, the judge).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import doctable  # bench/doctable.py: --write-doc
from machine import machine_line

from missionplan.cli import main as cli
from missionplan.verify.verify import VerifySettings, verify_plan


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class TwoNodeRay:
    """A head and a worker node on this machine, one CPU each (`ray start --block`), stopped on exit."""

    def __enter__(self) -> str:
        ray = str(Path(sys.executable).parent / "ray")
        self.env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
        self.temp = tempfile.mkdtemp(prefix="mp-ray-")
        port = free_port()
        self.address = f"127.0.0.1:{port}"
        quiet: dict[str, Any] = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
        self.nodes = [subprocess.Popen([ray, "start", "--head", "--block", f"--port={port}", "--num-cpus=1",
                                        "--include-dashboard=false", f"--temp-dir={self.temp}"], env=self.env, **quiet)]
        self._wait(ray, 1)
        self.nodes.append(subprocess.Popen([ray, "start", "--block", f"--address={self.address}", "--num-cpus=1"],
                                           env=self.env, **quiet))
        self._wait(ray, 2)
        return self.address

    def _wait(self, ray: str, nodes: int) -> None:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline:
            probe = subprocess.run([ray, "status", f"--address={self.address}"], env=self.env, capture_output=True,
                                   text=True, timeout=60)
            if probe.returncode == 0 and probe.stdout.count("node_") >= nodes:
                return
            time.sleep(0.5)
        raise RuntimeError(f"the Ray cluster at {self.address} did not reach {nodes} nodes in 120 s")

    def __exit__(self, *exc: object) -> None:
        import signal

        for node in reversed(self.nodes):
            try:
                os.killpg(node.pid, signal.SIGTERM)
                node.wait(10)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                os.killpg(node.pid, signal.SIGKILL)
        shutil.rmtree(self.temp, ignore_errors=True)


def quiet_plan(out: Path, name: str, uavs: int) -> Path:
    """`missionplan plan` into out, its printed summary swallowed."""
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(["plan", "--map", name, "--uavs", str(uavs), "--out", str(out), "--quiet"]) == 0
    return out


def cost_row(name: str, plan: Path, out: Path, runs: int) -> str:
    """Simulated flight, wall and CPU seconds per run of `plan`, flown inline."""
    wall, cpu = time.monotonic(), time.process_time()
    result = verify_plan(plan, VerifySettings(runs=runs, seed=1), out=out, engine="inline", progress=False,
                         say=lambda s: None)
    wall, cpu = (time.monotonic() - wall) / runs, (time.process_time() - cpu) / runs
    flight = sum(float(r["makespan_s"]) for r in result.rows) / runs
    return f"{name:<16} {runs:>4} {flight:>9.0f} {wall:>7.1f} {cpu:>7.1f} {cpu / wall:>5.2f}"


def measure(plan: Path, out: Path, runs: int, engine: str, workers: int, address: str | None = None) -> str:
    started = time.monotonic()
    result = verify_plan(plan, VerifySettings(runs=runs, seed=1), out=out, engine=engine, workers=workers,
                         address=address, progress=False, say=lambda s: None)
    wall = time.monotonic() - started
    failed = [r for r in result.rows if r.get("error")]
    if failed:
        raise RuntimeError(f"{engine}: {len(failed)} runs failed to fly: {failed[0]['error']}")
    flights = sum(float(r["wall_s"]) for r in result.rows)
    info = result.engine
    nodes = info.nodes if info else 1
    used = info.workers if info else workers
    overhead = wall * used / flights - 1.0 if flights else float("nan")
    name = engine if address is None else "ray cluster"
    return (f"{name:<12} {nodes:>5} {used:>7} {runs:>4} {wall:>7.1f} {runs / wall * 60:>9.1f} {wall / runs:>7.2f} "
            f"{flights / runs:>8.2f} {overhead * 100:>9.0f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--big", default="grid-city:6", metavar="MAP:UAVS", help="the bigger plan flown inline")
    doctable.add_option(parser)
    args = parser.parse_args()
    # One Ray setting for the local Ray and the cluster this process joins (Ray reads it once per process).
    os.environ["RAY_AUTH_MODE"] = "disabled"
    with tempfile.TemporaryDirectory() as tmp, doctable.Recorder(args.write_doc, __file__):
        plan = quiet_plan(Path(tmp) / "leonardo-3", "leonardo", 3)
        big_name, big_uavs = args.big.split(":")
        big = quiet_plan(Path(tmp) / "big", big_name, int(big_uavs))
        print(f"{'engine':<12} {'nodes':>5} {'workers':>7} {'runs':>4} {'wall s':>7} {'runs/min':>9} {'s/run':>7} "
              f"{'flight s':>8} {'overhead':>9}")
        print(measure(plan, Path(tmp) / "inline", args.runs, "inline", 1))
        print(measure(plan, Path(tmp) / "pool", args.runs, "pool", args.workers))
        print(measure(plan, Path(tmp) / "ray", args.runs, "ray", args.workers))
        with TwoNodeRay() as address:
            print(measure(plan, Path(tmp) / "cluster", args.runs, "ray", args.workers, address))
        print("flight s: a run's own wall time in its worker (copy, mock fleet, fly, judge); overhead: the engine's "
              "share on top, over all workers")
        print()
        print(f"{'plan, inline':<16} {'runs':>4} {'flown s':>9} {'wall s':>7} {'cpu s':>7} {'cores':>5}")
        print(cost_row("leonardo, 3", plan, Path(tmp) / "cost-small", 2))
        print(cost_row(f"{big_name}, {big_uavs}", big, Path(tmp) / "cost-big", 2))
        print("flown s: the busiest drone's simulated flight; wall and cpu s per run; cores: cpu / wall")
        print(machine_line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
