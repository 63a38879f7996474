"""Plan every shipped map with 3, 4, 5 and 6 drones and print one table.

Ours beside the thesis's Cases I-IV (Table 5.1-5.4). Our synthetic maps are the size of
the thesis's cases, not copies of them, so the comparison is a yardstick, not a race on
the same grid. Run by hand:

    .venv/bin/python bench/plan_bench.py [--policy nn,expert] [--zones geodesic] [--maps leonardo,old-town]
                                         [--weights FILE] [--write-doc docs/measured-numbers.md]

--weights plans the nn rows with another network (a retrained one, before it ships) instead of the
shipped weights.
"""

from __future__ import annotations

import argparse
import time


from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.maps.catalog import load_shipped, shipped_map_names
from missionplan.planning.pipeline import POLICIES, make_policy, plan_map
from missionplan.grid.zones import DEFAULT_ZONE_METHOD, ZONE_METHODS

import doctable  # bench/doctable.py: --write-doc

# Thesis Tables 5.1-5.4, for 3, 4, 5, 6 UAVs: (MMN, TE %, MNT %, MUD, MDU).
THESIS = {
    "leonardo": ("I Leonardo", [(183, 41.1, 6.73, 22.25, 19.55), (168, 32.8, 7.21, 31.48, 14.04),
                                (133, 32.4, 6.31, 38.54, 13.39), (126, 27.1, 5.88, 35.31, 13.61)]),
    "grid-city": ("II Turin", [(1019, 37.5, 4.01, 153.10, 72.61), (854, 33.5, 4.51, 118.96, 54.18),
                               (827, 27.5, 5.27, 132.97, 50.37), (591, 32.1, 4.01, 120.33, 48.76)]),
    "old-town": ("III Genoa", [(1012, 23.6, 21.2, 53.76, 41.91), (674, 26.3, 20.8, 69.48, 25.33),
                               (553, 26.4, 19.39, 62.99, 26.96), (482, 24.23, 20.40, 65.73, 22.09)]),
    "river-city": ("IV Porto", [(1537, 21.7, 19.43, 131.11, 46.01), (1157, 21.6, 18.56, 98.27, 38.01),
                                (911, 21.9, 17.56, 95.34, 38.45), (791, 20.8, 18.05, 90.13, 32.71)]),
}


def fmt(value: float | None, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default=",".join(POLICIES), help=f"comma list of {', '.join(POLICIES)}")
    parser.add_argument("--zones", default=DEFAULT_ZONE_METHOD, help=f"comma list of {', '.join(ZONE_METHODS)}")
    parser.add_argument("--maps", default=",".join(shipped_map_names()))
    parser.add_argument("--uavs", default="3,4,5,6")
    parser.add_argument("--balance", default="on", help="zone balancing: on, off or on,off")
    parser.add_argument("--weights", help="the network's weights for the nn rows (default: the shipped ones)")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:

    header = (f"{'map':<11} {'A':>2} {'policy':<7} {'zones':<12} {'U':>6} {'floor':>6} {'MMN':>7} {'/floor':>6} {'mkspan':>6} "
              f"{'TE%':>5} {'MNT%':>5} {'MUD*':>6} {'MDU*':>6} {'hover':>5} {'cov%':>5} {'plan s':>6} | "
              f"{'thesis case':<11} {'MMN':>5} {'TE%':>5} {'MNT%':>5} {'MUD':>6} {'MDU':>6}")
    print(header)
    print("-" * len(header))
    started = time.perf_counter()
    policies = {name: make_policy(name, args.weights if name == "nn" else None) for name in args.policy.split(",")}
    for name in args.maps.split(","):
        gmap = load_shipped(name)
        for uavs in (int(u) for u in args.uavs.split(",")):
            for zones, balance in [(z, b) for z in args.zones.split(",") for b in args.balance.split(",")]:
                for policy, planner in policies.items():
                    result = plan_map(gmap, uavs, policy=planner, zone_method=zones, balance_zones=balance == "on")
                    m, world = result.run.metrics, result.world
                    floor = world.num_targets / (CELLS_PER_FOOTPRINT * uavs)
                    seconds = result.zone_seconds + result.run.plan_seconds
                    row = (f"{name:<11} {uavs:>2} {policy:<7} {zones + ('+bal' if balance == 'on' else ''):<12} {world.num_targets:>6} {floor:>6.1f} "
                           f"{m['MMN']:>7.1f} {m['MMN'] / floor:>6.2f} {m['makespan']:>6} {m['TE']:>5.1f} {m['MNT']:>5.2f} "
                           f"{fmt(m['MUD'], 2):>6} {fmt(m['MDU'], 2):>6} {m['hover_steps']:>5} "
                           f"{m['coverage']:>5.1f} {seconds:>6.2f} | ")
                    if name in THESIS and 3 <= uavs <= 6:
                        case, numbers = THESIS[name]
                        t = numbers[uavs - 3]
                        row += f"{case:<11} {t[0]:>5} {t[1]:>5.1f} {t[2]:>5.2f} {t[3]:>6.2f} {t[4]:>6.2f}"
                    if not result.run.success:
                        row += f"  FAILED: {result.run.failure}"
                    print(row, flush=True)
    print(f"\n{time.perf_counter() - started:.1f} s in all; floor = U / (9 A), MMN if every move photographed 9 new cells (a lower bound up to the launch photos)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
