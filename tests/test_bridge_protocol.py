"""The pymavlink mission protocol against the mock autopilot on 127.0.0.1 (upload, download, clear,
set-current, every mission type, result messages, several vehicles on one link, reboots)."""

from __future__ import annotations

import math
import time

import pytest

from missionplan.bridge import BridgeError
from missionplan.bridge.link.connection import Link, wait_vehicle
from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot
from missionplan.bridge.transfer.protocol import MissionClient, MissionTransferError, Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan

FAST = Timeouts(item_timeout=0.2, retries=4)


def mission(n: int, lat: float = 45.07, alt: float = 30.0) -> Mission:
    # PX4 refuses to start a take-off at 0, 0 (5000 km away)
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=lat, y=7.68, z=alt)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.5, x=lat + i * 1e-4,
                          y=7.68 + (i % 7) * 1e-4, z=alt + i % 3)
              for i in range(n - 2)]
    items.append(MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION))
    return Mission(items=items, home=(lat, 7.68, 240.0))


def mock(**kw: object) -> MockAutopilot:
    kw.setdefault("request_interval", 0.02)
    kw.setdefault("upload_timeout", 1.0)
    return MockAutopilot(**kw).start()  # type: ignore[arg-type]


@pytest.mark.parametrize("flavour", ["ardupilot", "px4"])
def test_upload_and_read_back(flavour: str) -> None:
    with mock(flavour=flavour) as m, PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
        assert b.vehicle.flavour is Flavour(flavour)
        report = upload_plan(b, [mission(40)])
        assert report.verified and report.items == 40
        held = m.mission(1)
        sent = to_wire(mission(40), b.vehicle.flavour)
        assert len(held) == len(sent) == (41 if flavour == "ardupilot" else 40)
        assert compare_wire(sent, held, skip_home=flavour == "ardupilot", flavour=Flavour(flavour)) == []
        if flavour == "ardupilot":
            assert held[0].x == round(m.vehicle(1).options.home[0] * 1e7)  # the vehicle's real home


def test_fence_rally_clear_and_set_current() -> None:
    fence = Mission([MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.0, y=7.6),
                     MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.6),
                     MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.8)],
                    MissionType.FENCE)  # round the mock's home
    rally = Mission([MissionItem(CMD_RALLY_POINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.05, y=7.05, z=25)], MissionType.RALLY)
    with mock(flavour="px4") as m, PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
        report = upload_plan(b, [mission(10), fence, rally])
        assert [p.mission_type for p in report.parts] == [0, 1, 2] and report.verified
        assert len(m.mission(1, MissionType.FENCE)) == 3 and len(m.mission(1, MissionType.RALLY)) == 1
        b.set_current(4)
        assert m.vehicle(1).flight.state.current == 4
        b.clear(MissionType.FENCE)
        assert m.mission(1, MissionType.FENCE) == [] and len(m.mission(1)) == 10
        b.clear(MissionType.ALL)
        assert m.mission(1) == [] and m.mission(1, MissionType.RALLY) == []
        assert b.download(MissionType.MISSION) == []
        upload_plan(b, [mission(5)])
        upload_plan(b, [Mission([])])  # an empty upload clears
        assert m.mission(1) == []


def test_three_vehicles_on_one_udp_port_each_get_their_own_mission() -> None:
    with mock(sysids=[1, 2, 3]) as m:
        missions = {sysid: mission(10 + 5 * sysid, lat=45.0 + sysid) for sysid in (1, 2, 3)}
        for sysid in (2, 1, 3):
            with PymavlinkBackend(m.client_url, sysid, timeouts=FAST, connect_timeout=3) as b:
                assert upload_plan(b, [missions[sysid]]).verified
        for sysid in (1, 2, 3):
            with PymavlinkBackend(m.client_url, sysid, timeouts=FAST, connect_timeout=3) as b:
                got = b.download(MissionType.MISSION)
                sent = to_wire(missions[sysid], Flavour.ARDUPILOT)
                assert compare_wire(sent, got, skip_home=True, flavour=Flavour.ARDUPILOT) == []
        assert {s: m.vehicle(s).uploads_completed for s in (1, 2, 3)} == {1: 1, 2: 1, 3: 1}


def test_tcp_link_and_legacy_requests() -> None:
    with mock(listen="tcpin:127.0.0.1:0", flavour="ardupilot") as m:
        assert m.vehicle(1).options.legacy_requests  # ArduCopter asks with MISSION_REQUEST (#40)
        with PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
            assert m.client_url.startswith("tcp:127.0.0.1:")
            assert upload_plan(b, [mission(25)]).verified


def test_result_codes_become_clear_messages() -> None:
    with mock(flavour="px4", max_items=20) as m, PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
        upload_plan(b, [mission(8)])
        before = m.mission(1)
        cases = [
            (mission(30), 4, "no space for this many items"),
            (Mission([MissionItem(CMD_NAV_WAYPOINT, 99, x=1, y=1)]), 2,  # raw: no MAV_FRAME is 99
             "coordinate frame the vehicle does not support"),
            (Mission([MissionItem(999, FRAME_GLOBAL_RELATIVE_ALT, x=45.0, y=7.0)]), 3,  # raw: not a command PX4 knows
             "command or mission type the vehicle does not support"),
        ]
        for bad, code, text in cases:
            with pytest.raises(MissionTransferError) as err:
                b.upload(0, to_wire(bad, Flavour.PX4))
            assert err.value.result == code and text in str(err.value) and "vehicle 1" in str(err.value)
            assert m.mission(1) == before  # a refused upload leaves the old mission
    # PX4 takes a latitude of 95 degrees as sent (measured on SIH); ArduPilot refuses it with INVALID_PARAM5_X.
    with mock(flavour="ardupilot") as m, PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
        with pytest.raises(MissionTransferError) as err:
            b.upload(0, to_wire(Mission([MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=95.0, y=7.0)]),
                                Flavour.ARDUPILOT))
        assert err.value.result == 10 and "invalid x / latitude" in str(err.value)


def test_stalled_upload_leaves_the_old_mission_and_the_vehicle_gives_up() -> None:
    with mock(flavour="px4", upload_timeout=0.3) as m:
        with PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
            upload_plan(b, [mission(6)])
        before = m.mission(1)
        with Link(m.client_url) as link:
            vehicle = wait_vehicle(link, 1, timeout=3)
            link.mav.mission_count_send(1, 1, 50, 0)  # start an upload, then walk away
            deadline = time.monotonic() + 3
            acks = []
            while time.monotonic() < deadline and not acks:
                msg = link.recv(deadline)
                if msg is not None and msg.get_type() == "MISSION_ACK":
                    acks.append(int(msg.type))
            assert acks == [15]  # OPERATION_CANCELLED after the vehicle's time-out
            assert vehicle.flavour is Flavour.PX4
        assert m.mission(1) == before


def test_reboot_mid_upload_fails_clearly_and_the_next_upload_succeeds() -> None:
    with mock(flavour="ardupilot") as m, PymavlinkBackend(m.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
        m.reboot_after_items(1, 12, offline=0.3)
        start = time.monotonic()
        with pytest.raises(MissionTransferError) as err:
            b.upload(0, to_wire(mission(40), Flavour.ARDUPILOT))
        assert "rebooted" in str(err.value) and "did not complete" in str(err.value)
        # Given up on the reboot, not after every retry of every item (40 x 5 x 0.2 s); generous for a busy machine.
        assert time.monotonic() - start < 8
        assert m.vehicle(1).reboots == 1 and len(m.mission(1)) == 1  # it forgot everything but home
        assert upload_plan(b, [mission(40)]).verified


def test_unreachable_sysid_fails_within_the_timeout_naming_it() -> None:
    with mock(sysids=[1]) as m:
        with Link(m.client_url) as link:
            start = time.monotonic()
            with pytest.raises(BridgeError) as err:
                wait_vehicle(link, 9, timeout=0.6)
            assert time.monotonic() - start < 5  # its own 0.6 s, not the default 10 s; generous for a busy machine
            assert "system 9" in str(err.value) and "heard only system 1 component 1" in str(err.value)


def test_lossy_link_with_duplicates_and_reordering_small() -> None:
    faults = LinkFaults.lossy(0.2, duplicate=0.1, reorder=0.1, seed=7)
    with mock(flavour="px4", faults=faults, request_interval=0.01) as m:
        with PymavlinkBackend(m.client_url, 1, timeouts=Timeouts(item_timeout=0.1, retries=30), connect_timeout=5) as b:
            assert upload_plan(b, [mission(60)]).verified
        assert m.stats["dropped_in"] > 0 and m.stats["dropped_out"] > 0


def test_download_survives_out_of_order_requests() -> None:
    with mock(flavour="px4") as m, Link(m.client_url) as link:
        vehicle = wait_vehicle(link, 1, timeout=3)
        client = MissionClient(link, vehicle, FAST)
        client.upload(0, to_wire(mission(12), Flavour.PX4))
        for seq in (7, 2, 11, 7):  # any in-range item, in any order, any number of times
            link.mav.mission_request_int_send(1, 1, seq, 0)
        got: list[int] = []
        deadline = time.monotonic() + 2
        while len(got) < 4 and time.monotonic() < deadline:
            msg = link.recv(deadline)
            if msg is not None and msg.get_type() == "MISSION_ITEM_INT":
                got.append(int(msg.seq))
        assert got == [7, 2, 11, 7]
        assert math.isclose(m.mission(1)[7].x / 1e7, 45.07 + 6e-4, abs_tol=1e-7)


def test_uploader_serves_out_of_order_and_repeated_requests() -> None:
    """A scripted vehicle asks 0, 2, 1, 1 (legacy), 3, 3 and acknowledges: each answer is the item asked for."""
    from missionplan.bridge.link.connection import parse_url
    from missionplan.bridge.sim.mock import MockAutopilot as _Probe

    probe = _Probe(listen="udpin:127.0.0.1:0")
    port = probe.port
    probe.close_sockets()
    vehicle_link = Link(f"udpin:127.0.0.1:{port}", source_system=3, source_component=1)
    gcs = Link(f"udpout:127.0.0.1:{port}")
    assert parse_url(f"udpout:127.0.0.1:{port}").port == port
    answers: list[tuple[int, int]] = []
    wire = to_wire(mission(4), Flavour.PX4)

    def vehicle() -> None:
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:  # heartbeat until the ground station's count arrives
            vehicle_link.mav.heartbeat_send(2, 12, 0, 0, 3)
            msg = vehicle_link.recv(time.monotonic() + 0.1)
            if msg is not None and msg.get_type() == "MISSION_COUNT":
                break
        for seq, legacy in ((0, False), (2, False), (1, False), (1, True), (3, False), (3, False)):
            if legacy:
                vehicle_link.mav.mission_request_send(255, 190, seq, 0)
            else:
                vehicle_link.mav.mission_request_int_send(255, 190, seq, 0)
            while time.monotonic() < deadline:
                msg = vehicle_link.recv(deadline)
                if msg is not None and msg.get_type() == "MISSION_ITEM_INT":
                    answers.append((seq, int(msg.seq)))
                    break
        vehicle_link.mav.mission_ack_send(255, 190, 0, 0)

    import threading

    thread = threading.Thread(target=vehicle)
    thread.start()
    try:
        info = wait_vehicle(gcs, 3, timeout=3)
        MissionClient(gcs, info, FAST).upload(0, wire)
    finally:
        thread.join(5)
        gcs.close()
        vehicle_link.close()
    assert answers == [(0, 0), (2, 2), (1, 1), (1, 1), (3, 3), (3, 3)]


def test_connection_strings() -> None:
    from missionplan.bridge import BridgeUsageError
    from missionplan.bridge.link.connection import parse_sysids, parse_url

    assert parse_url("udpin:0.0.0.0:14550").url == "udpin:0.0.0.0:14550"
    assert parse_url("udp:127.0.0.1:14550").scheme == "udpin"
    assert parse_url("tcp:127.0.0.1:5760").port == 5760
    serial = parse_url("/dev/ttyUSB0,57600")
    assert (serial.scheme, serial.device, serial.baud) == ("serial", "/dev/ttyUSB0", 57600)
    assert parse_url("/dev/ttyACM0").baud == 115200
    for bad in ("", "udpin:127.0.0.1", "udpin:127.0.0.1:0", "tcp:host:99999", "ws://x", "COM"):
        with pytest.raises(BridgeUsageError):
            parse_url(bad)
    assert parse_sysids("1, 2,3") == [1, 2, 3]
    with pytest.raises(BridgeUsageError):
        parse_sysids("1,255")
