"""Loopback helpers for the integration tests (a module of its own: `conftest` names collide
between tests/ and sitl_tests/, so nothing should import from a conftest): free ports, stopping a
simulator's process group, a bounded poll, and a listener that tells which vehicles armed."""

import os
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterable
from typing import TypeVar

T = TypeVar("T")


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago (for peers that cannot bind port 0 themselves)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def udp_port_free(port: int, host: str = "127.0.0.1") -> bool:
    """Whether nobody has bound UDP `port` on `host` (a peer started elsewhere has, once it listens)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def wait_until(condition: Callable[[], T], timeout: float, interval: float = 0.05) -> T | None:
    """Poll `condition` until it returns something truthy (returned) or `timeout` s pass (None). For
    events that arrive with no message to block on: a line in a simulator's log, a peer library's list
    of systems. The tests' one sleep: between polls, bounded, never to let time pass for its own sake."""
    deadline = time.monotonic() + timeout
    while True:
        result = condition()
        if result or time.monotonic() >= deadline:
            return result or None
        time.sleep(min(interval, max(0.0, deadline - time.monotonic())))


def stop_process_group(proc: "subprocess.Popen[bytes]") -> None:
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


MODE_FLAG_ARMED = 128  # HEARTBEAT base_mode: MAV_MODE_FLAG_SAFETY_ARMED


def armed_ever(url: str, sysids: Iterable[int], seconds: float) -> set[int]:
    """System ids whose HEARTBEAT says armed at any time within `seconds` (a listener on the port)."""
    from bridge.shared_link import SharedLink

    armed: set[int] = set()
    with SharedLink(url) as shared:
        views = {sysid: shared.vehicle(sysid) for sysid in sysids}
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for sysid, view in views.items():
                msg = view.recv(time.monotonic() + 0.05)
                if msg is not None and msg.get_type() == "HEARTBEAT" and msg.base_mode & MODE_FLAG_ARMED:
                    armed.add(sysid)
    return armed
