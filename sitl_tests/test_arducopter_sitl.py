"""The bridge against real ArduCopter SITL (../shared/sitl/arducopter): upload and read-back verify
through the real CLI, download equals upload, fence and rally, and stale fences cleared.

Each test starts its own SITL instance (sitl_tests/arducopter.py: own temp folder, own session,
free ports, killed in teardown) and skips when the binary is absent.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, MissionType, to_wire
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.formats.missionfile import PlanFile, read_mission_file, write_plan
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import open_backend, upload_plan
from missionplan.cli import main
from missionplan.testing.arducopter import ArduCopter

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

CLI_FAST = ["--timeout", "20", "--quiet"]


@pytest.fixture(scope="module")
def shipped_plans(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """uav1.plan of `missionplan plan --map leonardo --uavs 5` (20 items) and of old-town with one
    drone (about 350 items, the size of the field report's failing 348-item upload)."""
    out: dict[str, Path] = {}
    for name, uavs in (("leonardo", 5), ("old-town", 1)):
        folder = tmp_path_factory.mktemp(f"{name}-{uavs}")
        # --endurance 0: one mission however long (old-town's would be cut into battery sorties).
        assert main(["plan", "--map", name, "--uavs", str(uavs), "--out", str(folder), "--endurance", "0",
                     "--quiet"]) == 0
        out[name] = folder / "uav1.plan"
    return out


def _fenced(mission: Mission) -> PlanFile:
    lat, lon = mission.home[0], mission.home[1]  # type: ignore[index]
    square = [(lat - 0.001, lon - 0.001), (lat - 0.001, lon + 0.001), (lat + 0.001, lon + 0.001),
              (lat + 0.001, lon - 0.001)]
    fence = Mission([MissionItem(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, mavlink.MAV_FRAME_GLOBAL,
                                 param1=4.0, x=a, y=b) for a, b in square]
                    + [MissionItem(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, mavlink.MAV_FRAME_GLOBAL, param1=15.0,
                                   x=lat + 0.0002, y=lon + 0.0002)], MissionType.FENCE)
    rally = Mission([MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat + 0.0003,
                                 y=lon - 0.0003, z=20.0),
                     MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat - 0.0004,
                                 y=lon + 0.0001, z=25.0)], MissionType.RALLY)
    return PlanFile(mission=mission, fence=fence, rally=rally)


def _same_by_ardupilot_rule(sent: Mission, got: Mission) -> list[str]:
    """Differences between two missions' wire items beyond what ArduPilot may legally change."""
    a, b = to_wire(sent, Flavour.ARDUPILOT), to_wire(got, Flavour.ARDUPILOT)
    return compare_wire(a, b, skip_home=sent.mission_type == MissionType.MISSION, flavour=Flavour.ARDUPILOT)


@pytest.mark.parametrize("name, at_least", [("leonardo", 15), ("old-town", 340)])
def test_cli_upload_of_a_shipped_plan_verifies_and_downloads_the_same(arducopter, shipped_plans, tmp_path,
                                                                      capsys, name, at_least) -> None:
    vehicle: ArduCopter = arducopter(sysid=1)
    plan_path = shipped_plans[name]
    planned = read_mission_file(plan_path)
    items, fence = len(planned.mission.items), len(planned.fence.items)
    assert items >= at_least and fence >= 3  # every plan carries its drone's geofence
    assert main(["upload", str(plan_path), "--sysid", "1", "--connect", vehicle.url, *CLI_FAST]) == 0
    out = capsys.readouterr().out
    assert f"uploaded {items + fence} items ({items} mission, {fence} fence, no rally) to vehicle 1 " \
           "(ardupilot, pymavlink); verified by read-back" in out
    assert "set WPNAV_RADIUS = " in out
    down = tmp_path / "down.plan"
    assert main(["download", "--sysid", "1", "--connect", vehicle.url, "-o", str(down), *CLI_FAST]) == 0
    sent, got = read_mission_file(plan_path), read_mission_file(down)
    assert len(got.mission.items) == items
    assert _same_by_ardupilot_rule(sent.mission, got.mission) == []
    assert len(got.fence.items) == fence and got.rally.items == []
    assert _same_by_ardupilot_rule(planned.fence, got.fence) == []


def test_no_invalid_sequence_acks_and_wpnav_radius_is_set(arducopter, shipped_plans) -> None:
    vehicle: ArduCopter = arducopter(sysid=2)
    plan = read_mission_file(shipped_plans["old-town"])
    with open_backend("pymavlink", vehicle.url, 2, timeouts=Timeouts(), connect_timeout=20) as backend:
        report = upload_plan(backend, plan.parts())
        assert report.verified and report.parts[0].items == len(plan.mission.items) >= 340
        assert backend.client.invalid_sequence_acks == 0  # type: ignore[attr-defined]
        radius = min(it.param2 for it in plan.mission.items if it.command == mavlink.MAV_CMD_NAV_WAYPOINT)
        assert backend.set_param("WPNAV_RADIUS", max(round(radius * 100), 5))[0] == max(round(radius * 100), 5)


def test_fence_and_rally_round_trip_and_an_unfenced_plan_clears_them(arducopter, shipped_plans, tmp_path,
                                                                     capsys) -> None:
    vehicle: ArduCopter = arducopter(sysid=3)
    plain = read_mission_file(shipped_plans["leonardo"])
    fenced = _fenced(plain.mission)
    fenced_path = tmp_path / "fenced.plan"
    write_plan(fenced_path, fenced)
    assert main(["upload", str(fenced_path), "--sysid", "3", "--connect", vehicle.url, *CLI_FAST]) == 0
    n = len(plain.mission.items)
    assert f"({n} mission, 5 fence, 2 rally)" in capsys.readouterr().out
    down = tmp_path / "down.plan"
    assert main(["download", "--sysid", "3", "--connect", vehicle.url, "-o", str(down), *CLI_FAST]) == 0
    got = read_mission_file(down)
    assert len(got.fence.items) == 5 and len(got.rally.items) == 2
    assert _same_by_ardupilot_rule(fenced.fence, got.fence) == []
    assert _same_by_ardupilot_rule(fenced.rally, got.rally) == []
    # The same mission without fence or rally: the vehicle must not keep the old ones.
    unfenced_path = tmp_path / "unfenced.plan"
    write_plan(unfenced_path, PlanFile(mission=plain.mission))
    assert main(["upload", str(unfenced_path), "--sysid", "3", "--connect", vehicle.url, *CLI_FAST]) == 0
    assert f"({n} mission, no fence, no rally)" in capsys.readouterr().out
    with open_backend("pymavlink", vehicle.url, 3, connect_timeout=20) as backend:
        assert backend.download(MissionType.FENCE) == [] and backend.download(MissionType.RALLY) == []
        assert len(backend.download(MissionType.MISSION)) == n + 1  # and home


def test_a_vehicle_that_sends_to_a_udpin_port(arducopter, shipped_plans, capsys) -> None:
    """How fleets reach a ground station: SITL with --serial0 udpclient:127.0.0.1:PORT, we listen there."""
    from missionplan.testing.loopback import free_udp_port

    port = free_udp_port()
    arducopter(sysid=4, serial0=f"udpclient:127.0.0.1:{port}")
    assert main(["upload", str(shipped_plans["leonardo"]), "--sysid", "4", "--connect", f"udpin:127.0.0.1:{port}",
                 *CLI_FAST]) == 0
    assert "to vehicle 4 (ardupilot, pymavlink); verified by read-back" in capsys.readouterr().out
