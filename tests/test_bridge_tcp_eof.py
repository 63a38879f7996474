"""A TCP peer that goes away mid-upload.

pymavlink printed "EOF on TCP socket" on every read of the closed socket, and select() wakes at
once for a closed socket, so one upload printed it over a million times. Now: nothing from
pymavlink, a bounded reconnect, and either the upload goes on or one line says why it stopped.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    Mission,
    MissionItem,
)
from missionplan.bridge.formats.missionfile import PlanFile, write_plan
from missionplan.bridge.sim.mock import MockAutopilot

from test_bridge_commands import FAST, run  # tests/: pyproject.toml's pytest pythonpath


def _plan(tmp_path: Path, n: int = 300) -> Path:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param1=1.0, x=45.07 + i * 1e-5, y=7.68,
                          z=25.0) for i in range(n)]
    path = tmp_path / "long.plan"
    write_plan(path, PlanFile(mission=Mission(items, home=(45.07, 7.68, 240.0))))
    return path


def _when_mid_upload(mock: MockAutopilot, action: str) -> threading.Thread:
    """Once the vehicle has taken 40 packets (well into a 300-item upload), break the link."""
    def act() -> None:
        if mock.wait_until(lambda m: m.stats["in"] >= 40, timeout=20):
            mock.stop() if action == "die" else mock.drop_clients()

    thread = threading.Thread(target=act, daemon=True)
    thread.start()
    return thread


def test_peer_that_dies_gives_one_line_and_no_flood(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = _plan(tmp_path)
    mock = MockAutopilot("tcpin:127.0.0.1:0", request_interval=0.05, upload_timeout=2.0).start()
    try:
        thread = _when_mid_upload(mock, "die")
        start = time.monotonic()
        code = run(["upload", str(path), "--sysid", "1", "--connect", mock.client_url] + FAST)
        elapsed = time.monotonic() - start
        thread.join(5)
        assert mock.stats["clients"] == 1  # the mock is gone: the reconnects were refused
    finally:
        mock.stop()
    out, err = capfd.readouterr()
    assert code == 1
    assert "EOF on TCP socket" not in out + err and "Connection reset" not in out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("missionplan upload: tcp:127.0.0.1:")
    assert "closed the TCP connection and 4 reconnects over 2 s failed" in lines[0]
    assert elapsed < 30  # bounded: not the step limit of every retry of every item


def test_peer_that_drops_the_connection_and_comes_back_finishes_the_upload(
        tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = _plan(tmp_path)
    with MockAutopilot("tcpin:127.0.0.1:0", request_interval=0.05, upload_timeout=2.0) as mock:
        thread = _when_mid_upload(mock, "drop")
        code = run(["upload", str(path), "--sysid", "1", "--connect", mock.client_url] + FAST)
        thread.join(5)
        assert mock.vehicle(1).uploads_completed == 1 and len(mock.mission(1)) == 1 + 301
        assert mock.stats["clients"] == 2  # the first connection was dropped mid-upload; we came back
    out, err = capfd.readouterr()
    assert code == 0, err
    assert "verified by read-back" in out and "EOF on TCP socket" not in out + err


def test_a_clean_close_is_reported_once(capfd: pytest.CaptureFixture[str]) -> None:
    """A peer that closes cleanly (FIN, not RST): the case that printed "EOF on TCP socket" per read
    (28 501 lines in one second of waiting on the old code)."""
    import socket

    from missionplan.bridge import BridgeError
    from missionplan.bridge.link.connection import Link, mavlink

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    heard = threading.Event()  # the close comes only after the client has read the heartbeat

    def serve() -> None:
        client, _ = server.accept()
        encoder = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        client.sendall(encoder.heartbeat_encode(2, 3, 0, 0, 4).pack(encoder))
        heard.wait(5.0)
        server.close()  # first: a reconnect that came between the two closes would be accepted
        client.shutdown(socket.SHUT_RDWR)
        client.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    with Link(f"tcp:127.0.0.1:{port}") as link:
        assert link.recv(time.monotonic() + 2.0).get_type() == "HEARTBEAT"
        heard.set()
        with pytest.raises(BridgeError, match="the other end closed the TCP connection and 4 reconnects"):
            link.recv(time.monotonic() + 5.0)
        assert link.reconnects == 1
    thread.join(2)
    out, err = capfd.readouterr()
    assert "EOF" not in out + err and "Connection reset" not in out + err
