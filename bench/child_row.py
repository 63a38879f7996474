"""One bench row planned in a fresh child process, so its CPU seconds and peak RSS are its own.

A bench script re-runs itself with `--row ...`; the child prints the row's figures as one JSON line,
last. Used by scale_bench.py and unseen_bench.py.
"""

from __future__ import annotations

import json
import subprocess
from typing import Any


def run_child_row(command: list[str], timeout: float) -> dict[str, Any] | str:
    """The figures the child printed last, or why there are none ("did not finish in N s", "failed (exit N)")."""
    try:
        done = subprocess.run(command, stdout=subprocess.PIPE, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"did not finish in {timeout:.0f} s"
    if done.returncode != 0:
        return f"failed (exit {done.returncode})"
    return json.loads(done.stdout.strip().splitlines()[-1])
