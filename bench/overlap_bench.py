"""How long measuring a plan's overlaps takes (missionplan/mission/photo_overlap.py), up to a 20-drone city.

    python bench/overlap_bench.py [--sizes 350,700,1050] [--repeat 3] [--write-doc FILE]

Each row is a made-up city of SIZE x SIZE cells of 2 m: streets 15 cells wide every 60 cells, both ways,
their cells the targets; 20 drones, each flying the streets of its block of the city (4 x 5 blocks)
in two lanes 6 cells apart, a photo every cell (front overlap 8/9 of an 18 m footprint, side overlap
1 - 12/18). The photos are in the order flown, one run per drone, the strips derived from the headings
(as the judge derives them), the streets the flyable cells. It prints the photos, the target cells, the
strips found, the measured overlaps and photos per target point, the reachable target points and those
of them short of the implied count, and the best CPU and wall seconds of --repeat measures (one core:
the CPU time is the measure's own, the wall time also what else the machine was running).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from missionplan.mission.photo_overlap import OverlapMeasure, measure_overlap

import doctable  # bench/doctable.py: --write-doc

CELL_M = 2.0
FOOTPRINT_M = 18.0  # 9 cells, the planner's footprint
STREET_EVERY, STREET_WIDTH, LANE_GAP = 60, 15, 6  # cells
BLOCKS = (4, 5)  # 20 drones


def city(size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(photo centres (n, 2) m in the order flown, each photo's drone, target cells (m, 2), the flyable
    cells (the streets: the blocks between them are buildings))."""
    offset = np.arange(size) % STREET_EVERY
    street = offset < STREET_WIDTH
    target = street[:, None] | street[None, :]
    middle = STREET_WIDTH // 2
    lanes = [s + middle + d for s in range(0, size, STREET_EVERY) for d in (-LANE_GAP // 2, LANE_GAP // 2)
             if s + middle + d < size]
    edges = [np.linspace(0, size, n + 1).astype(int) for n in BLOCKS]
    centres, runs = [], []
    drone = 0
    for r0, r1 in zip(edges[0][:-1], edges[0][1:]):
        for c0, c1 in zip(edges[1][:-1], edges[1][1:]):
            legs = []
            mine = [lane for lane in lanes if r0 <= lane < r1]
            for k, lane in enumerate(mine):  # along the rows' streets, back and forth
                cols = np.arange(c0, c1)[::1 if k % 2 == 0 else -1]
                legs.append(np.column_stack([np.full(len(cols), lane), cols]))
            mine = [lane for lane in lanes if c0 <= lane < c1]
            for k, lane in enumerate(mine):  # then along the columns' streets
                rows = np.arange(r0, r1)[::1 if k % 2 == 0 else -1]
                legs.append(np.column_stack([rows, np.full(len(rows), lane)]))
            if legs:
                points = np.vstack(legs) * CELL_M
                centres.append(points)
                runs.append(np.full(len(points), drone))
            drone += 1
    return np.vstack(centres), np.concatenate(runs), np.argwhere(target), target


def pct(value: float) -> str:
    return f"{100 * value:.0f}"


def row(size: int, repeat: int) -> str:
    centres, runs, cells, flyable = city(size)
    cpu = wall = float("inf")
    measure = None
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        measure = measure_overlap(centres, runs, FOOTPRINT_M, cells, CELL_M, asked_front=8 / 9,
                                  asked_side=1 - LANE_GAP * CELL_M / FOOTPRINT_M, flyable=flyable)
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    assert isinstance(measure, OverlapMeasure) and measure.front is not None and measure.side is not None
    assert measure.reach is not None
    return (f"{size:>5} x {size:<5} {len(centres):>8,} {len(cells):>9,} {measure.strips:>7,} "
            f"{pct(measure.front.median):>4} {pct(measure.front.p5):>4} {pct(measure.side.median):>4} "
            f"{pct(measure.side.p5):>4} {measure.per_point_median:>5g} {measure.per_point_p5:>4} "
            f"{measure.implied_neighbouring:>4} {measure.reach.reachable.points:>9,} {measure.reach.reachable.short:>6,} "
            f"{cpu:>6.2f} {wall:>6.2f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="350,700,1050", help="city sides in cells, comma-separated")
    parser.add_argument("--repeat", type=int, default=3, help="measures per row; the best time is printed")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        print(f"{'city cells':<13} {'photos':>8} {'targets':>9} {'strips':>7} {'front %':>9} {'side %':>9} "
              f"{'photos/point':>10} {'impl':>4} {'reachable':>9} {'short':>6} {'cpu s':>6} {'wall s':>6}")
        print(f"{'':<13} {'':>8} {'':>9} {'':>7} {'med':>4} {'p5':>4} {'med':>4} {'p5':>4} {'med':>5} {'p5':>4} "
              f"{'':>4} {'':>9} {'':>6} {'':>6} {'':>6}")
        for size in (int(s) for s in args.sizes.split(",")):
            print(row(size, args.repeat))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
