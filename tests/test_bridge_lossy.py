"""A 500-item mission through a bad link (20 % loss each way, duplicates, reordering) to the mock
autopilot, uploaded and read back item by item, with each backend."""

from __future__ import annotations

import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_DO_SET_CAM_TRIGG_DIST,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan


def survey(n: int) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.07, y=7.68, z=30.0),
             MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=8.0)]  # not at 0, 0 (PX4)
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, x=45.07 + (i // 20) * 2e-4,
                          y=7.68 + (i % 20) * 1e-4, z=30.0)
              for i in range(n - 4)]
    items += [MissionItem(CMD_DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, param1=0.0),
              MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)]
    return Mission(items, home=(45.07, 7.68, 240.0))


@pytest.mark.parametrize("backend, flavour", [("pymavlink", "ardupilot"), ("mavsdk", "px4")])
def test_500_items_through_loss_duplicates_and_reordering(backend: str, flavour: str) -> None:
    faults = LinkFaults.lossy(0.2, duplicate=0.05, reorder=0.05, seed=2024)
    mission = survey(500)
    with MockAutopilot(flavour=flavour, faults=faults, request_interval=0.01, upload_timeout=3.0) as mock:
        with open_backend(backend, mock.client_url, 1, timeouts=Timeouts(item_timeout=0.1, retries=30),
                          connect_timeout=5) as b:
            report = upload_plan(b, [mission])
            assert report.verified and report.items == 500
            reader = report.parts[0].read_back_by
        held = mock.mission(1)
        stats = dict(mock.stats)
    sent = to_wire(mission, Flavour(flavour))
    assert compare_wire(sent, held, skip_home=flavour == "ardupilot", flavour=Flavour(flavour)) == []
    # The faults really happened, in both directions.
    assert stats["dropped_in"] > 100 and stats["dropped_out"] > 100
    print(f"{backend}: {report.summary()} (read back by {reader}); mock {stats}")
