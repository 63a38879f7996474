"""`missionplan fly DIR`: fly a planned fleet over MAVLink, keep its journal and judge it (flight/fly.py does
the work; this module checks the options, turns SIGTERM into Ctrl-C, and prints the flight).

Exit 0 when the flight is judged good, 1 when it is not (or a link cannot be opened), 2 for bad input, 3 when
the flight's record is not whole in its folder (fly.EXIT_NOT_RECORDED), 130 when interrupted before any
vehicle was started. `--replan` gives fly the live re-task planner (missionplan/planning/retask.py)."""

from __future__ import annotations

import shlex
import signal
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.bridge.errors import BridgeError, BridgeUsageError
from missionplan.bridge.limits import check_integer, check_range
from missionplan.bridge.link.readiness import DEFAULT_LAUNCH_OFFSET_M
from missionplan.bridge.terminal_text import printable

from ..flight.display import print_flight
from ..flight.fleet_start import DEFAULT_READY_S
from ..flight.fly import (ABORT_WINDOW_S, DEFAULT_TELEMETRY_HZ, EXIT_NOT_RECORDED, ON_ABORT, UPLOADERS, fly,
                          refuse_empty_missions)
from ..flight.link_silence import GONE_SILENT_S
from ..flight.retask_planner import RetaskPlan, Survivor
from ..mission.plan_record import PlanRecord
from .errors import said
from .parsing import runs
from .vehicle import CONNECT_HELP, DEFAULT_CONNECT, GcsIdentity, add_gcs_arguments, gcs_identity, signing_key


@dataclass(frozen=True)
class FlyRequest(GcsIdentity):
    """`fly`: the plan folder, resume or not, the links, the waits and checks before arming, the telemetry
    and the time scale, who uploads, the sortie, photos from the track, live re-tasking, what Ctrl-C does,
    and whether to show progress."""

    dir: str
    resume: bool
    connect: tuple[str, ...] | None
    ready_timeout: float
    max_launch_offset: float
    timeout: float
    telemetry_hz: float
    time_scale: float | None
    upload_with: str
    sortie: int
    photos_from_track: bool
    replan: bool
    replan_after: float
    on_abort: str
    quiet: bool


def _sigterm_as_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _plan_retask(plan_dir: Path, record: PlanRecord, survivors: Sequence[Survivor],
                 photos_latlon: np.ndarray) -> RetaskPlan | None:
    """fly --replan's planner (missionplan/planning/retask.py: a flight.retask_planner.RetaskPlanner), imported when a
    re-task is planned."""
    from ..planning.retask import retask_planner

    return retask_planner(plan_dir, record, survivors, photos_latlon)


def cmd_fly(request: FlyRequest) -> int:
    # Every number first, in one place's words (missionplan.bridge.limits; the table: docs/cli.md).
    check_range(request.timeout, "--timeout", 0.0, 7 * 86_400.0, low_open=True, unit=" s")
    check_range(request.telemetry_hz, "--telemetry-hz", 0.01, 1_000.0, unit=" Hz")
    if request.time_scale is not None:
        check_range(request.time_scale, "--time-scale", 0.0, 1_000.0, low_open=True)
    check_range(request.replan_after, "--replan-after", 0.0, 86_400.0, low_open=True, unit=" s")
    check_range(request.ready_timeout, "--ready-timeout", 0.0, 86_400.0, low_open=True, unit=" s")
    check_range(request.max_launch_offset, "--max-launch-offset", 0.0, 10_000.0, unit=" m")
    check_integer(request.sortie, "--sortie", 1, 10_000)
    if not (Path(request.dir) / "report.json").is_file():
        raise BridgeUsageError(f"{request.dir}: no report.json (run `missionplan plan --out {request.dir}` first)")
    if not request.resume:  # a resumed flight uploads nothing
        refuse_empty_missions(Path(request.dir), request.sortie)
    gcs = gcs_identity(request, [])  # the drones' own ids are checked by fly(), once report.json is read
    # --connect appends; its default applies only when none is given (an argparse append default
    # would be appended to, not replaced).
    connect = list(request.connect or [DEFAULT_CONNECT])
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _sigterm_as_interrupt)  # a stop from a service manager: as Ctrl-C
    try:
        result = fly(Path(request.dir), connect, timeout_s=request.timeout, progress=not request.quiet,
                     time_scale=request.time_scale, telemetry_hz=request.telemetry_hz,
                     upload_with=request.upload_with, sortie=request.sortie, ready_s=request.ready_timeout,
                     max_launch_offset_m=request.max_launch_offset, photos_from_track=request.photos_from_track,
                     key=signing_key(request.signing_key), source_system=gcs[0], source_component=gcs[1],
                     resume=request.resume, on_abort=request.on_abort,
                     command=" ".join(shlex.quote(a) for a in sys.argv),
                     replan=_plan_retask if request.replan else None, replan_after_s=request.replan_after)
    except BridgeUsageError:
        raise
    except BridgeError as err:  # a link that cannot be opened: one line, exit 1
        print(f"missionplan fly: {printable(said(err))}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # before any drone's thread ran: nothing was started or commanded
        print("missionplan fly: interrupted before any vehicle was started; nothing was commanded", file=sys.stderr)
        return 130
    print_flight(result)
    if not result.recorded:
        return EXIT_NOT_RECORDED
    return 0 if result.ok else 1


def register(subparsers: Any) -> None:
    """Add `fly DIR [--resume] [--connect URL ...] [--ready-timeout S] [--max-launch-offset M] [--timeout S]
    [--telemetry-hz HZ] [--time-scale X] [--upload-with W] [--sortie J] [--photos-from-track]
    [--on-abort A] [--signing-key FILE] [--gcs-sysid N] [--gcs-compid N] [--quiet]`."""
    p = subparsers.add_parser("fly", help="upload a planned fleet, fly it over MAVLink and judge the flight "
                                          "(flight.json, flight.png)", allow_abbrev=False)
    p.add_argument("dir", help="plan folder written by `missionplan plan` (report.json, uavK.plan)")
    p.add_argument("--resume", action="store_true",
                   help="follow again the flight a stopped or killed fly left in DIR (its journal): only vehicles "
                        "holding that flight's mission, nothing commanded; then judge the whole flight")
    p.add_argument("--connect", action="append", default=None, metavar="URL",
                   help=f"{CONNECT_HELP}; the vehicles share it, told apart by system id; repeat it for vehicles on "
                        "several links (each found on its link by its heartbeat), or give SYSID=URL (1,2=URL) to "
                        "say which")
    p.add_argument("--ready-timeout", type=float, default=DEFAULT_READY_S,
                   help=f"wait this many seconds at most for each vehicle's GPS fix, EKF, home position and pre-arm "
                        f"checks (default {DEFAULT_READY_S:g})")
    p.add_argument("--max-launch-offset", type=float, default=DEFAULT_LAUNCH_OFFSET_M, metavar="M",
                   help=f"refuse to arm any vehicle when one's home is more than M metres plus its reported GPS "
                        f"error from its plan's launch point (default {DEFAULT_LAUNCH_OFFSET_M:g})")
    p.add_argument("--timeout", type=float, default=600.0, help="give up after this many seconds (default 600)")
    p.add_argument("--telemetry-hz", type=float, default=DEFAULT_TELEMETRY_HZ,
                   help=f"position stream rate to ask each vehicle for (default {DEFAULT_TELEMETRY_HZ:g})")
    p.add_argument("--time-scale", type=float, default=None,
                   help="simulated seconds per wall second of a sped-up simulator (default: estimated from the "
                        "reported velocities; 1 for real vehicles)")
    p.add_argument("--upload-with", choices=UPLOADERS, default="missionplan",
                   help="who reads the .plan files and uploads them: our reader and uploader (default), or "
                        "MAVSDK's QGroundControl importer and MissionRaw (checked against ours by read-back)")
    p.add_argument("--sortie", type=int, default=1, metavar="J",
                   help="battery sortie to fly: 1 (uavK.plan, default) or J (uavK-sJ.plan, drones that have one)")
    p.add_argument("--photos-from-track", action="store_true",
                   help="a vehicle that reports no photos (no CAMERA_FEEDBACK: no camera configured) gets one every "
                        "trigger distance along its flown track; without this flag such a flight fails")
    p.add_argument("--replan", action="store_true",
                   help="live re-tasking: when a drone is lost or ends early, plan what is left for the drones still "
                        "flying, from where they are (endurance, separation and fences checked), and upload it to "
                        "them in flight; a lost drone heard again is sent home (RTL)")
    p.add_argument("--replan-after", type=float, default=GONE_SILENT_S, metavar="S",
                   help=f"with --replan: a drone not heard for S seconds mid-mission counts as lost "
                        f"(default {GONE_SILENT_S:g})")
    p.add_argument("--on-abort", choices=ON_ABORT, default="none",
                   help="what Ctrl-C commands the vehicles this run started: nothing (default: they fly on with their "
                        f"missions; a second Ctrl-C within {ABORT_WINDOW_S:g} s sends them home), rtl or land")
    add_gcs_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bars or progress lines (alerts are still said)")
    p.set_defaults(handler=runs(FlyRequest, cmd_fly))
