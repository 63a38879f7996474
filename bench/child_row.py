"""One bench row planned in a fresh child process, so its CPU seconds and peak RSS are its own.

A bench script re-runs itself with `--row ...`; the child prints the row's figures as one JSON line,
last. Used by scale_bench.py and unseen_bench.py.
"""

from __future__ import annotations

import json
import resource
import subprocess
from typing import Any


def peak_rss_mb() -> float:
    """This process's own peak resident memory, in MB.

    getrusage's ru_maxrss is not it: Linux carries the parent's high-water mark over fork and exec,
    so a child started by a bench that had built a 2048² city reports that city's memory. The
    kernel's VmHWM is the peak of this process's own memory map, which exec replaced.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # no /proc (not Linux): the best there is


def run_child_row(command: list[str], timeout: float) -> dict[str, Any] | str:
    """The figures the child printed last, or why there are none ("did not finish in N s", "failed (exit N)")."""
    try:
        done = subprocess.run(command, stdout=subprocess.PIPE, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"did not finish in {timeout:.0f} s"
    if done.returncode != 0:
        return f"failed (exit {done.returncode})"
    return json.loads(done.stdout.strip().splitlines()[-1])
