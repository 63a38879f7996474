"""Faults injected by the mock autopilot's link (mock.MockAutopilot), per packet and per direction.

Owns LinkFaults: loss each way, duplicates, reordering (a packet held back so that later ones overtake it) and
added latency, from a seeded random generator (seed) so that a run can be repeated.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import BridgeUsageError


@dataclass
class LinkFaults:
    """Per-packet faults. Probabilities in [0, 1], latency in seconds (one way)."""

    loss_in: float = 0.0     # ground station -> vehicle
    loss_out: float = 0.0    # vehicle -> ground station
    duplicate: float = 0.0   # chance a packet is delivered twice
    reorder: float = 0.0     # chance a packet is held back so that later ones overtake it
    reorder_delay: float = 0.01
    latency: float = 0.0
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("loss_in", "loss_out", "duplicate", "reorder"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise BridgeUsageError(f"{name.replace('_', '-')} must be between 0 and 1, got {value}")
        if self.latency < 0 or self.reorder_delay < 0:
            raise BridgeUsageError("latency and reorder delay must not be negative")

    @classmethod
    def lossy(cls, loss: float, duplicate: float = 0.0, reorder: float = 0.0, latency: float = 0.0,
              seed: int | None = None) -> LinkFaults:
        return cls(loss_in=loss, loss_out=loss, duplicate=duplicate, reorder=reorder, latency=latency, seed=seed)
