"""Independent implementations on both sides: MAVSDK (C++ MAVSDK through its Python binding) as the
ground station against our mock autopilot, and our pymavlink uploader against MAVSDK's vehicle-side
MissionRawServer."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_CIRCLE_INCLUSION,
    CMD_NAV_LAND,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend, open_backend, upload_plan
from missionplan.testing.loopback import free_udp_port, wait_until

mavsdk = pytest.importorskip("mavsdk")
from mavsdk.plugins.mission_raw import MissionItem as RawItem  # noqa: E402
from mavsdk.plugins.mission_raw import MissionRaw  # noqa: E402
from mavsdk.plugins.mission_raw_server import MissionRawServer  # noqa: E402


def survey(n: int) -> Mission:
    # PX4 refuses to start a take-off at 0, 0
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.07, y=7.68, z=30.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, param4=float(i % 360),
                          x=45.07 + i * 1e-4, y=7.68, z=30.0 + i % 4)
              for i in range(n - 2)]
    return Mission(items + [MissionItem(CMD_NAV_LAND, FRAME_GLOBAL_RELATIVE_ALT)], home=(45.07, 7.68, 240.0))


def _system(sdk: Any, sysid: int, autopilot: int, timeout: float = 5.0) -> Any:
    def found() -> Any:
        return next((system for system in sdk.get_systems() if system.get_system_id() == sysid
                     and system.has_autopilot() and int(system.autopilot_type()) == autopilot), None)

    system = wait_until(found, timeout, interval=0.02)  # MAVSDK's list of systems: polled, bounded
    if system is None:
        raise AssertionError(f"MAVSDK did not find system {sysid}")
    return system


@pytest.mark.parametrize("flavour, autopilot", [("ardupilot", 2), ("px4", 1)])
def test_mavsdk_own_transport_uploads_and_downloads_to_the_mock(flavour: str, autopilot: int) -> None:
    mission = survey(120)
    with MockAutopilot(sysids=[1, 2], flavour=flavour, request_interval=0.05) as mock:
        sdk = mavsdk.Mavsdk(mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION))
        try:
            assert int(sdk.add_any_connection(mock.mavsdk_url)) == 0  # MAVSDK's own UDP socket
            plugin = MissionRaw(_system(sdk, 2, autopilot))
            wire = to_wire(mission, Flavour(flavour))
            plugin.upload_mission([RawItem(**w.fields()) for w in wire])
            held = mock.mission(2)
            assert compare_wire(wire, held, skip_home=flavour == "ardupilot", flavour=Flavour(flavour)) == []
            assert mock.mission(1) == mock.mission(1)[:1]  # sysid 1 untouched (only home, or nothing)
            got = plugin.download_mission()
            assert len(got) == len(wire)
            assert all(g.seq == w.seq and g.command == w.command and g.x == w.x and g.y == w.y
                       for g, w in zip(got, held))
        finally:
            sdk.destroy()


def test_mavsdk_backend_over_tcp_with_fence() -> None:
    fence = Mission([MissionItem(CMD_FENCE_CIRCLE_INCLUSION, FRAME_GLOBAL, param1=1000.0, x=45.07, y=7.68)],
                    mission_type=MissionType.FENCE)  # round the home
    with MockAutopilot(listen="tcpin:127.0.0.1:0", flavour="px4", request_interval=0.05) as mock:
        with open_backend("mavsdk", mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            report = upload_plan(b, [survey(30), fence])
            # The file has no rally points: the vehicle's are cleared, and that is read back too.
            assert report.verified and [p.read_back_by for p in report.parts] == ["mavsdk", "mavsdk", "mavsdk"]
            assert [p.items for p in report.parts] == [30, 1, 0]
        assert len(mock.mission(1)) == 30 and len(mock.mission(1, 1)) == 1 and mock.mission(1, 2) == []


def test_our_uploader_against_mavsdk_mission_raw_server() -> None:
    port = free_udp_port()
    config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.AUTOPILOT)
    config.system_id = 7
    sdk = mavsdk.Mavsdk(config)
    received: dict[str, Any] = {}
    done = threading.Event()

    def incoming(result: Any, plan: Any, _user: Any) -> None:
        received["result"], received["items"] = result, plan.mission_items
        done.set()

    try:
        assert int(sdk.add_any_connection(f"udpin://127.0.0.1:{port}")) == 0
        server = MissionRawServer(sdk.server_component())
        server.subscribe_incoming_mission(incoming)
        mission = survey(200)
        with PymavlinkBackend(f"udpout:127.0.0.1:{port}", 7, timeouts=Timeouts(item_timeout=0.5),
                              connect_timeout=5) as b:
            assert b.vehicle.flavour is Flavour.GENERIC  # MAVSDK's autopilot says MAV_AUTOPILOT_GENERIC: no home item
            sent = to_wire(mission, b.vehicle.flavour)
            b.upload(0, sent)
            assert done.wait(5)
            assert received["result"].name == "SUCCESS"
            items = received["items"]
            assert len(items) == len(sent)
            for got, want in zip(items, sent):
                assert (got.seq, got.frame, got.command, got.current, got.autocontinue, got.x, got.y, got.mission_type) \
                    == (want.seq, want.frame, want.command, want.current, want.autocontinue, want.x, want.y, 0)
                assert (got.param1, got.param2, got.param3, got.param4, got.z) \
                    == pytest.approx((want.param1, want.param2, want.param3, want.param4, want.z))
            # And read back through MAVSDK's server: the mission it holds is ours.
            assert compare_wire(sent, b.download(0), skip_home=False) == []
    finally:
        sdk.destroy()


def test_mavsdk_backend_to_an_ardupilot_vehicle_verifies_by_its_rule_and_sets_wpnav_radius() -> None:
    with MockAutopilot(flavour="ardupilot", request_interval=0.05) as mock:
        with open_backend("mavsdk", mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3), connect_timeout=5) as b:
            report = upload_plan(b, [survey(20)])
        assert report.verified and report.params and report.params[0].startswith("set WPNAV_RADIUS = ")
        assert mock.vehicle(1).params["WPNAV_RADIUS"] != 200.0 and len(mock.mission(1)) == 21
