"""The anytime improvement (`plan --improve SECONDS`): the busiest drone's makespan against the time spent.

Each row plans one map and fleet with the expert (seed 0), then spends --budget seconds on
planning/improve.py's local search, and prints the makespan of the best plan found by each of the
--checkpoints (seconds since the improvement began; `first` is the planner's own plan), how much
shorter the last is than the first, the rounds tried and which moves were kept, and the lower bound
(reachable targets / (9 x drones): every move photographing 9 new cells, no drone ever waiting).

Maps: the MovingAI street maps in ../shared/maps/movingai/ (grid plans: the objective is the makespan in
moves) and, with --shipped, shipped maps planned with missions (the objective is the busiest drone's
flight time in seconds, as `plan --improve` on them judges it). Run by hand:

    .venv/bin/python bench/improve_bench.py [--budget 30] [--checkpoints 5,10,30] [--uavs 6,20]
                                            [--movingai-dir ../shared/maps/movingai] [--shipped grid-city:6]
                                            [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from missionplan.geo.camera import CELLS_PER_FOOTPRINT
from missionplan.maps.gridmap import read_map_text
from missionplan.maps.movingai import parse_movingai
from missionplan.planning.field_plan import plan_field
from missionplan.planning.plan_folder import shipped_ground

import doctable  # bench/doctable.py: --write-doc
from machine import machine_line

ROOT = Path(__file__).resolve().parent.parent
MOVINGAI_DIR = ROOT.parent / "shared" / "maps" / "movingai"


def best_by(candidates, first: float, at_s: float) -> float:
    """The makespan of the best plan found by `at_s` seconds."""
    best = first
    for c in candidates:
        if c.at_s <= at_s and c.kept and c.value is not None:
            best = min(best, c.value)
    return best


def row(name: str, uavs: int, budget: float, checkpoints: list[float], shipped: bool) -> str:
    if shipped:
        ground = shipped_ground(name, uavs)
        gmap, frame, settings, safety = ground.gmap, ground.frame, ground.settings, ground.safety
    else:
        gmap = parse_movingai(read_map_text(name), Path(name).name, launches=uavs)
        frame = settings = safety = None
    began = time.perf_counter()
    field = plan_field(gmap, uavs, frame, settings, safety, improve_s=budget, seed=0)
    wall = time.perf_counter() - began
    block = field.improvement
    assert block is not None, f"{name}: the first plan failed"
    targets = int(field.result.world.num_targets)
    floor = targets / (CELLS_PER_FOOTPRINT * uavs)
    unit = "s" if block.objective == "flight_s" else "mv"
    kept = Counter(c.move for c in block.candidates if c.kept)
    kept_text = ",".join(f"{m}x{n}" for m, n in sorted(kept.items())) or "-"
    at = " ".join(f"{best_by(block.candidates, block.first, t):>8.0f}" for t in checkpoints)
    gain = 100 * (block.kept / block.first - 1) if block.first else 0.0
    floor_text = f"{floor:.0f} mv" if unit == "mv" else "-"
    return (f"{gmap.name[:16]:<16} {uavs:>3} {unit:>4} {block.first:>8.0f} {at} {gain:>+7.1f}% {block.rounds:>6} "
            f"{kept_text:<26} {floor_text:>8} {wall:>7.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--budget", type=float, default=30.0, help="seconds of improvement per row")
    parser.add_argument("--checkpoints", default="5,10,30", help="comma list of seconds to read the best at")
    parser.add_argument("--uavs", default="6,20", help="drones on each MovingAI map (empty: none)")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--shipped", default="", help="comma list of NAME:DRONES planned with missions")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        checkpoints = [float(t) for t in args.checkpoints.split(",")]
        head = " ".join(f"{f'@{t:g} s':>8}" for t in checkpoints)
        print(f"{'map':<16} {'A':>3} {'unit':>4} {'first':>8} {head} {'gain':>8} {'rounds':>6} {'kept moves':<26} "
              f"{'floor':>8} {'wall s':>7}")
        print("-" * (90 + 9 * len(checkpoints)))
        uavs = [int(u) for u in args.uavs.split(",") if u]
        for uav in uavs:
            for path in sorted(Path(args.movingai_dir).glob("*.map")):
                print(row(str(path), uav, args.budget, checkpoints, shipped=False), flush=True)
        for item in filter(None, args.shipped.split(",")):
            name, drones = item.split(":")
            print(row(name, int(drones), args.budget, checkpoints, shipped=True), flush=True)
        print(f"budget {args.budget:g} s per row, expert, seed 0; first: the planner's plan; floor: reachable targets / (9 A)")
        print(machine_line())


if __name__ == "__main__":
    main()
