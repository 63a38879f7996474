"""`missionplan verify PLAN_DIR`: fly a plan many times on simulated fleets, in wind and with faults, and answer
each promise as a distribution (missionplan/verify/: the runs, the engines, the files).

Exit 0 when every run kept every promise (coverage, separation, battery reserve), 1 when some did not or a run
failed to fly, 2 for bad input (one line), 130 when stopped by Ctrl-C (what finished is kept: --resume)."""

from __future__ import annotations

import os
import signal
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.errors import BridgeUsageError
from missionplan.bridge.limits import SEED_MAX, check_integer, check_range

from ..verify.conditions import FAULT_KINDS, ConditionsError, parse_faults, parse_wind
from ..verify.engines import ENGINES, EngineError
from ..verify.verify import DEFAULT_TIME_SCALE, VerifySettings, verify_plan
from ..verify.verify_files import VerifyFolderError
from .errors import said
from .parsing import runs

SIMULATORS = ("mock", "sitl")
EXIT_STOPPED = 130


@dataclass(frozen=True)
class VerifyRequest:
    """`verify`: the plan folder, the runs and what they meet, the simulator, the engine and where it runs, the
    output folder, resume or not, and whether to show progress."""

    dir: str
    runs: int
    wind: str
    faults: str
    replan: bool
    seed: int
    sim: str
    sitl_dir: str | None
    time_scale: float
    engine: str
    workers: int | None
    address: str | None
    out: str | None
    resume: bool
    keep_flights: bool
    quiet: bool


def _sigterm_as_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def cmd_verify(request: VerifyRequest) -> int:
    check_integer(request.runs, "--runs", 1, 100_000)
    check_integer(request.seed, "--seed", 0, SEED_MAX)
    check_range(request.time_scale, "--time-scale", 0.0, 1_000.0, low_open=True)
    if request.workers is not None:
        check_integer(request.workers, "--workers", 1, 10_000)
    try:
        wind, faults = parse_wind(request.wind), parse_faults(request.faults)
    except ConditionsError as err:
        raise BridgeUsageError(said(err)) from None
    if request.sim == "sitl" and not request.sitl_dir:
        raise BridgeUsageError("--sim sitl needs --sitl-dir DIR (the folder of the arducopter binary and copter.parm)")
    settings = VerifySettings(runs=request.runs, seed=request.seed, wind=wind, faults=faults, replan=request.replan,
                              sim=request.sim, time_scale=request.time_scale)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    address = request.address or os.environ.get("RAY_ADDRESS") or None
    try:
        result = verify_plan(Path(request.dir), settings, out=Path(request.out) if request.out else None,
                             engine=request.engine, workers=request.workers, address=address, resume=request.resume,
                             keep_flights=request.keep_flights, progress=not request.quiet, sitl_dir=request.sitl_dir)
    except (VerifyFolderError, EngineError) as err:
        raise BridgeUsageError(said(err)) from None
    print(f"verify: {result.verdict}")
    print(f"  {', '.join(str(p) for p in result.files)}")
    if not result.complete:
        return EXIT_STOPPED
    s = result.summary
    kept = s["kept"]
    every = (kept["coverage"] == s["flown"] and kept["separation"] == s["flown"]
             and kept["battery_reserve"] in (None, s["flown"]) and not s["failed_to_fly"])
    return 0 if every else 1


def register(subparsers: Any) -> None:
    """Add `verify DIR [--runs N] [--wind MIN-MAX] [--faults F,...] [--replan] [--seed S] [--sim mock|sitl]
    [--sitl-dir DIR] [--time-scale X] [--engine E] [--workers N] [--address ADDR] [--out DIR] [--resume]
    [--keep-flights] [--quiet]`."""
    p = subparsers.add_parser("verify", help="fly a plan many times on simulated fleets, in wind and with faults, "
                                             "and give each promise as a distribution (verify.json, .png, .html)",
                              allow_abbrev=False)
    p.add_argument("dir", help="plan folder written by `missionplan plan` (report.json, uavK.plan)")
    p.add_argument("--runs", type=int, default=20, help="simulated flights (default 20)")
    p.add_argument("--wind", default="0", metavar="MIN-MAX",
                   help="mean wind in m/s drawn per run between MIN and MAX, from a random direction, with gusts "
                        "(default 0: calm)")
    p.add_argument("--faults", default="", metavar="F,...",
                   help=f"faults each run meets, one of each on a drawn drone at a drawn mission item: "
                        f"{', '.join(FAULT_KINDS)} (default none)")
    p.add_argument("--replan", action="store_true", help="fly as `fly --replan`: a lost drone's share re-tasked live")
    p.add_argument("--seed", type=int, default=0, help="base seed: run K's conditions come from (seed, K) (default 0)")
    p.add_argument("--sim", choices=SIMULATORS, default="mock",
                   help="mock autopilots (default) or ArduCopter SITL vehicles, each run its own on free ports")
    p.add_argument("--sitl-dir", default=None, metavar="DIR",
                   help="with --sim sitl: the folder holding the arducopter binary and copter.parm")
    p.add_argument("--time-scale", type=float, default=DEFAULT_TIME_SCALE,
                   help=f"simulated seconds per wall second (default {DEFAULT_TIME_SCALE:g} on the mock; SITL is "
                        "stable up to about 10)")
    p.add_argument("--engine", choices=ENGINES, default="auto",
                   help="auto (default): Ray when installed, else a local process pool; inline: one run after the "
                        "other in this process")
    p.add_argument("--workers", type=int, default=None, help="runs at once on a local engine (default: the CPU count)")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="join the running Ray cluster at ADDR (default: RAY_ADDRESS, else a local Ray started here)")
    p.add_argument("--out", default=None, metavar="DIR", help="where verify.json goes (default DIR/verify)")
    p.add_argument("--resume", action="store_true", help="continue the verify a stopped run left in --out")
    p.add_argument("--keep-flights", action="store_true",
                   help="keep each run's whole flight folder (journal, flight.html), not only flight.json")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=runs(VerifyRequest, cmd_verify))
