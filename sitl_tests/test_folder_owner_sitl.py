"""One owner per survey folder, on real ArduCopter SITL: a second `fly` on the folder a first one is flying
is refused in one line before it opens any link, and the autopilots see one ground station, one upload
and one arming each.

Two vehicles (system ids 1-2, each in its own temp folder, killed in teardown) stand at their plan's
launch points. Each sends its serial0 through a loopback relay (sitl_tests/loopback.py UdpRelay) to the
port the first `fly` listens on: the relay is the ground truth of what that fly sent and of how often
each vehicle armed (its own HEARTBEATs). The second `fly` is pointed at each vehicle's serial1 (its own
TCP port: a second ground station on the same vehicles, which the old code let upload, arm and start
them too); ArduCopter's console says "New connection on SERIAL1" when anything connects there.
Both fly run as child processes, the second started once the first is talking to the vehicles,
well before either vehicle is ready to arm (35-40 simulated seconds).

Skipped with a reason when ../shared/sitl/arducopter is absent.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.link.connection import mavlink
from missionplan.flight.ledger import Ledger
from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.loopback import free_udp_port, wait_until
from missionplan.testing.plans import plan_area
from missionplan.testing.relay import UdpRelay

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

ROOT = Path(__file__).resolve().parent.parent
SYSIDS = (1, 2)
# A 120 x 90 m block in Milan (around the SITL fixture's default home), two launch points on its southern
# edge: about 50 simulated seconds per drone.
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1904")
FLY_TIMEOUT_S = 300.0
ARM = f"COMMAND_LONG {mavlink.MAV_CMD_COMPONENT_ARM_DISARM}"


def _home(plan_dir: Path, sysid: int) -> tuple[float, float, float, float]:
    lat, lon, alt = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return (float(lat), float(lon), float(alt), 0.0)


def _fly(plan_dir: Path, *connect: str) -> list[str]:
    command = [sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--timeout", str(FLY_TIMEOUT_S),
               "--telemetry-hz", "10", "--photos-from-track", "--quiet"]
    for url in connect:
        command += ["--connect", url]
    return command


def test_a_second_fly_on_the_folder_reaches_no_autopilot(arducopter, tmp_path: Path) -> None:
    plan_dir = plan_area(tmp_path, AREA, LAUNCHES)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    port = free_udp_port()
    with UdpRelay(port) as relay:
        vehicles: list[ArduCopter] = [
            arducopter(wait=False, sysid=k, home=_home(plan_dir, k), serial0=f"udpclient:127.0.0.1:{relay.vehicle_port}")
            for k in SYSIDS]
        first = subprocess.Popen(_fly(plan_dir, f"udpin:127.0.0.1:{port}"), cwd=ROOT, env=env, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        try:
            assert wait_until(lambda: relay.sent, 60.0), "the first fly never talked to the vehicles"
            serial1 = [f"{v.sysid}=tcp:127.0.0.1:{5760 + 10 * v.instance + 2}" for v in vehicles]
            second = subprocess.run(_fly(plan_dir, *serial1), cwd=ROOT, env=env, capture_output=True, text=True,
                                    timeout=60)
            out, _ = first.communicate(timeout=FLY_TIMEOUT_S + 30)
        finally:
            if first.poll() is None:
                first.kill()
                first.wait(10)
        arms = {k: relay.state(k).get("arms", 0) for k in SYSIDS}
        arming_sent = {addr: kinds.count(ARM) for addr, kinds in relay.sent.items()}
        consoles = {v.sysid: v.log_bytes().decode("utf-8", "replace") for v in vehicles}
    lines = second.stderr.splitlines()
    assert second.returncode == 2 and second.stdout == "" and len(lines) == 1 and "Traceback" not in second.stderr, \
        (second.returncode, second.stdout, second.stderr)
    assert lines[0].startswith(f"missionplan: {plan_dir} is in use by pid {first.pid} on "), lines[0]
    assert not [k for k, text in consoles.items() if "New connection on SERIAL1" in text]  # nobody reached serial1
    doc = json.loads((plan_dir / "flight.json").read_text())
    assert all(d["finished"] for d in doc["drones"]), (doc["problems"], out)
    assert arms == {k: 1 for k in SYSIDS}, (arms, arming_sent)  # each vehicle went from disarmed to armed once
    with Ledger.of(plan_dir) as ledger:
        assert len(ledger.flights()) == 1
    # The first fly flew and judged the flight (its verdict, e.g. the separation kept within the judge's
    # tolerance, is the fleet tests' business: sitl_tests/test_fleet_arducopter.py).
    assert first.returncode in (0, 1) and "Traceback" not in out, out
