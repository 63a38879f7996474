"""Real PX4 SIH for the tests: start instances, set boot parameters, stop them whatever happens.

PX4 v1.15.4 SITL with its built-in physics (SIH, airframe 10040) is `px4/` of the simulators folder
(simulators.py: `../shared/px4/` beside a checkout, or `--simulators DIR` / MISSIONPLAN_SIMULATORS; read
in place, never copied; its README says how it was built). Below, `../shared/px4` stands for that
folder. One vehicle is `../shared/px4/run-sih.sh I`, run in its own session (`start_new_session=True`) so that teardown
kills its whole process group, with PX4_WORKDIR a fresh `tempfile.mkdtemp()` folder (parameters,
mission storage; removed at teardown) and its home from PX4_HOME_LAT / PX4_HOME_LON (integers in
1e-7 degrees: a decimal is silently wrong) and SIH_LOC_H0 (PX4_HOME_ALT is passed too, but this
build's start-up script reads only the first two).

The module commands. PX4's start-up script calls `px4-param`, `px4-dataman`, ... found on PATH
(PX4 puts its own `bin/` there). In ../shared/px4/bin those are plain 3-byte files, not links to
`px4`, so the script fails ("px4-param: Permission denied", then "no autostart file found"). Each
vehicle therefore gets, in its own temp folder, a `bin/` of symbolic links `px4-NAME -> ../shared/
px4/bin/px4` put first on PATH (links, not copies). The same links are the PX4 client (`px4-param
--instance I set ...`, see `client()`).

Boot parameters. The start-up script sources `px4-rc.params` through PATH after the airframe's
defaults and before any module starts (PX4's hook for per-instance parameters), so the same `bin/`
holds one that sets `params`: SDLOG_MODE = -1 always (logging off: the logger is never started,
no .ulg is written; otherwise about 12 MB per minute), plus what the test asks, e.g. TRIG_MODE,
which starts camera_trigger / camera_feedback only at boot. Parameters are also saved in the
workdir: `restart(params)` stops the vehicle and starts it again with the same workdir.

Instances and ports, picked free at run time. Instance I takes /tmp/px4_lock-I (a flock) and binds UDP
18570+I (GCS link), 14580+I (offboard link), 14280+I, 13030+I, 19450+I; an instance is used only when
its lock is free and all those ports were free a moment ago (the search starts at a number spread by
our pid, so two test runs probe different numbers first). Where it SENDS is ours to choose: the same
`bin/` holds our own `px4-rc.mavlink` (PX4's, read from ../shared/px4/etc at run time, with the GCS
link given `-o GCS_PORT` and the offboard link's remote port set), so every vehicle sends its GCS link
to `gcs_port` (default: a free port of its own; a fleet passes one shared port, as radios into one
ground station) and its offboard link to a free port of its own (`offboard_url`). Its system id is
`sysid` (default I + 1), set at boot through MAV_SYS_ID. PX4 SIH runs in real time: at most three at a
time on a 2-core machine.

`px4_or_skip()` skips a test with a reason when ../shared/px4/bin/px4 is absent; the `px4` pytest
fixture (plugin.py) is a factory of vehicles stopped at teardown even when the test fails.
"""

from __future__ import annotations

import errno
import fcntl
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from missionplan.testing import simulators
from missionplan.testing.loopback import ANY_INTERFACE, free_udp_port, stop_process_group, udp_port_free, wait_until

FIRST_INSTANCE, INSTANCE_SPAN = 10, 100  # numbers 10..109: clear of the 0, 1, 2 a person starts by hand
DEFAULT_HOME = (45.4641, 9.1891, 120.0)
BOOT_PARAMS: dict[str, float] = {"SDLOG_MODE": -1}  # logging off, always
STARTED_MARKER = b"Startup script returned successfully"
FAILED_MARKERS = (b"Startup script returned with return value", b"already running", b"ERROR [init]")
# The lines of PX4's px4-rc.mavlink that choose where its GCS and offboard links send.
GCS_LINK_START = "mavlink start -x -u $udp_gcs_port_local -r 4000000 -f\n"
OFFBOARD_REMOTE = "udp_offboard_port_remote=$((14540+px4_instance))\n"
OFFBOARD_REMOTE_ABOVE_9 = "[ \"$px4_instance\" -gt 9 ] && udp_offboard_port_remote=14549"


def px4_dir() -> Path:
    """PX4 SIH's folder (simulators.py); px4_or_skip() first says whether there is one."""
    found = simulators.px4_dir()
    assert found is not None, "no simulators folder known"
    return found


def binary() -> Path:
    return px4_dir() / "bin" / "px4"


def run_sih() -> Path:
    """The script that starts one SIH vehicle: run-sih.sh INSTANCE."""
    return px4_dir() / "run-sih.sh"


def mavlink_script_path() -> Path:
    """PX4's own px4-rc.mavlink, read at each start (mavlink_script)."""
    return px4_dir() / "etc" / "init.d-posix" / "px4-rc.mavlink"


def px4_or_skip() -> Path:
    """The PX4 binary, or skip the calling test saying why."""
    folder = simulators.px4_dir()
    found = None if folder is None else folder / "bin" / "px4"
    if found is None or not (found.is_file() and os.access(found, os.X_OK) and run_sih().is_file()):
        import pytest

        pytest.skip(simulators.missing("PX4 SIH", found, None if folder is None else folder / "README.md"))
    return found


def e7(degrees: float) -> int:
    """Degrees as PX4's integer 1e-7 degrees (rounded, not truncated)."""
    return int(round(degrees * 1e7))


def instance_ports(instance: int) -> tuple[int, ...]:
    """Every UDP port instance I binds."""
    return (18570 + instance, 14580 + instance, 14280 + instance, 13030 + instance, 19450 + instance)


def _lock_free(instance: int) -> bool:
    """Whether /tmp/px4_lock-I is not held by a running PX4 (it flocks it; the file outlives it)."""
    path = Path(f"/tmp/px4_lock-{instance}")
    if not path.exists():
        return True
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        return exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN)
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return True
    finally:
        os.close(fd)


def instance_free(instance: int) -> bool:
    """Whether instance I's lock and every port it would bind are free now."""
    return _lock_free(instance) and all(udp_port_free(p, ANY_INTERFACE) for p in instance_ports(instance))


def free_instance(skip: set[int] | None = None) -> int:
    """A free instance number (lock and ports), not in `skip`; the search starts at a number spread by
    our pid, so that test runs started together do not race for the same one."""
    skip = skip or set()
    offset = (os.getpid() * 7) % INSTANCE_SPAN
    for k in range(INSTANCE_SPAN):
        instance = FIRST_INSTANCE + (offset + k) % INSTANCE_SPAN
        if instance not in skip and instance_free(instance):
            return instance
    raise RuntimeError(f"no free PX4 instance number in {FIRST_INSTANCE}..{FIRST_INSTANCE + INSTANCE_SPAN - 1}")


def mavlink_script(gcs_port: int, offboard_port: int) -> str:
    """PX4's own px4-rc.mavlink, its GCS link sending to `gcs_port` and its offboard link to
    `offboard_port` (PX4 sends them to 14550 and 14540+I, ports every other instance and ground
    station on the machine use too)."""
    script = mavlink_script_path()
    text = script.read_text()
    for line in (GCS_LINK_START, OFFBOARD_REMOTE, OFFBOARD_REMOTE_ABOVE_9):
        if line not in text:  # PX4 changed its script: say so rather than start a vehicle on fixed ports
            raise RuntimeError(f"{script} no longer holds {line.strip()!r}")
    text = text.replace(GCS_LINK_START, f"{GCS_LINK_START.rstrip()} -o {gcs_port}\n")
    text = text.replace(OFFBOARD_REMOTE, f"udp_offboard_port_remote={offboard_port}\n")
    return text.replace(OFFBOARD_REMOTE_ABOVE_9, "")


def _module_links(bin_dir: Path) -> None:
    """bin_dir/px4-NAME -> ../shared/px4/bin/px4 for every module command the build names."""
    bin_dir.mkdir(parents=True, exist_ok=True)
    for entry in sorted((px4_dir() / "bin").iterdir()):
        if entry.name.startswith("px4-") and not entry.name.endswith(".sh"):
            (bin_dir / entry.name).symlink_to(binary())


class PX4:
    """One PX4 SIH process. Use as a context manager, or start() / stop().

    `instance` None picks a free one. `sysid` None is PX4's own choice, instance + 1. `home` is (lat,
    lon, alt AMSL m). `gcs_port` is where its GCS link sends (None: a free port of its own). `params`
    are set at boot, before any module starts (SDLOG_MODE = -1 is always among them)."""

    def __init__(self, instance: int | None = None, home: tuple[float, float, float] = DEFAULT_HOME,
                 params: dict[str, float] | None = None, sysid: int | None = None,
                 gcs_port: int | None = None) -> None:
        self.wanted = instance
        self.instance = -1 if instance is None else instance
        self.wanted_sysid = sysid
        self.home = home
        self.params: dict[str, float] = {**BOOT_PARAMS, **(params or {})}
        self.gcs_port = gcs_port if gcs_port is not None else free_udp_port()
        self.offboard_port = free_udp_port()
        self.folder: Path | None = None  # ours: bin/ (links, px4-rc.*), work/ (PX4_WORKDIR), px4.log
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def sysid(self) -> int:
        return self.wanted_sysid if self.wanted_sysid is not None else self.instance + 1

    @property
    def workdir(self) -> Path:
        assert self.folder is not None, "not started"
        return self.folder / "work"

    @property
    def bin_dir(self) -> Path:
        assert self.folder is not None, "not started"
        return self.folder / "bin"

    @property
    def gcs_url(self) -> str:
        """Where a ground station hears its GCS link (shared by a fleet started with one gcs_port)."""
        return f"udpin:127.0.0.1:{self.gcs_port}"

    @property
    def offboard_url(self) -> str:
        """This vehicle's own port (its offboard link sends there, to nobody else)."""
        return f"udpin:127.0.0.1:{self.offboard_port}"

    def env(self) -> dict[str, str]:
        lat, lon, alt = self.home
        env = dict(os.environ)
        env.update({"PX4_WORKDIR": str(self.workdir), "PX4_HOME_LAT": str(e7(lat)), "PX4_HOME_LON": str(e7(lon)),
                    "PX4_HOME_ALT": f"{alt:g}", "PATH": f"{self.bin_dir}{os.pathsep}{env.get('PATH', '')}"})
        return env

    def _write_start_scripts(self) -> None:
        """px4-rc.params and px4-rc.mavlink on PATH: the start-up script sources them, the parameters
        before the modules start, the links after."""
        lines = ["#!/bin/sh", "# written by missionplan/testing/px4_sih.py: this vehicle's boot parameters"]
        lines += [f"param set SIH_LOC_H0 {self.home[2]:g}"]
        if self.wanted_sysid is not None:
            lines += [f"param set MAV_SYS_ID {self.wanted_sysid}"]
        lines += [f"param set {name} {value:g}" for name, value in self.params.items()]
        (self.bin_dir / "px4-rc.params").write_text("\n".join(lines) + "\n")
        (self.bin_dir / "px4-rc.mavlink").write_text(mavlink_script(self.gcs_port, self.offboard_port))

    def start(self, attempts: int = 3, boot_wait: float = 30.0) -> PX4:
        """Start on a free instance; return once its start-up script has finished (a HEARTBEAT
        follows within a second; readiness to fly takes tens of seconds more, and `fly` waits for it)."""
        px4_or_skip()
        tried: set[int] = set()
        for _ in range(attempts):
            if self.wanted is None:
                self.instance = free_instance(skip=tried)
            elif not instance_free(self.wanted):
                raise RuntimeError(f"PX4 instance {self.wanted} is taken (its lock or one of its ports)")
            tried.add(self.instance)
            self.folder = Path(tempfile.mkdtemp(prefix=f"px4-{self.instance}-"))
            self.workdir.mkdir()
            _module_links(self.bin_dir)
            if self._launch(boot_wait):
                return self
            self.stop()
            if self.wanted is not None:
                break
        raise RuntimeError(f"PX4 SIH did not start (instances tried {sorted(tried)})")

    def _launch(self, boot_wait: float) -> bool:
        self._write_start_scripts()
        log = open(self.folder / "px4.log", "ab")  # noqa: SIM115 (closed with the process)
        self.proc = subprocess.Popen([str(run_sih()), str(self.instance)], cwd=self.workdir, env=self.env(),
                                     stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     start_new_session=True)
        log.close()
        return self._wait_started(boot_wait)

    def restart(self, params: dict[str, float] | None = None, boot_wait: float = 30.0) -> PX4:
        """Stop and start again on the same instance and workdir (parameters and mission kept),
        with `params` added to the boot parameters: for modules that read them only at boot."""
        assert self.folder is not None, "not started"
        self.params.update(params or {})
        if self.proc is not None and self.proc.poll() is None:
            self.client("param", "save")  # PX4 saves changes after a delay: not lost to the kill
        self._kill()
        (self.folder / "px4.log").write_bytes(b"")
        if not self._launch(boot_wait):
            raise RuntimeError(f"PX4 instance {self.instance} did not restart:\n{self.log_text()[-2000:]}")
        return self

    def _wait_started(self, timeout: float) -> bool:
        """Until its start-up script says it finished (True) or failed, or the process died (False)."""
        assert self.proc is not None
        proc = self.proc

        def outcome() -> str | None:
            text = self.log_bytes()
            if STARTED_MARKER in text:
                return "started"
            if proc.poll() is not None or any(m in text for m in FAILED_MARKERS):
                return "failed"
            return None

        return wait_until(outcome, timeout, interval=0.1) == "started"

    def log_bytes(self) -> bytes:
        try:
            return (self.folder / "px4.log").read_bytes() if self.folder else b""
        except OSError:
            return b""

    def log_text(self) -> str:
        return self.log_bytes().decode("utf-8", "replace")

    def client(self, *args: str, timeout: float = 10.0) -> str:
        """Run a PX4 console command on this instance (`client("param", "show", "TRIG_MODE")`)."""
        command = [str(self.bin_dir / f"px4-{args[0]}"), "--instance", str(self.instance), *args[1:]]
        done = subprocess.run(command, cwd=self.workdir, env=self.env(), capture_output=True, timeout=timeout,
                              check=False)
        return (done.stdout + done.stderr).decode("utf-8", "replace")

    def log_files(self) -> list[Path]:
        """The .ulg files PX4 wrote (none, with logging off)."""
        return sorted(self.workdir.rglob("*.ulg")) if self.folder else []

    def _kill(self) -> None:
        """Kill the whole process group: SIGTERM, then SIGKILL."""
        proc, self.proc = self.proc, None
        if proc is not None:
            stop_process_group(proc)

    def stop(self) -> None:
        """Kill the process group, then remove its folder."""
        self._kill()
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None

    def __enter__(self) -> PX4:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
