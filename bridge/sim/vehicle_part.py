"""What every part of a mock vehicle shares: the vehicle it belongs to, and answering the messages it owns.

Owns VehiclePart, the base of the mission server, the command handler, the parameter server and the telemetry
(the shape of QGroundControl's MockLink and its MockLinkMissionItemHandler): each part names the message types it
answers in HANDLERS (type -> method name), and MockVehicle hands every message to its parts until one answers.
"""

from __future__ import annotations

from typing import Any

from ..formats.mission_items import Flavour


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
        """Answer `msg` if this part owns its type; False for any other message."""
        name = self.HANDLERS.get(msg.get_type())
        if name is None:
            return False
        getattr(self, name)(msg, peer, now)  # looked up per message, so a test may patch the method in flight
        return True
