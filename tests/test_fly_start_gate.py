"""fly's gates: ready drones go on together; a drone that failed does not hold them up; a veto reaches all."""

from __future__ import annotations

import threading
import time

from missionplan.flight.fleet_start import FleetGate


def _ready(gate: FleetGate, released: list[float]) -> threading.Thread:
    def run() -> None:
        gate.check_in(5.0)
        released.append(time.monotonic())

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_ready_drones_wait_for_the_last_one_and_a_failed_one_does_not_hold_them() -> None:
    gate = FleetGate(3)
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


def test_a_veto_reaches_every_drone_and_none_without_one() -> None:
    gate = FleetGate(2)
    heard: list[list[str]] = []
    waiting = threading.Thread(target=lambda: heard.append(gate.check_in(5.0)), daemon=True)
    waiting.start()
    assert gate.check_in(0.0, veto="uav2 failed the site check") == ["uav2 failed the site check"]
    waiting.join(2.0)
    assert heard == [["uav2 failed the site check"]]
    assert FleetGate(1).check_in(5.0) == []  # alone, nobody to wait for, no veto: go on
