"""Flight that survives what goes wrong, against in-process mock autopilots (the fast suite's share of
sitl_tests/test_fly_faults_sitl.py): a `fly` killed mid-flight loses nothing journaled, a plain `fly`
touches no vehicle that is flying, `fly --resume` re-attaches and judges the whole flight, Ctrl-C stops
following and commands nothing (or what --on-abort says), and a link gap is a gap, not an end.

`fly` runs in a child process where a test kills or interrupts it (SIGKILL as a crash, SIGINT as
Ctrl-C); the mock fleet runs here and is the ground truth (what the vehicles did, were sent, took)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from missionplan.bridge.sim.mock import LinkFaults
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.journal_read import read_flight
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.testing.loopback import wait_until

pytestmark = pytest.mark.flight  # flies mock autopilots: `pytest -m "not flight"` leaves it out

ROOT = Path(__file__).resolve().parent.parent
SPEEDUP = 2.0  # Leonardo's 3-drone missions, about 60 s planned each: 30 s of wall time
SYSIDS = (1, 2, 3)


@pytest.fixture(scope="module")
def leonardo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leonardo-3")
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    return out


def _copy(plan: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "plan"
    copy.mkdir()
    for path in plan.iterdir():
        (copy / path.name).write_bytes(path.read_bytes())
    return copy


def _fly_process(plan_dir: Path, url: str, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "missionplan", "fly", str(plan_dir), "--connect", url,
                             "--time-scale", str(SPEEDUP), "--timeout", "120", *extra],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})


def _in_flight(mock, item: int, timeout: float = 60.0) -> bool:
    """Until every vehicle is armed in AUTO at mission item `item` or later (bounded)."""
    return mock.wait_until(lambda m: all(v.flight.state.armed and v.flight.state.mode == "AUTO"
                                         and v.flight.state.current >= item for v in m.vehicles.values()), timeout)


def _finished(mock, timeout: float = 120.0) -> bool:
    return mock.wait_until(lambda m: all(v.flight.state.mission_done and not v.flight.state.armed
                                         for v in m.vehicles.values()), timeout)


def test_a_killed_fly_keeps_its_journal_a_plain_fly_touches_no_flying_vehicle_and_resume_finishes(
        leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    try:
        crashed = _fly_process(plan_dir, mock.client_url, "--quiet")
        assert _in_flight(mock, 8), "the fleet never got going"
        crashed.send_signal(signal.SIGKILL)  # a laptop crash
        crashed.wait(10)
        # Nothing journaled before the crash is lost: the mission start and the positions up to it.
        _, _, kept = read_flight(plan_dir)
        assert all(rec.started and len(rec.samples) > 10 for rec in kept) and any(rec.camera for rec in kept), \
            [(rec.id, rec.started, len(rec.samples), len(rec.camera)) for rec in kept]
        assert not (plan_dir / "flight.json").exists()
        uploads = {k: mock.vehicle(k).uploads_completed for k in SYSIDS}

        # A plain fly finds them armed: it sends them nothing and says so, one line each.
        plain = fly(plan_dir, mock.client_url, timeout_s=60, progress=False, time_scale=SPEEDUP)
        assert not plain.ok
        armed = [p for p in plain.problems if "is ARMED" in p and "nothing was sent to it" in p]
        assert sorted(p.split(":")[0] for p in armed) == [f"uav{k}" for k in SYSIDS], plain.problems
        assert {k: mock.vehicle(k).uploads_completed for k in SYSIDS} == uploads
        assert all(v.flight.state.mode == "AUTO" and v.flight.state.armed for v in mock.vehicles.values())

        # fly --resume follows the flight the crashed run started, to the end, and judges all of it.
        resumed = fly(plan_dir, mock.client_url, timeout_s=120, progress=False, time_scale=SPEEDUP, resume=True)
        assert _finished(mock, 10.0)
    finally:
        mock.stop()
    doc = json.loads((plan_dir / "flight.json").read_text())
    assert all(d["finished"] for d in doc["drones"]), doc["problems"]
    assert {k: mock.vehicle(k).uploads_completed for k in SYSIDS} == uploads  # nothing uploaded again
    taken = {k: mock.vehicle(k).flight.state.photos for k in SYSIDS}
    assert all(abs(d["photos"] + d["photos_placed_on_track"] - taken[d["id"]]) <= 1 for d in doc["drones"]), \
        (taken, [(d["photos"], d["photos_placed_on_track"]) for d in doc["drones"]])
    assert resumed.ok and doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    # The photos taken while no fly was listening came from the vehicles' logs, not from guesses.
    assert sum(d["photos_from_log"] for d in doc["drones"]) > 0
    assert sum(d["photos_placed_on_track"] for d in doc["drones"]) == 0
    assert any("re-attached" in text for d in doc["drones"] for _, text in d["events"])


def test_ctrl_c_stops_following_writes_the_record_and_commands_nothing(leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP / 2)
    try:
        run = _fly_process(plan_dir, mock.client_url)
        assert _in_flight(mock, 3)
        run.send_signal(signal.SIGINT)
        out, _ = run.communicate(timeout=30)
        assert run.returncode == 1, out
        assert "stopped following: uav1, uav2, uav3 fly on with their missions" in out, out
        assert "Traceback" not in out
        doc = json.loads((plan_dir / "flight.json").read_text())
        assert not any(d["finished"] for d in doc["drones"])
        assert all("fly --resume" in p for p in doc["problems"] if "not followed to the end" in p)
        # The vehicles fly on with their missions: nothing was commanded.
        assert all(v.flight.state.mode == "AUTO" and v.flight.state.armed for v in mock.vehicles.values())
    finally:
        mock.stop()


def test_ctrl_c_with_on_abort_rtl_sends_the_fleet_home(leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP / 2)
    try:
        run = _fly_process(plan_dir, mock.client_url, "--on-abort", "rtl", "--quiet")
        assert _in_flight(mock, 3)
        run.send_signal(signal.SIGINT)
        out, _ = run.communicate(timeout=30)
        assert "commanded RTL: accepted" in out, out
        # Failed twice in slow hours with nothing else to read: say what each vehicle was doing and what fly said.
        assert mock.wait_until(lambda m: all(v.flight.state.mode == "RTL" for v in m.vehicles.values()), 5.0), (
            {k: (v.flight.state.mode, v.flight.state.armed) for k, v in mock.vehicles.items()}, out)
    finally:
        mock.stop()


def test_a_link_gap_is_a_gap_and_its_photos_are_read_from_the_vehicles(leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    result: list = []
    flying = threading.Thread(target=lambda: result.append(
        fly(plan_dir, mock.client_url, timeout_s=120, progress=False, time_scale=SPEEDUP)))
    try:
        flying.start()
        assert _in_flight(mock, 3)
        mock.set_faults(LinkFaults.lossy(1.0))  # every packet lost, both ways...
        # ...until fly has said, for every drone, that its link is lost (journaled as it is said).
        assert wait_until(lambda: all(any("alert: link lost" in text for _, text in rec.events)
                                      for rec in read_flight(plan_dir)[2]), 20.0)
        mock.set_faults(LinkFaults())
        flying.join(120)
    finally:
        mock.stop()
    doc = json.loads((plan_dir / "flight.json").read_text())
    assert result and result[0].ok, doc["problems"]
    assert all(d["finished"] for d in doc["drones"])
    events = [text for d in doc["drones"] for _, text in d["events"]]
    assert any("alert: link lost" in text for text in events) and any("alert: link back" in text for text in events)
    assert sum(d["photos_from_log"] for d in doc["drones"]) > 0
    assert sum(d["photos_placed_on_track"] for d in doc["drones"]) == 0
    assert doc["coverage"] >= 99.0


def test_flight_json_is_judged_from_the_journal(leonardo: Path, tmp_path: Path) -> None:
    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, SPEEDUP * 5)
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=120, progress=False, time_scale=SPEEDUP * 5)
    finally:
        mock.stop()
    assert result.ok
    doc = json.loads((plan_dir / "flight.json").read_text())
    _, _, records = read_flight(plan_dir)
    assert [len(rec.samples) for rec in records] == [d["samples"] for d in doc["drones"]]
    assert [len(rec.camera) for rec in records] == [d["photos"] for d in doc["drones"]]
    missed = json.loads((plan_dir / "missed.geojson").read_text())
    assert missed["features"][0]["properties"]["cells"] == len(doc["missed_cells"])
    assert all(d["last_position"] and abs(d["last_position"]["up_m"]) < 1.0 for d in doc["drones"])


# ------------------------------------------------------------------------------ the faults real autopilots have
# (missionplan.bridge.sim.mock: kill, ArduCopter's battery failsafe, another ground station's upload;
# tests/test_mock_faults.py checks them at the MAVLink level). A high speedup: fly waits planned x 1.5 + 60 s of vehicle
# time for a silent vehicle, and the failsafe's timer and RTL run on the vehicle's clock.
FAST = 10.0
OTHER_GCS = 250  # another ground station's system id (fly speaks as 255)


def _fly_cli(plan_dir: Path, url: str, *extra: str, timeout_s: float = 120.0) -> int:
    return main(["fly", str(plan_dir), "--connect", url, "--time-scale", str(FAST), "--timeout", str(timeout_s),
                 "--quiet", *extra])


def _in_thread(target) -> tuple[threading.Thread, list]:
    out: list = []
    thread = threading.Thread(target=lambda: out.append(target()), daemon=True)
    thread.start()
    return thread, out


def _drones(plan_dir: Path) -> tuple[dict, dict[int, dict]]:
    doc = json.loads((plan_dir / "flight.json").read_text())
    return doc, {int(d["id"]): d for d in doc["drones"]}


def _events(drone: dict) -> list[str]:
    return [text for _, text in drone["events"]]


KILLED_TIMEOUT_S = 40.0  # fly's --timeout here: well above the give-up time of a silent vehicle (about 21 s)


def test_a_vehicle_killed_in_flight_is_link_lost_and_the_others_finish(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from missionplan.bridge.link.readiness import ground_distance_m

    plan_dir = _copy(leonardo, tmp_path)
    planned = {int(d["id"]): float(d["flight_s"]) for d in json.loads((plan_dir / "report.json").read_text())["drones"]}
    mock = start_mock_fleet(plan_dir, FAST)
    mock.kill(2, at_item=8)  # its SITL process killed once it reached item 8: silent for good
    started = time.monotonic()
    try:
        code = _fly_cli(plan_dir, mock.client_url, timeout_s=KILLED_TIMEOUT_S)
        took = time.monotonic() - started
        out = capsys.readouterr()
        killed = mock.vehicle(2).flight.state
        assert mock.killed(2) and killed.armed and killed.alt > 1.0
    finally:
        mock.stop()
    text = out.out + out.err
    assert code == 1, text
    assert "uav2: link lost" in text and "Traceback" not in text
    doc, drones = _drones(plan_dir)
    assert drones[1]["finished"] and drones[3]["finished"], doc["problems"]
    assert not drones[2]["finished"] and not drones[2]["ended_early"]
    assert any(e.startswith("alert: link lost") for e in _events(drones[2]))
    assert not any(e.startswith("alert: link back") for e in _events(drones[2]))
    # Its last known position: where it was killed, in the air.
    last = drones[2]["last_position"]
    assert last is not None and last["up_m"] > 1.0
    assert ground_distance_m((last["lat"], last["lon"]), (killed.lat, killed.lon)) < 5.0
    assert abs(last["up_m"] - killed.alt) < 2.0
    # Given up when its mission would be long over, not at the time-out (which a clamped give-up time once did).
    assert any(p.startswith("uav2: link lost for") and "last known position in flight.json" in p
               for p in doc["problems"]), doc["problems"]
    # fly gave it up when its mission would be long over (planned x 1.5 + 60 s of vehicle time), not at --timeout.
    assert took < (planned[2] * 1.5 + 60.0) / FAST + 15.0 < KILLED_TIMEOUT_S, took


def test_a_battery_failsafe_ends_that_drone_at_its_landing_with_the_reason(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from missionplan.bridge.link.connection import Link, wait_vehicle

    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, FAST)
    try:
        with Link(mock.client_url, source_system=OTHER_GCS) as crew:
            wait_vehicle(crew, 2, timeout=5)
            crew.mav.param_set_send(2, 1, b"BATT_FS_LOW_ACT", 2.0, 9)  # RTL, as a team configures it
            assert mock.wait_until(lambda m: m.vehicle(2).params["BATT_FS_LOW_ACT"] == 2.0, 5.0)
            started = time.monotonic()
            flying, code = _in_thread(lambda: _fly_cli(plan_dir, mock.client_url))
            assert mock.wait_until(lambda m: m.vehicle(2).flight.state.current >= 6, 60.0), "uav2 never got going"
            crew.mav.param_set_send(2, 1, b"SIM_BATT_VOLTAGE", 10.0, 9)  # as on SITL: the pack sags
            assert mock.wait_until(lambda m: m.vehicle(2).battery_failsafe == 1, 10.0)
            # RTL, home, landed and disarmed before the end of its mission
            assert mock.wait_until(lambda m: not m.vehicle(2).flight.state.armed, 60.0)
            landed = time.monotonic()
            flying.join(60)
        took = time.monotonic() - started
        vehicle = mock.vehicle(2)
        assert not vehicle.flight.state.mission_done and vehicle.flight.state.on_ground
    finally:
        mock.stop()
    out = capsys.readouterr()
    assert code == [1], out.out + out.err
    doc, drones = _drones(plan_dir)
    assert drones[1]["finished"] and drones[3]["finished"], doc["problems"]
    ended = drones[2]["ended_early"]
    assert not drones[2]["finished"] and ended and "battery" in ended.lower() and "failsafe" in ended.lower(), ended
    assert "Battery 1 is low 10.00V" in ended
    events = _events(drones[2])
    assert any(e.startswith("alert: says: Battery 1 is low 10.00V used ") for e in events), events
    assert "mode RTL" in events
    # fly ended it at its landing, not at a time-out: the whole run lasted little after that landing.
    assert took - (landed - started) < 15.0 and took < 100.0, took
    assert not any("time-out" in p for p in doc["problems"]), doc["problems"]


def _hold_upload(mock, sysid: int):
    """Another ground station (system OTHER_GCS) starts a mission upload to `sysid` and then says nothing:
    the vehicle keeps that transfer (its upload time-out set long) and denies everybody else's."""
    from missionplan.bridge.link.connection import Link, wait_vehicle

    holder = Link(mock.client_url, source_system=OTHER_GCS)
    info = wait_vehicle(holder, sysid, timeout=5)
    holder.mav.mission_count_send(sysid, 1, 3, 0)
    assert mock.wait_until(lambda m: m.vehicle(sysid).upload is not None, 5.0)
    return holder, info


def test_another_ground_station_holding_the_upload_is_named_after_the_retries(
        leonardo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from missionplan.bridge.transfer.protocol import DENIED_TRIES

    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, FAST, upload_timeout=60.0)
    try:
        holder, _ = _hold_upload(mock, 2)
        with holder:
            code = _fly_cli(plan_dir, mock.client_url)
        vehicle = mock.vehicle(2)
    finally:
        mock.stop()
    out = capsys.readouterr()
    text = out.out + out.err
    assert code == 1, text
    assert vehicle.denied_transfers == DENIED_TRIES  # tried again, then given up
    assert vehicle.uploads_completed == 0 and not vehicle.flight.state.armed
    doc, drones = _drones(plan_dir)
    assert drones[1]["finished"] and drones[3]["finished"], doc["problems"]
    said = [p for p in doc["problems"] if p.startswith("uav2:")]
    assert any("another ground station" in p and f"{DENIED_TRIES} times" in p for p in said), said
    assert "another ground station" in text


def test_another_ground_stations_upload_that_finishes_meanwhile_lets_flys_through(
        leonardo: Path, tmp_path: Path) -> None:
    from missionplan.bridge.formats.mission_items import (
        CMD_NAV_WAYPOINT,
        FRAME_GLOBAL_RELATIVE_ALT,
        Flavour,
        Mission,
        MissionItem,
        to_wire,
    )
    from missionplan.bridge.transfer.protocol import MissionClient, Timeouts

    plan_dir = _copy(leonardo, tmp_path)
    mock = start_mock_fleet(plan_dir, FAST, upload_timeout=60.0)
    try:
        holder, info = _hold_upload(mock, 2)
        with holder:
            flying, result = _in_thread(lambda: fly(plan_dir, mock.client_url, timeout_s=120, progress=False,
                                                    time_scale=FAST))
            assert mock.wait_until(lambda m: m.vehicle(2).denied_transfers >= 1, 30.0), "fly was never denied"
            # The other ground station now sends its whole mission (a restart of its own transfer).
            home = mock.vehicle(2).options.home
            theirs = Mission([MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=home[0], y=home[1], z=10.0)],
                             home=home)
            MissionClient(holder, info, Timeouts(item_timeout=0.3)).upload(0, to_wire(theirs, Flavour.ARDUPILOT))
            flying.join(120)
        vehicle = mock.vehicle(2)
    finally:
        mock.stop()
    from missionplan.bridge.transfer.protocol import DENIED_TRIES

    doc, drones = _drones(plan_dir)
    assert result and result[0].ok, doc["problems"]
    assert all(d["finished"] for d in drones.values())
    assert 1 <= vehicle.denied_transfers < DENIED_TRIES
    assert vehicle.uploads_completed >= 2  # theirs, then fly's (and fly's empty fence / rally lists)
    assert drones[2]["held_after_flight"] is True  # it flew fly's mission, not theirs
