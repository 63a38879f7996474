"""A plan's geofence round-trips through real ArduCopter SITL (../shared/sitl/arducopter).

Plans Leonardo for 3 drones, uploads uav2.plan (mission and the drone's geofence) to one SITL vehicle
(sitl_tests/arducopter.py: own session, own temp folder, free instance, killed in teardown; skipped
when the binary is absent), reads the fence back and compares it point by point. A second upload of
the fence alone (an empty mission) must leave the vehicle with no mission and the same fence.
"""

from __future__ import annotations

import pytest

from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.mission_items import Flavour, MissionType, to_wire
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan
from missionplan.cli import main
from missionplan.testing.arducopter import ArduCopter

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def test_planned_geofence_round_trips_through_arducopter(arducopter, tmp_path):
    sysid = 2
    vehicle: ArduCopter = arducopter(sysid=sysid)
    out = tmp_path / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    plan = read_mission_file(out / f"uav{sysid}.plan")
    assert plan.fence.items and all(i.command == mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                                      for i in plan.fence.items)
    sent = to_wire(plan.fence, Flavour.ARDUPILOT)

    def fence_points(held: list) -> list[tuple]:
        return [(w.command, w.x, w.y, round(w.param1)) for w in held]

    with open_backend("pymavlink", vehicle.url, sysid, timeouts=Timeouts(), connect_timeout=30.0) as backend:
        assert backend.vehicle.flavour == Flavour.ARDUPILOT
        report = upload_plan(backend, plan.parts(), verify=True)  # raises if any read-back differs
        assert [p.verified for p in report.parts] == [True, True, True]
        assert fence_points(backend.download(MissionType.FENCE)) == fence_points(sent)

        # The fence alone: the mission list is cleared, the fence is the same.
        report = upload_plan(backend, [plan.fence], verify=True)
        assert report.parts[0].items == 0 and report.parts[0].verified
        assert len(backend.download(MissionType.MISSION)) <= 1  # nothing, or home alone
        assert fence_points(backend.download(MissionType.FENCE)) == fence_points(sent)
