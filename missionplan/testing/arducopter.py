"""Real ArduCopter SITL for the tests: start instances, find free ports, stop them whatever happens.

The process itself (ports, instances, readiness, reboot, stop) is the product's ArduCopterSitl
(missionplan/bridge/sim/sitl_process.py: `verify --sim sitl` starts SITL too); ArduCopter here is that process
with the tests' binary (the simulators folder) and a skip when it is absent. The names below stay here for the tests.

The binary and its default parameters are `sitl/arducopter` and `sitl/copter.parm` of the simulators
folder (simulators.py: `../shared` beside a checkout, or `--simulators DIR` / MISSIONPLAN_SIMULATORS;
read in place, never copied). Each instance runs in its own `tempfile.mkdtemp()` folder (it writes
eeprom.bin, terrain/ and logs/ there), in its own session (`start_new_session=True`) so that teardown
kills its whole process group, with `-w` (wiped parameters and mission) and `--speedup`.

Ports: instance I listens on TCP 5760 + 10·I (serial0; serial1 / serial2 on +2 / +3) and binds UDP
5501 + 10·I (RC input). Other test runs on this machine start SITL too, so an instance number is
used only when all of those were free a moment ago, and an instance that dies at start (a port
taken between the probe and the bind) is retried on the next free number.

Readiness: just after start ArduCopter reports a mission of 0 items and refuses uploads with
NO_SPACE until its mission store is loaded; start() waits for that (wait_mission_ready).

Reuse: `ArduCopter(...)` is one vehicle; `serial0` picks how it talks: `tcp:0` (the default: we
connect to `tcp:127.0.0.1:PORT`, see `.url`) or `udpclient:127.0.0.1:PORT` (it sends to a ground
station listening there, `.gcs_url`: several vehicles, each with its own sysid, into one `udpin:`
port, as a fleet flies; start them with wait=False and call wait_mission_ready on the shared link).
`sitl_or_skip()` skips a test with a reason when the binary is absent; the `arducopter` fixture
(plugin.py) is a factory of vehicles stopped at teardown.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.bridge.sim.sitl_process import (FIRST_INSTANCE, MAX_INSTANCE, SPEEDUP, ArduCopterSitl, boot_ms,
                                                  free_instance, instance_free, reboot_and_wait, wait_mission_ready)
from missionplan.testing import simulators

__all__ = ["FIRST_INSTANCE", "MAX_INSTANCE", "SPEEDUP", "ArduCopter", "binary", "boot_ms", "configure_camera_and_wait_ready",
           "defaults", "free_instance", "instance_free", "reboot_and_wait", "sitl_or_skip", "wait_mission_ready"]


def binary() -> Path | None:
    """Where the SITL binary should be (None: no simulators folder known; simulators.py)."""
    folder = simulators.sitl_dir()
    return None if folder is None else folder / "arducopter"


def defaults() -> Path:
    """The default parameters SITL starts with, beside the binary."""
    found = binary()
    assert found is not None, "no simulators folder known"
    return found.parent / "copter.parm"


def sitl_or_skip() -> Path:
    """The SITL binary, or skip the calling test saying why."""
    found = binary()
    if found is None or not (found.is_file() and os.access(found, os.X_OK)):
        import pytest

        pytest.skip(simulators.missing("ArduCopter SITL", found, None if found is None else found.parent / "README.md"))
    return found


class ArduCopter(ArduCopterSitl):
    """One ArduCopter SITL process from the simulators folder (skipping the test when it is absent). Use as a
    context manager, or start() / stop()."""

    def __init__(self, sysid: int = 1, home: tuple[float, float, float, float] = (45.4643, 9.1895, 120.0, 0.0),
                 speedup: float = SPEEDUP, serial0: str = "tcp:0", extra_args: tuple[str, ...] = ()) -> None:
        super().__init__(sysid, home, speedup, serial0, extra_args)

    def folder(self) -> Path:
        return sitl_or_skip().parent

    def start(self, attempts: int = 4, bind_wait: float = 10.0, wait: bool = True) -> ArduCopter:
        """Start on a free instance number; with wait, return once its mission store is loaded."""
        sitl_or_skip()
        super().start(attempts, bind_wait, wait)
        return self

    def __enter__(self) -> ArduCopter:
        return self.start()


ARM_RETRY_S = 1.0


def configure_camera_and_wait_ready(vehicle: ArduCopter, timeout: float = 240.0) -> None:
    """What a team does once before flying: CAM1_TYPE = 1 (a relay-triggered camera; without one
    ArduCopter sends no CAMERA_FEEDBACK) and a reboot for it to take effect; then wait, with a bound,
    until the vehicle arms (its EKF has a GPS fix after ~35-40 simulated seconds), and disarm.
    (`fly` waits for readiness itself too; waiting here keeps the flight's own wait short.)"""
    from missionplan.bridge.link.connection import Link, wait_vehicle
    from missionplan.bridge.link.params import ParamClient

    deadline = time.monotonic() + timeout
    with Link(vehicle.gcs_url) as link:
        info = wait_vehicle(link, vehicle.sysid, timeout=30.0)
        ParamClient(link, info).set("CAM1_TYPE", 1.0)
        reboot_and_wait(link, vehicle.sysid, timeout=min(60.0, timeout))
        while time.monotonic() < deadline:
            link.command_long(vehicle.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)
            arm = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
            if link.command_long(vehicle.sysid, arm, [1.0], deadline) == mavlink.MAV_RESULT_ACCEPTED:
                link.command_long(vehicle.sysid, arm, [0.0], deadline)
                return
            retry_at = min(deadline, time.monotonic() + ARM_RETRY_S)  # not ready yet: listen, then ask again
            while link.recv(retry_at) is not None:
                pass
    raise RuntimeError(f"ArduCopter SITL system {vehicle.sysid} did not become ready to arm within {timeout:g} s")
