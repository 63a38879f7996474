"""`missionplan verify`'s engines under stress: a pool worker and a Ray worker killed mid-run (each run retried once
and counted), a local Ray's rows and what it names, and a two-node Ray cluster started on this machine whose
nodes both get runs."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

from missionplan.testing.loopback import stop_process_group, wait_until
from missionplan.verify.verify import VerifySettings, verify_plan
from verify_runs import FLY_S, leonardo_3, verify_doc



@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return leonardo_3(tmp_path_factory.mktemp("verify-engines"))


def _kill_when(find: Any, timeout: float) -> int:
    pid = wait_until(find, timeout, interval=0.02)
    assert pid, "no worker to kill appeared"
    os.kill(pid, signal.SIGKILL)
    return pid


def _processes(marker: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if cmdline.startswith(marker):
                found.append(int(entry.name))
    return found


@pytest.mark.flight
def test_a_pool_worker_killed_mid_run_is_retried_once_and_counted(plan: Path, tmp_path: Path) -> None:
    out = tmp_path / "v"
    proc = subprocess.Popen([sys.executable, "-m", "missionplan", "verify", str(plan), "--runs", "1", "--engine",
                             "pool", "--out", str(out), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        pid_file = out / "runs" / "0000" / "worker.pid"
        killed = _kill_when(lambda: pid_file.is_file() and pid_file.read_text().strip()
                            and int(pid_file.read_text()), FLY_S)
        stdout, stderr = proc.communicate(timeout=FLY_S)
    finally:
        stop_process_group(proc)  # type: ignore[arg-type]
    row = verify_doc(out)["rows"][0]
    assert row["attempts"] == 2 and f"worker process {killed} ended with signal SIGKILL" in row["retried"]
    assert not row.get("error") and row["coverage"] >= 99.0
    assert verify_doc(out)["summary"]["retried"] == 1 and "1 retried after a worker died" in stdout, stdout + stderr


@pytest.mark.flight
def test_local_ray_flies_the_runs_and_retries_a_killed_worker(plan: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="the cluster extra (make test installs it)")
    import threading

    out = tmp_path / "v"
    settings = VerifySettings(runs=2, seed=3, wind=(4.0, 8.0), faults=("link-gap", "gps-glitch"))
    result: dict[str, Any] = {}
    runner = threading.Thread(target=lambda: result.update(r=verify_plan(
        plan, settings, out=out, engine="ray", workers=2, progress=False, say=lambda s: None)))
    runner.start()
    killed = _kill_when(lambda: next(iter(_processes("ray::ray_task")), None), FLY_S)
    runner.join(FLY_S)
    assert not runner.is_alive() and "r" in result
    rows = result["r"].rows
    assert [r["run"] for r in rows] == [0, 1] and not any(r.get("error") for r in rows)
    retried = [r for r in rows if r["attempts"] == 2]
    assert len(retried) == 1 and "WorkerCrashedError" in retried[0]["retried"], (killed, rows)
    engine = verify_doc(out)["engine"]
    assert engine["engine"] == "ray" and engine["version"] and engine["nodes"] == 1 and engine["workers"] == 2
    assert all(r["worker"]["node"] for r in rows)
    for row in rows:  # both faults struck at their items, in a wind of 4-8 m/s
        assert sorted(f["kind"] for f in row["struck"]) == ["gps-glitch", "link-gap"], row["struck"]
        assert 4.0 <= row["conditions"]["wind_mps"] <= 8.0


def _free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.flight
def test_a_two_node_ray_cluster_on_this_machine_gets_runs_on_both_nodes(plan: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="the cluster extra (make test installs it)")
    ray_cli = str(Path(sys.executable).parent / "ray")
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
    port = _free_tcp_port()
    address = f"127.0.0.1:{port}"
    ray_temp = tempfile.mkdtemp(prefix="mp-ray-")  # short: Ray's socket paths live under it (107 bytes at most)
    head = subprocess.Popen([ray_cli, "start", "--head", "--block", f"--port={port}", "--num-cpus=1",
                             "--include-dashboard=false", f"--temp-dir={ray_temp}"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    nodes = [head]
    try:
        def joined() -> bool:
            if head.poll() is not None:
                raise AssertionError("the head node stopped")
            probe = subprocess.run([ray_cli, "status", f"--address={address}"], env=env, capture_output=True,
                                   text=True, timeout=60)
            return probe.returncode == 0

        assert wait_until(joined, 120.0, interval=0.5), "the head node did not answer"
        nodes.append(subprocess.Popen([ray_cli, "start", "--block", f"--address={address}", "--num-cpus=1"],
                                      env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      start_new_session=True))

        def two_nodes() -> bool:
            probe = subprocess.run([ray_cli, "status", f"--address={address}"], env=env, capture_output=True,
                                   text=True, timeout=60)
            return probe.stdout.count("node_") >= 2

        assert wait_until(two_nodes, 120.0, interval=0.5), "the second node did not join"
        out = tmp_path / "v"
        run = subprocess.run([sys.executable, "-m", "missionplan", "verify", str(plan), "--runs", "2", "--address",
                              address, "--out", str(out), "--quiet"], env=env, capture_output=True, text=True,
                             timeout=FLY_S)
        assert run.returncode in (0, 1), run.stderr
        verified = verify_doc(out)
        assert verified["engine"] == {"engine": "ray", "version": verified["engine"]["version"], "nodes": 2,
                                      "workers": 2, "address": address}
        landed = {r["worker"]["node"] for r in verified["rows"]}
        assert len(verified["rows"]) == 2 and len(landed) == 2, verified["rows"]
    finally:
        for node in reversed(nodes):
            stop_process_group(node)  # type: ignore[arg-type]
        shutil.rmtree(ray_temp, ignore_errors=True)
