"""Integration tests against mock autopilots on loopback (the planner -> files -> MAVLink path).

Tests here start their peers themselves on 127.0.0.1, bound every wait, and stop them.
"""

import socket  # noqa: E402


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago (for peers that cannot bind port 0 themselves)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])
