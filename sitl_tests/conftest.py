"""Tests against real autopilots in simulation: ArduCopter SITL and PX4 SIH from the simulators folder
(missionplan/testing/simulators.py: ../shared beside the repository, or --simulators DIR). Their fixtures
(`arducopter`, `px4`, `arducopter_fleet`, `fly_runs`) come from missionplan's pytest plugin
(missionplan/testing/plugin.py); the fleet the fault and survey tests fly is below.

Tests here start their peers themselves on 127.0.0.1, bound every wait, and stop them.
"""

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from missionplan.testing.loopback import let_children_hear_ctrl_c
from missionplan.testing.plans import plan_area
from missionplan.testing.sitl_fleet import AREA, LAUNCHES, SPEEDUP, Fleet

let_children_hear_ctrl_c()


@pytest.fixture(scope="module")
def block(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Milan block (sitl_fleet.AREA) planned for its three launch points, once per module."""
    return plan_area(tmp_path_factory.mktemp("milan-block"), AREA, LAUNCHES)


@pytest.fixture()
def fleet(arducopter_fleet: Callable[..., Any], block: Path, tmp_path: Path) -> Fleet:
    """Three SITL vehicles at the block's launch points, sending through a relay to a free udpin port
    (a copy of the plan of their own in tmp_path/plan); not configured yet."""
    plan_dir = tmp_path / "plan"
    plan_dir.mkdir()
    for path in block.iterdir():
        (plan_dir / path.name).write_bytes(path.read_bytes())
    return arducopter_fleet(plan_dir, speedup=SPEEDUP)
