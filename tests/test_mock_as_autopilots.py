"""The mock held to what the real autopilots did, without starting one: the halves of the differential
tests in sitl_tests/ that need only the mock.

- The comparisons of sitl_tests/test_mock_vs_arducopter.py and test_mock_vs_px4.py (one mission session,
  missionplan/testing/arducopter_mission_session.py and px4_mission_session.py) catch a mock that drifted:
  the faithful mock against one that stores what it got (the old mock) differ exactly where ArduCopter
  or PX4 and the old mock did.
- A mission replaced in flight (missionplan.bridge.transfer.retask.replace_mission_in_flight, the re-task
  harness missionplan/testing/retask_harness.py): the mock's SITL-like flight must answer it as ArduCopter
  SITL and PX4 SIH did in sitl_tests/test_retask_sitl.py, with the same function and assertions.
"""

from __future__ import annotations

import pytest

from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.connection import Link
from missionplan.bridge.sim.mission_server import MissionServer
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.testing import arducopter_mission_session as arducopter_session
from missionplan.testing import px4_mission_session as px4_session
from missionplan.testing.retask_harness import check, retask_and_follow
from missionplan.testing.retask_harness import line as row_line


def test_the_arducopter_comparison_catches_a_mock_that_stores_verbatim(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without SITL: the faithful mock against one that stores what it got (the old mock) and answers
    out-of-turn items like PX4 differ exactly where ArduCopter and the old mock did."""
    faithful = arducopter_session.mock_record()
    assert faithful["answers"] == {"request": "MISSION_REQUEST", "early item": 13, "final": 0, "stray item": 1}
    monkeypatch.setattr(MissionServer, "_stored", lambda self, item: item)
    verbatim = arducopter_session.mock_record()
    found = arducopter_session.drift(faithful, verbatim)
    assert any(line.startswith("mission item 4 param2: ArduCopter 0.0, mock 0.0595") for line in found), found
    assert "mission item 2 frame: ArduCopter 0, mock 2" in found
    assert "fence item 0 z: ArduCopter 0.0, mock 7.0" in found


def test_the_px4_comparison_catches_a_mock_that_stores_verbatim(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without PX4: the faithful mock against one that stores what it got (the old PX4 mock) and asks
    with MISSION_REQUEST_INT from the start differ where PX4 and the old mock did."""
    session, start_session = px4_session.session, px4_session.start_session
    faithful, faithful_starts = px4_session.mock_record(session), px4_session.mock_record(start_session)
    monkeypatch.setattr(MissionServer, "_stored", lambda self, item: item)
    monkeypatch.setattr(MissionServer, "start_refusals", lambda self: [])
    verbatim, verbatim_starts = px4_session.mock_record(session), px4_session.mock_record(start_session)
    found = px4_session.drift(faithful, verbatim)
    assert "mission item 3 frame: PX4 6, mock 3" in found, found
    assert "mission item 3 param3: PX4 0.0, mock 0.5" in found
    assert "fence item 0 autocontinue: PX4 0, mock 1" in found
    assert "far: start: PX4 (2, ['Mission start denied! No valid mission']), mock (2, [])" in \
        px4_session.drift(faithful_starts, verbatim_starts)


@pytest.mark.flight
@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4], ids=["ardupilot", "px4"])
def test_the_mock_takes_a_new_mission_in_flight_as_the_autopilots_do(flavour: Flavour) -> None:
    """The same function and assertions as sitl_tests/test_retask_sitl.py's, against the mock's SITL-like
    flight."""
    home = (45.4643, 9.1895, 120.0)
    with MockAutopilot(homes={1: home}, flavour=flavour, speedup=10.0, sitl_like=True,
                       streams_until_asked=True, request_interval=0.1).start() as mock:
        with Link(mock.client_url) as link:
            report, row, flight, started = retask_and_follow(link, 1, flavour, home, 10.0)
    print(report.summary(), row_line(row), sep="\n")
    check(report, row, flight, started)
