"""Differential test of values an autopilot cannot store: the same out-of-range mission, rally and fence items
(sitl_tests/limit_cases.py, which says what each autopilot answered), uploaded raw to real ArduCopter SITL and
to the ArduPilot-flavoured mock, and to real PX4 SIH and the PX4-flavoured mock, must draw the same MISSION_ACK
and leave the same stored item. The mock alone is held to the measured answers in every run
(tests/test_limits.py)."""

from __future__ import annotations

import pytest
from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.limit_cases import EXPECTED_ARDUCOPTER, EXPECTED_PX4, HOME, drift, mock_answers, session
from missionplan.testing.px4_mission_session import HOME as PX4_HOME
from missionplan.testing.px4_sih import PX4

pytestmark = pytest.mark.sitl


def test_arducopter_and_the_mock_refuse_alike(arducopter) -> None:
    vehicle: ArduCopter = arducopter(sysid=7, home=(*HOME, 0.0))
    real = session(vehicle.url, 7, home=True)
    mocked = mock_answers("ardupilot", HOME, 7)
    assert drift(real, mocked, "ArduCopter") == [], "\n".join(drift(real, mocked, "ArduCopter"))
    assert {name: result for name, (result, _) in real.items()} == EXPECTED_ARDUCOPTER


def test_px4_and_the_mock_take_alike(px4) -> None:
    vehicle: PX4 = px4(home=PX4_HOME)
    real = session(vehicle.offboard_url, vehicle.sysid, home=False)
    mocked = mock_answers("px4", PX4_HOME, vehicle.sysid)
    assert drift(real, mocked, "PX4") == [], "\n".join(drift(real, mocked, "PX4"))
    assert {name: result for name, (result, _) in real.items()} == EXPECTED_PX4
