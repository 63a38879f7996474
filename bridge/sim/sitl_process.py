"""ArduCopter SITL as a process beside the mock: start instances on free ports, wait until they can take a
mission, reboot them, stop them whatever happens.

The binary and its default parameters are `arducopter` and `copter.parm` of one folder (the SITL folder: given by
the caller; the tests find theirs through missionplan/testing/simulators.py). Each instance runs in its own
`tempfile.mkdtemp()` folder (it writes eeprom.bin, terrain/ and logs/ there), in its own session
(`start_new_session=True`) so that stopping it kills its whole process group, with `-w` (wiped parameters and
mission) and `--speedup`.

Ports: instance I listens on TCP 5760 + 10·I (serial0; serial1 / serial2 on +2 / +3) and binds UDP 5501 + 10·I
(RC input). Other runs on this machine start SITL too, so an instance number is used only when all of those were
free a moment ago, and an instance that dies at start (a port taken between the probe and the bind) is retried on
the next free number.

Readiness: just after start ArduCopter reports a mission of 0 items and refuses uploads with NO_SPACE until its
mission store is loaded; start() waits for that (wait_mission_ready) unless told not to.

`serial0` picks how a vehicle talks: `tcp:0` (the default: connect to `tcp:127.0.0.1:PORT`, `.url`) or
`udpclient:127.0.0.1:PORT` (it sends to a ground station listening there, `.gcs_url`: several vehicles, each with
its own sysid, into one `udpin:` port, as a fleet flies; start them with wait=False and call wait_mission_ready on
the shared link). Its serial1 (TCP, `.serial1_url`) speaks MAVLink too: the simulator's knobs (SIM_* parameters)
can be turned there, beside the ground station's link.

Also here, the loopback basics any SITL user needs: free ports, a port's state, stopping a process group.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

from ..link.connection import AUTOPILOT_COMPONENT_ID, mavlink

SPEEDUP = 10  # stable on 2 shared cores (the SITL README)
FIRST_INSTANCE = 20  # stay clear of the usual 0..9 a person would start by hand
MAX_INSTANCE = 120
BINARY, DEFAULTS = "arducopter", "copter.parm"  # in the SITL folder
# Where SITL binds its ports: every interface, so a port is free for it only if it is free there.
ANY_INTERFACE = "0.0.0.0"
POLL_S = 0.05  # wall seconds between looks at a starting vehicle's log


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago (for peers that cannot bind port 0 themselves)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _port_free(kind: int, port: int, host: str) -> bool:
    with socket.socket(socket.AF_INET, kind) as sock:
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def udp_port_free(port: int, host: str = "127.0.0.1") -> bool:
    """Whether nobody has bound UDP `port` on `host` (a peer started elsewhere has, once it listens)."""
    return _port_free(socket.SOCK_DGRAM, port, host)


def tcp_port_free(port: int, host: str = "127.0.0.1") -> bool:
    """Whether nobody listens on TCP `port` on `host` (bound, so a peer could not take it now)."""
    return _port_free(socket.SOCK_STREAM, port, host)


def stop_process_group(proc: subprocess.Popen[bytes]) -> None:
    """Kill a simulator started with start_new_session=True and everything it spawned: SIGTERM to its
    process group, then SIGKILL if it is still there after 3 s."""
    if proc.poll() is not None:
        proc.wait()
        return
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(3.0)
            return
        except subprocess.TimeoutExpired:
            continue


def instance_free(instance: int) -> bool:
    """Whether every port instance I would bind is free now."""
    base = 5760 + 10 * instance
    return (all(tcp_port_free(p, ANY_INTERFACE) for p in (base, base + 2, base + 3))
            and udp_port_free(5501 + 10 * instance, ANY_INTERFACE))


def free_instance(start: int = FIRST_INSTANCE, skip: set[int] | None = None) -> int:
    """The first instance number from `start` whose ports are all free (spread by pid across runs)."""
    skip = skip or set()
    span = MAX_INSTANCE - FIRST_INSTANCE
    offset = (os.getpid() * 7) % span  # two runs started together probe different numbers first
    for k in range(span):
        instance = FIRST_INSTANCE + (start - FIRST_INSTANCE + offset + k) % span
        if instance not in skip and instance_free(instance):
            return instance
    raise RuntimeError(f"no free SITL instance number in {FIRST_INSTANCE}..{MAX_INSTANCE - 1}")


def wait_mission_ready(link: object, sysid: int, timeout: float = 30.0) -> None:
    """Until vehicle sysid reports a mission of at least its home item. Just after start ArduCopter
    answers MISSION_COUNT 0 and refuses uploads with NO_SPACE: its mission store is not loaded yet."""
    from ..link.connection import wait_vehicle

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


def sitl_binary_problem(folder: Path | None) -> str | None:
    """Why the SITL folder cannot be flown (no folder, no executable arducopter, no copter.parm), None if it can."""
    if folder is None:
        return "no ArduCopter SITL folder given"
    binary = Path(folder) / BINARY
    if not (binary.is_file() and os.access(binary, os.X_OK)):
        return f"no executable ArduCopter SITL at {binary}"
    if not (Path(folder) / DEFAULTS).is_file():
        return f"no {DEFAULTS} beside {binary}"
    return None


class ArduCopterSitl:
    """One ArduCopter SITL process, from the SITL folder `sitl_dir`. Use as a context manager, or start() / stop().
    die_with_parent: the kernel kills it if the thread that started it dies without stopping it (util-linux's
    setpriv --pdeathsig, when installed): a SITL vehicle never outlives a killed runner."""

    def __init__(self, sysid: int = 1, home: tuple[float, float, float, float] = (45.4643, 9.1895, 120.0, 0.0),
                 speedup: float = SPEEDUP, serial0: str = "tcp:0", extra_args: tuple[str, ...] = (),
                 sitl_dir: Path | str | None = None, die_with_parent: bool = False) -> None:
        self.sysid = sysid
        self.home = home
        self.speedup = speedup
        self.serial0 = serial0
        self.extra_args = extra_args
        self.sitl_dir = None if sitl_dir is None else Path(sitl_dir)
        self.die_with_parent = die_with_parent
        self.instance = -1
        self.workdir: Path | None = None
        self.proc: subprocess.Popen[bytes] | None = None

    def folder(self) -> Path:
        """The SITL folder (arducopter and copter.parm)."""
        problem = sitl_binary_problem(self.sitl_dir)
        if problem is not None or self.sitl_dir is None:
            raise RuntimeError(problem)
        return self.sitl_dir

    @property
    def tcp_port(self) -> int:
        return 5760 + 10 * self.instance

    @property
    def url(self) -> str:
        """Our pymavlink connection string for serial0 = tcp:0."""
        return f"tcp:127.0.0.1:{self.tcp_port}"

    @property
    def serial1_url(self) -> str:
        """Its serial1 (MAVLink on TCP 5762 + 10·I), beside the ground station's link."""
        return f"tcp:127.0.0.1:{self.tcp_port + 2}"

    def command(self) -> list[str]:
        lat, lon, alt, heading = self.home
        folder = self.folder()
        return [str(folder / BINARY), "--model", "+", "--speedup", f"{self.speedup:g}",
                "--home", f"{lat},{lon},{alt},{heading}", "--defaults", str(folder / DEFAULTS),
                "--sysid", str(self.sysid), "-w", "-I", str(self.instance), "--serial0", self.serial0,
                *self.extra_args]

    def start(self, attempts: int = 4, bind_wait: float = 10.0, wait: bool = True) -> ArduCopterSitl:
        """Start on a free instance number; with wait, return once its mission store is loaded."""
        tried: set[int] = set()
        for _ in range(attempts):
            self.instance = free_instance(skip=tried)
            tried.add(self.instance)
            self.workdir = Path(tempfile.mkdtemp(prefix=f"arducopter-{self.sysid}-"))
            command = self.command()
            if self.die_with_parent and (setpriv := shutil.which("setpriv")):
                # killed by the kernel (SIGKILL) should we die unannounced (a worker SIGKILLed): setpriv sets the
                # parent-death signal and execs SITL in its place (same pid; kept across SITL's own re-exec at reboot)
                command = [setpriv, "--pdeathsig", "KILL", "--", *command]
            log = open(self.workdir / "sitl.log", "wb")  # noqa: SIM115 (closed with the process)
            self.proc = subprocess.Popen(command, cwd=self.workdir, stdout=log, stderr=subprocess.STDOUT,
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
        from ..link.connection import Link

        with Link(self.gcs_url) as link:
            wait_mission_ready(link, self.sysid, timeout)

    def _wait_bound(self, timeout: float) -> bool:
        """Until SITL has bound its ports: SERIAL0's TCP port (tcp), or with udpclient its serial1 / serial2
        TCP ports, bound after "Starting sketch" (returning before them let the next vehicle's probe pick
        the same instance number and die on them). False if it died first. Between looks at its log it waits on
        the process itself (its exit), never a bare sleep."""
        assert self.proc is not None and self.workdir is not None
        marker = b"SERIAL0 on TCP port" if self.serial0.startswith("tcp") else b"SERIAL2 on TCP port"
        deadline = time.monotonic() + timeout
        while True:
            if marker in self.log_bytes():
                return True
            if self.proc.poll() is not None or time.monotonic() >= deadline:
                return False
            try:
                self.proc.wait(min(POLL_S, max(0.0, deadline - time.monotonic())))
            except subprocess.TimeoutExpired:
                pass

    def log_bytes(self) -> bytes:
        try:
            return (self.workdir / "sitl.log").read_bytes() if self.workdir else b""
        except OSError:
            return b""

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def kill(self) -> None:
        """SIGKILL its whole process group at once (a crash: no goodbye on the link), its folder kept until stop()."""
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            return
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            pass

    def stop(self) -> None:
        """Kill the whole process group (SIGTERM, then SIGKILL), then remove its folder."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        stop_process_group(proc)
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> ArduCopterSitl:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
