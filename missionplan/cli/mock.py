"""`missionplan mock`: run mock autopilots (bridge.sim.mock.MockAutopilot) on loopback, a serial device or a
pty until interrupted, with the faults, homes, kills and ground (--dem) asked for; say what it serves and, when
stopped, what it did."""

from __future__ import annotations

import logging
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.errors import BridgeUsageError
from missionplan.bridge.limits import ALTITUDE_AMSL_M, SEED_MAX, check_integer, check_range

from .parsing import runs
from .vehicle import SIGNING_KEY_HELP, signing_key

DEFAULT_LISTEN = "udpin:127.0.0.1:14550"
DEFAULT_HOME_ALT = 0.0  # metres AMSL when --home gives none
MOCK_DEM_MARGIN_M = 10_000.0  # --dem is read this far around the homes: where the vehicles fly and land


@dataclass(frozen=True)
class MockRequest:
    """`mock`: the vehicles and where they listen, the autopilot imitated and how it behaves, the link's
    faults, where each vehicle starts and where it dies, and how long to run."""

    sysid: str
    listen: str
    flavour: str
    speedup: float
    loss: float
    duplicate: float
    reorder: float
    latency: float
    request_interval: float | None
    signing_key: Path | None
    home: tuple[str, ...]
    plan: Path | None
    ready_after: float
    streams_until_asked: bool
    sitl_like: bool
    camera_configured: bool
    kill: tuple[str, ...]
    dem: tuple[Path, ...]
    seed: int | None
    duration: float | None


def register(subparsers: Any) -> None:
    """Add the mock subcommand to an argparse subparsers object."""
    mock = subparsers.add_parser("mock", help="run mock autopilots on loopback until interrupted", allow_abbrev=False)
    mock.add_argument("--sysid", default="1", help="system ids to serve, comma-separated (default 1)")
    mock.add_argument("--listen", default=DEFAULT_LISTEN,
                      help=f"udpin:HOST:PORT, udpout:HOST:PORT, tcpin:HOST:PORT, a serial device DEVICE,BAUD, or "
                           f"pty (a pseudo-terminal: connect to the /dev/pts/N it prints) (default {DEFAULT_LISTEN})")
    mock.add_argument("--flavour", default="ardupilot", choices=("ardupilot", "px4"), help="autopilot to imitate")
    mock.add_argument("--speedup", type=float, default=1.0, help="simulated seconds per real second when flying")
    mock.add_argument("--loss", type=float, default=0.0, help="packet loss probability in each direction")
    mock.add_argument("--duplicate", type=float, default=0.0, help="probability a packet arrives twice")
    mock.add_argument("--reorder", type=float, default=0.0, help="probability a packet is overtaken by later ones")
    mock.add_argument("--latency", type=float, default=0.0, help="added one-way latency in seconds")
    mock.add_argument("--request-interval", type=float, default=None,
                      help="re-request a missing item after this many seconds (default: the flavour's)")
    mock.add_argument("--signing-key", type=Path, metavar="FILE", help=SIGNING_KEY_HELP)
    mock.add_argument("--home", action="append", default=[], metavar="[SYSID=]LAT,LON[,ALT]",
                      help="where a vehicle starts: LAT,LON for every one (drone K placed K-1 x 55 m north), "
                           "or SYSID=LAT,LON for one; repeatable")
    mock.add_argument("--plan", type=Path, metavar="DIR",
                      help="start each vehicle K at the plannedHomePosition of DIR/uavK.plan")
    mock.add_argument("--ready-after", type=float, default=0.0, metavar="S",
                      help="like ArduCopter SITL after power-on: no GPS fix, EKF position, home or arming for S "
                           "simulated seconds, with its PreArm reasons (SITL: 35-40; default 0)")
    mock.add_argument("--streams-until-asked", action="store_true",
                      help="like ArduPilot: send nothing but HEARTBEAT until SET_MESSAGE_INTERVAL asks for a message")
    mock.add_argument("--sitl-like", action="store_true",
                      help="behave like ArduCopter SITL: no camera until CAM1_TYPE is set and the vehicle rebooted, "
                           "img_idx from 1 across flights, ArduCopter's navigation parameters and flight "
                           "(docs/flight-timeline.md)")
    mock.add_argument("--camera-configured", action="store_true",
                      help="with --sitl-like: each vehicle's camera set up as a team does once (ArduPilot CAM1_TYPE 1, "
                           "PX4 TRIG_MODE 4, and a reboot), so it reports its photos from the start")
    mock.add_argument("--kill", action="append", default=[], metavar="SYSID@ITEM",
                      help="vehicle SYSID goes silent for good once it reaches mission item ITEM, as a SITL process "
                           "killed in flight; repeatable")
    mock.add_argument("--dem", type=Path, action="append", default=[], metavar="FILE",
                      help="the world's ground (a GeoTIFF, SRTM .hgt tiles or a folder of them; repeatable): each "
                           "vehicle's home is at the ground's height, it lands on the ground, and an ArduPilot vehicle "
                           "asks the ground station for its terrain and flies terrain-frame items from what it was sent "
                           "(docs/terrain.md)")
    mock.add_argument("--seed", type=int, default=None, help="seed of the fault injection")
    mock.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    mock.set_defaults(handler=runs(MockRequest, cmd_mock))


def _home_value(text: str, option: str) -> tuple[float, float, float]:
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise BridgeUsageError(f"{option} {text}: expected LAT,LON or LAT,LON,ALT in degrees and metres")
    lat, lon = values[0], values[1]
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise BridgeUsageError(f"{option} {text}: latitude must be within -90..90 and longitude within -180..180")
    if len(values) == 3:
        check_range(values[2], f"{option} {text}: altitude", *ALTITUDE_AMSL_M, unit=" m", what="metres above sea level")
    return lat, lon, values[2] if len(values) == 3 else DEFAULT_HOME_ALT


def mock_homes(sysids: list[int], homes: list[str] | tuple[str, ...],
               plan_dir: Path | None) -> dict[int, tuple[float, float, float]]:
    """Each vehicle's home from --home (all, or per SYSID=) and --plan DIR (uavK.plan's planned home)."""
    from missionplan.bridge.link.connection import parse_sysid
    from missionplan.bridge.formats.missionfile import read_mission_file

    out: dict[int, tuple[float, float, float]] = {}
    if plan_dir is not None:
        if not plan_dir.is_dir():
            raise BridgeUsageError(f"--plan {plan_dir}: not a folder")
        for sysid in sysids:
            path = plan_dir / f"uav{sysid}.plan"
            if not path.is_file():
                raise BridgeUsageError(f"--plan {plan_dir}: no uav{sysid}.plan for system id {sysid}")
            home = read_mission_file(path).mission.home
            if home is None:
                raise BridgeUsageError(f"{path}: no plannedHomePosition")
            out[sysid] = (float(home[0]), float(home[1]), float(home[2]))
    for text in sorted(homes, key=lambda t: "=" in t):  # one for all first, then per system id
        if "=" in text:
            who, _, where = text.partition("=")
            sysid = parse_sysid(who, "home")
            if sysid not in sysids:
                raise BridgeUsageError(f"--home {text}: system id {sysid} is not served (--sysid)")
            out[sysid] = _home_value(where, "--home")
        else:
            lat, lon, alt = _home_value(text, "--home")
            for index, sysid in enumerate(sysids):  # side by side, 0.0005 degree (55 m) apart
                out[sysid] = (lat + 0.0005 * index, lon, alt)
    return out


def parse_kills(texts: list[str] | tuple[str, ...], sysids: list[int]) -> dict[int, int]:
    """`--kill SYSID@ITEM` values -> {sysid: mission item}."""
    kills: dict[int, int] = {}
    for text in texts:
        sysid, sep, item = text.partition("@")
        if not sep or not sysid.strip().isdigit() or not item.strip().isdigit():
            raise BridgeUsageError(f"--kill {text}: expected SYSID@ITEM, e.g. 2@8 (vehicle 2 at mission item 8)")
        if int(sysid) not in sysids:
            raise BridgeUsageError(f"--kill {text}: no vehicle {sysid} in --sysid {','.join(map(str, sysids))}")
        kills[int(sysid)] = int(item)
    return kills


def mock_ground(dem: tuple[Path, ...], sysids: list[int], homes: dict[int, tuple[float, float, float]]) -> Any:
    """The ground of --dem (geo.dem.Ground), read MOCK_DEM_MARGIN_M around the vehicles' homes; one line
    (BridgeUsageError, GeoError) when a vehicle has no home given or the DEM no height at one."""
    import numpy as np

    from missionplan.geo.dem import read_ground

    missing = [sysid for sysid in sysids if sysid not in homes]
    if missing:
        raise BridgeUsageError(f"--dem needs each vehicle's home (--home or --plan): none for system id "
                               f"{', '.join(map(str, missing))}")
    lats, lons = [home[0] for home in homes.values()], [home[1] for home in homes.values()]
    ground = read_ground(list(dem), around=(min(lats), min(lons), max(lats), max(lons)), margin_m=MOCK_DEM_MARGIN_M)
    for sysid in sysids:
        lat, lon, _ = homes[sysid]
        if not np.isfinite(ground.height_amsl(np.array([lat]), np.array([lon]))[0]):
            raise BridgeUsageError(f"--dem {', '.join(map(str, dem))}: no ground at system {sysid}'s home "
                                   f"{lat:.7f}, {lon:.7f}")
    return ground


def cmd_mock(request: MockRequest) -> int:
    from missionplan.bridge.link.connection import parse_sysids
    from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot

    sysids = parse_sysids(request.sysid)
    check_range(request.speedup, "--speedup", 0.0, 1_000.0, low_open=True, what="simulated seconds per second")
    for name in ("loss", "duplicate", "reorder"):
        check_range(getattr(request, name), f"--{name}", 0.0, 1.0, what="a probability")
    check_range(request.latency, "--latency", 0.0, 60.0, unit=" s")
    if request.request_interval is not None:
        check_range(request.request_interval, "--request-interval", 0.0, 60.0, unit=" s", low_open=True)
    check_range(request.ready_after, "--ready-after", 0.0, 86_400.0, unit=" s")
    if request.seed is not None:
        check_integer(request.seed, "--seed", 0, SEED_MAX)
    if request.duration is not None:
        check_range(request.duration, "--duration", 0.0, 365 * 86_400.0, unit=" s", low_open=True)
    key = signing_key(request.signing_key)
    faults = LinkFaults(loss_in=request.loss, loss_out=request.loss, duplicate=request.duplicate,
                        reorder=request.reorder, latency=request.latency, seed=request.seed)
    homes = mock_homes(sysids, request.home, request.plan)
    kills = parse_kills(request.kill, sysids)
    if request.camera_configured and not request.sitl_like:
        raise BridgeUsageError("--camera-configured needs --sitl-like (without it every mock vehicle's camera works)")
    ground = mock_ground(request.dem, sysids, homes) if request.dem else None
    mock = MockAutopilot(request.listen, sysids=sysids, flavour=request.flavour, speedup=request.speedup,
                         faults=faults, key=key, request_interval=request.request_interval, homes=homes,
                         gps_fix_after=request.ready_after, streams_until_asked=request.streams_until_asked,
                         sitl_like=request.sitl_like, ground=ground)
    ids = ",".join(str(s) for s in sysids)
    if mock.spec.scheme == "serial":
        where, connect = f"serial device {mock.device}", f"the other end of {mock.device}"
    elif mock.spec.scheme == "pty":
        where, connect = f"pseudo-terminal {mock.device}", mock.client_url
    else:
        where, connect = f"{request.listen} (port {mock.port})", mock.client_url
    print(f"mock autopilot: systems {ids} ({request.flavour}{', signed' if key else ''}) on {where}; "
          f"connect with --connect {connect}; Ctrl-C stops", flush=True)
    if ground is not None:
        print(f"  ground: {', '.join(ground.sources)} ({ground.resolution_m:.0f} m); homes at its height", flush=True)
    for sysid in sorted(homes):
        lat, lon, alt = mock.vehicle(sysid).options.home
        print(f"  system {sysid} starts at {lat:.7f}, {lon:.7f}, {alt:g} m AMSL", flush=True)
    for sysid, item in kills.items():
        mock.kill(sysid, at_item=item)
    # What the mock survives (a message it could not answer) is said on stderr, one escaped line each.
    said = logging.StreamHandler(sys.stderr)
    said.setFormatter(logging.Formatter("missionplan mock: %(message)s"))
    logging.getLogger("missionplan.bridge.sim").addHandler(said)
    mock.start()
    if request.camera_configured:
        mock.configure_cameras()
    try:
        deadline = None if request.duration is None else time.monotonic() + request.duration
        while deadline is None or time.monotonic() < deadline:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        mock.stop()
        logging.getLogger("missionplan.bridge.sim").removeHandler(said)
    done = sum(v.uploads_completed for v in mock.vehicles.values())
    print(f"mock autopilot stopped: {done} uploads completed, {mock.stats['in']} packets in, "
          f"{mock.stats['out']} out, {mock.stats['dropped_in'] + mock.stats['dropped_out']} dropped", flush=True)
    return 0
