"""fly's start gate: ready drones start together; a drone that failed does not hold them up."""

from __future__ import annotations

import threading
import time

from missionplan.flight.drone_flight import StartGate


def _ready(gate: StartGate, released: list[float]) -> threading.Thread:
    def run() -> None:
        gate.check_in(5.0)
        released.append(time.monotonic())

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_ready_drones_wait_for_the_last_one_and_a_failed_one_does_not_hold_them() -> None:
    gate = StartGate(3)
    released: list[float] = []
    first = _ready(gate, released)
    gate.check_in(0.0)  # a drone whose upload failed: checks in, does not wait
    first.join(0.3)  # a release would end the thread: give it the chance, bounded
    assert first.is_alive() and released == []  # the third drone is still uploading: nobody starts yet
    last_in = time.monotonic()
    second = _ready(gate, released)
    first.join(2.0)
    second.join(2.0)
    assert len(released) == 2 and all(t >= last_in for t in released)
