"""A fleet on one link (missionplan.bridge.link.shared_link, missionplan.bridge.link.connection's udpin routing),
readiness and the site check (missionplan.bridge.link.readiness) against the mock made like ArduCopter SITL, and the
judge's small honesty fixes."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest

from missionplan.bridge.errors import BridgeUsageError
from missionplan.bridge.link.connection import Link, wait_vehicle
from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.link.readiness import (Vehicle, VehicleState, launch_offset_m, request_streams, site_problem,
                                               stream_rates)
from missionplan.bridge.link.shared_link import SharedLink, parse_connects
from missionplan.flight import flight_report as fr
from missionplan.mission.plan_blocks import SeparationPromise
from missionplan.testing.loopback import free_udp_port, wait_until

MILAN = (45.4643, 9.1895, 120.0)


def _senders(port: int, sysids: tuple[int, ...], **options) -> list[MockAutopilot]:
    """One mock per system id, each from its own socket, all sending to one ground-station port."""
    return [MockAutopilot(f"udpout:127.0.0.1:{port}", sysids=[k], homes={k: (MILAN[0] + 0.001 * k, MILAN[1], MILAN[2])},
                          **options).start() for k in sysids]


def test_one_udpin_port_answers_each_vehicle_at_its_own_address() -> None:
    port = free_udp_port()
    mocks = _senders(port, (1, 2, 3))
    try:
        with SharedLink(f"udpin:127.0.0.1:{port}") as shared:
            views = {k: shared.vehicle(k) for k in (1, 2, 3)}
            for k, view in views.items():
                assert wait_vehicle(view, k, timeout=5.0).sysid == k
            assert len(set(shared.link.addresses[k] for k in (1, 2, 3))) == 3
            before = [m.stats["in"] for m in mocks]
            for _ in range(30):
                views[2].mav.param_request_read_send(2, 1, b"WPNAV_RADIUS", -1)
            # Every answer comes back to vehicle 2's queue, none to the others'.
            got = 0
            deadline = time.monotonic() + 3.0
            while got < 30 and (msg := views[2].recv(deadline)) is not None:
                got += msg.get_type() == "PARAM_VALUE"
            assert got == 30
            after = [m.stats["in"] for m in mocks]
        assert after[1] - before[1] >= 30
        # Vehicles 1 and 3 got our 1 Hz heartbeat at most, not vehicle 2's requests (pymavlink's udpin
        # sends every packet to every address it ever heard).
        assert after[0] - before[0] < 10 and after[2] - before[2] < 10
    finally:
        for mock in mocks:
            mock.stop()


def test_cli_upload_to_one_vehicle_of_a_fleet_on_one_udpin_port(tmp_path, capsys) -> None:
    from missionplan.bridge.formats.mission_items import (
        CMD_NAV_RETURN_TO_LAUNCH,
        CMD_NAV_TAKEOFF,
        CMD_NAV_WAYPOINT,
        FRAME_GLOBAL_RELATIVE_ALT,
        FRAME_MISSION,
        Mission,
        MissionItem,
    )
    from missionplan.bridge.formats.missionfile import PlanFile, write_plan
    from missionplan.cli import main

    lat, lon, _ = MILAN
    mission = Mission([MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=10.0)]
                      + [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=lat + 0.0001 * k, y=lon, z=10.0)
                         for k in range(1, 6)]
                      + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=MILAN)
    path = tmp_path / "one.plan"
    write_plan(path, PlanFile(mission=mission))
    port = free_udp_port()
    mocks = _senders(port, (1, 2, 3))
    try:
        # The vehicles are sending before the ground station listens, as in the field.
        assert wait_until(lambda: all(m.stats["out"] > 0 for m in mocks), 5.0)
        code = main(["upload", str(path), "--sysid", "2", "--connect", f"udpin:127.0.0.1:{port}", "--timeout", "5"])
        out = capsys.readouterr().out
        assert code == 0, out
        assert len(mocks[1].mission(2)) == 8  # home + 7
        assert len(mocks[0].mission(1)) == 1 and len(mocks[2].mission(3)) == 1  # only their homes
        assert mocks[0].stats["in"] < 20 and mocks[2].stats["in"] < 20  # heartbeats, not vehicle 2's mission
    finally:
        for mock in mocks:
            mock.stop()


def test_a_shared_link_routes_by_system_id_and_bounds_each_queue() -> None:
    with MockAutopilot(sysids=[1, 2]) as mock:
        with SharedLink(mock.client_url, queue_packets=50) as shared:
            one, two = shared.vehicle(1), shared.vehicle(2)
            assert shared.vehicle(1) is one
            assert wait_vehicle(one, 1, timeout=5.0).sysid == 1
            request_streams(two, 2, {33: 200.0}, time.monotonic() + 5.0)  # 200 Hz positions of vehicle 2
            # Nobody reads vehicle 2's queue meanwhile: it fills, then drops its oldest.
            assert wait_until(lambda: shared.dropped.get(2, 0) > 0, 5.0)
            assert len(shared._queues[2]) == 50
            while (msg := one.recv(time.monotonic() + 0.2)) is not None:
                assert msg.get_srcSystem() == 1


def test_wait_vehicle_on_a_view_names_the_systems_heard_instead() -> None:
    with MockAutopilot(sysids=[7]) as mock, SharedLink(mock.client_url) as shared:
        shared.vehicle(7)
        with pytest.raises(Exception, match="heard only system 7 component 1"):
            wait_vehicle(shared.vehicle(8), 8, timeout=1.5)


def test_a_link_pool_finds_each_vehicle_on_the_link_that_carries_its_heartbeat() -> None:
    from missionplan.bridge.errors import BridgeError
    from missionplan.bridge.link.shared_link import LinkPool

    ports = [free_udp_port(), free_udp_port()]
    mocks = [_senders(port, (k,))[0] for port, k in zip(ports, (1, 2))]
    urls = [f"udpin:127.0.0.1:{port}" for port in ports]
    try:
        with LinkPool(urls) as pool:
            pool.open_all()
            pool.register([1, 2, 9])
            assert pool.vehicle(2, timeout=5.0).url == urls[1]
            assert pool.vehicle(1, timeout=5.0).url == urls[0]
            with pytest.raises(BridgeError, match="no heartbeat from system 9 on any of"):
                pool.vehicle(9, timeout=0.5)
    finally:
        for mock in mocks:
            mock.stop()


def test_parse_connects() -> None:
    assert parse_connects(["udpin:0.0.0.0:14550"]) == ({}, ["udpin:0.0.0.0:14550"])
    by, pooled = parse_connects(["1,2=udpin:127.0.0.1:14550", "3=tcp:127.0.0.1:5760", "udpin:127.0.0.1:14551"])
    assert by == {1: "udpin:127.0.0.1:14550", 2: "udpin:127.0.0.1:14550", 3: "tcp:127.0.0.1:5760"}
    assert pooled == ["udpin:127.0.0.1:14551"]
    for bad, why in ((["1=nowhere"], "not a connection string"), (["1=udpin:a:1", "1=udpin:b:2"], "twice"),
                     (["0=udpin:a:1"], "system ids run from 1 to 254"), ([], "no connection")):
        with pytest.raises(BridgeUsageError, match=why):
            parse_connects(bad)


# -------------------------------------------------------------------------------- readiness
def test_a_sitl_like_mock_streams_nothing_until_asked_and_refuses_arming_until_ready() -> None:
    # 30 simulated seconds at 10x: 3 s of wall time without a GPS fix, EKF position or home.
    with MockAutopilot(sysids=[1], homes={1: MILAN}, speedup=10.0, gps_fix_after=30.0,
                       streams_until_asked=True) as mock, Link(mock.client_url) as link:
        info = wait_vehicle(link, 1, timeout=5.0)
        said: list[str] = []
        vehicle = Vehicle(link, info, said.append)
        assert vehicle.wait_ready(time.monotonic() + 1.0)[0] == "GPS (no GPS_RAW_INT yet)"  # not asked: silent
        assert request_streams(link, 1, stream_rates(10.0), time.monotonic() + 5.0, other=vehicle.take) == []
        missing = vehicle.wait_ready(time.monotonic() + 0.5)
        assert any("3-D GPS fix" in m for m in missing) and any("EKF" in m for m in missing)
        assert "a home position" in missing and "its pre-arm checks" in missing
        armed, why = vehicle.arm(time.monotonic() + 0.5)
        assert not armed and "MAV_RESULT 4" in why and "PreArm: Need Position Estimate" in why
        assert not mock.vehicle(1).flight.state.armed
        assert vehicle.wait_ready(time.monotonic() + 10.0) == []
        assert vehicle.state.home is not None and launch_offset_m(vehicle.state.home[:2], MILAN[:2]) < 0.01
        assert any("waiting for" in line for line in said) and any("ready after" in line for line in said)
        assert any("AHRS: waiting for home" in line for line in said)  # the vehicle's own words, passed on
        armed, why = vehicle.arm(time.monotonic() + 5.0)
        assert armed, why
        assert mock.vehicle(1).flight.state.armed
        assert vehicle.make_safe(time.monotonic() + 5.0).startswith("left disarmed in ")
        assert not mock.vehicle(1).flight.state.armed


def test_arming_is_retried_while_the_vehicle_is_still_getting_ready() -> None:
    with MockAutopilot(sysids=[1], homes={1: MILAN}, speedup=10.0, gps_fix_after=15.0) as mock, \
            Link(mock.client_url) as link:
        vehicle = Vehicle(link, wait_vehicle(link, 1, timeout=5.0))
        armed, why = vehicle.arm(time.monotonic() + 15.0)  # refused (FAILED) at first, then taken
        assert armed, why
        assert mock.vehicle(1).flight.state.armed


def test_site_problem_names_the_distance() -> None:
    state = VehicleState(Flavour.ARDUPILOT, home=(45.4643, 9.1895, 120.0), h_acc_m=1.5)
    assert site_problem(state, (45.46432, 9.1895), 5.0) == ""  # 2.2 m
    near = site_problem(state, (45.4644, 9.1895), 5.0)  # 11 m
    assert "11.1 m from the plan's launch point" in near and "5 m + 1.5 m GPS error" in near
    far = site_problem(state, (45.0703, 7.6869), 5.0)  # Turin
    assert " km from the plan's launch point" in far and "swapped system ids" in far
    assert 120_000 < launch_offset_m((45.4643, 9.1895), (45.0703, 7.6869)) < 130_000
    assert site_problem(VehicleState(Flavour.ARDUPILOT), (45.0, 7.0), 5.0).startswith("no home position")


# -------------------------------------------------------------------------------- the judge
def test_separation_is_not_called_kept_when_fewer_than_two_drones_flew() -> None:
    track = np.column_stack([np.arange(10.0), np.zeros(10), np.arange(10.0), np.full(10, 20.0)])
    promise = SeparationPromise.from_json({"3d": 8.0, "horizontal": 8.0})
    sep = fr._separation(promise, [], {1: track}, {}, 1.0, 10.0)
    assert sep["kept"] is None and sep["3d"] is None and sep["tracks"] == 1


def test_vehicle_clock_of_a_sped_up_simulator_is_brought_to_ours() -> None:
    ours = np.linspace(100.0, 110.0, 101)
    samples = np.zeros((101, 7))
    samples[:, 0] = ours + 0.02 + 0.01 * (np.arange(101) % 3)  # arrival: one-way delay and jitter
    samples[:, 5] = 5.0 + 10.0 * (ours - 100.0)  # the vehicle's clock runs 10x (SITL --speedup 10)
    assert fr.vehicle_rate(samples) == pytest.approx(10.0, rel=1e-3)
    np.testing.assert_allclose(fr.vehicle_clock(samples), ours + 0.02, atol=0.005)


def test_only_a_streams_clock_starting_again_is_a_reboot() -> None:
    # PX4 sends messages whose time_boot_ms is the time of what they report (a setpoint, a photo),
    # seconds old: those must not look like a clock that started again. GLOBAL_POSITION_INT's does.
    from missionplan.bridge.link.connection import Link

    link = Link.__new__(Link)  # the boot tracking alone, without a connection
    link._boot_epoch, link._boot_ms, link._status, link.reboots = {}, {}, {}, {}

    def message(kind: str, boot_ms: int) -> SimpleNamespace:
        return SimpleNamespace(get_type=lambda: kind, get_srcSystem=lambda: 1, time_boot_ms=boot_ms)

    link._track_boot(message("GLOBAL_POSITION_INT", 43_000))
    link._track_boot(message("POSITION_TARGET_GLOBAL_INT", 37_000))  # a setpoint from 6 s ago
    link._track_boot(message("CAMERA_IMAGE_CAPTURED", 40_000))
    assert link.reboots == {}
    link._track_boot(message("GLOBAL_POSITION_INT", 100))  # its clock started again: a reboot
    assert link.reboots == {1: 1}
