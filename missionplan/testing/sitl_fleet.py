"""A fleet of real ArduCopter SITL vehicles behind a loopback relay, flown by `missionplan fly` as a child
process: what the flight-fault and survey tests (sitl_tests/test_fly_faults_sitl.py, test_survey_sitl.py)
and benches (bench/fly_bench.py --faults, bench/survey_bench.py) fly.

The fleet: one SITL vehicle per drone of a plan folder (system id K for uavK.plan, started at its launch
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.loopback import free_udp_port, wait_until
from missionplan.testing.relay import UdpRelay

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


@dataclass
class Fleet:
    plan_dir: Path
    relay: UdpRelay
    vehicles: list[ArduCopter]
    url: str  # where fly listens (the relay forwards there)

    def vehicle(self, sysid: int) -> ArduCopter:
        return next(v for v in self.vehicles if v.sysid == sysid)

    @property
    def sysids(self) -> list[int]:
        return [v.sysid for v in self.vehicles]


def plan_home(plan_dir: Path, sysid: int) -> tuple[float, float, float, float]:
    """Drone sysid's launch point as SITL's --home (lat, lon, alt, heading), from its uavK.plan."""
    from missionplan.bridge.formats.missionfile import read_mission_file

    lat, lon, alt = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return (float(lat), float(lon), float(alt), 0.0)


def plan_sysids(plan_dir: Path) -> tuple[int, ...]:
    """The drones of a plan folder: K of every uavK.plan (a later sortie, uavK-sJ.plan, is the same drone)."""
    return tuple(sorted(int(p.stem[3:]) for p in plan_dir.glob("uav*.plan") if p.stem[3:].isdigit()))


@contextlib.contextmanager
def sitl_fleet(plan_dir: Path, sysids: tuple[int, ...] | None = None, speedup: float = SPEEDUP) -> Iterator[Fleet]:
    """One SITL vehicle per drone of plan_dir (or of `sysids`) at its launch point, sending through a relay
    to a free udpin port (Fleet.url); every vehicle stopped and the relay closed when the block ends.
    Not configured: call configure() before flying."""
    port = free_udp_port()
    vehicles: list[ArduCopter] = []
    with UdpRelay(port) as relay:
        try:
            for k in sysids or plan_sysids(plan_dir):
                # start() returns once SITL has bound its ports (arducopter.py), so the next vehicle's instance differs
                vehicles.append(ArduCopter(sysid=k, home=plan_home(plan_dir, k), speedup=speedup,
                                           serial0=f"udpclient:127.0.0.1:{relay.vehicle_port}"))
                vehicles[-1].start(wait=False)
            yield Fleet(plan_dir, relay, vehicles, f"udpin:127.0.0.1:{port}")
        finally:
            for vehicle in vehicles:
                vehicle.stop()


def configure(fleet: Fleet, params: dict[str, float] | None = None) -> None:
    """The team's one-time set-up over the relay: the camera (CAM1_TYPE = 1; without it ArduCopter sends
    no CAMERA_FEEDBACK) and `params`, then a reboot for them to take effect. What this sent is then
    forgotten by the relay: only fly's own messages count."""
    import pytest

    from missionplan.bridge.link.connection import mavlink, wait_vehicle
    from missionplan.bridge.link.params import ParamClient
    from missionplan.bridge.link.shared_link import SharedLink

    wanted = {"CAM1_TYPE": 1.0, **(params or {})}
    with SharedLink(fleet.url) as shared:
        for sysid in fleet.sysids:
            view = shared.vehicle(sysid)
            client = ParamClient(view, wait_vehicle(view, sysid, timeout=60.0))
            for name, value in wanted.items():
                assert client.set(name, value) == pytest.approx(value), (sysid, name)
        for sysid in fleet.sysids:
            result = shared.vehicle(sysid).command_long(sysid, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0],
                                                        time.monotonic() + 10.0)
            assert result == mavlink.MAV_RESULT_ACCEPTED, f"vehicle {sysid} refused the reboot (MAV_RESULT {result})"
    fleet.relay.forget()


def set_param_on_serial1(vehicle: ArduCopter, name: str, value: float) -> None:
    """PARAM_SET over the vehicle's own serial1 (TCP 5762 + 10 I), beside fly's link: the simulator's
    knob, not something fly would send."""
    import pytest

    from missionplan.bridge.link.connection import Link, wait_vehicle
    from missionplan.bridge.link.params import ParamClient

    with Link(f"tcp:127.0.0.1:{vehicle.tcp_port + 2}") as link:
        info = wait_vehicle(link, vehicle.sysid, timeout=10.0)  # it speaks MAVLink there: its HEARTBEAT
        assert ParamClient(link, info).set(name, value) == pytest.approx(value)


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
