"""`fly` against a fleet wired as in the field, without SITL: mocks made like ArduCopter SITL.

Each vehicle is its own mock autopilot with its own socket, all sending to ONE ground-station port
(`udpin:`), as SITL's `--serial0 udpclient:` or a radio fleet does; they stream nothing until asked
and have no GPS fix, EKF position or home, and refuse arming with ArduCopter's PreArm reasons, for
their first simulated seconds. fly is started right away. What this guards against: one socket per
drone on that port (only one would hear anything), no streams asked for, giving up at the first refused
arming, and flying a plan for another site.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.cli import main
from missionplan.testing.loopback import free_udp_port
from missionplan.testing.plans import plan_area

pytestmark = pytest.mark.flight  # flies mock autopilots: `pytest -m "not flight"` leaves it out

SYSIDS = (1, 2, 3)
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1898", "45.4641,9.1904")
SPEEDUP = 10.0
READY_AFTER_S = 20.0  # simulated: 2 s of wall time without GPS, EKF, home or arming


@pytest.fixture(scope="module")
def plan_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plan_area(tmp_path_factory.mktemp("wiring"), AREA, LAUNCHES)


def _launch(plan_dir: Path, sysid: int) -> tuple[float, float, float]:
    lat, lon, alt = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return float(lat), float(lon), float(alt)


def _vehicle(url: str, sysid: int, home: tuple[float, float, float]) -> MockAutopilot:
    """One vehicle made like ArduCopter SITL: its readiness and streams, its flight (the plan's timeline,
    which the separation promise rests on) and its camera, configured as a team does once."""
    return MockAutopilot(url, sysids=[sysid], homes={sysid: home}, speedup=SPEEDUP, gps_fix_after=READY_AFTER_S,
                         streams_until_asked=True, sitl_like=True).start().configure_cameras()


def _fleet(port: int, homes: dict[int, tuple[float, float, float]]) -> list[MockAutopilot]:
    return [_vehicle(f"udpout:127.0.0.1:{port}", k, homes[k]) for k in SYSIDS]


def test_a_fleet_on_one_udpin_port_waits_until_ready_and_flies(plan_dir, tmp_path, capsys) -> None:
    plan = Path(shutil.copytree(plan_dir, tmp_path / "plan"))
    port = free_udp_port()
    mocks = _fleet(port, {k: _launch(plan, k) for k in SYSIDS})
    try:
        code = main(["fly", str(plan), "--connect", f"udpin:127.0.0.1:{port}", "--timeout", "120",
                     "--telemetry-hz", "20", "--quiet"])
    finally:
        for mock in mocks:
            mock.stop()
    out = capsys.readouterr().out
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 0, (out, doc["problems"])
    assert all(d["finished"] and d["held_after_flight"] for d in doc["drones"]), doc["drones"]
    assert doc["coverage"] >= 99.0 and doc["min_separation_m"]["kept"] is True
    # Progress came from the MISSION_CURRENT stream fly asked for, not only from the end.
    assert all(mock.vehicle(k).intervals[42] is not None for mock, k in zip(mocks, SYSIDS))
    assert all(d["items_reached"] > 1 for d in doc["drones"])


def test_a_fleet_on_several_ports_each_vehicle_found_by_its_heartbeat(plan_dir, tmp_path, capsys) -> None:
    plan = Path(shutil.copytree(plan_dir, tmp_path / "plan"))
    ports = [free_udp_port(), free_udp_port()]
    homes = {k: _launch(plan, k) for k in SYSIDS}
    mocks = [_vehicle(f"udpout:127.0.0.1:{ports[0] if k < 3 else ports[1]}", k, homes[k]) for k in SYSIDS]
    try:
        # Vehicles 1 and 2 on the first port, 3 on the second: the first two found by their heartbeats,
        # the third named with SYSID=URL.
        code = main(["fly", str(plan), "--connect", f"udpin:127.0.0.1:{ports[0]}",
                     "--connect", f"3=udpin:127.0.0.1:{ports[1]}", "--timeout", "120", "--quiet"])
    finally:
        for mock in mocks:
            mock.stop()
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 0, doc["problems"]
    assert all(d["finished"] for d in doc["drones"])


def test_swapped_system_ids_arm_no_vehicle(plan_dir, tmp_path, capsys) -> None:
    plan = Path(shutil.copytree(plan_dir, tmp_path / "plan"))
    homes = {k: _launch(plan, k) for k in SYSIDS}
    homes[1], homes[2] = homes[2], homes[1]  # vehicles 1 and 2 stand at each other's launch points
    port = free_udp_port()
    mocks = _fleet(port, homes)
    armed_seen: set[int] = set()
    try:
        code = main(["fly", str(plan), "--connect", f"udpin:127.0.0.1:{port}", "--timeout", "60", "--quiet"])
        for mock, k in zip(mocks, SYSIDS):
            if mock.vehicle(k).flight.state.armed or mock.vehicle(k).reached:
                armed_seen.add(k)
    finally:
        for mock in mocks:
            mock.stop()
    out = capsys.readouterr().out
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 1
    assert armed_seen == set()
    problems = doc["problems"]
    assert sum("site check failed" in p for p in problems) == 2, problems
    assert any(p.startswith("uav1: site check failed: its home") and "swapped system ids" in p for p in problems)
    assert any(p.startswith("uav3: not armed: uav") for p in problems), problems
    assert out.count("left disarmed") == 3, out


def test_a_vehicle_that_never_gets_ready_is_named_with_its_reasons(plan_dir, tmp_path, capsys) -> None:
    plan = Path(shutil.copytree(plan_dir, tmp_path / "plan"))
    port = free_udp_port()
    # Never ready; 2 s of wall time are 60 simulated seconds, in which ArduPilot repeats its PreArm reason.
    mock = MockAutopilot(f"udpout:127.0.0.1:{port}", sysids=list(SYSIDS),
                         homes={k: _launch(plan, k) for k in SYSIDS}, speedup=30.0, gps_fix_after=1e6,
                         streams_until_asked=True).start()
    try:
        code = main(["fly", str(plan), "--connect", f"udpin:127.0.0.1:{port}", "--timeout", "60",
                     "--ready-timeout", "2", "--quiet"])
    finally:
        mock.stop()
    out = capsys.readouterr().out
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 1
    assert not any(v.flight.state.armed for v in mock.vehicles.values())
    for k in SYSIDS:
        assert any(p.startswith(f"uav{k}: not ready to fly within 2 s: still waiting for a 3-D GPS fix")
                   and "the vehicle said: " in p and "PreArm: Need Position Estimate" in p
                   for p in doc["problems"]), doc["problems"]
    assert "separation not measured" in out and out.count("left disarmed") == 3
