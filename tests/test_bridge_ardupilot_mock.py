"""The bridge against the ArduPilot-flavoured mock, where it behaves like ArduCopter: no
race with the vehicle's re-requests, stray acks after an upload, stale fence / rally cleared, the
home item before a GPS fix, and the mock command's --home / --plan."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from missionplan.bridge import BridgeUsageError
from missionplan.cli.mock import mock_homes
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem, MissionType, to_wire
from missionplan.bridge.formats.missionfile import PlanFile, write_plan
from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan


def survey(n: int, lat: float = 45.07) -> Mission:
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=30.0)]
    items += [MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.5,
                          x=lat + i * 1e-4, y=7.68, z=30.0) for i in range(n)]
    return Mission(items + [MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)],
                   home=(lat, 7.68, 240.0))


def test_upload_waits_for_the_vehicle_instead_of_racing_its_re_requests() -> None:
    # Replies that sometimes take 25-75 ms (a busy autopilot, a router): a retry timer tuned to the
    # round trip re-sent items the vehicle had not asked for, and ArduPilot complained each time.
    faults = LinkFaults(latency=0.002, reorder=0.3, reorder_delay=0.05, seed=3)
    with MockAutopilot(flavour="ardupilot", faults=faults) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(), connect_timeout=5) as b:
            report = upload_plan(b, [survey(60)])
            assert report.verified and b.client.invalid_sequence_acks == 0
        vehicle = mock.vehicle(1)
        assert vehicle.invalid_sequence_acks == 0 and vehicle.stray_item_acks == 0
        assert len(mock.mission(1)) == 63


def test_a_late_error_ack_after_accepted_does_not_fail_what_follows() -> None:
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            wire = to_wire(survey(5), Flavour.ARDUPILOT)
            b.upload(MissionType.MISSION, wire)
            # A duplicate of the last item reaches the vehicle after its ACCEPTED: it answers ERROR.
            b.link.mav.mission_item_int_send(1, 1, **wire[-1].fields())
            assert len(b.download(MissionType.MISSION)) == len(wire)
            b.link.mav.mission_item_int_send(1, 1, **wire[-1].fields())
            b.upload(MissionType.MISSION, wire)  # and a second upload right after one is not refused
        assert mock.vehicle(1).stray_item_acks == 2 and mock.vehicle(1).uploads_completed == 2


def test_an_upload_without_fence_or_rally_clears_the_old_ones(tmp_path: Path) -> None:
    fence = Mission([MissionItem(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, mavlink.MAV_FRAME_GLOBAL, param1=300.0,
                                 x=45.07, y=7.68)], MissionType.FENCE)
    rally = Mission([MissionItem(mavlink.MAV_CMD_NAV_RALLY_POINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=45.071,
                                 y=7.681, z=20.0)], MissionType.RALLY)
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            assert upload_plan(b, [survey(5), fence, rally]).verified
            assert len(mock.mission(1, MissionType.FENCE)) == 1 and len(mock.mission(1, MissionType.RALLY)) == 1
            report = upload_plan(b, [survey(6)])
        assert mock.mission(1, MissionType.FENCE) == [] and mock.mission(1, MissionType.RALLY) == []
        assert [(p.mission_type, p.items, p.verified) for p in report.parts] == [(0, 8, True), (1, 0, True),
                                                                                  (2, 0, True)]
        assert "(8 mission, no fence, no rally)" in report.summary()


def test_home_item_reads_zero_until_the_gps_has_a_fix() -> None:
    home = (44.4, 8.9, 12.0)
    for fix_after, expected in ((1e6, (0, 0, 0.0)), (0.0, (444_000_000, 89_000_000, 12.0))):
        with MockAutopilot(flavour="ardupilot", homes={1: home}, gps_fix_after=fix_after) as mock:
            with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
                item0 = b.download(MissionType.MISSION)[0]
        assert (item0.x, item0.y) == expected[:2] and math.isclose(item0.z, expected[2], abs_tol=1e-4)


def test_mock_homes_from_the_command_line_and_from_plans(tmp_path: Path) -> None:
    assert mock_homes([1, 2], ["44.4,8.9"], None) == {1: (44.4, 8.9, 0.0), 2: (44.4005, 8.9, 0.0)}
    assert mock_homes([1, 2], ["2=41.1,-8.6,30", "44.4,8.9"], None) == {1: (44.4, 8.9, 0.0), 2: (41.1, -8.6, 30.0)}
    for k, lat in ((1, 41.15), (2, 41.16)):
        write_plan(tmp_path / f"uav{k}.plan", PlanFile(mission=survey(2, lat=lat)))
    assert mock_homes([1, 2], [], tmp_path) == {1: (41.15, 7.68, 240.0), 2: (41.16, 7.68, 240.0)}
    for homes, plan, message in ((["91,8"], None, "latitude must be within"), (["1=nan,8"], None, "expected LAT,LON"),
                                 (["3=45,8"], None, "system id 3 is not served"), ([], tmp_path / "none", "not a folder"),
                                 (["x"], None, "expected LAT,LON")):
        with pytest.raises(BridgeUsageError, match=message):
            mock_homes([1, 2], homes, plan)
    with pytest.raises(BridgeUsageError, match="no uav3.plan"):
        mock_homes([3], [], tmp_path)


def test_wpnav_radius_from_the_plan_clamped_to_its_range_and_proven_by_param_value(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from missionplan.bridge.errors import BridgeError
    from missionplan.bridge.link.connection import VehicleInfo
    from missionplan.bridge.sim import vehicle_params
    from missionplan.bridge.link.params import acceptance_radius_setting

    copter = VehicleInfo(1, 1, 3, 2, Flavour.ARDUPILOT, False)
    assert acceptance_radius_setting(copter, survey(3)).value == 50.0  # type: ignore[union-attr]
    tiny = Mission([MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.01,
                                x=45.0, y=7.0, z=5.0)])
    setting = acceptance_radius_setting(copter, tiny)
    assert setting is not None and setting.value == 5.0 and "clamped from 1" in setting.describe(200.0)
    huge = Mission([MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=25.0,
                                x=45.0, y=7.0, z=5.0)])
    assert acceptance_radius_setting(copter, huge).value == 1000.0  # type: ignore[union-attr]
    assert acceptance_radius_setting(VehicleInfo(1, 1, 12, 2, Flavour.PX4, False), survey(3)) is None
    assert acceptance_radius_setting(VehicleInfo(1, 1, 3, 1, Flavour.ARDUPILOT, False), survey(3)) is None  # plane
    plain = Mission([MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=45.0, y=7.0,
                                 z=5.0)])
    assert acceptance_radius_setting(copter, plain) is None
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            report = upload_plan(b, [survey(3)], set_params=False)
            assert report.params == [] and mock.vehicle(1).params["WPNAV_RADIUS"] == 200.0
            assert upload_plan(b, [survey(3)]).params == [
                "set WPNAV_RADIUS = 50 cm (was 200): the plan's acceptance radius (ArduCopter ignores the waypoints' param2)"]
            assert mock.vehicle(1).flight.default_acceptance == 0.5  # and the mock flies it
            # A vehicle that keeps another value fails the upload instead of flying a radius nobody chose.
            monkeypatch.setattr(vehicle_params.ParamServer, "_on_set",
                                lambda self, msg, peer, now: self._send_value("WPNAV_RADIUS", peer))
            with pytest.raises(BridgeError, match="kept WPNAV_RADIUS = 50 when set to 20"):
                upload_plan(b, [Mission([MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT,
                                                     mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.2, x=45.0, y=7.0,
                                                     z=5.0)])])


def test_a_lost_final_accepted_is_settled_by_read_back(monkeypatch: pytest.MonkeyPatch) -> None:
    from missionplan.bridge.sim.mission_server import MissionServer

    original = MissionServer._ack
    dropped: list[int] = []

    def lossy_ack(self, peer, mission_type, result):  # type: ignore[no-untyped-def]
        if result == mavlink.MAV_MISSION_ACCEPTED and mission_type == MissionType.MISSION and not dropped:
            dropped.append(result)  # the ACCEPTED of the first mission upload never arrives
            return
        for _ in range(2 if result == mavlink.MAV_MISSION_ERROR else 1):  # and every ERROR arrives twice
            original(self, peer, mission_type, result)

    monkeypatch.setattr(MissionServer, "_ack", lossy_ack)
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            report = upload_plan(b, [survey(5)], verify=False)
        # Our copy of the last item drew ArduPilot's ERROR: the outcome was unknown, so it was read back.
        assert dropped and mock.vehicle(1).stray_item_acks >= 1
        assert len(mock.mission(1)) == 8 and not report.verified


def test_a_late_param_value_with_the_old_value_does_not_fail_the_set(monkeypatch: pytest.MonkeyPatch) -> None:
    # Through a lossy link a PARAM_VALUE answering an earlier read (the old value) can arrive after
    # our PARAM_SET went out; the vehicle's answer to the set follows it.
    from missionplan.bridge.sim import vehicle_params

    original = vehicle_params.ParamServer._on_set

    def stale_first(self, msg, peer, now):  # type: ignore[no-untyped-def]
        self._send_value("WPNAV_RADIUS", peer)  # the old value, late
        original(self, msg, peer, now)

    monkeypatch.setattr(vehicle_params.ParamServer, "_on_set", stale_first)
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            assert b.set_param("WPNAV_RADIUS", 25.0) == (200.0, 25.0)
        assert mock.vehicle(1).params["WPNAV_RADIUS"] == 25.0
