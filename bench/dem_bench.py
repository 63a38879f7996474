"""Reading the ground from a DEM (geo/dem.py): read_ground over a 1 km² box, and height_amsl at 1e5 and 1e6 points.

    python bench/dem_bench.py [--runs 5] [--write-doc FILE]

Two DEMs are written in a temporary folder (missionplan/testing/dem_files.py; nothing downloaded, about 30 MB
on disk, a few seconds to write):
- `country`: 20000 x 20000 int16 pixels of 10 m in UTM 32N (EPSG:32632), a 200 km square, tiled 512 x 512 and
  ZSTD-compressed as national DEMs are served: a query point is moved into UTM by pyproj;
- `SRTM`: one 1 arc-second tile (N45E007.hgt, EPSG:4326, 3601 x 3601) of a hill: a query point is used as is.

Each row: `read_ground` over a 1 km x 1 km box at Turin (45.07 N, 7.68 E) with its default 200 m margin (the
pixels of the window it read), then `height_amsl` at uniform random points of the box. Wall seconds: the
first call (fresh arrays: the page faults of a first use are in it) and the least of `--runs` more.
"""

from __future__ import annotations

import argparse
import functools
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import doctable  # bench/doctable.py: --write-doc
from machine import machine_line
from missionplan.geo.dem import read_ground
from missionplan.testing.dem_files import hill, write_flat_geotiff, write_srtm_tile

CENTRE = (45.07, 7.68)
BOX = (45.0655, 7.6736, 45.0745, 7.6864)  # 1 km x 1 km about CENTRE
POINTS = (100_000, 1_000_000)


def timed(fn: Callable[[], object], runs: int) -> tuple[float, float]:
    """Wall seconds of the first call and the least of `runs` more."""
    times = []
    for _ in range(runs + 1):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return times[0], min(times[1:])


def table(runs: int) -> int:
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory(prefix="dem-bench-") as tmp:
        folder = Path(tmp)
        dems = {"country, 10 m UTM": write_flat_geotiff(folder / "country.tif", 250, CENTRE),
                "SRTM 1\", EPSG:4326": write_srtm_tile(folder, 45, 7, functools.partial(hill, centre=CENTRE))}
        print(f"{'DEM':<20}{'file px':>14}{'call':>28}{'window px':>11}{'first s':>10}{'least s':>10}")
        print("-" * 93)
        for name, path in dems.items():
            first, least = timed(lambda: read_ground([path], BOX), runs)
            ground = read_ground([path], BOX)
            window = ground.windows[0]
            rows, cols = window.file_shape
            shape = f"{window.heights.shape[0]} x {window.heights.shape[1]}"
            call = "read_ground, 1 km2"
            print(f"{name:<20}{f'{rows} x {cols}':>14}{call:>28}{shape:>11}{first:>10.4f}{least:>10.4f}")
            for count in POINTS:
                lat, lon = rng.uniform(BOX[0], BOX[2], count), rng.uniform(BOX[1], BOX[3], count)
                first, least = timed(lambda: ground.height_amsl(lat, lon), runs)
                call = f"height_amsl, {count:,} pts"
                print(f"{'':<20}{'':>14}{call:>28}{'':>11}{first:>10.4f}{least:>10.4f}")
    print(machine_line())
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="timed calls after the first (the least is shown)")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args.runs)


if __name__ == "__main__":
    raise SystemExit(main())
