"""Points a PX4 mission needs over hills: a lawnmower survey of 1 km^2 over two peaks, split for sea level.

PX4 takes no terrain frame, so a mission that keeps a height above the ground is written in sea-level
altitude and each leg is split wherever the ground leaves the straight line by more than a tolerance
(missionplan.mission.terrain_legs.amsl_track). This measures, per tolerance, how many waypoints that adds
to a survey track, the worst departure from the height asked for along the legs as flown (flown_heights,
every step metres), and the time the split takes (the best of --repeat runs: the machine is shared). The
ground is analytic: a 150 m plain with an 80 m and a 55 m peak (Gaussian, sigma 150 m and 110 m), so no
terrain file is read. Run by hand:

    .venv/bin/python bench/terrain_legs_bench.py [--tolerances 1,2,5] [--spacing 30] [--height 40]
                                                 [--step 5] [--repeat 5] [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from missionplan.mission.terrain_legs import amsl_track, flown_heights, sample_legs

import doctable  # bench/doctable.py: --write-doc

LAT0, LON0 = 44.41, 8.93  # Genoa
SIDE_M = 1000.0  # the survey square's side: 1 km^2
M_PER_DEG_LAT = 111_132.0  # near 44 degrees north; the bench needs no better
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))
PEAKS = ((300.0, 350.0, 80.0, 150.0), (720.0, 650.0, 55.0, 110.0))  # east m, north m, height m, sigma m
PLAIN_M = 150.0


def two_peaks(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """The ground, metres above sea level."""
    east = (np.asarray(lon) - LON0) * M_PER_DEG_LON
    north = (np.asarray(lat) - LAT0) * M_PER_DEG_LAT
    height = np.full(east.shape, PLAIN_M)
    for x, y, top, sigma in PEAKS:
        height += top * np.exp(-((east - x) ** 2 + (north - y) ** 2) / (2 * sigma**2))
    return height


def lawnmower(spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """East-west lanes `spacing_m` apart across the square, each lane's two ends a waypoint."""
    north = np.arange(0.0, SIDE_M + 1e-9, spacing_m)
    west_first = np.arange(north.size) % 2 == 0
    east = np.column_stack((np.where(west_first, 0.0, SIDE_M), np.where(west_first, SIDE_M, 0.0))).ravel()
    return LAT0 + np.repeat(north, 2) / M_PER_DEG_LAT, LON0 + east / M_PER_DEG_LON


def qgc_rule(lat: np.ndarray, lon: np.ndarray, height: float, tolerance: float, step: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """QGroundControl's decimation of a terrain-following transect, applied to every leg: keep the leg's ends
    and each sample whose altitude differs from the last kept point's by more than the tolerance."""
    s_lat, s_lon, leg = sample_legs(lat, lon, step)
    amsl = two_peaks(s_lat, s_lon) + height
    keep = np.zeros(leg.size, dtype=bool)
    ends = np.flatnonzero(np.diff(leg, prepend=-1, append=leg.size))
    keep[ends[:-1]] = keep[ends[1:] - 1] = True
    last = amsl[0]
    for i in range(leg.size):  # a walk: each decision depends on the last point kept
        if keep[i] or abs(amsl[i] - last) > tolerance:
            keep[i], last = True, amsl[i]
    keep[ends[1:-1]] = False  # a waypoint between two legs once: as the last sample of the leg before it
    return s_lat[keep], s_lon[keep], amsl[keep]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerances", default="1,2,5", help="metres, comma-separated")
    parser.add_argument("--spacing", type=float, default=30.0, help="lane spacing, metres")
    parser.add_argument("--height", type=float, default=40.0, help="height above the ground asked for, metres")
    parser.add_argument("--step", type=float, default=5.0, help="sample spacing along the legs, metres")
    parser.add_argument("--repeat", type=int, default=5, help="runs per tolerance; the best time is shown")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:
    lat, lon = lawnmower(args.spacing)
    samples = sample_legs(lat, lon, args.step)[0].size
    relief = two_peaks(*np.meshgrid(np.linspace(LAT0, lat.max(), 200), np.linspace(LON0, lon.max(), 200)))
    print(f"1 km^2 lawnmower, lanes {args.spacing:g} m apart: {lat.size} waypoints, {samples:,} samples every "
          f"{args.step:g} m; ground {relief.min():.0f}-{relief.max():.0f} m; {args.height:g} m above it asked")
    print(f"{'tolerance m':>11} {'waypoints':>9} {'added':>6} {'worst off m':>11} {'split ms':>9}"
          f" | {'QGC rule: added':>15} {'worst off m':>11}")
    for tolerance in (float(t) for t in args.tolerances.split(",")):
        best = math.inf
        for _ in range(max(1, args.repeat)):
            start = time.perf_counter()
            out_lat, out_lon, amsl, source = amsl_track(lat, lon, args.height, two_peaks, tolerance, args.step)
            best = min(best, time.perf_counter() - start)
        off = np.abs(flown_heights(out_lat, out_lon, amsl, two_peaks, args.step) - args.height).max()
        q_lat, q_lon, q_amsl = qgc_rule(lat, lon, args.height, tolerance, args.step)
        q_off = np.abs(flown_heights(q_lat, q_lon, q_amsl, two_peaks, args.step) - args.height).max()
        print(f"{tolerance:>11g} {out_lat.size:>9} {int((source < 0).sum()):>6} {off:>11.2f} {best * 1000:>9.1f}"
              f" | {q_lat.size - lat.size:>15} {q_off:>11.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
