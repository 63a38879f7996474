"""The machine a bench ran on, and how fast it was that hour: one line under a bench's table.

The CPU seconds of a plan drift by a third between hours on the same kind of virtual machine (the
same code measured 1.7 s one day and 2.3 s another), far more than most changes to the planner.
So every table says which processor it ran on and how long a fixed reference workload took in the
same run: two tables are comparable only when their reference times are.

The reference is a small copy of what planning spends its time on: Python-level dictionary and
heap work (A*, the step loop), many calls on small numpy arrays (the views, the distance search)
and one float32 matrix-vector product per drone-step (the expert's gains). The least of three
runs stands, as for the plans.
"""

from __future__ import annotations

import heapq
import os
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits

REFERENCE_RUNS = 3


def _processor() -> str:
    """The processor's model name (Linux), else what the platform module says."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _reference_workload() -> None:
    """A few tenths of a second of planning-like work."""
    # Python-level: a heap and a dictionary, as A* uses them.
    heap: list[tuple[int, int]] = []
    best: dict[int, int] = {}
    for i in range(300_000):
        key = (i * 7919) % 65_521
        if best.get(key, 1 << 30) > i:
            best[key] = i
            heapq.heappush(heap, (key, i))
        if len(heap) > 64:
            heapq.heappop(heap)
    # Many calls on small arrays, as the views and the distance search make.
    grid = np.zeros(400, dtype=bool)
    grid[::7] = True
    grown = np.empty_like(grid)
    for _ in range(150_000):
        np.bitwise_or(grid[:-20], grid[20:], out=grown[:-20])
        grown &= ~grid
        np.count_nonzero(grown)
    # The expert's per-drone product.
    weights = np.random.default_rng(0).random((1024, 361), dtype=np.float32)
    view = (np.arange(361) % 3 == 0).astype(np.float32)
    out = np.empty(1024, dtype=np.float32)
    for _ in range(6_000):
        np.matmul(weights, view, out=out)


def reference_seconds(runs: int = REFERENCE_RUNS) -> float:
    """CPU seconds of the reference workload: the least of `runs`."""
    best = float("inf")
    with threadpool_limits(limits=1, user_api="blas"):  # as the planner runs its products
        for _ in range(runs):
            started = time.process_time()
            _reference_workload()
            best = min(best, time.process_time() - started)
    return best


def machine_line() -> str:
    """One line for under a table: processor, cores, the reference workload's CPU seconds."""
    return (f"machine: {_processor()}, {os.cpu_count()} cores; reference workload "
            f"{reference_seconds():.2f} CPU s (bench/machine.py, least of {REFERENCE_RUNS})")


if __name__ == "__main__":
    print(machine_line())
