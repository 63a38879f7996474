"""The `missionplan` command: its parser (every subcommand's, in the order `--help` lists them) and main(),
which parses, runs the subcommand's handler on its typed request, and turns the library's bad-input
errors into one line on stderr and exit 2."""

from __future__ import annotations

import argparse
import sys

from missionplan.bridge import BridgeUsageError
from missionplan.bridge.terminal_text import printable
from missionplan.geo.errors import GeoError

from ..maps.gridmap import MapError
from .cameras import register as register_cameras
from .demo import register as register_demo
from .errors import said
from .fly import register as register_fly
from .geotag import register as register_geotag
from .mock import register as register_mock
from .parsing import EXIT_USAGE, CommandParser, package_version
from .plan import register as register_plan
from .survey import register as register_survey
from .train import register as register_train
from .vehicle import register as register_vehicle
from .verify import register as register_verify


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(prog="missionplan", description="Plan photo-coverage missions for several drones.")
    parser.add_argument("--version", action="version", version=f"missionplan {package_version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=CommandParser)
    register_plan(sub)  # maps, plan
    register_cameras(sub)  # cameras
    register_train(sub)  # train
    register_vehicle(sub)  # upload, download, clear
    register_mock(sub)  # mock
    register_fly(sub)  # fly
    register_survey(sub)  # status, replan
    register_geotag(sub)  # geotag
    register_verify(sub)  # verify = many simulated flights of a plan
    register_demo(sub)  # demo = plan + mock fleet + fly
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except (MapError, BridgeUsageError, GeoError) as err:
        print(f"missionplan: {printable(said(err))}", file=sys.stderr)  # the message may quote a file's text
        return EXIT_USAGE
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
