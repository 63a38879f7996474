"""Differential test: one mission session, run against the ArduPilot-flavoured mock and against real
ArduCopter SITL, must leave the same stored lists and draw the same answers. When the mock drifts from
ArduCopter (what it stores, how it answers out-of-turn items, its parameters), this fails and says
where.

The session: a raw upload that sends an item before it was asked for, finishes, then sends a stray
item after the end (the answers are recorded); a full upload of a mission with every kind of item our
files hold plus odd values (fractional hold time, yaw, pass radius, deprecated frames, DO_* in frame
3, RTL with a position), a fence and rally points; a download of all three lists, field by field;
WPNAV_RADIUS set below its range and read back (missionplan/testing/arducopter_mission_session.py;
tests/test_mock_as_autopilots.py shows, without SITL, that the comparison catches a drifted mock).
"""

from __future__ import annotations

import pytest

from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.arducopter_mission_session import HOME, drift, mock_record, session

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def test_mock_and_arducopter_store_and_answer_alike(arducopter) -> None:
    vehicle: ArduCopter = arducopter(sysid=7, home=(*HOME, 0.0))
    real = session(vehicle.url, 7)
    mocked = mock_record()
    assert drift(real, mocked) == [], "the mock drifted from ArduCopter:\n" + "\n".join(drift(real, mocked))
    # And the session did exercise what it is about.
    assert real["answers"] == {"request": "MISSION_REQUEST", "early item": 13, "final": 0, "stray item": 1}
    assert real["invalid_sequence_acks"] == 0
    assert real["mission"][0][9:11] != (0, 0)  # a real home, compared too
