"""Plan, upload and fly shipped maps and Turin street plans against mock autopilots and ArduCopter SITL;
print one row per flight.

Run by hand: `.venv/bin/python bench/fly_bench.py [--maps leonardo,grid-city] [--uavs 3,5,6]
[--streets block,cenisia] [--sitl] [--px4 milan3,block3] [--policy nn] [--keep DIR] [--write-doc FILE]`.
`[--faults sitl]`.
Each row: the flown coverage (our rule, and the stricter whole-cell rule), the closest approach of two
drones against the plan's promise, flight time (the longest drone's, on the vehicles' own clock:
simulated seconds) against the plan's, the worst drone's gap between flown and planned time, photos,
and wall time of the flight (upload, verify, fly, judge).

Mock rows fly the whole fleet at once against in-process SITL-like mock autopilots (ArduCopter's flight
model, cameras configured). SITL rows (`--sitl`, needs ../shared/sitl/arducopter) fly each drone on its
own ArduCopter SITL at 10x, one after the other (its camera configured once: CAM1_TYPE = 1 and a reboot),
then judge the drones together with their recordings aligned at their mission starts, as the plan's
separation assumes they start: coverage from all drones' CAMERA_FEEDBACK, the flown closest approach
against the promise. Street plans read the Turin map in place from ../shared/maps.

PX4 rows (`--px4 PLANS`, needs ../shared/px4/bin/px4): each plan made with `plan --autopilot px4`
(report.json timed by PX4's flight model), flown by the PX4 flavour of the mock (PX4's flight model,
CAMERA_IMAGE_CAPTURED) and by the whole fleet at once on PX4 SIH (real time, free instances with
system ids 1-N, every GCS link into one free udpin port, TRIG_MODE 4 at boot, fly started right after boot; at most 3
drones: SIH runs in real time and the machine has 2 cores). Coverage from the vehicles' CAMERA_IMAGE_CAPTURED.

Fault rows (`--faults sitl`, needs ../shared/sitl/arducopter): the fleet of sitl_tests/test_fly_faults_sitl.py
(missionplan/testing/sitl_fleet.py: three ArduCopter SITL vehicles at 5x through a loopback relay, the
200 x 140 m Milan block from 20 m, fly as a child process) with one fault mid-flight (every vehicle past mission item 5): `kill` (uav2's SITL
SIGKILLed), `link-drop` (the relay drops everything both ways for 30 s of wall time), `battery` (uav2's
SIM_BATT_VOLTAGE set under BATT_LOW_VOLT, BATT_FS_LOW_ACT = 2: RTL). Each row: the time from the fault to
fly's first alert about it (wall seconds, and the vehicles' seconds at 5x), the photos fly recorded, how
many of them it read from the vehicles' logs, and how many the vehicles took (their own CAMERA_FEEDBACK
as the relay saw it), the coverage fly recorded against the coverage of the photos really taken (same
rule), fly's exit code and its wall time.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import missionplan.flight.fly as fly_module
from missionplan.cli import main
from missionplan.flight.flight_report import judge
from missionplan.flight.fly import fly, flight_view
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.mission.plan_record import read_plan_record, report_path, write_plan_record

import doctable  # bench/doctable.py: --write-doc

ROOT = Path(__file__).resolve().parent.parent


SPEEDUP = {"leonardo": 2.0}  # a 20 x 10 m arena; the street maps are hundreds of metres: 50x
DEFAULT_SPEEDUP = 50.0
TELEMETRY_HZ = 50.0
SITL_TELEMETRY_HZ = 10.0  # wall Hz at 10x: one position per simulated second
OSM = ROOT.parent / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"
# Street plans at 20 m over Turin's Cenisia district (README): a block for one drone and for three, the
# district for four.
STREETS: dict[str, tuple[list[list[float]], list[str]]] = {
    "block": ([[7.652188, 45.069850], [7.654088, 45.069850], [7.654088, 45.068250], [7.652188, 45.068250]],
              ["45.069450,7.652588"]),
    # The same block for three drones, launched from street points of the one-drone plan: close neighbours.
    "block3": ([[7.652188, 45.069850], [7.654088, 45.069850], [7.654088, 45.068250], [7.652188, 45.068250]],
               ["45.069441,7.652592", "45.068404,7.653226", "45.069302,7.653053"]),
    "cenisia": ([[7.65189, 45.06563], [7.65861, 45.06563], [7.65861, 45.07000], [7.65189, 45.07000]],
                ["45.069450,7.652588", "45.069513,7.657924", "45.066065,7.652668", "45.066127,7.658004"]),
}
# Plain areas (no buildings map) for the PX4 rows: the fleet test's Milan block.
AREAS: dict[str, tuple[list[list[float]], list[str]]] = {
    "milan3": ([[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648]],
               ["45.4641,9.1891", "45.4641,9.1898", "45.4641,9.1904"]),
}
PX4_MAX_VEHICLES = 3
FAULTS = ("kill", "link-drop", "battery")
FAULT_SYSID = 2
FAULT_ITEM = 5  # every vehicle past this mission item when the fault comes
FAULT_HEADER = (f"{'fault':<11}{'uav':>4}{'alert s':>9}{'veh s':>8}{'photos':>8}{'log':>6}{'taken':>7}"
                f"{'cover %':>9}{'true %':>8}{'exit':>6}{'wall s':>8}  first alert")
HEADER = (f"{'vehicle':<16}{'plan':<11}{'A':>3}{'targets':>9}{'cover %':>9}{'whole %':>9}{'sep 3d m':>10}"
          f"{'promised':>10}{'tol m':>7}{'flight s':>10}{'planned':>9}{'worst':>8}{'photos':>8}{'wall s':>8}")


def _plan(out: Path, name: str, uavs: int, policy: str, autopilot: str = "ardupilot") -> bool:
    if name in STREETS or name in AREAS:
        corners, launches = STREETS[name] if name in STREETS else AREAS[name]
        area = out / "area.geojson"
        out.mkdir(parents=True, exist_ok=True)
        area.write_text(json.dumps({"type": "Feature", "properties": {"name": name},
                                    "geometry": {"type": "Polygon", "coordinates": [corners + corners[:1]]}}))
        argv = ["plan", "--area", str(area), *(["--osm", str(OSM)] if name in STREETS else []), "--altitude", "20",
                "--fov", "84", "--policy", policy, "--out", str(out / "plan"), "--quiet"]
        for launch in launches[:uavs]:
            argv += ["--launch", launch]
    else:
        argv = ["plan", "--map", name, "--uavs", str(uavs), "--policy", policy, "--out", str(out / "plan"), "--quiet"]
    argv += ["--autopilot", autopilot]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):  # the table only
        return main(argv) == 0


def _row(vehicle: str, name: str, uavs: int, plan_dir: Path, problems: list[str], wall: float) -> str:
    doc = json.loads((plan_dir / "flight.json").read_text())
    sep = doc["min_separation_m"]
    drones = doc["drones"]
    flight = max(d["flight_s"] for d in drones)
    planned = max(d["planned_flight_s"] for d in drones)
    worst = max(abs(d["flight_s"] - d["planned_flight_s"]) / max(d["flight_s"], 1e-9) for d in drones)
    photos = sum(d["photos"] for d in drones)

    def metres(value: Any) -> str:
        return f"{value:.2f}" if value is not None else "-"

    sorties = read_plan_record(plan_dir).sorties
    note = "" if sorties == 1 else f"  (sortie 1 of {sorties})"
    note += "" if not problems else "  " + "; ".join(problems)
    return (f"{vehicle:<16}{name:<11}{uavs:>3}{doc['targets']:>9}{doc['coverage']:>9.2f}"
            f"{doc['coverage_other_rules']['whole_cell']:>9.2f}{metres(sep['3d']):>10}{metres(sep['planned_3d']):>10}"
            f"{sep['tolerance']:>7.2f}{flight:>10.1f}{planned:>9.1f}{100 * worst:>7.1f}%{photos:>8}{wall:>8.1f}{note}")


def mock_row(name: str, uavs: int, plan_dir: Path, flavour: str = "ardupilot") -> str:
    speedup = SPEEDUP.get(name, DEFAULT_SPEEDUP)
    mock = start_mock_fleet(plan_dir, speedup, flavour=flavour)
    start = time.monotonic()
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=1800, progress=False, time_scale=speedup,
                     telemetry_hz=TELEMETRY_HZ)
    finally:
        mock.stop()
    vehicle = f"mock {speedup:g}x" + (" px4" if flavour == "px4" else "")
    return _row(vehicle, name, uavs, plan_dir, result.problems, time.monotonic() - start)


def px4_row(name: str, uavs: int, plan_dir: Path) -> str:
    """The whole fleet at once on PX4 SIH, as sitl_tests/test_fleet_px4.py flies it."""
    from missionplan.testing.loopback import free_udp_port
    from missionplan.testing.px4_sih import PX4

    from missionplan.bridge.formats.missionfile import read_mission_file

    if uavs > PX4_MAX_VEHICLES:
        return f"{'PX4 SIH':<16}{name:<11}{uavs:>3}  skipped: more than {PX4_MAX_VEHICLES} PX4 SIH at a time"
    vehicles: list[Any] = []
    port = free_udp_port()
    try:
        for sysid in range(1, uavs + 1):
            lat, lon, _ = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
            vehicles.append(PX4(sysid=sysid, gcs_port=port, home=(lat, lon, 120.0),
                                params={"TRIG_MODE": 4}).start())
        start = time.monotonic()
        result = fly(plan_dir, f"udpin:127.0.0.1:{port}", timeout_s=1800, progress=False, telemetry_hz=SITL_TELEMETRY_HZ)
        wall = time.monotonic() - start  # includes the wait for readiness after boot (~35 s)
    finally:
        for vehicle in vehicles:
            vehicle.stop()
    return _row("PX4 SIH", name, uavs, plan_dir, result.problems, wall)


def _shifted(rec: Any, by: float) -> Any:
    """The record with every time on our clock moved by `by` (the vehicle's own stamps unchanged)."""
    out = copy.deepcopy(rec)
    out.samples = [(s[0] + by, *s[1:]) for s in rec.samples]
    out.reached = [(t + by, seq) for t, seq in rec.reached]
    out.camera = {k: (v[0] + by, *v[1:]) for k, v in rec.camera.items()}
    out.t_start = None if rec.t_start is None else rec.t_start + by
    out.t_end = None if rec.t_end is None else rec.t_end + by
    out.last_heard += by
    return out


def sitl_row(name: str, uavs: int, plan_dir: Path) -> str:
    from missionplan.testing.arducopter import ArduCopter, configure_camera_and_wait_ready

    from missionplan.bridge.formats.missionfile import read_mission_file

    record = read_plan_record(plan_dir)
    records: list[Any] = []
    wall = 0.0
    for drone in record.drones or ():
        # A plan folder with this drone alone; its recordings are kept for the judgement together.
        single = plan_dir.parent / f"single-{drone.id}"
        shutil.copytree(plan_dir, single, dirs_exist_ok=True)
        write_plan_record(replace(record, drones=(drone,)), report_path(single))
        kept: list[Any] = []
        original = fly_module.judge

        def keep(*args: Any, **kwargs: Any) -> Any:
            kept.extend(args[2])
            return original(*args, **kwargs)

        home = read_mission_file(single / f"uav{drone.id}.plan").mission.home
        fly_module.judge = keep
        try:
            with ArduCopter(sysid=drone.id, home=(home[0], home[1], 240.0, 0.0)) as vehicle:
                configure_camera_and_wait_ready(vehicle)
                start = time.monotonic()
                fly(single, vehicle.url, timeout_s=1800, progress=False, time_scale=vehicle.speedup,
                    telemetry_hz=SITL_TELEMETRY_HZ)
                wall += time.monotonic() - start
        finally:
            fly_module.judge = original
        records.append(_shifted(kept[0], -kept[0].t_start if kept[0].t_start is not None else 0.0))
    # Judged as fly judges sortie 1 of the whole fleet (a long plan flies in battery sorties).
    view = flight_view(plan_dir, record, 1)
    result = judge(plan_dir, view, records, 10.0, wall_s=wall, telemetry_hz=SITL_TELEMETRY_HZ)
    return _row("ArduCopter SITL", name, uavs, plan_dir, result.problems, wall)


def _true_coverage(plan_dir: Path, photos_at: dict[int, dict[int, tuple[float, float]]]) -> float:
    """Coverage of the photos the vehicles really took (their own reports, as the relay saw them all),
    by flight_report's rule."""
    from missionplan.flight import flight_report as fr

    record = read_plan_record(plan_dir)
    frame = fr.frame_of(record)
    points = [p for taken in photos_at.values() for p in taken.values()]
    if not points:
        return 0.0
    grid = fr.to_grid_m(frame, [p[0] for p in points], [p[1] for p in points])
    covered = fr.coverage(frame, fr.target_cells(record), grid, fr.georeference_of(record).footprint_m,
                          fr.SLACK_CELLS * frame.cell_m)
    return 100.0 * float(covered.mean())


def fault_row(fault: str, plan_dir: Path) -> str:
    """One fault on a fresh SITL fleet (missionplan/testing/sitl_fleet.py, as sitl_tests/test_fly_faults_sitl.py flies it); its row."""
    import os
    import signal

    from missionplan.testing.loopback import wait_until
    from missionplan.testing.sitl_fleet import SPEEDUP as FAULT_SPEEDUP
    from missionplan.testing.sitl_fleet import (BATTERY_LOW_V, BATTERY_SIM_V, FLY_TIMEOUT_S, LINK_DROP_S, SYSIDS,
                                                FlyRun, configure, in_flight, set_param_on_serial1, sitl_fleet)

    params = {"BATT_FS_LOW_ACT": 2.0, "BATT_LOW_VOLT": BATTERY_LOW_V} if fault == "battery" else None
    with sitl_fleet(plan_dir, SYSIDS) as fleet:
        configure(fleet, params)
        relay = fleet.relay
        run = FlyRun(plan_dir, fleet.url)
        try:
            if not in_flight(relay, FAULT_ITEM):
                run.kill()
                return f"{fault:<11}{FAULT_SYSID:>4}  the fleet never got past item {FAULT_ITEM}"
            seen = len(run.lines)
            target = f"uav{FAULT_SYSID}:"
            if fault == "kill":
                os.killpg(fleet.vehicle(FAULT_SYSID).proc.pid, signal.SIGKILL)
                words: tuple[str, ...] = ("link lost",)
            elif fault == "link-drop":
                relay.drop()
                words, target = ("link lost",), ""
            else:
                set_param_on_serial1(fleet.vehicle(FAULT_SYSID), "SIM_BATT_VOLTAGE", BATTERY_SIM_V)
                words = ("battery", "failsafe", "mode changed")
            fault_at = time.monotonic()

            def alert() -> tuple[float, str] | None:
                return next(((t, text) for t, text in run.lines[seen:] if target in text
                             and any(w in text.lower() for w in words)), None)

            if fault == "link-drop":
                wait_until(lambda: time.monotonic() - fault_at >= LINK_DROP_S, LINK_DROP_S + 1.0)
                relay.restore()
            code = run.finish(FLY_TIMEOUT_S)
            said = alert()
        finally:
            run.kill()
        doc = json.loads((plan_dir / "flight.json").read_text())
        taken = sum(int(relay.state(k).get("photos", 0)) for k in SYSIDS)
        true = _true_coverage(plan_dir, relay.photos_at)
    photos = sum(d["photos"] for d in doc["drones"])
    from_log = sum(d.get("photos_from_log", 0) for d in doc["drones"])
    delay = f"{said[0] - fault_at:>9.1f}{(said[0] - fault_at) * FAULT_SPEEDUP:>8.0f}" if said else f"{'-':>9}{'-':>8}"
    text = said[1].strip()[:70] if said else "(none)"
    return (f"{fault:<11}{FAULT_SYSID if fault != 'link-drop' else 'all':>4}{delay}{photos:>8}{from_log:>6}{taken:>7}"
            f"{doc['coverage']:>9.2f}{true:>8.2f}{code:>6}{time.monotonic() - run.started:>8.1f}  {text}")


def fault_table(policy: str) -> None:
    from missionplan.testing.sitl_fleet import AREA, LAUNCHES

    print(FAULT_HEADER)
    print("-" * len(FAULT_HEADER))
    for fault in FAULTS:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            area = out / "area.geojson"
            area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
            argv = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--policy", policy,
                    "--out", str(out / "plan"), "--quiet"]
            for launch in LAUNCHES:
                argv += ["--launch", launch]
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                planned = main(argv) == 0
            print(fault_row(fault, out / "plan") if planned else f"{fault:<11}  plan failed", flush=True)


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default="leonardo,grid-city,old-town,river-city", help="shipped maps ('' for none)")
    parser.add_argument("--uavs", default="3,5,6", help="drones per shipped map")
    parser.add_argument("--streets", default="block,block3,cenisia", help=f"street plans ({', '.join(STREETS)}; '' for none)")
    parser.add_argument("--sitl", action="store_true", help="also fly the street plans on ArduCopter SITL")
    parser.add_argument("--px4", default="", help=f"plans to fly for PX4 on the PX4 mock and PX4 SIH "
                                                   f"({', '.join([*AREAS, *STREETS])}; at most {PX4_MAX_VEHICLES} drones)")
    parser.add_argument("--faults", default="", choices=("", "sitl"),
                        help="also the fault rows on ArduCopter SITL (a vehicle killed, a 30 s link drop, a battery "
                             "failsafe): fly's alert delay, photos read from the logs, coverage recorded vs true")
    parser.add_argument("--policy", default="nn", choices=("nn", "expert"))
    parser.add_argument("--keep", default="", metavar="DIR",
                        help="copy every SITL / PX4 SIH flight's folder (flight.json with its phases, flight.png) "
                             "into DIR/NAME-VEHICLE, to see where a row's time went")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        table(args)


def table(args: argparse.Namespace) -> None:
    jobs = [(name, int(u)) for name in filter(None, args.maps.split(",")) for u in args.uavs.split(",")]
    jobs += [(name, len(STREETS[name][1])) for name in filter(None, args.streets.split(","))]
    if jobs or args.px4 or not args.faults:
        print(HEADER)
        print("-" * len(HEADER))
    for name, uavs in jobs:
        with tempfile.TemporaryDirectory() as tmp:
            if not _plan(Path(tmp), name, uavs, args.policy):
                print(f"{'':<16}{name:<11}{uavs:>3}  plan failed")
                continue
            plan_dir = Path(tmp) / "plan"
            print(mock_row(name, uavs, plan_dir), flush=True)
            if args.sitl and name in STREETS:
                fresh = Path(tmp) / "sitl-plan"
                shutil.copytree(plan_dir, fresh)
                print(sitl_row(name, uavs, fresh), flush=True)
                _keep(args.keep, fresh, f"{name}-sitl")
    for name in filter(None, args.px4.split(",")):
        uavs = len((STREETS.get(name) or AREAS[name])[1])
        with tempfile.TemporaryDirectory() as tmp:
            if not _plan(Path(tmp), name, uavs, args.policy, autopilot="px4"):
                print(f"{'':<16}{name:<11}{uavs:>3}  plan failed")
                continue
            plan_dir = Path(tmp) / "plan"
            print(mock_row(name, uavs, plan_dir, flavour="px4"), flush=True)
            fresh = Path(tmp) / "px4-plan"
            shutil.copytree(plan_dir, fresh)
            print(px4_row(name, uavs, fresh), flush=True)
            _keep(args.keep, fresh, f"{name}-px4")
    if args.faults == "sitl":
        if jobs or args.px4:
            print()
        fault_table(args.policy)


def _keep(keep: str, flown: Path, name: str) -> None:
    if keep:
        shutil.copytree(flown, Path(keep) / name, dirs_exist_ok=True)


if __name__ == "__main__":
    main_bench()
