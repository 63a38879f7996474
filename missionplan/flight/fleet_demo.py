"""`missionplan demo`: the whole flow on the embedded default, in one command (what `make demo` runs).

Plans the shipped Leonardo map for 5 drones with the shipped network (the same code as
`missionplan plan`, which prints the plan metrics), starts one in-process mock autopilot per drone
on 127.0.0.1 (SITL-like: ArduCopter's flight, each camera configured as a team does, CAM1_TYPE and a
reboot, so the judge has the vehicles' own photo reports), and flies the missions against them with `fly` at a speed-up, which prints the
flown coverage, the closest approach against the plan's promise, and each vehicle's flight.
Nothing leaves the machine. Exit 0 only when the flight is judged good (fly's rule).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

DEMO_MAP, DEMO_UAVS, DEMO_POLICY = "leonardo", 5, "nn"
# Leonardo is a 20 x 10 m arena flown at 5 m/s: 2x keeps the telemetry (50 Hz) within a cell of flight.
DEMO_SPEEDUP = 2.0
DEMO_TELEMETRY_HZ = 50.0
DEMO_TIMEOUT_S = 300.0


def cmd_demo(args: argparse.Namespace, plan_command: Any, plan_parser: argparse.ArgumentParser) -> int:
    from .display import print_flight
    from .fly import fly
    from .mock_fleet import start_mock_fleet

    if args.speedup <= 0:
        from ..maps.gridmap import MapError

        raise MapError(f"--speedup must be positive, got {args.speedup}")
    # Progress on stderr: bars on a terminal, plain lines in a log (plan and fly each decide which).
    quiet = args.quiet
    plan_argv = ["plan", "--map", DEMO_MAP, "--uavs", str(args.uavs), "--policy", DEMO_POLICY, "--out", str(args.out)]
    print(f"== 1/2 plan: missionplan {' '.join(plan_argv)}")
    status = plan_command(plan_parser.parse_args(plan_argv + (["--quiet"] if quiet else [])))
    if status != 0:
        return status
    print(f"== 2/2 fly: {args.uavs} mock autopilots on 127.0.0.1 (in-process, {args.speedup:g}x speed-up), "
          f"upload, verify, arm, start together, follow, judge")
    mock = start_mock_fleet(Path(args.out), speedup=args.speedup)
    try:
        result = fly(Path(args.out), mock.client_url, timeout_s=DEMO_TIMEOUT_S, progress=not quiet,
                     time_scale=args.speedup, telemetry_hz=DEMO_TELEMETRY_HZ)
    finally:
        mock.stop()
    print_flight(result)
    return 0 if result.ok else 1


def register(subparsers: Any, plan_command: Any, plan_parser: argparse.ArgumentParser) -> None:
    """Add `demo [--out DIR] [--uavs N] [--speedup X] [--quiet]`; plan_command runs `plan` (the CLI's)."""
    p = subparsers.add_parser("demo", help=f"plan {DEMO_MAP} for {DEMO_UAVS} drones with the shipped network, "
                                           "fly it against in-process mock autopilots and judge the flight",
                              allow_abbrev=False)
    p.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (default demo-out/)")
    p.add_argument("--uavs", type=int, default=DEMO_UAVS, help=f"number of drones (default {DEMO_UAVS})")
    p.add_argument("--speedup", type=float, default=DEMO_SPEEDUP,
                   help=f"simulated seconds per wall second of the mock autopilots (default {DEMO_SPEEDUP:g})")
    p.add_argument("--quiet", action="store_true", help="no progress bars or progress lines")
    p.set_defaults(handler=lambda args: cmd_demo(args, plan_command, plan_parser))
