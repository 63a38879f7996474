"""Loopback basics for tests that start peers: free ports, a bounded poll, stopping a simulator's
process group, and Ctrl-C given back to the processes a test starts.

The relay that breaks a link on purpose and watches what crosses it is relay.py."""

import os
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")
# Where SITL and PX4 bind their ports: every interface, so a port is free for them only if it is free there.
ANY_INTERFACE = "0.0.0.0"


def let_children_hear_ctrl_c() -> None:
    """A suite started from a background shell (`nohup`, `cmd &` in a script) inherits SIGINT ignored, and
    so would every `fly` and `mock` it starts: the tests that stop them with Ctrl-C would fail for the
    wrong reason. A Python handler is reset to the default in a child at exec, so installing Python's own
    here gives the children a working Ctrl-C again; an interactive run is unchanged."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


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
