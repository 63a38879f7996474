"""A fleet of 3 PX4 SIH vehicles flown as a field team wires PX4: every GCS link into one udpin port.

Each vehicle (instances 0-2, system ids 1-3, its own temp PX4_WORKDIR, logging off, killed in
teardown; sitl_tests/px4.py) starts at its plan's launch point and sends its GCS link to
127.0.0.1:14550, where `missionplan fly --connect udpin:127.0.0.1:14550` listens. The camera is set
up at boot (TRIG_MODE 4: camera_trigger and camera_feedback start, distance-triggered by the
mission's DO_SET_CAM_TRIGG_DIST; TRIG_INTERFACE 3, the SITL default): PX4 then reports each photo
with CAMERA_IMAGE_CAPTURED on the GCS link. `fly` starts right after boot: no sleep, it waits for
each vehicle itself (PX4 refuses arming, TEMPORARILY_REJECTED, until "Ready for takeoff!").

Required: every drone finishes; flown coverage >= 99 % from the vehicles' own CAMERA_IMAGE_CAPTURED;
flown time (the vehicles' own clock) within 15 % of the plan, with every phase (take-off, survey,
return, landing: flight.json `phases`) measured and none far over its plan; the separation promise
kept. And with a plan for another site: fly exits non-zero and no vehicle arms.
Skipped with a reason when ../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

import json
from pathlib import Path

from loopback import armed_ever
from px4 import GCS_URL, px4, px4_or_skip  # noqa: F401  (the fixture)

from bridge.missionfile import read_mission_file
from bridge.px4 import reported_items
from missionplan.cli import main
from missionplan.flight.phases import (PX4_LANDED_STATES, PX4_LANDED_STATES_QUICK, landed_states,
                                      reached_navigation_items, slow_phase)

SYSIDS = (1, 2, 3)
# The same 120 x 90 m Milan block as the ArduCopter fleet test: about 90 s planned per drone.
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1898", "45.4641,9.1904")
OTHER_SITE = [[7.6519, 45.0656], [7.6534, 45.0656], [7.6534, 45.0664], [7.6519, 45.0664], [7.6519, 45.0656]]
OTHER_LAUNCHES = ("45.0657,7.6520", "45.0657,7.6527", "45.0657,7.6533")  # Turin, 125 km west
CAMERA = {"TRIG_MODE": 4, "TRIG_INTERFACE": 3}  # boot parameters: the camera modules start only at boot
FLY_TIMEOUT_S = 480.0
TELEMETRY_HZ = 10.0
HOME_ALT_M = 120.0


def _plan(tmp_path: Path, name: str, ring: list[list[float]], launches: tuple[str, ...]) -> Path:
    area = tmp_path / f"{name}.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    out = tmp_path / name
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(out), "--quiet",
            "--autopilot", "px4"]  # firmwareType 12, and report.json's times by PX4's flight (bridge.px4_model)
    for point in launches:
        args += ["--launch", point]
    assert main(args) == 0
    return out


def _home(plan_dir: Path, sysid: int) -> tuple[float, float, float]:
    lat, lon, _ = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return (float(lat), float(lon), HOME_ALT_M)


def _fleet(px4, homes_from: Path) -> None:  # noqa: F811
    """Instances 0-2 (system ids 1-3), each at its plan's launch point, camera set at boot."""
    for sysid in SYSIDS:
        px4(instance=sysid - 1, home=_home(homes_from, sysid), params=CAMERA)


def test_three_px4_vehicles_on_one_udpin_port_fly_the_plan(px4, tmp_path, capsys) -> None:  # noqa: F811
    plan_dir = _plan(tmp_path, "milan", AREA, LAUNCHES)
    _fleet(px4, plan_dir)
    code = main(["fly", str(plan_dir), "--connect", GCS_URL, "--timeout", str(FLY_TIMEOUT_S),
                 "--telemetry-hz", str(TELEMETRY_HZ), "--quiet"])
    out = capsys.readouterr().out
    doc = json.loads((plan_dir / "flight.json").read_text())
    report = json.loads((plan_dir / "report.json").read_text())
    planned = {int(d["id"]): float(d["flight_s"]) for d in report["drones"]}
    rows = {int(d["id"]): d for d in doc["drones"]}
    summary = {k: (rows[k]["finished"], rows[k]["flight_s"], planned[k], rows[k]["photos"],
                   rows[k]["planned_flight_s_vehicle"]) for k in SYSIDS}
    print(out, summary, doc["problems"], doc["min_separation_m"])
    assert all(rows[k]["finished"] for k in SYSIDS), (doc["problems"], out)
    assert doc["photos_from"] == "camera", doc["photos_from"]  # the vehicles' CAMERA_IMAGE_CAPTURED
    placed = {k: rows[k]["photos_placed_on_track"] for k in SYSIDS}
    assert all(rows[k]["photos"] > 0 and placed[k] == 0 for k in SYSIDS), (summary, placed)
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    sep = doc["min_separation_m"]
    assert sep["kept"] is True and sep["3d"] >= sep["planned_3d"] - sep["tolerance"], sep
    assert code == 0, (out, doc["problems"])
    phases = {k: rows[k]["phases"] for k in SYSIDS}  # where the time went, flown and planned
    for k in SYSIDS:  # flown in the vehicle's own time, within 15 % of the plan
        assert abs(rows[k]["flight_s"] - planned[k]) <= 0.15 * planned[k], (summary, phases)
        # The landed states the mock's PX4 flavour reports too (tests/test_fly_px4.py), so all four phases
        # are measured; and none took minutes (a take-off started while the position estimate still moved).
        assert landed_states(rows[k]) in (PX4_LANDED_STATES, PX4_LANDED_STATES_QUICK), rows[k]["events"]
        commands = [int(item.command) for item in read_mission_file(plan_dir / f"uav{k}.plan").mission.items]
        # As the mock's PX4 reports them (tests/test_fly_px4.py): none for the take-off and the final RTL.
        assert reached_navigation_items(rows[k], commands) == reported_items(commands), rows[k]["events"]
        assert all(p["flown_s"] is not None for p in phases[k]) and not slow_phase(phases[k]), phases


def test_a_plan_for_another_site_arms_no_px4_vehicle(px4, tmp_path, capsys) -> None:  # noqa: F811
    here = _plan(tmp_path, "milan", AREA, LAUNCHES)
    elsewhere = _plan(tmp_path, "turin", OTHER_SITE, OTHER_LAUNCHES)
    _fleet(px4, here)  # the vehicles stand in Milan; the plan is for Turin
    code = main(["fly", str(elsewhere), "--connect", GCS_URL, "--timeout", "120", "--telemetry-hz",
                 str(TELEMETRY_HZ), "--quiet"])
    out = capsys.readouterr().out
    doc = json.loads((elsewhere / "flight.json").read_text())
    assert code != 0
    assert not any(d["finished"] or d["samples"] for d in doc["drones"]), doc["drones"]
    site = [p for p in doc["problems"] if "site check failed" in p]
    assert len(site) == 3 and all(" km from the plan's launch point" in p for p in site), doc["problems"]
    assert "left disarmed" in out, out
    assert armed_ever(GCS_URL, SYSIDS, 3.0) == set()  # and none armed after fly gave up either
