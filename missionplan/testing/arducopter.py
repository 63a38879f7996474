"""Real ArduCopter SITL for the tests: start instances, find free ports, stop them whatever happens.

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
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, mavlink
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.testing import simulators
from missionplan.testing.loopback import ANY_INTERFACE, stop_process_group, tcp_port_free, udp_port_free, wait_until

SPEEDUP = 10  # stable on 2 shared cores (the SITL README)
FIRST_INSTANCE = 20  # stay clear of the usual 0..9 a person would start by hand
MAX_INSTANCE = 120


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


def instance_free(instance: int) -> bool:
    """Whether every port instance I would bind is free now."""
    base = 5760 + 10 * instance
    return (all(tcp_port_free(p, ANY_INTERFACE) for p in (base, base + 2, base + 3))
            and udp_port_free(5501 + 10 * instance, ANY_INTERFACE))


def free_instance(start: int = FIRST_INSTANCE, skip: set[int] | None = None) -> int:
    """The first instance number from `start` whose ports are all free (spread by pid across runs)."""
    skip = skip or set()
    span = MAX_INSTANCE - FIRST_INSTANCE
    offset = (os.getpid() * 7) % span  # two test runs started together probe different numbers first
    for k in range(span):
        instance = FIRST_INSTANCE + (start - FIRST_INSTANCE + offset + k) % span
        if instance not in skip and instance_free(instance):
            return instance
    raise RuntimeError(f"no free SITL instance number in {FIRST_INSTANCE}..{MAX_INSTANCE - 1}")


def wait_mission_ready(link: object, sysid: int, timeout: float = 30.0) -> None:
    """Until vehicle sysid reports a mission of at least its home item. Just after start ArduCopter
    answers MISSION_COUNT 0 and refuses uploads with NO_SPACE: its mission store is not loaded yet."""
    from missionplan.bridge.link.connection import wait_vehicle

    deadline = time.monotonic() + timeout
    wait_vehicle(link, sysid, timeout=timeout)  # type: ignore[arg-type]
    while time.monotonic() < deadline:
        link.mav.mission_request_list_send(sysid, AUTOPILOT_COMPONENT_ID,  # type: ignore[attr-defined]
                                           mavlink.MAV_MISSION_TYPE_MISSION)
        ask_again = min(time.monotonic() + 0.2, deadline)  # listen this long for the answer, then ask again
        while (msg := link.recv(ask_again)) is not None:  # type: ignore[attr-defined]
            if msg.get_srcSystem() == sysid and msg.get_type() == "MISSION_COUNT" and int(msg.count) >= 1:
                return
    raise RuntimeError(f"ArduCopter SITL system {sysid} did not load its mission store within {timeout:g} s")


def boot_ms(link: object, sysid: int, deadline: float) -> int | None:
    """The vehicle's time_boot_ms, asked for now (MAV_CMD_REQUEST_MESSAGE SYSTEM_TIME): None when it
    does not answer by the deadline (rebooting)."""
    link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID,  # type: ignore[attr-defined]
                               mavlink.MAV_CMD_REQUEST_MESSAGE, 0, mavlink.MAVLINK_MSG_ID_SYSTEM_TIME, 0, 0, 0, 0, 0, 0)
    while (msg := link.recv(deadline)) is not None:  # type: ignore[attr-defined]
        if msg.get_srcSystem() == sysid and msg.get_type() == "SYSTEM_TIME":
            return int(msg.time_boot_ms)
    return None


def reboot_and_wait(link: object, sysid: int, timeout: float = 60.0) -> None:
    """MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, then until the vehicle answers from its new boot (its clock
    started again): a parameter that acts only after a reboot (CAM1_TYPE) acts from then on."""
    deadline = time.monotonic() + timeout
    before = boot_ms(link, sysid, min(deadline, time.monotonic() + 5.0))
    if before is None:
        raise RuntimeError(f"ArduCopter SITL system {sysid} did not say its clock before the reboot")
    if link.command_long(sysid, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0],  # type: ignore[attr-defined]
                         deadline) != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError(f"ArduCopter SITL system {sysid} refused the reboot")
    while time.monotonic() < deadline:
        now_ms = boot_ms(link, sysid, min(deadline, time.monotonic() + 0.5))
        if now_ms is not None and now_ms < before:
            return
    raise RuntimeError(f"ArduCopter SITL system {sysid} did not come back from its reboot within {timeout:g} s")


class ArduCopter:
    """One ArduCopter SITL process. Use as a context manager, or start() / stop()."""

    def __init__(self, sysid: int = 1, home: tuple[float, float, float, float] = (45.4643, 9.1895, 120.0, 0.0),
                 speedup: int = SPEEDUP, serial0: str = "tcp:0", extra_args: tuple[str, ...] = ()) -> None:
        self.sysid = sysid
        self.home = home
        self.speedup = speedup
        self.serial0 = serial0
        self.extra_args = extra_args
        self.instance = -1
        self.workdir: Path | None = None
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def tcp_port(self) -> int:
        return 5760 + 10 * self.instance

    @property
    def url(self) -> str:
        """Our pymavlink connection string for serial0 = tcp:0."""
        return f"tcp:127.0.0.1:{self.tcp_port}"

    def command(self) -> list[str]:
        lat, lon, alt, heading = self.home
        return [str(binary()), "--model", "+", "--speedup", str(self.speedup),
                "--home", f"{lat},{lon},{alt},{heading}", "--defaults", str(defaults()),
                "--sysid", str(self.sysid), "-w", "-I", str(self.instance), "--serial0", self.serial0,
                *self.extra_args]

    def start(self, attempts: int = 4, bind_wait: float = 10.0, wait: bool = True) -> ArduCopter:
        """Start on a free instance number; with wait, return once its mission store is loaded."""
        sitl_or_skip()
        tried: set[int] = set()
        for _ in range(attempts):
            self.instance = free_instance(skip=tried)
            tried.add(self.instance)
            self.workdir = Path(tempfile.mkdtemp(prefix=f"arducopter-{self.sysid}-"))
            log = open(self.workdir / "sitl.log", "wb")  # noqa: SIM115 (closed with the process)
            self.proc = subprocess.Popen(self.command(), cwd=self.workdir, stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True)
            log.close()
            if self._wait_bound(bind_wait):
                if wait:
                    self.wait_ready()
                return self
            self.stop()
        raise RuntimeError(f"ArduCopter SITL did not start after {attempts} tries (instances {sorted(tried)})")

    @property
    def gcs_url(self) -> str:
        """Where a ground station reaches it: tcp:127.0.0.1:PORT, or udpin:HOST:PORT for udpclient."""
        if self.serial0.startswith("udpclient:"):
            return "udpin:" + self.serial0.split(":", 1)[1]
        return self.url

    def wait_ready(self, timeout: float = 30.0) -> None:
        """Until its mission store is loaded: we connect (or, for udpclient, listen), ask, and let go.
        A caller that already holds the vehicle's udpin port uses wait_mission_ready on its own link."""
        from missionplan.bridge.link.connection import Link

        with Link(self.gcs_url) as link:
            wait_mission_ready(link, self.sysid, timeout)

    def _wait_bound(self, timeout: float) -> bool:
        """Until SITL has bound its ports: SERIAL0's TCP port (tcp), or with udpclient its serial1 / serial2
        TCP ports, bound after "Starting sketch" (returning before them let the next vehicle's probe pick
        the same instance number and die on them). False if it died first."""
        assert self.proc is not None and self.workdir is not None
        proc = self.proc
        marker = b"SERIAL0 on TCP port" if self.serial0.startswith("tcp") else b"SERIAL2 on TCP port"

        def outcome() -> str | None:
            if marker in self.log_bytes():
                return "bound"
            return "died" if proc.poll() is not None else None

        return wait_until(outcome, timeout) == "bound"

    def log_bytes(self) -> bytes:
        try:
            return (self.workdir / "sitl.log").read_bytes() if self.workdir else b""
        except OSError:
            return b""

    def stop(self) -> None:
        """Kill the whole process group (SIGTERM, then SIGKILL), then remove its folder."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        stop_process_group(proc)
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> ArduCopter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


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
