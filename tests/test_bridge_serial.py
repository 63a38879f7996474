"""Serial links for real: a pseudo-terminal pair with the mock on one end.

The mock keeps the pty master; `missionplan upload` opens the slave /dev/pts/N through pymavlink's
serial driver (pyserial), exactly as it opens /dev/ttyUSB0 on a telemetry radio.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

from missionplan.bridge import BridgeUsageError
from missionplan.bridge.link.connection import Link, parse_url
from missionplan.bridge.formats.mission_items import (
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Mission,
    MissionItem,
)
from missionplan.bridge.formats.missionfile import PlanFile, read_plan, write_plan
from missionplan.bridge.sim.mock import MockAutopilot

from test_bridge_commands import FAST, run  # tests/: pyproject.toml's pytest pythonpath

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs POSIX pseudo-terminals")


def _mission(n: int = 30) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param1=1.0, x=45.07 + i * 1e-4, y=7.68,
                          z=25.0) for i in range(n)]
    return Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=(45.07, 7.68, 240.0))


def test_serial_urls_parse() -> None:
    assert parse_url("/dev/ttyUSB0,57600").url == "/dev/ttyUSB0,57600"
    assert parse_url("/dev/ttyACM0:115200").baud == 115200
    assert parse_url("/dev/serial/by-id/usb-3DR_Radio-if00-port0,57600").device.endswith("port0")
    assert parse_url("/dev/ttyUSB0").baud == 115200
    by_path = "/dev/serial/by-path/pci-0000:00:14.0-usb-0:2:1.0-port0"
    assert (parse_url(by_path + ",57600").device, parse_url(by_path).device) == (by_path, by_path)
    assert parse_url("COM3,57600").device == "COM3"
    with pytest.raises(BridgeUsageError, match="bad baud rate"):
        parse_url("/dev/ttyUSB0,fast")


def test_upload_and_download_over_a_pty(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission()))
    with MockAutopilot("pty", request_interval=0.05, upload_timeout=2.0) as mock:
        url = mock.client_url
        assert url.startswith("/dev/pts/") and url.endswith(",57600")
        assert run(["upload", str(plan_path), "--sysid", "1", "--connect", url] + FAST) == 0
        assert "verified by read-back" in capsys.readouterr().out
        assert len(mock.mission(1)) == 1 + 32
        out = tmp_path / "back.plan"  # a second client on the same line, after the first closed it
        assert run(["download", "--sysid", "1", "--connect", url, "-o", str(out)] + FAST) == 0
    assert [i.command for i in read_plan(out).mission.items] == [i.command for i in _mission().items]


def test_missionplan_upload_process_over_a_pty(tmp_path: Path) -> None:
    """The installed command in its own process: the README's serial recipe, no traceback."""
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission(10)))
    with MockAutopilot("pty", request_interval=0.05, upload_timeout=2.0) as mock:
        done = subprocess.run([sys.executable, "-m", "missionplan", "upload", str(plan_path), "--sysid", "1",
                               "--connect", mock.client_url, *FAST], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr
        assert "verified by read-back" in done.stdout and "Traceback" not in done.stderr
        assert mock.vehicle(1).uploads_completed == 1


def test_a_serial_line_that_goes_away_mid_upload_is_one_line(tmp_path: Path,
                                                              capfd: pytest.CaptureFixture[str]) -> None:
    """The far end of the line disappears (the mock closes its pty: a radio unplugged)."""
    import threading

    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.07 + i * 1e-5, y=7.68, z=25.0)
              for i in range(300)]
    plan_path = tmp_path / "long.plan"
    write_plan(plan_path, PlanFile(mission=Mission(items, home=(45.07, 7.68, 240.0))))
    mock = MockAutopilot("pty", request_interval=0.05).start()
    try:
        def unplug() -> None:
            if mock.wait_until(lambda m: m.stats["in"] >= 40, timeout=20):
                mock.stop()

        thread = threading.Thread(target=unplug, daemon=True)
        thread.start()
        code = run(["upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url] + FAST)
        thread.join(5)
    finally:
        mock.stop()
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 1 and "the serial device went away (unplugged?)" in lines[0]
    assert "Traceback" not in out + err


def test_missing_serial_device_is_one_line_exit_2(tmp_path: Path) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission(3)))
    # The library names the setting (`connect`); the command line says it as its option, below.
    with pytest.raises(BridgeUsageError, match=r"^connect /dev/ttyNOPE9,57600: no such device /dev/ttyNOPE9"):
        Link("/dev/ttyNOPE9,57600")
    done = subprocess.run([sys.executable, "-m", "missionplan", "upload", str(plan_path), "--sysid", "1",
                           "--connect", "/dev/ttyNOPE9,57600", "--quiet"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip().splitlines() == [
        "missionplan: --connect /dev/ttyNOPE9,57600: no such device /dev/ttyNOPE9 (is the radio or autopilot "
        "plugged in? see ls /dev/serial/by-id/)"]


def test_mock_serves_a_serial_device_by_name() -> None:
    """`--listen DEVICE,BAUD`: here the device is the slave of a pty this test holds the master of."""
    master, slave = os.openpty()
    name = os.ttyname(slave)
    os.set_blocking(master, False)
    try:
        with MockAutopilot(f"{name},57600") as mock:
            assert mock.device == name
            parser = __import__("missionplan.bridge.link.connection", fromlist=["mavlink"]).mavlink.MAVLink(None)
            parser.robust_parsing = True
            deadline = time.monotonic() + 5
            kinds: list[str] = []
            while "HEARTBEAT" not in kinds and time.monotonic() < deadline:
                readable, _, _ = select.select([master], [], [], max(0.0, deadline - time.monotonic()))
                if readable:  # bytes from the mock, or nothing until the deadline
                    kinds += [m.get_type() for m in parser.parse_buffer(os.read(master, 4096)) or []]
            assert "HEARTBEAT" in kinds
    finally:
        os.close(master)
        os.close(slave)
