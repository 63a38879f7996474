"""A run's wind and faults put on a mock fleet (missionplan.bridge.sim.mock.MockAutopilot).

The wind is set on every vehicle before it flies (SITL's SIM_WIND_SPD / SIM_WIND_DIR / SIM_WIND_TURB, which the
mock flies in as ArduCopter SITL does: docs/wind-model.md). A lost drone is the mock's own kill at a mission item.
The faults that strike at an item and then end (a battery that reads low, a dropped link, a GPS glitch) are put on
by a watcher thread that looks at the vehicles' reached items: the simulator's ground truth, never what `fly` says.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from missionplan.bridge.sim.mock import LinkFaults

from .conditions import Conditions, Fault

LOW_BATTERY_V = 10.0  # below BATT_LOW_VOLT (10.5 V): ArduCopter's low-battery failsafe after BATT_LOW_TIMER
BATTERY_FAILSAFE_RTL = 2.0  # BATT_FS_LOW_ACT 2: RTL, as a team configures it
LOOK_S = 0.01  # wall seconds between looks at the reached items (a fraction of a mission leg at any speed-up)


class MockFaults:
    """The conditions of one run on one mock fleet; start() before `fly`, stop() after it."""

    def __init__(self, mock: Any, conditions: Conditions, speedup: float) -> None:
        self.mock, self.conditions, self.speedup = mock, conditions, speedup
        self.struck: list[dict[str, Any]] = []  # what was put on, when (simulated seconds after start)
        self._pending = list(conditions.faults)  # a lost drone is the mock's own kill: recorded when it happens
        self._ends: list[tuple[float, Fault]] = []  # wall time a lasting fault ends
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="verify-faults", daemon=True)
        self._t0 = time.monotonic()

    def start(self) -> MockFaults:
        c = self.conditions
        if c.wind_mps > 0 or c.turbulence_mps > 0:  # calm air: the mock as it flies without wind
            self.mock.set_wind(c.wind_mps, c.wind_from_deg, c.turbulence_mps, seed=c.seed)
        for fault in c.faults:
            if fault.kind == "lost-drone":
                self.mock.kill(fault.drone, at_item=fault.at_item)
            elif fault.kind == "battery-failsafe":
                self.mock.vehicle(fault.drone).params["BATT_FS_LOW_ACT"] = BATTERY_FAILSAFE_RTL
        self._t0 = time.monotonic()
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def _sim_s(self) -> float:
        return round((time.monotonic() - self._t0) * self.speedup, 1)

    def _watch(self) -> None:
        while not self._stop.wait(LOOK_S):
            now = time.monotonic()
            for fault in [f for f in self._pending if self._reached(f)]:
                self._pending.remove(fault)
                self._strike(fault, now)
            for end, fault in [e for e in self._ends if e[0] <= now]:
                self._ends.remove((end, fault))
                self._clear(fault)
            if not self._pending and not self._ends:
                return

    def _reached(self, fault: Fault) -> bool:
        vehicle = self.mock.vehicle(fault.drone)
        if fault.kind == "lost-drone":
            return bool(vehicle.killed)
        return not vehicle.killed and any(seq >= fault.at_item for seq in vehicle.reached)

    def _strike(self, fault: Fault, now: float) -> None:
        if fault.kind == "lost-drone":
            pass  # already silent (the mock's kill at its item)
        elif fault.kind == "battery-failsafe":
            self.mock.set_battery(fault.drone, LOW_BATTERY_V)
        elif fault.kind == "link-gap":
            self.mock.set_faults(LinkFaults(loss_in=1.0, loss_out=1.0))
        elif fault.kind == "gps-glitch":
            self.mock.set_gps_glitch(fault.drone, fault.north_m, fault.east_m)
        if fault.seconds > 0:
            self._ends.append((now + fault.seconds / self.speedup, fault))
        self.struck.append({"kind": fault.kind, "drone": fault.drone, "at_item": fault.at_item,
                            "at_s": self._sim_s()})

    def _clear(self, fault: Fault) -> None:
        if fault.kind == "link-gap":
            self.mock.set_faults(LinkFaults())
        elif fault.kind == "gps-glitch":
            self.mock.set_gps_glitch(fault.drone, 0.0, 0.0)
