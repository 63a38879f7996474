"""Fly a planned fleet over MAVLink and judge the flight: `missionplan fly DIR --connect URL`.

Owns:
- fly(): read DIR/report.json and every DIR/uavK.plan; one thread per drone (each with its own
  pymavlink link) uploads uavK.plan to system id K and verifies the read-back (bridge.uploader),
  sets GUIDED (ArduPilot), arms, starts the mission, then follows that vehicle's telemetry
  (HEARTBEAT, GLOBAL_POSITION_INT, MISSION_CURRENT, MISSION_ITEM_REACHED, CAMERA_FEEDBACK) with one
  tqdm bar per drone until it lands and disarms, the time-out passes, or it stops answering;
- the judgement (flight_report): coverage of the plan's reachable targets by photo positions,
  closest approach between drones, per-drone flight time; written to DIR/flight.json and DIR/flight.png;
- start_mock_fleet(): in-process mock autopilots on 127.0.0.1 for K = 1..uavs, homes at the plan's
  launch points when a plan directory is given;
- register(): the `fly` subcommand (handler returns 0 when coverage >= 99 % and no problems, else 1).

Times: every sample is stamped with our monotonic clock on arrival. Against a sped-up mock the
flight times are wall seconds times the time scale (given, or estimated from the reported
velocities against the distance flown between samples).
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge.errors import BridgeError
from bridge.link import mavlink
from bridge.mission import Flavour, to_wire
from bridge.missionfile import read_mission_file
from bridge.protocol import Timeouts
from bridge.uploader import open_backend, upload_plan

from . import flight_report as fr
from .atomic import write_text_atomic

CMD_ARM, CMD_DO_SET_MODE, CMD_MISSION_START = 400, 176, 300
CMD_WAYPOINT, CMD_CAM_TRIGG_DIST = 16, 206
MODE_FLAG_ARMED = 128
ARDUPILOT_GUIDED = 4
SILENCE_S = 5.0        # a vehicle that says nothing for this long has stopped answering
COMMAND_TRIES = 4
COMMAND_WAIT_S = 1.0
COVERAGE_OK = 99.0


@dataclass
class DroneFlight:
    """What one thread learned about one vehicle."""

    id: int
    plan_photos: int = 0
    uploaded: bool = False
    started: bool = False
    finished: bool = False
    mission_state: int = 0
    current: int = 0
    total: int = 0
    reached: list[tuple[float, int]] = field(default_factory=list)            # arrival time, seq
    samples: list[tuple[float, float, float, float, float]] = field(default_factory=list)  # t, lat, lon, rel alt m, speed m/s
    camera: list[tuple[float, float]] = field(default_factory=list)           # lat, lon of CAMERA_FEEDBACK
    wire: list[Any] = field(default_factory=list)
    t_start: float | None = None
    t_end: float | None = None
    last_heard: float = 0.0
    problems: list[str] = field(default_factory=list)


@dataclass
class FlightResult:
    coverage: float
    min_separation_m: dict[str, Any]
    drones: list[dict[str, Any]]
    problems: list[str]
    time_scale: float
    wall_s: float
    json_path: Path
    png_path: Path

    @property
    def ok(self) -> bool:
        return self.coverage >= COVERAGE_OK and not self.problems


# ---------------------------------------------------------------------------------------------- mocks
def plan_homes(plan_dir: Path, uavs: int) -> dict[int, tuple[float, float, float]]:
    """sysid -> (lat, lon, alt AMSL) of each uavK.plan's planned home (else its first positional item)."""
    homes: dict[int, tuple[float, float, float]] = {}
    for k in range(1, uavs + 1):
        path = Path(plan_dir) / f"uav{k}.plan"
        if not path.exists():
            continue
        plan = read_mission_file(path)
        if plan.mission.home is not None:
            homes[k] = tuple(float(v) for v in plan.mission.home)  # type: ignore[assignment]
            continue
        for item in plan.mission.items:
            if item.x or item.y:
                homes[k] = (float(item.x), float(item.y), 0.0)
                break
    return homes


def start_mock_fleet(uavs: int, speedup: float, plan_dir: Path | None = None, flavour: str = "ardupilot",
                     faults: Any = None, acceptance_m: float | None = None) -> tuple[Any, str]:
    """Start in-process mock autopilots (system ids 1..uavs) on 127.0.0.1; returns (mock, connect URL).
    With plan_dir, each vehicle's home is its plan's launch point. acceptance_m sets the vehicles'
    default waypoint acceptance radius (used for items whose param2 is 0; the mock's default is 1 m,
    like a WPNAV_RADIUS setting) — the plans leave param2 at 0, so on fine grids (Leonardo: 0.24 m
    cells, ~1 m legs) the default makes the mock cut corners and miss targets. Call mock.stop() when done."""
    from bridge.mock import MockAutopilot

    homes = plan_homes(Path(plan_dir), uavs) if plan_dir is not None else None
    mock = MockAutopilot("udpin:127.0.0.1:0", sysids=range(1, uavs + 1), flavour=flavour, speedup=speedup,
                         faults=faults, homes=homes)
    if acceptance_m is not None:
        for vehicle in mock.vehicles.values():  # before start(): no other thread touches them yet
            vehicle.flight.default_acceptance = float(acceptance_m)
    mock.start()
    return mock, mock.client_url


# ---------------------------------------------------------------------------------------------- one drone
def _command(link: Any, sysid: int, command: int, params: list[float], deadline: float) -> int | None:
    """COMMAND_LONG with retries; the MAV_RESULT of its COMMAND_ACK, or None without one."""
    p = (params + [0.0] * 7)[:7]
    for attempt in range(COMMAND_TRIES):
        link.mav.command_long_send(sysid, 1, command, attempt, *p)
        wait_until = min(time.monotonic() + COMMAND_WAIT_S, deadline)
        while True:
            msg = link.recv(wait_until)
            if msg is None:
                break
            if msg.get_srcSystem() == sysid and msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
                return int(msg.result)
        if time.monotonic() >= deadline:
            break
    return None


def _fly_one(url: str, drone: DroneFlight, plan_path: Path, deadline: float, bar: Any,
             start_barrier: threading.Barrier, stop: threading.Event) -> None:
    sysid = drone.id
    backend = None
    try:
        try:
            backend = open_backend("pymavlink", url, sysid, timeouts=Timeouts(item_timeout=0.5, retries=10),
                                   connect_timeout=max(1.0, min(10.0, deadline - time.monotonic())))
            plan = read_mission_file(plan_path)
            upload_plan(backend, plan.parts(), verify=True)
            drone.wire = to_wire(plan.mission, backend.vehicle.flavour)
            drone.uploaded = True
        except (BridgeError, OSError) as err:
            drone.problems.append(f"uav{sysid}: upload failed: {err}")
            return
        finally:
            try:
                start_barrier.wait(timeout=max(0.1, deadline - time.monotonic()))  # start together
            except threading.BrokenBarrierError:
                pass
        link = backend.link
        if backend.vehicle.flavour is Flavour.ARDUPILOT:
            _command(link, sysid, CMD_DO_SET_MODE, [1.0, float(ARDUPILOT_GUIDED)], deadline)  # denial is not fatal
        result = _command(link, sysid, CMD_ARM, [1.0], deadline)
        if result != 0:
            drone.problems.append(f"uav{sysid}: arming {'not acknowledged' if result is None else f'refused ({result})'}")
            return
        result = _command(link, sysid, CMD_MISSION_START, [0.0, 0.0], deadline)
        if result != 0:
            drone.problems.append(f"uav{sysid}: mission start {'not acknowledged' if result is None else f'refused ({result})'}")
            return
        drone.started = True
        drone.t_start = drone.last_heard = time.monotonic()
        drone.total = len(drone.wire)
        if bar is not None:
            bar.reset(total=max(drone.total - 1, 1))
        armed = True
        while not stop.is_set():
            now = time.monotonic()
            if now >= deadline:
                drone.problems.append(f"uav{sysid}: mission not finished within the time-out "
                                      f"(item {drone.current} of {drone.total})")
                break
            if now - drone.last_heard > SILENCE_S:
                drone.problems.append(f"uav{sysid}: vehicle stopped answering ({SILENCE_S:g} s without a message)")
                break
            msg = link.recv(min(deadline, now + 0.5))
            if msg is None or msg.get_srcSystem() != sysid:
                continue
            t = time.monotonic()
            drone.last_heard = t
            kind = msg.get_type()
            if kind == "GLOBAL_POSITION_INT":
                speed = math.hypot(msg.vx, msg.vy) / 100.0
                drone.samples.append((t, msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0, speed))
            elif kind == "MISSION_CURRENT":
                drone.current = int(msg.seq)
                drone.mission_state = int(getattr(msg, "mission_state", 0) or 0)
                if bar is not None:
                    bar.n = min(max(drone.current, bar.n), bar.total)
                    bar.refresh()
            elif kind == "MISSION_ITEM_REACHED":
                drone.reached.append((t, int(msg.seq)))
            elif kind == "CAMERA_FEEDBACK":
                drone.camera.append((msg.lat / 1e7, msg.lng / 1e7))
            elif kind == "HEARTBEAT" and msg.type != 6:
                armed = bool(msg.base_mode & MODE_FLAG_ARMED)
            if not armed and (drone.reached or drone.mission_state == 5):
                drone.finished = True
                drone.t_end = t
                if bar is not None:
                    bar.n = bar.total
                    bar.refresh()
                break
    except Exception as err:  # noqa: BLE001 - one drone's failure must not hide the others'
        drone.problems.append(f"uav{sysid}: {type(err).__name__}: {err}")
    finally:
        if backend is not None:
            backend.close()


# ---------------------------------------------------------------------------------------------- judging
def _survey_window(drone: DroneFlight) -> tuple[int | None, int | None]:
    """Wire seqs of the first and last waypoint flown with the distance trigger on."""
    first = last = None
    on = False
    for item in drone.wire:
        if item.command == CMD_CAM_TRIGG_DIST:
            on = item.param1 > 0
        elif item.command == CMD_WAYPOINT and on:
            first = item.seq if first is None else first
            last = item.seq
    return first, last


def _estimate_time_scale(drones: list[DroneFlight]) -> float:
    """Simulated seconds per wall second: distance flown between samples over the reported speed."""
    ratios: list[float] = []
    for d in drones:
        s = d.samples
        for a, b in zip(s, s[1:]):
            dt = b[0] - a[0]
            speed = 0.5 * (a[4] + b[4])
            if dt <= 0.05 or speed < 0.5:
                continue
            dn = math.radians(b[1] - a[1]) * 6_378_137.0
            de = math.radians(b[2] - a[2]) * 6_378_137.0 * math.cos(math.radians(a[1]))
            dist = math.hypot(dn, de)
            if dist > 0:
                ratios.append(dist / (dt * speed))
    if len(ratios) < 3:
        return 1.0
    return float(np.median(ratios))


def _photo_positions(frame: Any, drone: DroneFlight, trigger_m: float, acceptance_m: float) -> np.ndarray:
    """Photo positions (grid metres): camera reports, else every trigger_m along the survey part of the track."""
    if drone.camera:
        lat, lon = zip(*drone.camera)
        return fr.to_grid_m(frame, lat, lon)
    if not drone.samples:
        return np.zeros((0, 2))
    first, last = _survey_window(drone)
    reached = {seq: t for t, seq in reversed(drone.reached)}  # first arrival of each seq
    t0 = reached.get(first) if first is not None else None
    t1 = None
    if last is not None:
        later = [t for t, seq in drone.reached if seq == last]
        t1 = later[-1] if later else None
    t0 = drone.samples[0][0] if t0 is None else t0
    t1 = drone.samples[-1][0] if t1 is None else t1
    # The recorded samples (4 Hz against the mock: they cut corners) merged, in arrival order, with the
    # waypoints the vehicle reported reached. A reached waypoint counts as flown only up to where the
    # vehicle, flying straight from its last known point, entered the waypoint's acceptance circle
    # (param2, or acceptance_m when 0): a vehicle that turns early must not be credited with the corner.
    by_seq = {it.seq: it for it in drone.wire}
    merged = [(s[0], 1, s[1], s[2], 0.0) for s in drone.samples if t0 <= s[0] <= t1]
    if first is not None and last is not None:
        for t, seq in drone.reached:
            item = by_seq.get(seq)
            if item is not None and item.command == CMD_WAYPOINT and first <= seq <= last and t0 <= t <= t1:
                radius = float(item.param2) if item.param2 > 0 else acceptance_m
                merged.append((t, 0, item.x / 1e7, item.y / 1e7, radius))
    merged.sort()
    if not merged:
        return np.zeros((0, 2))
    xy = fr.to_grid_m(frame, [m[2] for m in merged], [m[3] for m in merged])
    pts: list[np.ndarray] = []
    here: np.ndarray | None = None
    for m, q in zip(merged, xy):
        if m[1] == 1 or here is None:
            here = q
        else:
            gap = q - here
            dist = float(np.hypot(gap[0], gap[1]))
            if dist > m[4]:
                here = here + gap * (1.0 - m[4] / dist)
        pts.append(here)
    pts_arr = np.array(pts)
    return fr.resample_polyline(pts_arr, trigger_m) if trigger_m > 0 else pts_arr


def judge(plan_dir: Path, report: dict[str, Any], drones: list[DroneFlight], time_scale: float | None,
          wall_s: float, problems: list[str], acceptance_m: float = 1.0) -> FlightResult:
    frame = fr.frame_of(report)
    geo = report["georeference"]
    footprint = float(geo["footprint_m"])
    trigger = float(geo.get("trigger_distance_m") or 0.0)
    scale = time_scale if time_scale else _estimate_time_scale(drones)
    targets = fr.target_cells(report)
    photos: list[np.ndarray] = []
    tracks_m: dict[int, np.ndarray] = {}
    timed: dict[int, np.ndarray] = {}
    flight_s: dict[int, float] = {}
    out_drones: list[dict[str, Any]] = []
    for d in drones:
        p = _photo_positions(frame, d, trigger, acceptance_m)
        photos.append(p)
        if d.samples:
            arr = np.array(d.samples)
            xy = fr.to_grid_m(frame, arr[:, 1], arr[:, 2])
            tracks_m[d.id] = xy
            # north/east-like metres in the grid frame (rows down, cols right), up = relative altitude
            timed[d.id] = np.column_stack([arr[:, 0], xy[:, 0], xy[:, 1], arr[:, 3]])
        else:
            tracks_m[d.id] = np.zeros((0, 2))
        if d.t_start is not None:
            end = d.t_end if d.t_end is not None else (d.samples[-1][0] if d.samples else d.t_start)
            flight_s[d.id] = round((end - d.t_start) * scale, 2)
        else:
            flight_s[d.id] = 0.0
        out_drones.append({"id": d.id, "flight_s": flight_s[d.id], "finished": d.finished,
                           "photos": int(len(d.camera) if d.camera else len(p)),
                           "photos_source": "camera" if d.camera else "track",
                           "planned_photos": d.plan_photos, "uploaded": d.uploaded,
                           "samples": len(d.samples), "items_reached": len({s for _, s in d.reached})})
    all_photos = np.vstack(photos) if photos else np.zeros((0, 2))
    covered = fr.coverage(frame, targets, all_photos, footprint)
    pct = 100.0 * float(covered.mean()) if len(targets) else 100.0
    sep = fr.min_separation(timed)
    json_path = plan_dir / "flight.json"
    png_path = plan_dir / "flight.png"
    doc = {"coverage": round(pct, 2), "targets": int(len(targets)), "covered": int(covered.sum()),
           "min_separation_m": sep, "drones": out_drones, "problems": problems,
           "time_scale": round(scale, 3), "acceptance_m": acceptance_m, "wall_s": round(wall_s, 2),
           "photos_assumed": ("camera reports where present, else every trigger_distance_m along the recorded track "
                              "(GLOBAL_POSITION_INT samples merged with the positions of waypoints reported reached)")}
    write_text_atomic(json_path, json.dumps(doc, indent=2) + "\n")
    fr.draw_flight(png_path, report, frame, targets, covered, tracks_m, flight_s, pct)
    return FlightResult(coverage=round(pct, 2), min_separation_m=sep, drones=out_drones, problems=problems,
                        time_scale=scale, wall_s=wall_s, json_path=json_path, png_path=png_path)


# ---------------------------------------------------------------------------------------------- fly
def fly(plan_dir: Path, connect: str, timeout_s: float = 600.0, progress: bool = True,
        time_scale: float | None = None, acceptance_m: float = 1.0) -> FlightResult:
    """Upload, verify, arm, start and follow every drone of plan_dir in parallel; write flight.json/.png."""
    plan_dir = Path(plan_dir)
    report = json.loads((plan_dir / "report.json").read_text())
    ids = [int(d["id"]) for d in report["drones"]]
    drones = [DroneFlight(id=k, plan_photos=int(next(d for d in report["drones"] if int(d["id"]) == k)
                                               .get("photos", 0))) for k in ids]
    problems: list[str] = []
    plans = {k: plan_dir / f"uav{k}.plan" for k in ids}
    for k, path in plans.items():
        if not path.exists():
            problems.append(f"uav{k}: upload failed: {path.name} is missing")
    start = time.monotonic()
    deadline = start + timeout_s
    runnable = [d for d in drones if plans[d.id].exists()]
    barrier = threading.Barrier(max(len(runnable), 1))
    stop = threading.Event()
    bars: dict[int, Any] = {}
    if progress:
        from tqdm import tqdm

        for pos, d in enumerate(runnable):
            bars[d.id] = tqdm(total=1, desc=f"uav{d.id}", position=pos, unit="item", leave=True)
    threads = [threading.Thread(target=_fly_one, name=f"fly-uav{d.id}",
                                args=(connect, d, plans[d.id], deadline, bars.get(d.id), barrier, stop), daemon=True)
               for d in runnable]
    for th in threads:
        th.start()
    try:
        for th in threads:
            th.join(max(0.0, deadline - time.monotonic()) + 5.0)
    finally:
        stop.set()
        for th in threads:
            th.join(2.0)
        for bar in bars.values():
            bar.close()
    wall = time.monotonic() - start
    for d in drones:
        problems.extend(d.problems)
        if d.started and not d.finished and not d.problems:
            problems.append(f"uav{d.id}: mission not finished")
    return judge(plan_dir, report, drones, time_scale, wall, problems, acceptance_m)


# ---------------------------------------------------------------------------------------------- CLI
def cmd_fly(args: Any) -> int:
    result = fly(Path(args.dir), args.connect, timeout_s=args.timeout, progress=not args.quiet,
                 time_scale=args.time_scale, acceptance_m=args.acceptance)
    sep = result.min_separation_m
    print(f"coverage {result.coverage:.2f} %, min separation {sep.get('horizontal')} m horizontal / "
          f"{sep.get('3d')} m 3-D, {len(result.drones)} drones, {result.wall_s:.1f} s wall")
    for d in result.drones:
        print(f"  uav{d['id']}: {'finished' if d['finished'] else 'NOT finished'}, {d['flight_s']} s, "
              f"{d['photos']} photos")
    for p in result.problems:
        print(f"  problem: {p}")
    print(f"wrote {result.json_path} and {result.png_path}")
    return 0 if result.ok else 1


def register(subparsers: Any) -> None:
    """Add `fly DIR --connect URL [--timeout S] [--quiet] [--time-scale X] [--acceptance M]`."""
    p = subparsers.add_parser("fly", help="upload a planned fleet, fly it over MAVLink and write flight.json/.png")
    p.add_argument("dir", help="plan directory (report.json and uavK.plan)")
    p.add_argument("--connect", required=True, help="pymavlink URL of the vehicles' link, e.g. udpout:127.0.0.1:14550")
    p.add_argument("--timeout", type=float, default=600.0, help="give up after this many seconds (default 600)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--time-scale", type=float, default=None,
                   help="simulated seconds per wall second (default: estimated from the telemetry)")
    p.add_argument("--acceptance", type=float, default=1.0,
                   help="the vehicles' waypoint acceptance radius in metres for items that give none (default 1)")
    p.set_defaults(handler=cmd_fly)
