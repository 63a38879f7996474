"""Differential test: the same mission sessions against the mock's PX4 flavour and against real PX4
SIH (v1.15.4) must draw the same answers and leave the same stored lists, field by field.

The sessions are sitl_tests/px4_mission_session.py's: the request type of the first uploads after start,
MISSION_REQUEST_LIST by target component, every frame and a list of commands in frames 3 and 2 (the
MISSION_ACK of each single-item upload), a rejected upload that must keep the previous mission, a
count of 0, a mission with every item kind we write plus odd values, a fence and rally points
downloaded field by field (frames 3 -> 6 and 0 -> 5, `current`, PX4's float32 yaw); and the mission
start PX4 refuses once ready ("Mission start denied! No valid mission": a first waypoint 2.2 km away)
and the STATUSTEXT of a fence that leaves home out. Skips when ../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

from typing import Any

import pytest
from plans import same_answer
from px4_sih import PX4, px4  # noqa: F401  (the fixture)
from px4_mission_session import HOME, session, start_session

from missionplan.bridge.formats.mission_items import WireItem
from missionplan.bridge.sim.mission_server import MissionServer
from missionplan.bridge.sim.mock import MockAutopilot

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def drift(real: dict[str, Any], mocked: dict[str, Any]) -> list[str]:
    """Every difference between two session records, one line each (stored lists field by field)."""
    out = []
    for key in real:
        if key in ("mission", "fence", "rally", "after bad upload"):
            for seq, (r, m) in enumerate(zip(real[key], mocked[key])):
                for name, a, b in zip(WireItem.__dataclass_fields__, r, m):
                    if not same_answer(a, b):
                        out.append(f"{key} item {seq} {name}: PX4 {a!r}, mock {b!r}")
            if len(real[key]) != len(mocked[key]):
                out.append(f"{key}: PX4 holds {len(real[key])} items, mock {len(mocked[key])}")
        elif isinstance(real[key], dict) and isinstance(mocked.get(key), dict):
            out += [f"{key} {k}: PX4 {real[key][k]!r}, mock {mocked[key].get(k)!r}"
                    for k in real[key] if not same_answer(real[key][k], mocked[key].get(k))]
        elif not same_answer(real[key], mocked.get(key)):
            out.append(f"{key}: PX4 {real[key]!r}, mock {mocked.get(key)!r}")
    return out


def _mock(run: Any) -> dict[str, Any]:
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[11], flavour="px4", homes={11: HOME}) as mock:
        return run(mock.client_url, 11)


def test_mock_and_px4_store_and_answer_alike(px4) -> None:  # noqa: F811
    vehicle: PX4 = px4(home=HOME)
    real = session(vehicle.offboard_url, vehicle.sysid)
    mocked = _mock(session)
    assert drift(real, mocked) == [], "the mock drifted from PX4:\n" + "\n".join(drift(real, mocked))
    # What the session is about, as PX4 showed it.
    assert (real["first request"], real["second request"]) == ("MISSION_REQUEST", "MISSION_REQUEST_INT")
    assert real["frames"] == {0: 0, 1: 2, 2: 3, 3: 0, 5: 0, 6: 0, 10: 2, 11: 2}
    assert real["commands in frame 3"][999] == 3 and real["commands in frame 2"][206] == 0
    assert real["bad upload ack"] == 2 and len(real["after bad upload"]) == 2
    assert real["mission"][3][1] == 6 and real["mission"][5][1] == 5 and real["mission"][0][3] == 1


def test_mock_and_px4_refuse_the_same_starts(px4) -> None:  # noqa: F811
    vehicle: PX4 = px4(home=HOME)
    real = start_session(vehicle.offboard_url, vehicle.sysid)
    mocked = _mock(start_session)
    assert drift(real, mocked) == [], "the mock drifted from PX4:\n" + "\n".join(drift(real, mocked))
    assert real["far: start"] == (2, ["Mission start denied! No valid mission"])
    assert real["fence upload texts"] == ["Geofence invalid, doesn't contain Home position"]


def test_the_comparison_catches_a_mock_that_stores_verbatim(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without PX4: the faithful mock against one that stores what it got (the old PX4 mock) and asks
    with MISSION_REQUEST_INT from the start differ where PX4 and the old mock did."""
    faithful, faithful_starts = _mock(session), _mock(start_session)
    monkeypatch.setattr(MissionServer, "_stored", lambda self, item: item)
    monkeypatch.setattr(MissionServer, "start_refusals", lambda self: [])
    verbatim, verbatim_starts = _mock(session), _mock(start_session)
    found = drift(faithful, verbatim)
    assert "mission item 3 frame: PX4 6, mock 3" in found, found
    assert "mission item 3 param3: PX4 0.0, mock 0.5" in found
    assert "fence item 0 autocontinue: PX4 0, mock 1" in found
    assert "far: start: PX4 (2, ['Mission start denied! No valid mission']), mock (2, [])" in \
        drift(faithful_starts, verbatim_starts)
