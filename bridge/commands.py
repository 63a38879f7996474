"""The `upload`, `download`, `clear` and `mock` subcommands, for the missionplan command line.

Owns argument definitions and handlers only; the work is done by uploader, missionfile and mock.
`register(subparsers)` adds the four parsers, each with set_defaults(handler=...). A handler takes
the parsed arguments and returns the exit code: 0 on success (for upload: the vehicle holds exactly
the mission sent, unless --no-verify), 1 after printing one line to stderr when the vehicle or the
link fails. Bad input (missing file, bad URL, bad system id, bad key file) raises BridgeUsageError;
the main CLI prints its one-line message and exits 2.

Also the link options `fly` shares with upload / download / clear (add_gcs_arguments, CONNECT_HELP),
so every command has the same default connection, signing key and ground-station identity. No
parser here accepts abbreviated options (allow_abbrev=False): `--uav 3` is an error, not `--uavs 3`.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .errors import BridgeError, BridgeUsageError
from .limits import ALTITUDE_AMSL_M, SEED_MAX, check_integer, check_range
from .terminal_text import printable
from .link.connection import GCS_COMPONENT_ID, GCS_SYSTEM_ID
from .formats.mission_items import Flavour, MissionType

DEFAULT_CONNECT = "udpin:0.0.0.0:14550"  # where ground stations listen for vehicles by convention (QGroundControl)
CONNECT_HELP = (f"pymavlink connection string: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or a "
                f"serial device DEVICE,BAUD (default {DEFAULT_CONNECT}, where ground stations listen for vehicles)")
SIGNING_KEY_HELP = "MAVLink 2 signing key file (32 bytes or 64 hex digits): sign every packet, accept only signed ones"
GCS_SYSID_HELP = (f"our system id on the link, 1..255 (default {GCS_SYSTEM_ID}). ArduPilot's GCS failsafe watches "
                  f"system SYSID_MYGCS (default 255): with another id we are not \"the\" GCS for it; but two ground "
                  "stations with one id (MAVProxy and missionplan both 255) interleave in a mission transfer: give "
                  "one of them another id")
GCS_COMPID_HELP = f"our component id on the link, 1..255 (default {GCS_COMPONENT_ID}, MAV_COMP_ID_MISSIONPLANNER)"
DEFAULT_LISTEN = "udpin:127.0.0.1:14550"
DEFAULT_HOME_ALT = 0.0  # metres AMSL when --home gives none


def register(subparsers: Any) -> None:
    """Add the upload, download, clear and mock subcommands to an argparse subparsers object."""
    up = subparsers.add_parser("upload", help="upload a .plan or .waypoints mission to a vehicle and verify it",
                               allow_abbrev=False)
    up.add_argument("file", type=Path, help="mission file (.plan, .waypoints, QGC's legacy .mission, or a QGC WPL 110 .txt)")
    _vehicle_arguments(up)
    up.add_argument("--backend", default="pymavlink", choices=("pymavlink", "mavsdk"),
                    help="who runs the mission protocol (default pymavlink)")
    up.add_argument("--no-verify", action="store_true", help="skip the read-back (exit 0 then means accepted)")
    up.add_argument("--allow-empty", action="store_true",
                    help="let a file without mission items clear the vehicle's mission (refused otherwise)")
    up.add_argument("--keep-params", action="store_true",
                    help="set no vehicle parameter (by default an ArduCopter gets WPNAV_RADIUS = the plan's "
                         "acceptance radius, which it does not read from the waypoints)")
    up.set_defaults(handler=cmd_upload)

    down = subparsers.add_parser("download", help="download a vehicle's mission to a .plan or .waypoints file",
                                 allow_abbrev=False)
    _vehicle_arguments(down)
    down.add_argument("-o", "--output", required=True, type=Path, help="file to write (.plan, .waypoints or .txt)")
    down.set_defaults(handler=cmd_download)

    clear = subparsers.add_parser("clear", help="clear a vehicle's mission, geofence and rally points, and verify",
                                  allow_abbrev=False)
    _vehicle_arguments(clear)
    clear.set_defaults(handler=cmd_clear)

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
    mock.add_argument("--seed", type=int, default=None, help="seed of the fault injection")
    mock.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    mock.set_defaults(handler=cmd_mock)


def add_gcs_arguments(parser: argparse.ArgumentParser) -> None:
    """--signing-key, --gcs-sysid and --gcs-compid: how we appear on the link (upload, download, clear, fly)."""
    parser.add_argument("--signing-key", type=Path, metavar="FILE", help=SIGNING_KEY_HELP)
    parser.add_argument("--gcs-sysid", default=str(GCS_SYSTEM_ID), metavar="N", help=GCS_SYSID_HELP)
    parser.add_argument("--gcs-compid", default=str(GCS_COMPONENT_ID), metavar="N", help=GCS_COMPID_HELP)


def _vehicle_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sysid", required=True, help="the vehicle's MAVLink system id (1..254)")
    parser.add_argument("--compid", default="1", help="the autopilot's component id (default 1)")
    parser.add_argument("--connect", default=DEFAULT_CONNECT, metavar="URL", help=CONNECT_HELP)
    parser.add_argument("--timeout", type=float, default=10.0,
                        help="seconds to wait for the vehicle's heartbeat (default 10)")
    parser.add_argument("--item-timeout", type=float, default=1.5,
                        help="longest wait for one protocol step before re-sending (default 1.5 s)")
    parser.add_argument("--retries", type=int, default=5,
                        help="a step fails after item-timeout * (retries + 1) s without progress (default 5)")
    add_gcs_arguments(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


# ------------------------------------------------------------------------------------------ helpers

def _fail(command: str, err: BaseException) -> int:
    print(f"missionplan {command}: {printable(err)}", file=sys.stderr)  # it may quote a vehicle's words
    return 1


def _checked(args: argparse.Namespace) -> dict[str, Any]:
    """The options every vehicle command shares, checked before anything is opened."""
    from .link.connection import parse_compid, parse_sysid, parse_url
    from .transfer.protocol import Timeouts
    from .transfer.uploader import check_gcs_identity

    sysid = parse_sysid(args.sysid)
    compid = parse_compid(args.compid)
    gcs = gcs_identity(args, [sysid])
    check_gcs_identity(getattr(args, "backend", "pymavlink"), *gcs)
    parse_url(args.connect)
    check_range(args.timeout, "--timeout", 0.0, 86_400.0, unit=" s", low_open=True)
    check_range(args.item_timeout, "--item-timeout", 0.0, 3_600.0, unit=" s", low_open=True)
    check_integer(args.retries, "--retries", 0, 1_000)
    return {"url": args.connect, "sysid": sysid, "compid": compid, "key": signing_key(args),
            "timeouts": Timeouts(item_timeout=args.item_timeout, retries=args.retries),
            "connect_timeout": args.timeout, "source_system": gcs[0], "source_component": gcs[1]}


def gcs_identity(args: argparse.Namespace, vehicles: list[int]) -> tuple[int, int]:
    """(--gcs-sysid, --gcs-compid), checked: one-line BridgeUsageError for a bad id or a vehicle's own."""
    from .link.connection import parse_compid, parse_gcs_sysid

    return parse_gcs_sysid(args.gcs_sysid, vehicles), parse_compid(args.gcs_compid, "--gcs-compid")


def signing_key(args: argparse.Namespace) -> Any:
    """The --signing-key file's key (link.signing.SigningKey), or None without the option."""
    from .link.signing import load_key

    return load_key(args.signing_key) if args.signing_key is not None else None


class _Bars:
    """tqdm progress bars on stderr, one per transfer; silent when stderr is not a terminal."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bars: list[Any] = []

    def __call__(self, label: str, total: int) -> Callable[[int, int], None] | None:
        if self.quiet:
            return None
        from tqdm import tqdm

        bar = tqdm(total=total or None, desc=label, unit="item", leave=False, disable=None, file=sys.stderr)
        self.bars.append(bar)

        def update(done: int, all_items: int) -> None:
            if all_items and bar.total != all_items:
                bar.total = all_items
            bar.n = done
            bar.refresh()

        return update

    def close(self) -> None:
        for bar in self.bars:
            bar.close()
        self.bars.clear()


# ----------------------------------------------------------------------------------------- handlers

def cmd_upload(args: argparse.Namespace) -> int:
    from .formats.missionfile import check_firmware, read_mission_file
    from .transfer.uploader import open_backend, upload_plan

    opts = _checked(args)
    plan = read_mission_file(args.file)
    if not plan.mission.items and not args.allow_empty:
        # Uploading nothing replaces the vehicle's mission with nothing: never by accident.
        raise BridgeUsageError(f"{args.file}: the file holds no mission items; uploading it would wipe the "
                               "vehicle's mission (pass --allow-empty to mean that, or use `missionplan clear`)")
    bars = _Bars(args.quiet)
    backend = None
    try:
        backend = open_backend(args.backend, opts["url"], opts["sysid"], opts["compid"], opts["key"],
                               opts["timeouts"], opts["connect_timeout"], source_system=opts["source_system"],
                               source_component=opts["source_component"])
        check_firmware(plan, args.file, backend.vehicle.flavour, opts["sysid"])  # learned from its HEARTBEAT
        report = upload_plan(backend, plan.parts(), verify=not args.no_verify, progress=bars,
                             set_params=not args.keep_params)
    except BridgeUsageError:
        raise  # a file for the other autopilot: bad input, exit 2
    except BridgeError as err:
        bars.close()
        return _fail("upload", err)
    finally:
        bars.close()
        if backend is not None:
            backend.close()
    print(report.summary())
    return 0


def cmd_download(args: argparse.Namespace) -> int:
    from .formats.missionfile import PlanFile, write_mission_file
    from .transfer.uploader import download_plan, open_backend

    from .formats.missionfile import output_format

    opts = _checked(args)
    out: Path = args.output
    try:
        as_plan = output_format(out) == "plan"
    except BridgeUsageError:
        raise BridgeUsageError(f"-o {out}: unknown mission file type {out.suffix!r} (expected .plan, .waypoints "
                               "or .txt)") from None
    _check_writable(out)
    bars = _Bars(args.quiet)
    backend = None
    start = time.monotonic()
    try:
        backend = open_backend("pymavlink", opts["url"], opts["sysid"], opts["compid"], opts["key"],
                               opts["timeouts"], opts["connect_timeout"], source_system=opts["source_system"],
                               source_component=opts["source_component"])
        mission = download_plan(backend, [MissionType.MISSION], bars)[0]
        plan = PlanFile(mission=mission, firmware=backend.vehicle.flavour)
        if as_plan:  # a .plan also carries the geofence and rally points
            for mtype in (MissionType.FENCE, MissionType.RALLY):
                try:
                    part = download_plan(backend, [mtype], bars)[0]
                except BridgeError as err:
                    if getattr(err, "result", None) == 3:  # MAV_MISSION_UNSUPPORTED: the vehicle has none
                        continue
                    raise
                if mtype == MissionType.FENCE:
                    plan.fence = part
                else:
                    plan.rally = part
        flavour: Flavour = backend.vehicle.flavour
    except BridgeError as err:
        return _fail("download", err)
    finally:
        bars.close()
        if backend is not None:
            backend.close()
    try:
        write_mission_file(out, plan)  # atomic: on failure nothing is left behind
    except OSError as err:
        return _fail("download", BridgeError(f"cannot write {out}: {err.strerror or err}; nothing was written"))
    extra = "".join(f", {len(p.items)} {p.mission_type.label}" for p in (plan.fence, plan.rally) if p.items)
    print(f"downloaded {len(plan.mission.items)} mission items{extra} from vehicle {opts['sysid']} ({flavour.value}) "
          f"to {printable(out)} in {time.monotonic() - start:.2f} s")
    return 0


def _check_writable(out: Path) -> None:
    """-o must be creatable before we spend a download on it: probe with a temp file in its folder.

    (os.access says yes to root even on read-only or special file systems; a real create does not.)
    """
    if out.is_dir():
        raise BridgeUsageError(f"-o {out}: is a folder, not a file name")
    if not out.parent.is_dir():
        raise BridgeUsageError(f"-o {out}: folder {out.parent} does not exist")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".probe", dir=out.parent)
    except OSError as err:
        raise BridgeUsageError(f"-o {out}: cannot write in {out.parent} ({err.strerror or err})") from None
    os.close(fd)
    os.unlink(probe)


def cmd_clear(args: argparse.Namespace) -> int:
    from .transfer.uploader import clear_plan, open_backend

    opts = _checked(args)
    backend = None
    try:
        backend = open_backend("pymavlink", opts["url"], opts["sysid"], opts["compid"], opts["key"],
                               opts["timeouts"], opts["connect_timeout"], source_system=opts["source_system"],
                               source_component=opts["source_component"])
        report = clear_plan(backend)
    except BridgeError as err:
        return _fail("clear", err)
    finally:
        if backend is not None:
            backend.close()
    print(report)
    return 0
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


def mock_homes(sysids: list[int], homes: list[str], plan_dir: Path | None) -> dict[int, tuple[float, float, float]]:
    """Each vehicle's home from --home (all, or per SYSID=) and --plan DIR (uavK.plan's planned home)."""
    from .link.connection import parse_sysid
    from .formats.missionfile import read_mission_file

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
            sysid = parse_sysid(who, "--home")
            if sysid not in sysids:
                raise BridgeUsageError(f"--home {text}: system id {sysid} is not served (--sysid)")
            out[sysid] = _home_value(where, "--home")
        else:
            lat, lon, alt = _home_value(text, "--home")
            for index, sysid in enumerate(sysids):  # side by side, 0.0005 degree (55 m) apart
                out[sysid] = (lat + 0.0005 * index, lon, alt)
    return out


def parse_kills(texts: list[str], sysids: list[int]) -> dict[int, int]:
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


def cmd_mock(args: argparse.Namespace) -> int:
    from .link.connection import parse_sysids
    from .sim.mock import LinkFaults, MockAutopilot

    sysids = parse_sysids(args.sysid)
    check_range(args.speedup, "--speedup", 0.0, 1_000.0, low_open=True, what="simulated seconds per second")
    for name in ("loss", "duplicate", "reorder"):
        check_range(getattr(args, name), f"--{name}", 0.0, 1.0, what="a probability")
    check_range(args.latency, "--latency", 0.0, 60.0, unit=" s")
    if args.request_interval is not None:
        check_range(args.request_interval, "--request-interval", 0.0, 60.0, unit=" s", low_open=True)
    check_range(args.ready_after, "--ready-after", 0.0, 86_400.0, unit=" s")
    if args.seed is not None:
        check_integer(args.seed, "--seed", 0, SEED_MAX)
    if args.duration is not None:
        check_range(args.duration, "--duration", 0.0, 365 * 86_400.0, unit=" s", low_open=True)
    key = signing_key(args)
    faults = LinkFaults(loss_in=args.loss, loss_out=args.loss, duplicate=args.duplicate, reorder=args.reorder,
                        latency=args.latency, seed=args.seed)
    homes = mock_homes(sysids, args.home, args.plan)
    kills = parse_kills(args.kill, sysids)
    if args.camera_configured and not args.sitl_like:
        raise BridgeUsageError("--camera-configured needs --sitl-like (without it every mock vehicle's camera works)")
    mock = MockAutopilot(args.listen, sysids=sysids, flavour=args.flavour, speedup=args.speedup, faults=faults,
                         key=key, request_interval=args.request_interval, homes=homes,
                         gps_fix_after=args.ready_after, streams_until_asked=args.streams_until_asked,
                         sitl_like=args.sitl_like)
    ids = ",".join(str(s) for s in sysids)
    if mock.spec.scheme == "serial":
        where, connect = f"serial device {mock.device}", f"the other end of {mock.device}"
    elif mock.spec.scheme == "pty":
        where, connect = f"pseudo-terminal {mock.device}", mock.client_url
    else:
        where, connect = f"{args.listen} (port {mock.port})", mock.client_url
    print(f"mock autopilot: systems {ids} ({args.flavour}{', signed' if key else ''}) on {where}; "
          f"connect with --connect {connect}; Ctrl-C stops", flush=True)
    for sysid, (lat, lon, alt) in sorted(homes.items()):
        print(f"  system {sysid} starts at {lat:.7f}, {lon:.7f}, {alt:g} m AMSL", flush=True)
    for sysid, item in kills.items():
        mock.kill(sysid, at_item=item)
    # What the mock survives (a message it could not answer) is said on stderr, one escaped line each.
    said = logging.StreamHandler(sys.stderr)
    said.setFormatter(logging.Formatter("missionplan mock: %(message)s"))
    logging.getLogger("missionplan.bridge.sim").addHandler(said)
    mock.start()
    if args.camera_configured:
        mock.configure_cameras()
    try:
        deadline = None if args.duration is None else time.monotonic() + args.duration
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
