"""The mock flight's time-triggered capture: MAV_CMD_IMAGE_START_CAPTURE's photo every interval, until stopped.

Owns CaptureClock, which counts simulated seconds flown since the capture started (mock_flight.FlightSim asks it,
after each step, how many photos fell due). ArduPilot times a mission's IMAGE_START_CAPTURE on its own clock and a
MAVLink camera PX4 forwards it to times it on the camera's: either way one photo every interval seconds, the first
at the item itself (taken by the flight). The count (param3) is not kept: plans send 0, until the stop.
"""

from __future__ import annotations

DUE_TOLERANCE_S = 1e-6  # a photo this close to its time is due now, however the steps' rounding fell


class CaptureClock:
    """Seconds between photos (0: not capturing by time) and the seconds flown since the last one."""

    def __init__(self) -> None:
        self.interval_s = 0.0
        self.since_s = 0.0

    def set(self, interval_s: float) -> bool:
        """Start (interval > 0) or stop (0) capturing by time; the next photo is one interval away. Whether it
        started (the start's own photo is then the flight's to take)."""
        self.interval_s, self.since_s = max(interval_s, 0.0), 0.0
        return self.interval_s > 0

    def due(self, flown_s: float) -> int:
        """How many photos fall due in the next `flown_s` simulated seconds."""
        if self.interval_s <= 0 or flown_s <= 0:
            return 0
        self.since_s += flown_s
        photos = 0
        while self.since_s >= self.interval_s - DUE_TOLERANCE_S:
            self.since_s -= self.interval_s
            photos += 1
        return photos
