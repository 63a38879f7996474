"""One mock survey flight that goes wrong the same way for every test that needs it: Leonardo planned
for 3 drones and flown on the mock fleet at 10x with drone 2 killed at item 8."""

from __future__ import annotations

from pathlib import Path

from missionplan.cli import main
from missionplan.flight.mock_fleet import start_mock_fleet

FAST = 10.0


def fly_with_a_lost_drone(root: Path) -> int:
    """Plan into `root` and fly it; returns fly's exit code (1: a drone lost is a problem of the flight)."""
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(root), "--quiet"]) == 0
    mock = start_mock_fleet(root, FAST)
    mock.kill(2, at_item=8)
    try:
        return main(["fly", str(root), "--connect", mock.client_url, "--time-scale", str(FAST), "--timeout", "40",
                     "--quiet"])
    finally:
        mock.stop()
