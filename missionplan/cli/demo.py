"""`missionplan demo`: the whole flow on the embedded default, in one command (what `make demo` runs).

Plans the shipped Leonardo map for 5 drones with the shipped network (missionplan/planning/plan_folder.py, the
library call behind `missionplan plan`, printed as `plan` prints it), starts one in-process mock
autopilot per drone on 127.0.0.1 (SITL-like: ArduCopter's flight, each camera configured as a team
does, CAM1_TYPE and a reboot, so the judge has the vehicles' own photo reports), and flies the missions
against them with `fly` at a speed-up, which prints the flown coverage, the closest approach against
the plan's promise, and each vehicle's flight.
Nothing leaves the machine. Exit 0 only when the flight is judged good (fly's rule).

The plan and the flight each hold the folder while they run (write_plan_folder, fly: one after the
other in this one process). A plan never lands over a flight, so --out must not hold an earlier
demo's flight: that is refused in one line before anything is printed (`make demo` starts from an
empty demo-out/)."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.limits import check_integer, check_range

from ..maps.gridmap import MapError
from .plan_display import EXIT_FAILED, print_plan
from ..planning.plan_folder import PlanOptions, check_out_folder, shipped_ground, write_plan_folder
from .parsing import runs

DEMO_MAP, DEMO_UAVS, DEMO_POLICY = "leonardo", 5, "nn"
# Leonardo is a 20 x 10 m arena flown at 5 m/s: 2x keeps the telemetry (50 Hz) within a cell of flight.
DEMO_SPEEDUP = 2.0
DEMO_TELEMETRY_HZ = 50.0
DEMO_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class DemoRequest:
    """`demo`: the output folder, the number of drones, the mock autopilots' speed-up, progress or not."""

    out: Path
    uavs: int
    speedup: float
    quiet: bool


def cmd_demo(request: DemoRequest) -> int:
    from ..flight.display import print_flight
    from ..flight.fly import fly
    from ..flight.mock_fleet import start_mock_fleet

    check_integer(request.uavs, "--uavs", 1, 254, what="a number of drones", error=MapError)
    check_range(request.speedup, "--speedup", 0.0, 1_000.0, low_open=True, what="simulated seconds per second",
                error=MapError)
    # Progress on stderr: bars on a terminal, plain lines in a log (plan and fly each decide which).
    quiet = request.quiet
    out = Path(request.out)
    check_out_folder(out)  # an earlier demo's flight there: one line, before the first heading
    # The `plan` command this step is, for a crew who wants to run it alone.
    print(f"== 1/2 plan: missionplan plan --map {DEMO_MAP} --uavs {request.uavs} --policy {DEMO_POLICY} --out {out}")
    options = PlanOptions(policy=DEMO_POLICY, progress=not quiet and sys.stderr.isatty())
    folder = write_plan_folder(out, shipped_ground(DEMO_MAP, request.uavs), options)
    print_plan(folder)
    if not folder.success:
        return EXIT_FAILED
    print(f"== 2/2 fly: {request.uavs} mock autopilots on 127.0.0.1 (in-process, {request.speedup:g}x speed-up), "
          f"upload, verify, arm, start together, follow, judge")
    mock = start_mock_fleet(out, speedup=request.speedup)
    try:
        result = fly(out, mock.client_url, timeout_s=DEMO_TIMEOUT_S, progress=not quiet,
                     time_scale=request.speedup, telemetry_hz=DEMO_TELEMETRY_HZ)
    finally:
        mock.stop()
    print_flight(result)
    return 0 if result.ok else 1


def register(subparsers: Any) -> None:
    """Add `demo [--out DIR] [--uavs N] [--speedup X] [--quiet]`."""
    p = subparsers.add_parser("demo", help=f"plan {DEMO_MAP} for {DEMO_UAVS} drones with the shipped network, "
                                           "fly it against in-process mock autopilots and judge the flight",
                              allow_abbrev=False)
    p.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (default demo-out/)")
    p.add_argument("--uavs", type=int, default=DEMO_UAVS, help=f"number of drones (default {DEMO_UAVS})")
    p.add_argument("--speedup", type=float, default=DEMO_SPEEDUP,
                   help=f"simulated seconds per wall second of the mock autopilots (default {DEMO_SPEEDUP:g})")
    p.add_argument("--quiet", action="store_true", help="no progress bars or progress lines")
    p.set_defaults(handler=runs(DemoRequest, cmd_demo))
