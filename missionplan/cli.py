"""The `missionplan` command line: parses arguments, calls the library, prints.

Subcommands: `maps` (list the shipped maps), `plan` (plan a shipped map or a .map
file, write report.json and plan.png), `train` (reproduce the neural policy's weights
by imitation of the expert), and from bridge/commands.py `upload`, `download` and `mock`
(MAVLink mission transfer and the mock autopilot). Bad input gives one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bridge import BridgeUsageError
from bridge.commands import register as register_bridge_commands

from .catalog import load_shipped, shipped_map_names
from .gridmap import MapError
from .pipeline import DEFAULT_POLICY, POLICIES, launch_cells, make_policy, plan_map
from .zones import DEFAULT_ZONE_METHOD, ZONE_METHODS

EXIT_USAGE = 2
EXIT_FAILED = 1


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad argument in one line with exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"missionplan: {message}\n")
        raise SystemExit(EXIT_USAGE)


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="missionplan", description="Plan photo-coverage missions for several drones.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sub.add_parser("maps", help="list the shipped maps")
    plan = sub.add_parser("plan", help="plan full coverage of a map and write report.json and plan.png")
    plan.add_argument("--map", required=True, help="a shipped map name (see `missionplan maps`) or a .map file")
    plan.add_argument("--uavs", type=int, required=True, help="number of drones (uses the map's first N launch cells)")
    plan.add_argument("--out", required=True, type=Path, help="output folder (created if missing)")
    plan.add_argument("--policy", default=DEFAULT_POLICY, choices=POLICIES,
                      help="who decides moves in view of targets: the neural network (nn) or the expert it imitates")
    plan.add_argument("--weights", type=Path, help="network weights for --policy nn (default: the shipped ones)")
    plan.add_argument("--zones", default=DEFAULT_ZONE_METHOD, choices=ZONE_METHODS, help="zone distance")
    plan.add_argument("--no-balance", action="store_true",
                      help="plain Lloyd/Voronoi zones, without equalising their sizes")
    plan.add_argument("--seed", type=int, default=0, help="seed for zones and deadlock breaking")
    plan.add_argument("--quiet", action="store_true", help="no progress bar")
    train = sub.add_parser("train", help="train the neural policy by imitation of the expert and write its weights")
    train.add_argument("--out", required=True, type=Path, help="weights file to write (a training report goes beside it, .json)")
    train.add_argument("--seed", type=int, default=0, help="seed of the training maps, the split and the network")
    train.add_argument("--maps", type=int, default=None, help="number of training maps")
    train.add_argument("--no-dagger", action="store_true", help="skip the DAgger pass")
    train.add_argument("--workers", type=int, default=2, help="processes playing the expert demonstrations")
    train.add_argument("--quiet", action="store_true", help="no progress bars")
    register_bridge_commands(sub)  # upload, download, mock (bridge/commands.py)
    return parser


def _cmd_maps() -> int:
    print(f"{'name':<12} {'rows x cols':>11} {'targets':>8} {'launch':>6}  title")
    for name in shipped_map_names():
        gmap = load_shipped(name)
        rows, cols = gmap.shape
        print(f"{name:<12} {f'{rows} x {cols}':>11} {int(gmap.target.sum()):>8} {len(gmap.launch):>6}  "
              f"{gmap.meta.get('title', '')}")
    return 0


def _fmt(value: float | int | None, digits: int = 1) -> str:
    if value is None:
        return "-"
    return f"{value:.{digits}f}" if isinstance(value, float) else str(value)


def _cmd_plan(args: argparse.Namespace) -> int:
    from .plot import draw_plan  # matplotlib only when a picture is drawn
    from .report import build_report, write_report

    gmap = load_shipped(args.map)
    launch_cells(gmap, args.uavs)  # bad drone counts and weights fail before any folder is made
    policy = make_policy(args.policy, args.weights)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise MapError(f"--out {args.out}: cannot create folder ({err.strerror})") from None
    show_progress = not args.quiet and sys.stderr.isatty()
    result = plan_map(gmap, args.uavs, policy=policy, zone_method=args.zones, seed=args.seed,
                      progress=show_progress, balance_zones=not args.no_balance)
    report = build_report(result, args.seed)
    write_report(report, args.out / "report.json")
    draw_plan(result, args.out / "plan.png")

    m = report["metrics"]
    zones = args.zones + ("" if args.no_balance else ", balanced")
    print(f"map {gmap.name} ({gmap.shape[0]} x {gmap.shape[1]}), {args.uavs} UAVs, policy {args.policy}, "
          f"zones {zones}, seed {args.seed}")
    print(f"targets U = {report['targets']} reachable, {report['unreachable']} unreachable (set explored); "
          f"floor U/(9A) = {report['floor']:.1f}")
    rows = [("MMN", _fmt(m["MMN"]), "mean moves per drone"),
            ("TE %", _fmt(m["TE"]), "trajectory efficiency"),
            ("MNT %", _fmt(m["MNT"], 2), "weighted turns per move"),
            ("MUD*", _fmt(m["MUD"], 2), "mean drone spacing, steady state (cells)"),
            ("MDU*", _fmt(m["MDU"], 2), "mean distance unexplored -> drone, steady state"),
            ("coverage %", _fmt(m["coverage"]), ""),
            ("makespan", _fmt(m["makespan"]), "moves of the busiest drone"),
            ("hover steps", _fmt(m["hover_steps"]), ""),
            ("MMN / floor", f"{m['MMN'] / report['floor']:.2f}" if report["floor"] else "-", ""),
            ("plan s", f"{report['timing']['plan_s']:.2f}", "wall time, zones + planning")]
    for name, value, note in rows:
        print(f"  {name:<12} {value:>9}  {note}")
    print(f"wrote {args.out / 'report.json'} and {args.out / 'plan.png'}")
    if not report["success"]:
        print(f"missionplan: plan failed: {report['failure']}", file=sys.stderr)
        return EXIT_FAILED
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    import json

    from .atomic import write_text_atomic
    from .network import save_weights
    from .training import DEFAULT_MAPS, train_policy

    if args.maps is not None and args.maps < 4:
        raise MapError(f"--maps must be at least 4, got {args.maps}")
    if args.workers < 1:
        raise MapError(f"--workers must be at least 1, got {args.workers}")
    if not args.out.parent.is_dir():
        raise MapError(f"--out {args.out}: folder {args.out.parent} does not exist")
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
        if handler is not None:  # upload / download / mock
            return handler(args)
        if args.command == "maps":
            return _cmd_maps()
        if args.command == "train":
            return _cmd_train(args)
        return _cmd_plan(args)
    except (MapError, BridgeUsageError) as err:
        print(f"missionplan: {err}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
