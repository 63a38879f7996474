"""A loopback relay between vehicles and a ground station that breaks the link on purpose and watches
what crosses it (UdpRelay: the product's, missionplan/bridge/sim/udp_relay.py, which `verify --sim sitl` flies
through too), and a listener that tells which vehicles armed (armed_ever).

Tests of flight faults put it between a fleet and `fly`: the relay is the ground truth of what the
ground station sent and of what the vehicles did, whatever `fly` says."""

import time
from collections.abc import Iterable

from missionplan.bridge.sim.udp_relay import RELAY_BUFFER, UdpRelay, _one_log_data

__all__ = ["RELAY_BUFFER", "UdpRelay", "_one_log_data", "armed_ever"]


def armed_ever(url: str, sysids: Iterable[int], seconds: float) -> set[int]:
    """System ids whose HEARTBEAT says armed at any time within `seconds` (a listener on the port)."""
    from missionplan.bridge.link.connection import mavlink
    from missionplan.bridge.link.shared_link import SharedLink

    armed: set[int] = set()
    with SharedLink(url) as shared:
        views = {sysid: shared.vehicle(sysid) for sysid in sysids}
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for sysid, view in views.items():
                msg = view.recv(time.monotonic() + 0.05)
                if msg is not None and msg.get_type() == "HEARTBEAT" \
                        and msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                    armed.add(sysid)
    return armed
