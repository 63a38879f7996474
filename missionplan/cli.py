"""The `missionplan` command line: parses arguments, calls the library, prints.

Subcommands: `maps` (list the shipped maps), `plan` (plan a shipped map or a .map
file, write report.json and plan.png), `train` (reproduce the neural policy's weights
by imitation of the expert), from bridge/commands.py `upload`, `download`, `clear` and `mock`
(MAVLink mission transfer and the mock autopilot), `fly` (missionplan/flight/fly.py) and `demo`
(missionplan/demo.py), `status` (the survey's ledger: missionplan/flight/survey_status.py) and
`replan` (plan what the survey still misses: missionplan/replan.py). `missionplan --version` prints the
installed version.
Bad input gives one line on stderr and exit 2; no option may be abbreviated (`--uav` is not `--uavs`).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from missionplan.bridge import BridgeUsageError
from missionplan.geo.errors import GeoError
from missionplan.base.atomic import probe_writable
from missionplan.bridge.limits import SEED_MAX, check_integer, check_range
from missionplan.bridge.terminal_text import printable
from missionplan.bridge.commands import register as register_bridge_commands

from .flight.fly import register as register_fly_command
from .flight.survey_status import register as register_status_command
from .grid.lanes import MAX_OBSTACLE_SHARE
from .grid.zones import DEFAULT_ZONE_METHOD, ZONE_METHODS
from .maps.catalog import load_shipped, shipped_map_names
from .maps.gridmap import MapError
from .mission.drone_missions import DEFAULT_OVERLAP, DEFAULT_SPEED_M_S, END_ACTIONS
from .mission.safety import DEFAULT_CLEARANCE_M
from .mission.separation import DEFAULT_MAX_ALTITUDE_M
from .mission.sorties import DEFAULT_ENDURANCE_MIN, DEFAULT_RESERVE
from .pipeline import DEFAULT_POLICY, POLICIES
from .plan_display import EXIT_FAILED, print_plan
from .plan_folder import NO_UNKNOWN_HEIGHTS, PlanGround, PlanOptions, grid_ground, write_plan_folder
from .demo import register as register_demo_command
from .replan import register as register_replan_command

EXIT_USAGE = 2
MAX_PLAN_ALTITUDE_M = 5_000.0  # above launch: beyond any survey multirotor's ceiling (the legal one is 120 m)


# A negative number or LAT,LON pair such as -33.86,151.21 (argparse would take it for an option).
_NEGATIVE_VALUE = re.compile(r"-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(,\s*-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)*")


def attach_negative_values(argv: Sequence[str]) -> list[str]:
    """`--launch -33.86,151.21` -> `--launch=-33.86,151.21`, so a southern or western
    coordinate works with a space like any other value. argparse only recognises plain
    negative numbers, not a comma pair; the `=` form is unambiguous."""
    out: list[str] = []
    for token in argv:
        if (out and _NEGATIVE_VALUE.fullmatch(token) and out[-1].startswith("--") and "=" not in out[-1]
                and out[-1] != "--"):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def package_version() -> str:
    """The installed package's version (importlib.metadata); in a source tree that was never installed,
    the version its pyproject.toml declares; failing both, the package's __version__."""
    from importlib import metadata

    try:
        return metadata.version("missionplan")
    except metadata.PackageNotFoundError:
        pass
    import tomllib

    try:
        project = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())["project"]
        if project.get("name") == "missionplan" and isinstance(project.get("version"), str):
            return project["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        pass
    from . import __version__

    return __version__


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad argument in one line with exit code 2, and takes no abbreviated
    option (argparse would read `--uav 3` as `--uavs 3`; a typo must fail, not guess)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"missionplan: {printable(message)}\n")
        raise SystemExit(EXIT_USAGE)

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        argv = sys.argv[1:] if args is None else args
        return super().parse_known_args(attach_negative_values(argv), namespace)


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="missionplan", description="Plan photo-coverage missions for several drones.")
    parser.add_argument("--version", action="version", version=f"missionplan {package_version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sub.add_parser("maps", help="list the shipped maps")
    plan = sub.add_parser("plan", help="plan full coverage of a map and write report.json and plan.png")
    source = plan.add_mutually_exclusive_group(required=True)
    source.add_argument("--map", help="a shipped map name (see `missionplan maps`) or a .map file")
    source.add_argument("--area", type=Path, help="the area to photograph: GeoJSON, KML / KMZ, GeoPackage, Shapefile "
                        "(.shp or .zip), FlatGeobuf, GML or a QGroundControl .plan; FILE:LAYER for one layer of several")
    plan.add_argument("--uavs", type=int,
                      help="number of drones (with --map: the map's first N launch cells; with --area: one per --launch)")
    plan.add_argument("--obstacles", type=Path, action="append", default=[],
                      help="obstacle / no-fly polygons, any --area format (a .plan: its geofence exclusions), repeatable")
    plan.add_argument("--osm", type=Path, help="building footprints: OpenStreetMap .osm / .osm.pbf, or any --area "
                      "format with height, building:height or building:levels (3 m a level)")
    plan.add_argument("--height-field", metavar="NAME",
                      help="the --osm field (or OSM tag) holding each building's height in metres, read before "
                           "height, building:height and building:levels")
    plan.add_argument("--unknown-building-height", type=float, metavar="M",
                      help="height in metres of --osm buildings without height or building:levels "
                           "(default: unknown, so they are obstacles)")
    plan.add_argument("--launch", action="append", default=[], metavar="LAT,LON",
                      help="a launch point, one per drone (with --area; -33.86,151.21 works after a space)")
    plan.add_argument("--altitude", type=float, help="flight height above the launch points, metres (with --area)")
    plan.add_argument("--fov", type=float, help="camera field of view, degrees")
    plan.add_argument("--sensor-width", type=float, help="sensor width, mm (with --sensor-height and --focal-length)")
    plan.add_argument("--sensor-height", type=float, help="sensor height, mm")
    plan.add_argument("--focal-length", type=float, help="focal length, mm")
    plan.add_argument("--rotation", type=float, default=0.0, help="grid rotation, degrees clockwise from north")
    plan.add_argument("--speed", type=float, default=DEFAULT_SPEED_M_S, help="cruise speed, m/s")
    plan.add_argument("--overlap", type=float, default=DEFAULT_OVERLAP,
                      help="frontal overlap of consecutive photos, 0..1 (sets the camera trigger distance)")
    plan.add_argument("--end", choices=END_ACTIONS, default="rtl", help="after the survey: return to launch or land")
    plan.add_argument("--altitude-step", type=float, default=0.0,
                      help="drone k flies this many metres above drone k-1 (layers go up from --altitude)")
    plan.add_argument("--min-separation", type=float, metavar="M",
                      help="closest two drones may come, 3-D metres, over the whole flight (default: the map's "
                           "min_separation_m, else 5); altitude layers are added when needed")
    plan.add_argument("--max-altitude", type=float, default=DEFAULT_MAX_ALTITUDE_M, metavar="M",
                      help=f"no altitude layer above this (default {DEFAULT_MAX_ALTITUDE_M:g} m)")
    plan.add_argument("--clearance", type=float, metavar="M",
                      help="horizontal margin of the tracks from obstacles (default: the map's clearance_m, "
                           f"else the larger of {DEFAULT_CLEARANCE_M:g} m and one cell)")
    plan.add_argument("--endurance", type=float, default=DEFAULT_ENDURANCE_MIN, metavar="MIN",
                      help=f"usable flight minutes per battery; longer routes fly in sorties (default "
                           f"{DEFAULT_ENDURANCE_MIN:g}; 0: no limit)")
    plan.add_argument("--reserve", type=float, default=DEFAULT_RESERVE, metavar="F",
                      help=f"fraction of the endurance kept for landing (default {DEFAULT_RESERVE:g})")
    plan.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot",
                      help="the vehicles' autopilot: the .plan firmwareType that upload / fly check (default "
                           "ardupilot; px4 writes no .waypoints, see docs/px4-missions.md)")
    plan.add_argument("--out", required=True, type=Path, help="output folder (created if missing)")
    plan.add_argument("--basemap", metavar="URL",
                      help="plan.html draws map tiles from this tile server (e.g. "
                           "https://tile.openstreetmap.org/{z}/{x}/{y}.png); without it the page needs no network")
    plan.add_argument("--policy", default=DEFAULT_POLICY, choices=POLICIES,
                      help="who decides moves in view of targets: the neural network (nn) or the expert it imitates")
    plan.add_argument("--weights", type=Path, help="network weights for --policy nn (default: the shipped ones)")
    plan.add_argument("--zones", default=DEFAULT_ZONE_METHOD, choices=ZONE_METHODS, help="zone distance")
    plan.add_argument("--no-balance", action="store_true",
                      help="plain Lloyd/Voronoi zones, without equalising their sizes")
    plan.add_argument("--open-ground", choices=("lanes", "explore"), default="lanes",
                      help=f"a drone whose zone lies on open ground (at most {100 * MAX_OBSTACLE_SHARE:g} %% of the box "
                           "around it blocked, e.g. buildings low enough to fly over with a few tall ones) sweeps "
                           "it in footprint-wide lanes, or explores it cell by cell (default lanes)")
    plan.add_argument("--seed", type=int, default=0, help="seed for zones and deadlock breaking")
    plan.add_argument("--quiet", action="store_true", help="no progress bar")
    train = sub.add_parser("train", help="train the neural policy by imitation of the expert and write its weights")
    train.add_argument("--out", required=True, type=Path, help="weights file to write (a training report goes beside it, .json)")
    train.add_argument("--seed", type=int, default=0, help="seed of the training maps, the split and the network")
    train.add_argument("--maps", type=int, default=None, help="number of training maps")
    train.add_argument("--no-dagger", action="store_true", help="skip the DAgger rounds")
    train.add_argument("--workers", type=int, default=2, help="processes playing the expert demonstrations")
    train.add_argument("--quiet", action="store_true", help="no progress bars")
    register_bridge_commands(sub)  # upload, download, mock (bridge/commands.py)
    register_fly_command(sub, retask_planner=_plan_retask)  # fly (missionplan/flight/fly.py)
    register_status_command(sub)  # status (missionplan/flight/survey_status.py)
    register_replan_command(sub)  # replan (missionplan/replan.py)
    register_demo_command(sub)  # demo = plan + mock fleet + fly (missionplan/demo.py)
    return parser


def _plan_retask(*args: Any, **kwargs: Any) -> Any:
    """fly --replan's planner (missionplan/retask.py), imported when a re-task is planned."""
    from .retask import plan_retask

    return plan_retask(*args, **kwargs)


def _cmd_maps() -> int:
    print(f"{'name':<12} {'rows x cols':>11} {'targets':>8} {'launch':>6}  title")
    for name in shipped_map_names():
        gmap = load_shipped(name)
        rows, cols = gmap.shape
        print(f"{printable(name):<12} {f'{rows} x {cols}':>11} {int(gmap.target.sum()):>8} {len(gmap.launch):>6}  "
              f"{printable(gmap.meta.get('title', ''))}")
    return 0


def _plan_ground(args: argparse.Namespace) -> PlanGround:
    """What `plan` is asked to plan: a shipped map or .map file (--map), or an area drawn to a grid (--area)."""
    from .mission.georef import load_area_checked, shipped_frame

    if args.area is not None:
        gmap, frame, unknown, sources = load_area_checked(args)
        args.uavs = len(gmap.launch) if args.uavs is None else args.uavs
    else:
        if args.uavs is None:
            raise MapError("--uavs is required with --map")
        if getattr(args, "unknown_building_height", None) is not None:
            raise MapError("--unknown-building-height is for --area with --osm; a map's grid is already drawn")
        gmap = load_shipped(args.map)
        frame, unknown, sources = shipped_frame(gmap), NO_UNKNOWN_HEIGHTS, None
    mission = {"speed": args.speed, "overlap": args.overlap, "end": args.end, "altitude_step": args.altitude_step,
               "altitude": args.altitude, "autopilot": args.autopilot}
    safety = {"min_separation": args.min_separation, "max_altitude": args.max_altitude, "clearance": args.clearance,
              "endurance": args.endurance, "reserve": args.reserve}
    return grid_ground(gmap, args.uavs, frame, mission, safety, unknown=unknown, sources=sources,
                       from_osm=args.area is not None and args.osm is not None,
                       launch_labels=list(args.launch[:args.uavs]) if args.area is not None else None)


def _check_plan_numbers(args: argparse.Namespace) -> None:
    """plan's numeric options, each finite and within its range (docs/cli.md has the table and the reasons),
    before any file is read: a `--rotation 1e308` is refused, not stored."""
    def check(name: str, value: float | None, low: float, high: float, unit: str = "", **how: Any) -> None:
        if value is not None:
            check_range(value, name, low, high, unit=unit, error=MapError, **how)

    if args.uavs is not None:  # each drone is a MAVLink vehicle: system ids 1..254
        check_integer(args.uavs, "--uavs", 1, 254, what="a number of drones", error=MapError)
    check("--altitude", args.altitude, 0.0, MAX_PLAN_ALTITUDE_M, " m", low_open=True, what="metres above launch")
    check("--fov", args.fov, 0.0, 180.0, " degrees", low_open=True, high_open=True)
    check("--sensor-width", args.sensor_width, 0.0, 100.0, " mm", low_open=True)
    check("--sensor-height", args.sensor_height, 0.0, 100.0, " mm", low_open=True)
    check("--focal-length", args.focal_length, 0.0, 2_000.0, " mm", low_open=True)
    check("--rotation", args.rotation, -360.0, 360.0, " degrees", what="a grid angle")
    check("--speed", args.speed, 0.0, 100.0, " m/s", low_open=True)
    check("--overlap", args.overlap, 0.0, 1.0, high_open=True, what="a fraction")
    check("--altitude-step", args.altitude_step, 0.0, MAX_PLAN_ALTITUDE_M, " m")
    check("--min-separation", args.min_separation, 0.0, 1_000.0, " m", low_open=True)
    check("--max-altitude", args.max_altitude, 0.0, MAX_PLAN_ALTITUDE_M, " m", low_open=True)
    check("--clearance", args.clearance, 0.0, 1_000.0, " m")
    check("--endurance", args.endurance, 0.0, 1_440.0, " minutes", what="0 (no limit) or minutes")
    check("--reserve", args.reserve, 0.0, 1.0, high_open=True, what="a fraction")
    check("--unknown-building-height", args.unknown_building_height, 0.0, 1_000.0, " m", what="a height in metres")
    check_integer(args.seed, "--seed", 0, SEED_MAX, error=MapError)


def _cmd_plan(args: argparse.Namespace) -> int:
    _check_plan_numbers(args)
    options = PlanOptions(policy=args.policy, weights=args.weights, zones=args.zones, balance_zones=not args.no_balance,
                          open_ground=args.open_ground, seed=args.seed, basemap=args.basemap,
                          progress=not args.quiet and sys.stderr.isatty())
    folder = write_plan_folder(args.out, _plan_ground(args), options)
    print_plan(folder)
    return 0 if folder.success else EXIT_FAILED


def _cmd_train(args: argparse.Namespace) -> int:
    import json

    from missionplan.base.atomic import write_text_atomic
    from .learn.network import save_weights
    from .learn.training import DEFAULT_MAPS, train_policy

    check_integer(args.seed, "--seed", 0, SEED_MAX, error=MapError)
    if args.maps is not None:
        check_integer(args.maps, "--maps", 4, 100_000, what="a number of training maps", error=MapError)
    check_integer(args.workers, "--workers", 1, 256, what="a number of processes", error=MapError)
    if not args.out.parent.is_dir():
        raise MapError(f"--out {args.out}: folder {args.out.parent} does not exist")
    try:
        probe_writable(args.out.parent)  # before minutes of training, not after
    except OSError as err:
        raise MapError(f"--out {args.out}: cannot write files in {args.out.parent} ({err.strerror})") from None
    net, report = train_policy(seed=args.seed, num_maps=args.maps or DEFAULT_MAPS, dagger=not args.no_dagger,
                               workers=args.workers, progress=not args.quiet and sys.stderr.isatty())
    save_weights(net, args.out)
    report_path = args.out.with_suffix(".json")
    write_text_atomic(report_path, json.dumps(report, indent=1) + "\n")
    final = report["final"]
    print(f"{report['parameters']} parameters; {final['samples']['clean']} samples after augmentation and cleaning "
          f"({final['samples']['raw']} recorded)")
    print(f"accuracy against the expert: train {final['train_accuracy']:.2f} %, validation "
          f"{final['validation_accuracy']:.2f} %, test {final['test_accuracy']:.2f} %")
    print("test confusion (rows: expert up/right/down/left, columns: network):")
    for row in final["test_confusion"]:
        print("  " + " ".join(f"{value:>7}" for value in row))
    print(f"wrote {args.out} and {report_path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    try:
        handler = getattr(args, "handler", None)
        if handler is not None:  # upload / download / mock / fly / demo
            return handler(args)
        if args.command == "maps":
            return _cmd_maps()
        if args.command == "train":
            return _cmd_train(args)
        return _cmd_plan(args)
    except (MapError, BridgeUsageError, GeoError) as err:
        print(f"missionplan: {printable(err)}", file=sys.stderr)  # the message may quote a file's text
        return EXIT_USAGE
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
