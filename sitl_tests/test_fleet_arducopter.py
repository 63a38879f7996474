"""A fleet of 3 ArduCopter SITL vehicles flown as a field team wires it: all into one udpin port.

Each vehicle (system ids 1-3, `--speedup`, its own temp folder, killed in teardown) sends to ONE
ground-station UDP port (`--serial0 udpclient:127.0.0.1:PORT`), its home at its plan's launch point.
The team configures the camera once (PARAM_SET CAM1_TYPE = 1, reboot: without it ArduCopter sends no
CAMERA_FEEDBACK), then `missionplan fly --connect udpin:127.0.0.1:PORT` runs right away: no sleep,
fly itself waits until every vehicle is ready (GPS, EKF, home, pre-arm: 35-40 simulated seconds).

Required: every drone finishes; flown coverage >= 99 % from the vehicles' own CAMERA_FEEDBACK; flown
time (the vehicles' own simulated clock) within 15 % of the plan; the separation promise kept. And
with a plan for another site: fly exits non-zero and no vehicle arms.
Skipped with a reason when ../shared/sitl/arducopter is absent.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from missionplan.bridge.link.connection import mavlink, wait_vehicle
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.link.shared_link import SharedLink
from missionplan.cli import main
from missionplan.testing.arducopter import ArduCopter
from missionplan.testing.loopback import free_udp_port
from missionplan.testing.relay import armed_ever

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

SYSIDS = (1, 2, 3)
# A 120 x 90 m block in Milan (around the SITL fixture's default home), three launch points on its
# southern edge: a small georeferenced plan that flies in about 50 simulated seconds per drone.
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1898", "45.4641,9.1904")
OTHER_SITE = [[7.6519, 45.0656], [7.6534, 45.0656], [7.6534, 45.0664], [7.6519, 45.0664], [7.6519, 45.0656]]
OTHER_LAUNCHES = ("45.0657,7.6520", "45.0657,7.6527", "45.0657,7.6533")  # Turin, 125 km west
FLY_TIMEOUT_S = 420.0
TELEMETRY_HZ = 10.0


def _plan(tmp_path: Path, name: str, ring: list[list[float]], launches: tuple[str, ...]) -> Path:
    area = tmp_path / f"{name}.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    out = tmp_path / name
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(out), "--quiet"]
    for point in launches:
        args += ["--launch", point]
    assert main(args) == 0
    return out


def _home(plan_dir: Path, sysid: int) -> tuple[float, float, float, float]:
    lat, lon, alt = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return (float(lat), float(lon), float(alt), 0.0)


def _fleet(arducopter, homes_from: Path, port: int) -> list[ArduCopter]:
    """Three vehicles into one udpin port, each at its plan's launch point; not waited for."""
    return [arducopter(sysid=k, home=_home(homes_from, k), serial0=f"udpclient:127.0.0.1:{port}", wait=False)
            for k in SYSIDS]


def _configure_camera(url: str) -> None:
    """What a team does once per vehicle: CAM1_TYPE = 1 (servo trigger) and a reboot to apply it."""
    with SharedLink(url) as shared:
        for sysid in SYSIDS:
            view = shared.vehicle(sysid)
            info = wait_vehicle(view, sysid, timeout=60.0)
            assert ParamClient(view, info).set("CAM1_TYPE", 1.0) == 1.0
        for sysid in SYSIDS:
            view = shared.vehicle(sysid)
            result = view.command_long(sysid, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0], time.monotonic() + 10.0)
            assert result == mavlink.MAV_RESULT_ACCEPTED, f"vehicle {sysid} refused the reboot (MAV_RESULT {result})"


def test_three_vehicles_on_one_udpin_port_fly_the_plan(arducopter, tmp_path, capsys) -> None:
    plan_dir = _plan(tmp_path, "milan", AREA, LAUNCHES)
    port = free_udp_port()
    url = f"udpin:127.0.0.1:{port}"
    _fleet(arducopter, plan_dir, port)
    _configure_camera(url)
    code = main(["fly", str(plan_dir), "--connect", url, "--timeout", str(FLY_TIMEOUT_S),
                 "--telemetry-hz", str(TELEMETRY_HZ), "--quiet"])
    out = capsys.readouterr().out
    doc = json.loads((plan_dir / "flight.json").read_text())
    report = json.loads((plan_dir / "report.json").read_text())
    planned = {int(d["id"]): float(d["flight_s"]) for d in report["drones"]}
    rows = {int(d["id"]): d for d in doc["drones"]}
    summary = {k: (rows[k]["finished"], rows[k]["flight_s"], planned[k], rows[k]["photos"]) for k in SYSIDS}
    print(out, summary, doc["problems"], doc["min_separation_m"])
    assert all(rows[k]["finished"] for k in SYSIDS), (doc["problems"], out)
    assert doc["photos_from"] == "camera", doc["photos_from"]  # the vehicles' CAMERA_FEEDBACK
    # At most one photo placed on the track: img_idx 0, which ArduPilot never sends (it counts from 1;
    # the judge does not invent it).
    placed = {k: rows[k]["photos_placed_on_track"] for k in SYSIDS}
    assert all(rows[k]["photos"] > 0 and placed[k] <= 1 for k in SYSIDS), (summary, placed)
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    sep = doc["min_separation_m"]
    assert sep["kept"] is True and sep["3d"] >= sep["planned_3d"] - sep["tolerance"], sep
    assert code == 0, (out, doc["problems"])
    for k in SYSIDS:  # flown in the vehicle's own (simulated) time, within 15 % of the plan
        assert abs(rows[k]["flight_s"] - planned[k]) <= 0.15 * planned[k], summary


def test_a_plan_for_another_site_arms_no_vehicle(arducopter, tmp_path, capsys) -> None:
    here = _plan(tmp_path, "milan", AREA, LAUNCHES)
    elsewhere = _plan(tmp_path, "turin", OTHER_SITE, OTHER_LAUNCHES)
    port = free_udp_port()
    url = f"udpin:127.0.0.1:{port}"
    _fleet(arducopter, here, port)  # the vehicles stand in Milan; the plan is for Turin
    code = main(["fly", str(elsewhere), "--connect", url, "--timeout", "180", "--telemetry-hz", str(TELEMETRY_HZ),
                 "--quiet"])
    out = capsys.readouterr().out
    doc = json.loads((elsewhere / "flight.json").read_text())
    assert code != 0
    # Positions are recorded from the mission start on, which comes only after arming: none of them.
    assert not any(d["finished"] or d["samples"] for d in doc["drones"]), doc["drones"]
    site = [p for p in doc["problems"] if "site check failed" in p]
    assert len(site) == 3 and all(" km from the plan's launch point" in p for p in site), doc["problems"]
    assert "left disarmed" in out, out
    assert armed_ever(url, SYSIDS, 3.0) == set()  # and none armed after fly gave up either
