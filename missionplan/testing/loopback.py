"""Loopback basics for tests that start peers: free ports, a bounded poll, stopping a simulator's
process group, and Ctrl-C given back to the processes a test starts.

The relay that breaks a link on purpose and watches what crosses it is relay.py."""

import signal
import time
from collections.abc import Callable
from typing import TypeVar

# The ports and process groups are the product's (missionplan/bridge/sim/sitl_process.py: `verify --sim sitl` starts
# SITL too); the names stay here for the tests. ANY_INTERFACE: where SITL and PX4 bind their ports, every interface.
from missionplan.bridge.sim.sitl_process import (ANY_INTERFACE, free_udp_port, stop_process_group, tcp_port_free,
                                                  udp_port_free)

__all__ = ["ANY_INTERFACE", "free_udp_port", "let_children_hear_ctrl_c", "stop_process_group", "tcp_port_free",
           "udp_port_free", "wait_until"]
T = TypeVar("T")


def let_children_hear_ctrl_c() -> None:
    """A suite started from a background shell (`nohup`, `cmd &` in a script) inherits SIGINT ignored, and
    so would every `fly` and `mock` it starts: the tests that stop them with Ctrl-C would fail for the
    wrong reason. A Python handler is reset to the default in a child at exec, so installing Python's own
    here gives the children a working Ctrl-C again; an interactive run is unchanged."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


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
