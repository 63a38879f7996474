"""A plan's geofence round-trips through real ArduCopter SITL (../shared/sitl/arducopter).

Starts one SITL vehicle itself (own session, own temp folder, a free instance), uploads the geofence
of a planned uavK.plan over MAVLink, reads it back and compares, then kills the vehicle's process
group, also when the test fails. Skipped when the binary is absent.
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

import pytest

from bridge.mission import CMD_FENCE_POLYGON_VERTEX_INCLUSION, Flavour, MissionType, to_wire
from bridge.missionfile import read_mission_file
from bridge.protocol import Timeouts
from bridge.uploader import open_backend, upload_plan
from missionplan.cli import main

SITL_DIR = Path(__file__).resolve().parent.parent.parent / "shared" / "sitl"
ARDUCOPTER = SITL_DIR / "arducopter"
START_S = 60.0  # bound on the wait for the vehicle's TCP port


def _port_in_use(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.settimeout(0.2)
        return probe.connect_ex(("127.0.0.1", port)) == 0


def _free_instance() -> int:
    """An instance number whose ports (5760 + 10 I and the two after) nobody listens on."""
    for instance in range(31, 60):
        base = 5760 + 10 * instance
        if not any(_port_in_use(base + k) for k in range(3)):
            return instance
    pytest.skip("no free SITL instance between 31 and 59")


@pytest.fixture
def sitl_vehicle():
    """(tcp URL, sysid) of one ArduCopter SITL vehicle, killed with its process group afterwards."""
    if not ARDUCOPTER.is_file():
        pytest.skip(f"{ARDUCOPTER} is absent")
    instance, sysid = _free_instance(), 2
    workdir = tempfile.mkdtemp(prefix="fence-sitl-")
    proc = subprocess.Popen([str(ARDUCOPTER), "--model", "+", "--speedup", "10", "--home", "45.4784,9.2269,120,0",
                             "--defaults", str(SITL_DIR / "copter.parm"), "--sysid", str(sysid), "-w",
                             "-I", str(instance), "--serial0", "tcp:0"],
                            cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    port = 5760 + 10 * instance
    try:
        deadline = time.monotonic() + START_S
        while not _port_in_use(port):
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"SITL instance {instance} did not open TCP {port}")
            time.sleep(0.2)
        yield f"tcp:127.0.0.1:{port}", sysid
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)
        shutil.rmtree(workdir, ignore_errors=True)


def test_planned_geofence_round_trips_through_arducopter(sitl_vehicle, tmp_path):
    url, sysid = sitl_vehicle
    out = tmp_path / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    plan = read_mission_file(out / f"uav{sysid}.plan")
    assert plan.fence.items and all(i.command == CMD_FENCE_POLYGON_VERTEX_INCLUSION for i in plan.fence.items)
    backend = open_backend("pymavlink", url, sysid, timeouts=Timeouts(item_timeout=1.0, retries=10),
                           connect_timeout=30.0)
    try:
        assert backend.vehicle.flavour == Flavour.ARDUPILOT
        report = upload_plan(backend, [plan.fence], verify=True)  # raises if the read-back differs
        assert report.parts[0].verified
        held = backend.download(MissionType.FENCE)
    finally:
        backend.close()
    sent = to_wire(plan.fence, Flavour.ARDUPILOT)
    assert [(w.command, w.x, w.y, round(w.param1)) for w in held] == [(w.command, w.x, w.y, round(w.param1))
                                                                       for w in sent]
