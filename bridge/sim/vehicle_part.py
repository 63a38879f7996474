"""What every part of a mock vehicle shares: the vehicle it belongs to, and answering the messages it owns.

Owns VehiclePart, the base of the mission server, the command handler, the parameter server and the telemetry
(the shape of QGroundControl's MockLink and its MockLinkMissionItemHandler): each part names the message types it
answers in HANDLERS (type -> method name), and MockVehicle hands every message to its parts until one answers.
An exception while answering is logged (one escaped line, log_error) and answered by the part's failed(); the
mock's thread serves on.
"""

from __future__ import annotations

import logging
from typing import Any

from ..formats.mission_items import Flavour
from ..terminal_text import printable

LOG = logging.getLogger("missionplan.bridge.sim")


class VehiclePart:
    """One part of a MockVehicle; HANDLERS maps a MAVLink message type to the method that answers it."""

    HANDLERS: dict[str, str] = {}

    def __init__(self, vehicle: Any) -> None:
        # The MockVehicle this is part of (Any: mock_vehicle imports the parts, not the other way).
        self.vehicle = vehicle
        self.flavour: Flavour = vehicle.flavour
        self.options = vehicle.options
        self.mav = vehicle.mav

    def handle(self, msg: Any, peer: tuple[int, int], now: float) -> bool:
        """Answer `msg` if this part owns its type; False for any other message. Whatever answering raises
        is logged and answered by failed(): one odd message never stops the mock from serving."""
        name = self.HANDLERS.get(msg.get_type())
        if name is None:
            return False
        try:
            getattr(self, name)(msg, peer, now)  # looked up per message, so a test may patch the method in flight
        except Exception as err:  # noqa: BLE001 (a mock autopilot keeps serving whatever one message does)
            self.vehicle.handler_errors += 1
            log_error(f"mock vehicle {self.vehicle.sysid}: {type(err).__name__} answering {msg.get_type()}: {err}")
            self.failed(msg, peer)
        return True

    def failed(self, msg: Any, peer: tuple[int, int]) -> None:
        """Answering `msg` raised (already logged): the part answers what it can (the mission server: the
        transfer with MAV_MISSION_ERROR). Nothing by default."""


def log_error(text: str) -> None:
    """One line in the mock's log (stderr for `missionplan mock`), control characters escaped: a message's
    text never reaches the terminal raw."""
    LOG.error("%s", printable(text))
