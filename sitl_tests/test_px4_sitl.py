"""Missions against real PX4 SIH (../shared/px4, v1.15.4) through the real CLI: a planned mission
(the Leonardo map and a real street area, `plan --autopilot px4`) uploads, verifies, downloads the
same and then STARTS (PX4 answers "Mission start denied! No valid mission" to a mission it finds infeasible); the
same plan from the wrong place is refused by `upload` with PX4's reasons; a plan for ArduPilot is
refused with exit 2; fence and rally round trips; a 1,000-item mission, and PX4's list limits.

Each test starts its own PX4 instance (sitl_tests/px4_sih.py: a free instance number, its offboard link
sending to a free port of its own, own temp folder and session, logging off, killed in teardown) and
skips when ../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink, wait_vehicle
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, MissionType, to_wire
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.formats.missionfile import PlanFile, read_mission_file, write_plan
from missionplan.cli import main
from missionplan.testing.px4_mission_session import wait_ready
from missionplan.testing.px4_sih import PX4

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

CLI = ["--timeout", "20", "--quiet"]
READY_S = 90.0  # PX4 SIH says "Ready for takeoff!" some 30-40 s after boot (longer under load)
MILAN_BLOCK = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": {
    "type": "Polygon", "coordinates": [[[9.18560, 45.46560], [9.18660, 45.46560], [9.18660, 45.46620],
                                        [9.18560, 45.46620], [9.18560, 45.46560]]]}}]}


def _plan(tmp: Path, where: str, autopilot: str) -> Path:
    out = tmp / f"{where}-{autopilot}"
    if where == "leonardo":
        args = ["--map", "leonardo", "--uavs", "5"]
    else:  # a 20 m street plan over a Milan block, as crews fly them
        area = tmp / "milan.geojson"
        area.write_text(json.dumps(MILAN_BLOCK))
        args = ["--area", str(area), "--altitude", "20", "--fov", "70", "--uavs", "1", "--launch", "45.46590,9.18610"]
    assert main(["plan", *args, "--out", str(out), "--autopilot", autopilot, "--quiet"]) == 0
    return out / "uav1.plan"


def _start(url: str, sysid: int) -> tuple[int | None, list[str]]:
    """MISSION_START once PX4 is ready (before, it answers DENIED "No valid mission" even for a valid
    mission), repeated while TEMPORARILY_REJECTED: its final result and the STATUSTEXT lines seen."""
    texts: list[str] = []
    deadline = time.monotonic() + READY_S
    with Link(url) as link:
        wait_vehicle(link, sysid, AUTOPILOT_COMPONENT_ID, 20)
        assert wait_ready(link, sysid, READY_S), "PX4 never reported its pre-arm checks passing"
        while time.monotonic() < deadline:
            link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_MISSION_START, 0,
                                       0, 0, 0, 0, 0, 0, 0)
            result = None
            until = time.monotonic() + 2.0
            while (msg := link.recv(until)) is not None:
                if msg.get_srcSystem() != sysid:
                    continue
                if msg.get_type() == "STATUSTEXT":
                    texts.append(str(msg.text).rstrip("\t"))
                elif msg.get_type() == "COMMAND_ACK" and int(msg.command) == mavlink.MAV_CMD_MISSION_START \
                        and result is None:
                    result = int(msg.result)
                    until = time.monotonic() + 1.0  # the texts that follow it
            if result not in (None, mavlink.MAV_RESULT_TEMPORARILY_REJECTED):
                return result, texts
            ask_again = min(deadline, time.monotonic() + 1.0)  # not ready yet: listen, then ask again
            while (msg := link.recv(ask_again)) is not None:
                if msg.get_srcSystem() == sysid and msg.get_type() == "STATUSTEXT":
                    texts.append(str(msg.text).rstrip("\t"))
    return None, texts


@pytest.mark.parametrize("where", ["leonardo", "milan"])
def test_a_planned_mission_uploads_verifies_downloads_and_starts(px4, tmp_path, capsys, where) -> None:
    path = _plan(tmp_path, where, "px4")
    planned = read_mission_file(path)
    lat, lon, _ = planned.mission.home  # type: ignore[misc]
    vehicle: PX4 = px4(home=(lat, lon, 120.0))
    url, sysid = vehicle.offboard_url, str(vehicle.sysid)
    # A plan written for ArduPilot is refused, with one line, before anything is sent.
    assert main(["upload", str(_plan(tmp_path, where, "ardupilot")), "--sysid", sysid, "--connect", url, *CLI]) == 2
    assert "written for ArduPilot (firmwareType 3), but vehicle" in capsys.readouterr().err
    assert main(["upload", str(path), "--sysid", sysid, "--connect", url, *CLI]) == 0
    out = capsys.readouterr().out.strip().splitlines()[-1]
    fence = len(planned.fence.items)
    assert out.startswith(f"uploaded {len(planned.mission.items) + fence} items ({len(planned.mission.items)} "
                          f"mission, {fence} fence, no rally) to vehicle {sysid} (px4, pymavlink); verified"), out
    back = tmp_path / "back.plan"
    assert main(["download", "--sysid", sysid, "--connect", url, "-o", str(back), *CLI]) == 0
    got = read_mission_file(back)
    assert got.firmware is Flavour.PX4 and len(got.mission.items) == len(planned.mission.items)
    assert compare_wire(to_wire(planned.mission, Flavour.PX4), to_wire(got.mission, Flavour.PX4), skip_home=False,
                        flavour=Flavour.PX4) == []
    assert compare_wire(to_wire(planned.fence, Flavour.PX4), to_wire(got.fence, Flavour.PX4), skip_home=False,
                        flavour=Flavour.PX4) == []
    # And PX4 starts it (the vehicle arms itself on MISSION_START).
    result, texts = _start(url, vehicle.sysid)
    assert result == mavlink.MAV_RESULT_ACCEPTED and "Executing Mission" in texts, (result, texts)


def test_upload_from_the_wrong_place_is_refused_with_pxs_reasons(px4, tmp_path, capsys) -> None:
    path = _plan(tmp_path, "leonardo", "px4")
    montreal = (45.4671160, -73.7578370, 20.0)  # where PX4 SIH starts without PX4_HOME_LAT / LON
    vehicle: PX4 = px4(home=montreal)
    code = main(["upload", str(path), "--sysid", str(vehicle.sysid), "--connect", vehicle.offboard_url, *CLI])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1, err
    assert "would refuse to start this mission" in err and "First waypoint too far away: 61" in err
    assert "would fly it without its geofence (\"Geofence invalid, doesn't contain Home position\")" in err


def _small_plan(home: tuple[float, float, float], fence_and_rally: bool) -> PlanFile:
    lat, lon, _ = home
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=10.0)]
    items += [MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.5,
                          x=lat + i * 2e-5, y=lon, z=10.0) for i in range(1, 6)]
    plan = PlanFile(mission=Mission(items + [MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                         mavlink.MAV_FRAME_MISSION)], home=home), firmware=Flavour.PX4)
    if fence_and_rally:
        square = [(lat - 0.001, lon - 0.001), (lat - 0.001, lon + 0.001), (lat + 0.001, lon + 0.001),
                  (lat + 0.001, lon - 0.001)]
        plan.fence = Mission([MissionItem(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, mavlink.MAV_FRAME_GLOBAL,
                                          param1=4.0, x=a, y=b, autocontinue=False) for a, b in square]
                             + [MissionItem(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, mavlink.MAV_FRAME_GLOBAL,
                                            param1=15.0, x=lat + 0.0005, y=lon + 0.0005, autocontinue=False)],
                             MissionType.FENCE)
        plan.rally = Mission([MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                          x=lat + 0.0003, y=lon - 0.0003, z=20.0),
                              MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                          x=lat - 0.0004, y=lon + 0.0001, z=25.5)], MissionType.RALLY)
    return plan


def test_fence_and_rally_round_trip_and_a_plan_without_them_clears_them(px4, tmp_path, capsys) -> None:
    home = (45.4641, 9.1891, 120.0)
    vehicle: PX4 = px4(home=home)
    url, sysid = vehicle.offboard_url, str(vehicle.sysid)
    with_all, bare, back = tmp_path / "all.plan", tmp_path / "bare.plan", tmp_path / "back.plan"
    write_plan(with_all, _small_plan(home, True))
    write_plan(bare, _small_plan(home, False))
    assert main(["upload", str(with_all), "--sysid", sysid, "--connect", url, *CLI]) == 0
    assert "(7 mission, 5 fence, 2 rally)" in capsys.readouterr().out
    assert main(["download", "--sysid", sysid, "--connect", url, "-o", str(back), *CLI]) == 0
    doc = json.loads(back.read_text())
    assert [len(p["polygon"]) for p in doc["geoFence"]["polygons"]] == [4]
    assert [c["circle"]["radius"] for c in doc["geoFence"]["circles"]] == [15.0]
    assert [round(p[2], 3) for p in doc["rallyPoints"]["points"]] == [20.0, 25.5]
    assert main(["upload", str(bare), "--sysid", sysid, "--connect", url, *CLI]) == 0
    assert "(7 mission, no fence, no rally)" in capsys.readouterr().out
    assert main(["download", "--sysid", sysid, "--connect", url, "-o", str(back), *CLI]) == 0
    doc = json.loads(back.read_text())
    assert doc["geoFence"]["polygons"] == [] and doc["geoFence"]["circles"] == [] and doc["rallyPoints"]["points"] == []


def test_a_1000_item_mission_and_pxs_list_limits(px4, tmp_path, capsys) -> None:
    home = (45.4641, 9.1891, 120.0)
    vehicle: PX4 = px4(home=home)
    url, sysid = vehicle.offboard_url, str(vehicle.sysid)
    lat, lon, _ = home
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=lon, z=10.0)]
    items += [MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.5,
                          x=lat + (i % 40) * 1e-5, y=lon + (i // 40) * 1e-5, z=10.0 + i % 7)
              for i in range(1, 999)]
    path = tmp_path / "big.plan"
    write_plan(path, PlanFile(mission=Mission(items + [MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                                   mavlink.MAV_FRAME_MISSION)], home=home),
                              firmware=Flavour.PX4))
    assert main(["upload", str(path), "--sysid", sysid, "--connect", url, *CLI]) == 0
    assert "uploaded 1000 items (1000 mission, no fence, no rally)" in capsys.readouterr().out
    # PX4 holds at most 64 fence items and 32 rally points: one more is refused as NO_SPACE, by name.
    for kind, most in ((MissionType.FENCE, 64), (MissionType.RALLY, 32)):
        plan = PlanFile(mission=Mission(items[:3], home=home), firmware=Flavour.PX4)
        if kind == MissionType.FENCE:
            plan.fence = Mission([MissionItem(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, mavlink.MAV_FRAME_GLOBAL,
                                              param1=500.0 + i, x=lat, y=lon, autocontinue=False)
                                  for i in range(most + 1)], kind)
        else:
            plan.rally = Mission([MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                              x=lat + i * 1e-5, y=lon, z=20.0) for i in range(most + 1)], kind)
        write_plan(path, plan)
        assert main(["upload", str(path), "--sysid", sysid, "--connect", url, *CLI]) == 1
        assert "no space for this many items (MAV_MISSION_NO_SPACE)" in capsys.readouterr().err
        plan.fence.items, plan.rally.items = plan.fence.items[:most], plan.rally.items[:most]
        write_plan(path, plan)
        assert main(["upload", str(path), "--sysid", sysid, "--connect", url, *CLI]) == 0
        assert f"{most} {kind.label}" in capsys.readouterr().out
