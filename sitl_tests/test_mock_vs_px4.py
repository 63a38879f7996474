"""Differential test: the same mission sessions against the mock's PX4 flavour and against real PX4
SIH (v1.15.4) must draw the same answers and leave the same stored lists, field by field.

The sessions are missionplan/testing/px4_mission_session.py's: the request type of the first uploads after start,
MISSION_REQUEST_LIST by target component, every frame and a list of commands in frames 3 and 2 (the
MISSION_ACK of each single-item upload), a rejected upload that must keep the previous mission, a
count of 0, a mission with every item kind we write plus odd values, a fence and rally points
downloaded field by field (frames 3 -> 6 and 0 -> 5, `current`, PX4's float32 yaw); and the mission
start PX4 refuses once ready ("Mission start denied! No valid mission": a first waypoint 2.2 km away)
and the STATUSTEXT of a fence that leaves home out. Skips when ../shared/px4/bin/px4 is absent.
(tests/test_mock_as_autopilots.py shows, without PX4, that the comparison catches a drifted mock.)
"""

from __future__ import annotations

import pytest

from missionplan.testing.px4_mission_session import HOME, drift, mock_record, session, start_session
from missionplan.testing.px4_sih import PX4

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def test_mock_and_px4_store_and_answer_alike(px4) -> None:
    vehicle: PX4 = px4(home=HOME)
    real = session(vehicle.offboard_url, vehicle.sysid)
    mocked = mock_record(session)
    assert drift(real, mocked) == [], "the mock drifted from PX4:\n" + "\n".join(drift(real, mocked))
    # What the session is about, as PX4 showed it.
    assert (real["first request"], real["second request"]) == ("MISSION_REQUEST", "MISSION_REQUEST_INT")
    assert real["frames"] == {0: 0, 1: 2, 2: 3, 3: 0, 5: 0, 6: 0, 10: 2, 11: 2}
    assert real["commands in frame 3"][999] == 3 and real["commands in frame 2"][206] == 0
    assert real["bad upload ack"] == 2 and len(real["after bad upload"]) == 2
    assert real["mission"][3][1] == 6 and real["mission"][5][1] == 5 and real["mission"][0][3] == 1


def test_mock_and_px4_refuse_the_same_starts(px4) -> None:
    vehicle: PX4 = px4(home=HOME)
    real = start_session(vehicle.offboard_url, vehicle.sysid)
    mocked = mock_record(start_session)
    assert drift(real, mocked) == [], "the mock drifted from PX4:\n" + "\n".join(drift(real, mocked))
    assert real["far: start"] == (2, ["Mission start denied! No valid mission"])
    assert real["fence upload texts"] == ["Geofence invalid, doesn't contain Home position"]
