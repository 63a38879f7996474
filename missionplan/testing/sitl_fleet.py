"""A fleet of real ArduCopter SITL vehicles behind a loopback relay, flown by `missionplan fly` as a child
process: what the flight-fault and survey tests (sitl_tests/test_fly_faults_sitl.py, test_survey_sitl.py)
and benches (bench/fly_bench.py --faults, bench/survey_bench.py) fly.

The fleet (the product's, missionplan/bridge/sim/sitl_fleet.py, which `verify --sim sitl` flies too, here with
the simulators folder's vehicles): one SITL vehicle per drone of a plan folder (system id K for uavK.plan, started at its launch
point, `--speedup`, each in its own temp folder), each sending to a relay (relay.py UdpRelay,
`--serial0 udpclient:127.0.0.1:P`) that forwards to the port `fly --connect udpin:127.0.0.1:Q` listens
on. The relay breaks the link on purpose and is the ground truth of what fly sent to the vehicles
(`commands_sent`) and of what the vehicles did (`state`: armed, mode, mission item, photos taken, arming
count), whatever fly says. The team's one-time set-up (configure: the camera, CAM1_TYPE = 1 and a reboot;
the parameters a fault needs) goes over the same relay before fly runs. FlyRun is `fly` as a child process
(SIGKILL as a crash, SIGINT as Ctrl-C), its output read line by line with the time each line came.

The tests' and benches' scenario: a 200 x 140 m block in Milan (beside the SITL fixture's default home)
photographed from 20 m (AREA, LAUNCHES: three launch points on its southern edge): about 140-165
simulated seconds per drone, ~33 s of wall time at SPEEDUP 5: fly's 5 s window after Ctrl-C ends
mid-flight, and a 30 s (wall) link drop from mission item 3 on outlasts the flight (the vehicles land
unheard; fly must judge them from what they say afterwards), yet ends before fly would give a silent
vehicle up (planned x 1.5 + 60 s of vehicle time, ~55 s wall).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from missionplan.bridge.sim.sitl_fleet import SitlFleet, plan_home, plan_sysids, start_sitl_fleet
from missionplan.bridge.sim.sitl_fleet import configure as configure_fleet
from missionplan.bridge.sim.sitl_fleet import set_param_on_serial1 as product_set_param_on_serial1
from missionplan.bridge.sim.sitl_process import ArduCopterSitl
from missionplan.bridge.sim.udp_relay import UdpRelay
from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.loopback import wait_until

__all__ = ["AREA", "BATTERY_LOW_V", "BATTERY_SIM_V", "FLY_TIMEOUT_S", "LAUNCHES", "LINK_DROP_S", "SPEEDUP", "START_S",
           "SYSIDS", "TELEMETRY_HZ", "Fleet", "FlyRun", "configure", "flight_doc", "in_flight", "landed", "plan_home",
           "plan_sysids", "set_param_on_serial1", "sitl_fleet", "summary"]

AREA = [[9.1890, 45.4640], [9.19156, 45.4640], [9.19156, 45.46526], [9.1890, 45.46526], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.18926", "45.4641,9.19028", "45.4641,9.19131")
SYSIDS = (1, 2, 3)
SPEEDUP = 5
FLY_TIMEOUT_S = 300.0  # wall seconds: generous, no test here should come near it
START_S = 180.0  # wall seconds for a fleet to get from boot to flying (readiness, upload, arming)
TELEMETRY_HZ = 10.0
# The faults put on it.
LINK_DROP_S = 30.0
BATTERY_LOW_V, BATTERY_SIM_V = 10.5, 10.0  # the failsafe's threshold, and what the low vehicle's battery reads


Fleet = SitlFleet  # the product's (missionplan/bridge/sim/sitl_fleet.py), as the tests have always named it


def _test_vehicle(sysid: int, home: tuple[float, float, float, float], speedup: float, serial0: str) -> ArduCopter:
    return ArduCopter(sysid=sysid, home=home, speedup=speedup, serial0=serial0)


@contextlib.contextmanager
def sitl_fleet(plan_dir: Path, sysids: tuple[int, ...] | None = None, speedup: float = SPEEDUP) -> Iterator[Fleet]:
    """One SITL vehicle per drone of plan_dir (or of `sysids`) at its launch point, sending through a relay
    to a free udpin port (Fleet.url); every vehicle stopped and the relay closed when the block ends.
    Not configured: call configure() before flying. The vehicles are the simulators folder's (a test skips
    without it)."""
    with start_sitl_fleet(plan_dir, _test_vehicle, sysids, speedup) as fleet:
        yield fleet


def configure(fleet: Fleet, params: dict[str, float] | None = None) -> None:
    """The team's one-time set-up over the relay: the camera (CAM1_TYPE = 1; without it ArduCopter sends
    no CAMERA_FEEDBACK) and `params`, then a reboot for them to take effect. What this sent is then
    forgotten by the relay: only fly's own messages count. (The product's configure, a failure an assertion.)"""
    try:
        configure_fleet(fleet, params)
    except RuntimeError as err:
        raise AssertionError(str(err)) from err


def set_param_on_serial1(vehicle: ArduCopterSitl, name: str, value: float) -> None:
    """PARAM_SET over the vehicle's own serial1 (TCP 5762 + 10 I), beside fly's link: the simulator's
    knob, not something fly would send."""
    try:
        product_set_param_on_serial1(vehicle, name, value)
    except RuntimeError as err:
        raise AssertionError(str(err)) from err


class FlyRun:
    """`missionplan fly` as a child process; its output (stdout and stderr) kept line by line with our
    monotonic time of each line."""

    def __init__(self, plan_dir: Path, url: str, *extra: str, time_scale: float = SPEEDUP,
                 timeout_s: float = FLY_TIMEOUT_S) -> None:
        self.started = time.monotonic()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--connect", url, "--timeout",
             str(timeout_s), "--time-scale", str(time_scale), "--telemetry-hz", f"{TELEMETRY_HZ:g}", "--quiet",
             *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.lines: list[tuple[float, str]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    @property
    def out(self) -> str:
        return "\n".join(text for _, text in self.lines)

    def first(self, *words: str) -> float | None:
        """Our time of the first line holding every one of `words` (case-insensitive), None if none yet."""
        for t, text in self.lines:
            if all(w.lower() in text.lower() for w in words):
                return t
        return None

    def finish(self, timeout: float) -> int:
        """Its exit code, waited for with a bound (killed, and the test failed, past it)."""
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"fly did not exit within {timeout:g} s:\n{self.out}") from None
        self._reader.join(10.0)
        return code

    def kill(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10.0)


def in_flight(relay: UdpRelay, item: int, timeout: float = START_S, sysids: tuple[int, ...] = SYSIDS) -> bool:
    """Until every vehicle is armed in AUTO at mission item `item` or later (as the relay saw them)."""
    from missionplan.bridge.link.readiness import ARDUPILOT_AUTO

    return bool(wait_until(lambda: all(relay.state(k).get("armed") == 1
                                       and relay.state(k).get("custom_mode") == ARDUPILOT_AUTO
                                       and relay.state(k).get("current", -1) >= item for k in sysids), timeout))


def landed(relay: UdpRelay, sysids: tuple[int, ...] = SYSIDS, timeout: float = 120.0) -> bool:
    """Until every vehicle armed once and is disarmed again (as the relay saw them)."""
    return bool(wait_until(lambda: all(relay.state(k).get("armed") == 0 and relay.state(k).get("arms", 0) >= 1
                                       for k in sysids), timeout))


def flight_doc(plan_dir: Path) -> tuple[dict[str, Any], dict[int, dict[str, Any]]]:
    """flight.json as written, and its drones by id."""
    doc = json.loads((plan_dir / "flight.json").read_text())
    return doc, {int(d["id"]): d for d in doc["drones"]}


def summary(fleet: Fleet, run: FlyRun | None = None) -> str:
    """For assertion messages: the vehicles' states as relayed, and fly's output."""
    states = {k: fleet.relay.state(k) for k in fleet.sysids}
    return f"states {states}\n" + (run.out if run is not None else "")
