"""`missionplan upload`, `download` and `clear`: a mission to or from one vehicle over MAVLink, and the link
options `fly` and `mock` share with them.

A handler takes its typed request and returns the exit code: 0 on success (for upload: the vehicle holds
exactly the mission sent, unless --no-verify), 1 after printing one line to stderr when the vehicle or the
link fails. Bad input (missing file, bad URL, bad system id, bad key file) raises BridgeUsageError, which
main() prints in one line, exit 2. The work is the bridge's (transfer.uploader, formats.missionfile).
A mission of a plan folder made over a DEM (heights above the ground) uploaded to ArduPilot: the folder's
ground is served to the vehicle from before the upload until it reports it loaded, bounded
(flight.terrain_service.UploadTerrain); the line that says so follows the upload's (stderr when it did
not load: the mission is on board all the same, exit 0, and fly serves the ground again before arming).
A mission of a plan folder whose photos a MAVLink camera takes (report.json's `--capture camera` or
`camera-interval`): the vehicle's camera parameters and its camera are checked first (bridge.link.camera_check,
within --timeout), and a vehicle without them gets nothing, exit 1, in one line that says what to set.

The link options (add_gcs_arguments, CONNECT_HELP, DEFAULT_CONNECT) are shared with `fly`, so every
command has the same default connection, signing key and ground-station identity. No parser here
accepts abbreviated options (allow_abbrev=False): `--uav 3` is an error, not `--uavs 3`.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.errors import BridgeError, BridgeUsageError
from missionplan.bridge.formats.mission_items import Flavour, MissionType
from missionplan.bridge.limits import check_integer, check_range
from missionplan.bridge.link.connection import GCS_COMPONENT_ID, GCS_SYSTEM_ID
from missionplan.bridge.terminal_text import printable

from .errors import said
from .parsing import runs

DEFAULT_CONNECT = "udpin:0.0.0.0:14550"  # where ground stations listen for vehicles by convention (QGroundControl)
CONNECT_HELP = (f"pymavlink connection string: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or a "
                f"serial device DEVICE,BAUD (default {DEFAULT_CONNECT}, where ground stations listen for vehicles)")
SIGNING_KEY_HELP = "MAVLink 2 signing key file (32 bytes or 64 hex digits): sign every packet, accept only signed ones"
GCS_SYSID_HELP = (f"our system id on the link, 1..255 (default {GCS_SYSTEM_ID}). ArduPilot's GCS failsafe watches "
                  f"system SYSID_MYGCS (default 255): with another id we are not \"the\" GCS for it; but two ground "
                  "stations with one id (MAVProxy and missionplan both 255) interleave in a mission transfer: give "
                  "one of them another id")
GCS_COMPID_HELP = f"our component id on the link, 1..255 (default {GCS_COMPONENT_ID}, MAV_COMP_ID_MISSIONPLANNER)"


@dataclass(frozen=True)
class GcsIdentity:
    """How we appear on the link: the signing key file, our system and component ids (as given)."""

    signing_key: Path | None
    gcs_sysid: str
    gcs_compid: str


@dataclass(frozen=True)
class VehicleRequest(GcsIdentity):
    """`clear` (and what upload and download share): the vehicle (system and component id), the link, the
    waits and retries of the mission protocol, and whether to show progress."""

    sysid: str
    compid: str
    connect: str
    timeout: float
    item_timeout: float
    retries: int
    quiet: bool


@dataclass(frozen=True)
class UploadRequest(VehicleRequest):
    """`upload`: the mission file, who runs the protocol, and what to check or leave."""

    file: Path
    backend: str
    no_verify: bool
    allow_empty: bool
    keep_params: bool


@dataclass(frozen=True)
class DownloadRequest(VehicleRequest):
    """`download`: the file to write."""

    output: Path


def register(subparsers: Any) -> None:
    """Add the upload, download and clear subcommands to an argparse subparsers object."""
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
                         "acceptance radius, which it does not read from the waypoints, and for waypoints above the "
                         "ground the terrain parameters and RTL_ALT_TYPE = 1)")
    up.set_defaults(handler=runs(UploadRequest, cmd_upload))

    down = subparsers.add_parser("download", help="download a vehicle's mission to a .plan or .waypoints file",
                                 allow_abbrev=False)
    _vehicle_arguments(down)
    down.add_argument("-o", "--output", required=True, type=Path, help="file to write (.plan, .waypoints or .txt)")
    down.set_defaults(handler=runs(DownloadRequest, cmd_download))

    clear = subparsers.add_parser("clear", help="clear a vehicle's mission, geofence and rally points, and verify",
                                  allow_abbrev=False)
    _vehicle_arguments(clear)
    clear.set_defaults(handler=runs(VehicleRequest, cmd_clear))


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
    print(f"missionplan {command}: {printable(said(err))}", file=sys.stderr)  # it may quote a vehicle's words
    return 1


def _checked(request: VehicleRequest, backend: str = "pymavlink") -> dict[str, Any]:
    """The options every vehicle command shares, checked before anything is opened."""
    from missionplan.bridge.link.connection import parse_compid, parse_sysid, parse_url
    from missionplan.bridge.transfer.protocol import Timeouts
    from missionplan.bridge.transfer.uploader import check_gcs_identity

    sysid = parse_sysid(request.sysid)
    compid = parse_compid(request.compid)
    gcs = gcs_identity(request, [sysid])
    check_gcs_identity(backend, *gcs)
    parse_url(request.connect)
    check_range(request.timeout, "--timeout", 0.0, 86_400.0, unit=" s", low_open=True)
    check_range(request.item_timeout, "--item-timeout", 0.0, 3_600.0, unit=" s", low_open=True)
    check_integer(request.retries, "--retries", 0, 1_000)
    return {"url": request.connect, "sysid": sysid, "compid": compid, "key": signing_key(request.signing_key),
            "timeouts": Timeouts(item_timeout=request.item_timeout, retries=request.retries),
            "connect_timeout": request.timeout, "source_system": gcs[0], "source_component": gcs[1]}


def gcs_identity(request: GcsIdentity, vehicles: list[int]) -> tuple[int, int]:
    """(--gcs-sysid, --gcs-compid), checked: one-line BridgeUsageError for a bad id or a vehicle's own."""
    from missionplan.bridge.link.connection import parse_compid, parse_gcs_sysid

    return parse_gcs_sysid(request.gcs_sysid, vehicles), parse_compid(request.gcs_compid, "gcs_compid")


def signing_key(path: Path | None) -> Any:
    """The --signing-key file's key (link.signing.SigningKey), or None without the option."""
    from missionplan.bridge.link.signing import load_key

    return load_key(path) if path is not None else None


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

def cmd_upload(request: UploadRequest) -> int:
    from missionplan.bridge.formats.mission_items import to_wire
    from missionplan.bridge.formats.missionfile import check_firmware, read_mission_file
    from missionplan.bridge.transfer.uploader import open_backend, upload_plan

    from ..flight.terrain_service import UPLOAD_LOAD_S

    opts = _checked(request, request.backend)
    plan = read_mission_file(request.file)
    if not plan.mission.items and not request.allow_empty:
        # Uploading nothing replaces the vehicle's mission with nothing: never by accident.
        raise BridgeUsageError(f"{request.file}: the file holds no mission items; uploading it would wipe the "
                               "vehicle's mission (pass --allow-empty to mean that, or use `missionplan clear`)")
    ground, spacing = _ground_beside(request.file, plan)  # a plan over a DEM: its ground, served to ArduPilot
    capture = _capture_beside(request.file)  # a camera mode: the vehicle's MAVLink camera is checked first
    bars = _Bars(request.quiet)
    backend = None
    terrain: list[tuple[Any, str]] = []  # what the ground's serving came to: (stream, line)
    try:
        backend = open_backend(request.backend, opts["url"], opts["sysid"], opts["compid"], opts["key"],
                               opts["timeouts"], opts["connect_timeout"], source_system=opts["source_system"],
                               source_component=opts["source_component"])
        check_firmware(plan, request.file, backend.vehicle.flavour, opts["sysid"])  # learned from its HEARTBEAT
        _check_camera(backend, capture, opts["connect_timeout"], terrain)  # before anything is sent
        served = _serve_ground(backend, ground, terrain)
        report = upload_plan(backend, plan.parts(), verify=not request.no_verify, progress=bars,
                             set_params=not request.keep_params, terrain_spacing=spacing)
        if served is not None:
            bars.close()
            status = served.finish(to_wire(plan.mission, Flavour.ARDUPILOT), UPLOAD_LOAD_S)
            line = f"uav{opts['sysid']}: {status.line()}"
            terrain.append((sys.stdout, line) if status.loaded_ok else
                           (sys.stderr, f"missionplan upload: {line} (fly serves it again before arming)"))
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
    for stream, line in terrain:
        print(printable(line), file=stream)
    return 0


def _ground_beside(path: Path, plan: Any) -> tuple[Any, int | None]:
    """The ground of the plan folder `path` is in (report.json's georeference.terrain, its copy of the DEM) and
    the TERRAIN_SPACING its heights were checked on, when the mission flies heights above the ground on
    ArduPilot; (None, None) otherwise. GeoError, one line, when the folder's copy of the ground cannot be read."""
    from missionplan.bridge.link.params import uses_terrain

    from ..flight.terrain_service import plan_ground
    from ..mission.plan_record import read_plan_record

    folder = path.parent
    if plan.firmware is Flavour.PX4 or not uses_terrain(plan.mission) or not (folder / "report.json").is_file():
        return None, None
    record = read_plan_record(folder)
    terrain = record.georeference.terrain if record.georeference is not None else None
    return plan_ground(folder, record), terrain.spacing_m if terrain is not None else None


def _capture_beside(path: Path) -> str:
    """How the plan folder `path` is in takes its photos (report.json's `--capture`; "relay" without a report)."""
    from ..mission.plan_record import read_plan_record

    if not (path.parent / "report.json").is_file():
        return "relay"
    settings = read_plan_record(path.parent).settings
    return settings.mission.capture if settings is not None else "relay"


def _check_camera(backend: Any, capture: str, wait_s: float, said: list[tuple[Any, str]]) -> None:
    """A plan whose photos a MAVLink camera takes: the vehicle's camera parameters and its camera heard within
    wait_s (bridge.link.camera_check); BridgeError naming the vehicle, what it lacks and what to set. Not checked
    (said in `said`) when the backend owns its link."""
    from missionplan.bridge.link.camera_check import CAMERA_MODES, check_camera
    from missionplan.bridge.link.readiness import Vehicle
    from missionplan.bridge.transfer.uploader import PymavlinkBackend

    if capture not in CAMERA_MODES:
        return
    sysid = backend.vehicle.sysid
    if not isinstance(backend, PymavlinkBackend):
        said.append((sys.stderr, f"missionplan upload: uav{sysid}: its MAVLink camera not checked: the "
                                 f"{backend.name} backend reads the link itself (fly checks it before the upload)"))
        return
    start = time.monotonic()
    problem = check_camera(Vehicle(backend.link, backend.vehicle), capture, start + wait_s, start)
    if problem:
        raise BridgeError(f"vehicle {sysid}: {problem}")


def _serve_ground(backend: Any, ground: Any, said: list[tuple[Any, str]]) -> Any:
    """Begin serving `ground` on the upload's link (terrain_service.UploadTerrain); None when there is none
    to serve, or when the backend owns its link (said in `said`)."""
    if ground is None:
        return None
    from ..flight.terrain_service import UploadTerrain

    served = UploadTerrain.start(backend, ground)
    if served is None and backend.vehicle.flavour is Flavour.ARDUPILOT:
        said.append((sys.stderr, f"missionplan upload: uav{backend.vehicle.sysid}: terrain not served: the "
                                 f"{backend.name} backend reads the link itself (fly serves it before arming)"))
    return served


def cmd_download(request: DownloadRequest) -> int:
    from missionplan.bridge.formats.missionfile import PlanFile, write_mission_file
    from missionplan.bridge.transfer.uploader import download_plan, open_backend

    from missionplan.bridge.formats.missionfile import output_format

    opts = _checked(request)
    out: Path = request.output
    try:
        as_plan = output_format(out) == "plan"
    except BridgeUsageError:
        raise BridgeUsageError(f"-o {out}: unknown mission file type {out.suffix!r} (expected .plan, .waypoints "
                               "or .txt)") from None
    _check_writable(out)
    bars = _Bars(request.quiet)
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


def cmd_clear(request: VehicleRequest) -> int:
    from missionplan.bridge.transfer.uploader import clear_plan, open_backend

    opts = _checked(request)
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
