"""Loopback helpers for the integration tests (a module of its own: `conftest` names collide
between tests/ and sitl_tests/, so nothing should import from a conftest)."""

import socket


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago (for peers that cannot bind port 0 themselves)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])
