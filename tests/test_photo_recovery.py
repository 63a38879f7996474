"""Photos recovered from the vehicle's onboard log (missionplan.bridge.transfer.onboard_log) against the mock autopilot.

The mock's ArduPilot flavour keeps a DataFlash log of its flights (missionplan.bridge.sim.mock_log: one CAM per
photo) and serves it as ArduCopter does (LOG_REQUEST_LIST / DATA / END). A flight whose
CAMERA_FEEDBACK reports are lost for a while (the link drops every packet the vehicle sends) still
yields every photo, at the very position the mock took it; lost LOG_DATA chunks and lost requests are
asked for again; a vehicle without a log, an armed one and a PX4 one say so in one line.

Mocks listen on 127.0.0.1 only, on ports picked at run time; every wait is bounded.
"""

from __future__ import annotations

import math
import struct
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink import DFReader

from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.formats.mission_items import Flavour, Mission, MissionItem
from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.sim.mock_log import CAM, DataFlashWriter, gps_week_ms
from missionplan.bridge.transfer.onboard_log import (LogClient, LoggedPhoto, LogTransferError, read_dataflash_photos,
                                recover_photos)
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.formats.px4_rules import px4_millimetres
from missionplan.bridge.link.shared_link import SharedLink
from missionplan.bridge.transfer.uploader import open_backend, upload_plan

HOME = (45.0, 7.0, 200.0)
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS
FAST = Timeouts(item_timeout=0.2, retries=10)
ALT = 10.0


def _waypoint(north: float) -> MissionItem:
    return MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=0.5,
                       x=HOME[0] + north / M_PER_DEG_LAT, y=HOME[1], z=ALT)


def _survey(trigger_m: float, north: float) -> Mission:
    """Take off, photos every trigger_m metres on a leg north and back, return to launch."""
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0], y=HOME[1],
                         z=ALT),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=trigger_m),
             _waypoint(north),
             _waypoint(0.0),
             MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, param1=0.0),
             MissionItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)]
    return Mission(items, home=HOME)


def _mock(**kw: Any) -> MockAutopilot:
    kw.setdefault("homes", {1: HOME})
    kw.setdefault("request_interval", 0.02)
    kw.setdefault("upload_timeout", 2.0)
    kw.setdefault("speedup", 20.0)
    return MockAutopilot("udpin:127.0.0.1:0", **kw)


def _command(link: Any, command: int, *params: float, timeout: float = 3.0) -> int:
    result = link.command_long(1, command, list(params), time.monotonic() + timeout)
    assert result is not None, f"no COMMAND_ACK for command {command} within {timeout} s"
    return result


def _fly(mock: MockAutopilot, link: Any, timeout: float, while_flying: Any = None) -> list[Any]:
    """Arm, start, collect system 1's messages until it has finished its mission and disarmed;
    while_flying(msgs) is called with what came so far, after each message."""
    assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0) == 0
    assert _command(link, mavlink.MAV_CMD_MISSION_START, 0.0, 0.0) == 0
    msgs: list[Any] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = link.recv(min(deadline, time.monotonic() + 0.1))
        if msg is not None and msg.get_srcSystem() == 1:
            msgs.append(msg)
            if while_flying is not None:
                while_flying(msgs)
        state = mock.vehicle(1).flight.state
        if state.mission_done and not state.armed:
            return msgs
    raise AssertionError(f"the mock did not finish its mission within {timeout} s")


def _uploaded(mock: MockAutopilot, mission: Mission) -> Any:
    backend = open_backend("pymavlink", mock.client_url, 1, timeouts=FAST, connect_timeout=3.0)
    assert upload_plan(backend, [mission], verify=True).verified
    return backend


def _truth(mock: MockAutopilot, first: int = 0) -> dict[int, tuple[int, int, float]]:
    """img_idx -> (lat e7, lon e7, altitude above home) of every photo the mock took: rounded to 1e-7
    degree as ArduPilot stores positions, truncated as PX4 casts them into CAMERA_IMAGE_CAPTURED."""
    e7 = (lambda deg: int(deg * 1e7)) if mock.flavour is Flavour.PX4 else (lambda deg: int(round(deg * 1e7)))
    points = mock.vehicle(1).flight.state.photo_points
    return {first + k: (e7(lat), e7(lon), alt) for k, (lat, lon, alt) in enumerate(points)}


def _assert_equal(photos: list[LoggedPhoto], truth: dict[int, tuple[int, int, float]]) -> None:
    assert [p.img_idx for p in photos] == sorted(truth)
    for p in photos:
        lat, lon, alt = truth[p.img_idx]
        assert (p.lat_e7, p.lon_e7) == (lat, lon), p
        assert p.alt_rel == pytest.approx(alt, abs=0.006)  # logged in whole centimetres
        assert p.alt_amsl == pytest.approx(HOME[2] + alt, abs=0.006)


# ------------------------------------------------------------------------------------- the log itself
def test_the_mocks_dataflash_log_reads_back_with_pymavlinks_dfreader(tmp_path: Path) -> None:
    writer = DataFlashWriter()
    week, week_ms = gps_week_ms(1_700_000_000.0)
    writer.write(CAM, 12_345_678, 0, 7, week_ms, week, 450000123, 70000456, 21012, 1012, 21012, -150, 275, 35999)
    path = tmp_path / "x.BIN"
    path.write_bytes(bytes(writer.data))
    reader = DFReader.DFReader_binary(str(path), zero_time_base=True)
    cam = reader.recv_match(type="CAM")
    assert cam is not None and reader.recv_match(type="CAM") is None
    # ArduPilot's CAM record: 46 bytes, its format and columns (AP_Camera/LogStructure.h).
    assert cam.fmt.len == 46 and cam.fmt.format == "QBHIHLLeeeccC"
    assert (cam.Img, cam.Alt, cam.RelAlt, cam.R, cam.P, cam.Y) == (7, 210.12, 10.12, -1.5, 2.75, 359.99)
    [photo] = read_dataflash_photos(path, log_id=3)
    assert (photo.img_idx, photo.lat_e7, photo.lon_e7, photo.log_id) == (7, 450000123, 70000456, 3)
    assert photo.time_boot_s == pytest.approx(12.345678)
    assert photo.utc_s == pytest.approx(1_700_000_000.0, abs=1e-3)  # GPS week and ms back to UTC
    assert struct.unpack_from("<BB", writer.data) == (0xA3, 0x95)


# ------------------------------------------------------------------------------------- recovery
@pytest.mark.flight
def test_photos_whose_reports_were_lost_come_back_from_the_log() -> None:
    with _mock() as mock:
        backend = _uploaded(mock, _survey(2.0, 60.0))
        try:
            link = backend.link
            state: dict[str, Any] = {"dropped_from": None}

            def drop_for_a_while(msgs: list[Any]) -> None:
                # After the third report, the vehicle's every packet is lost until it took 8 more photos.
                reports = sum(m.get_type() == "CAMERA_FEEDBACK" for m in msgs)
                if state["dropped_from"] is None and reports >= 3:
                    state["dropped_from"] = mock.vehicle(1).flight.state.photos
                    mock.set_faults(LinkFaults(loss_out=1.0))
                    assert mock.wait_until(lambda m: m.vehicle(1).flight.state.photos >= state["dropped_from"] + 8,
                                           timeout=5.0)
                    mock.set_faults(LinkFaults())

            msgs = _fly(mock, link, 15.0, drop_for_a_while)
            reported = {int(m.img_idx) for m in msgs if m.get_type() == "CAMERA_FEEDBACK"}
            truth = _truth(mock)
            lost = set(truth) - reported
            assert len(lost) >= 8 and len(truth) >= 50, (len(lost), len(truth))
            recovered = recover_photos(link, 1, "ardupilot", time.monotonic() + 10.0, wanted=lost)
            _assert_equal(recovered, {k: truth[k] for k in lost})
            everything = recover_photos(link, 1, "ardupilot", time.monotonic() + 10.0)
            _assert_equal(everything, truth)
        finally:
            backend.close()
    assert all(p.message == "CAM" and p.log_id == 1 for p in everything)
    times = [p.time_boot_s for p in everything]
    assert times == sorted(times) and times[0] > 0


@pytest.mark.flight
def test_lost_chunks_and_lost_requests_are_asked_for_again(tmp_path: Path) -> None:
    with _mock() as mock:
        backend = _uploaded(mock, _survey(1.0, 80.0))
        try:
            _fly(mock, backend.link, 15.0)
        finally:
            backend.close()
        truth = _truth(mock)
        mock.set_faults(LinkFaults.lossy(0.2, seed=5))  # a fifth of every packet, each way
        with Link(mock.client_url) as link:
            client = LogClient(link, 1)
            [entry] = client.list_logs(time.monotonic() + 10.0)
            seen: list[tuple[int, int]] = []
            data = client.download(entry, time.monotonic() + 20.0,
                                   progress=lambda done, total: seen.append((done, total)))
            client.end()
        assert mock.stats["dropped_out"] > 20 and mock.stats["dropped_in"] > 0
    assert len(data) == entry.size == len(mock.vehicle(1).logs.logs[0].writer.data)
    assert data == bytes(mock.vehicle(1).logs.logs[0].writer.data)
    assert client.requests > 1  # the gaps were asked for again
    assert seen[-1] == (entry.size, entry.size) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    (tmp_path / "log.BIN").write_bytes(data)
    _assert_equal(read_dataflash_photos(tmp_path / "log.BIN"), truth)


@pytest.mark.flight
def test_over_a_shared_link_with_the_log_kept_and_two_flights_in_two_logs(tmp_path: Path) -> None:
    """A download ends the open log (as ArduPilot's does): the next flight writes a new one. The
    newest holds the second flight; older ones are read only for indices still missing."""
    utc = [1_700_000_000.0]  # the vehicle's UTC clock, which dates its logs (LOG_ENTRY time_utc)
    with _mock() as mock:
        mock.vehicle(1).logs.wall = lambda: utc[0]
        backend = _uploaded(mock, _survey(2.0, 30.0))
        try:
            _fly(mock, backend.link, 15.0)
            first = _truth(mock)
            assert len(recover_photos(backend.link, 1, "ardupilot", time.monotonic() + 10.0)) == len(first)
            utc[0] += 600.0  # the second flight, ten minutes later
            start = utc[0]
            _fly(mock, backend.link, 15.0)
        finally:
            backend.close()
        second = {k: v for k, v in _truth(mock).items() if k not in first}  # img_idx counts on
        assert second and min(second) == max(first) + 1
        with SharedLink(mock.client_url) as shared:
            view = shared.vehicle(1)
            newest = recover_photos(view, 1, "ardupilot", time.monotonic() + 10.0, save_dir=tmp_path)
            both = recover_photos(view, 1, "ardupilot", time.monotonic() + 10.0, wanted={0, max(second)})
            recent = recover_photos(view, 1, "ardupilot", time.monotonic() + 10.0, wanted={0, max(second)},
                                    since_utc=start)
    _assert_equal(newest, second)
    assert {p.log_id for p in newest} == {2} and (tmp_path / "log2.BIN").stat().st_size > 0
    _assert_equal(both, {0: first[0], max(second): second[max(second)]})
    assert [p.log_id for p in both] == [1, 2]
    assert [p.img_idx for p in recent] == [max(second)]  # log 1 was last written before the second flight


@pytest.mark.flight
def test_two_flights_in_one_log_are_told_apart_by_their_gps_time() -> None:
    """Without a reboot or a download in between, ArduPilot logs the next flight into the same log;
    since_utc (the flight's start) leaves the earlier flight's photos out."""
    utc = [1_700_000_000.0]
    with _mock() as mock:
        mock.vehicle(1).logs.wall = lambda: utc[0]
        backend = _uploaded(mock, _survey(2.0, 30.0))
        try:
            _fly(mock, backend.link, 15.0)
            first = _truth(mock)
            utc[0] += 600.0
            _fly(mock, backend.link, 15.0)
            both = recover_photos(backend.link, 1, "ardupilot", time.monotonic() + 10.0)
            second = recover_photos(backend.link, 1, "ardupilot", time.monotonic() + 10.0, since_utc=utc[0])
        finally:
            backend.close()
        truth = _truth(mock)
    assert {p.log_id for p in both} == {1} and len(mock.vehicle(1).logs.logs) == 1
    _assert_equal(both, truth)
    _assert_equal(second, {k: v for k, v in truth.items() if k not in first})


def test_a_vehicle_without_a_log_says_so_in_one_line() -> None:
    with _mock() as mock, Link(mock.client_url) as link:
        with pytest.raises(LogTransferError) as err:
            recover_photos(link, 1, "ardupilot", time.monotonic() + 5.0)
    assert str(err.value).startswith("vehicle 1 has no onboard log: ArduPilot logs only while armed")
    assert "\n" not in str(err.value)


def test_an_armed_vehicle_answers_disarm_for_log_download() -> None:
    with _mock() as mock, Link(mock.client_url) as link:
        assert _command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0) == 0
        assert mock.wait_until(lambda m: m.vehicle(1).logs.open_log is not None, timeout=2.0)
        started = time.monotonic()
        with pytest.raises(LogTransferError) as err:
            recover_photos(link, 1, "ardupilot", time.monotonic() + 5.0)
        assert time.monotonic() - started < 2.0  # its refusal ends the wait, not the deadline
    assert str(err.value) == ('vehicle 1 is armed: it sends its logs only when disarmed (after landing); '
                              'it said "Disarm for log download"')


@pytest.mark.flight
def test_px4_photos_come_back_from_its_ulog_when_it_logs() -> None:
    """PX4 with its logger on (SDLOG_MODE 0, PX4's default) writes a ULog from arming to disarming;
    its camera_capture messages are the photos CAMERA_IMAGE_CAPTURED reported, lost or not."""
    with _mock(flavour="px4") as mock:
        mock.vehicle(1).logs.logging = True
        backend = _uploaded(mock, _survey(2.0, 40.0))
        try:
            state: dict[str, Any] = {"dropped": False}

            def drop_for_a_while(msgs: list[Any]) -> None:
                if not state["dropped"] and sum(m.get_type() == "CAMERA_IMAGE_CAPTURED" for m in msgs) >= 2:
                    state["dropped"] = True
                    mock.set_faults(LinkFaults(loss_out=1.0))
                    assert mock.wait_until(lambda m: m.vehicle(1).flight.state.photos >= 12, timeout=5.0)
                    mock.set_faults(LinkFaults())

            msgs = _fly(mock, backend.link, 15.0, drop_for_a_while)
            reports = {int(m.image_index): m for m in msgs if m.get_type() == "CAMERA_IMAGE_CAPTURED"}
            photos = recover_photos(backend.link, 1, "px4", time.monotonic() + 10.0)
        finally:
            backend.close()
        truth = _truth(mock)
    assert len(truth) - len(reports) >= 8  # lost on the link
    _assert_equal(photos, truth)
    assert all(p.message == "camera_capture" and p.log_id == 0 for p in photos)  # PX4 counts its logs from 0
    for k, m in reports.items():  # the log's copy of a report that came is that report
        assert (photos[k].lat_e7, photos[k].lon_e7) == (int(m.lat), int(m.lon))
        assert px4_millimetres(photos[k].alt_amsl) == int(m.alt)


def test_px4_mock_has_no_log_like_px4_sih_with_its_logger_off() -> None:
    with _mock(flavour="px4") as mock, Link(mock.client_url) as link:
        with pytest.raises(LogTransferError) as err:
            recover_photos(link, 1, "px4", time.monotonic() + 5.0)
    assert str(err.value) == ("vehicle 1 has no onboard log: PX4 logs only with its logger on (SDLOG_MODE 0..3; "
                              "-1 turns it off)")


def test_a_silent_vehicle_is_a_bounded_failure() -> None:
    with _mock() as mock, Link(mock.client_url) as link:
        mock.set_faults(LinkFaults(loss_in=1.0))  # it hears nothing we send
        started = time.monotonic()
        with pytest.raises(LogTransferError) as err:
            recover_photos(link, 1, "ardupilot", time.monotonic() + 3.0)
        assert time.monotonic() - started < 4.5
    assert str(err.value) == "vehicle 1 did not answer LOG_REQUEST_LIST"
