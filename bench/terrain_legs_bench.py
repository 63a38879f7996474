"""Points a PX4 mission needs over hills: a lawnmower survey of 1 km^2 over two peaks, split for sea level.

PX4 takes no terrain frame, so a mission that keeps a height above the ground is written in sea-level
altitude and each leg is split wherever the ground leaves the straight line by more than a tolerance
(missionplan.mission.terrain_legs.amsl_track). This measures, per tolerance, how many waypoints that adds
to a survey track, the worst departure from the height asked for along the legs as flown (flown_heights,
every step metres), and the time the split takes (the best of --repeat runs: the machine is shared); the
straight-line split alone, without the cut of each leg's first stretch for PX4's turns (lead_in_turns). The
ground is analytic: a 150 m plain with an 80 m and a 55 m peak (Gaussian, sigma 150 m and 110 m), so no
terrain file is read.

A second table: what `missionplan plan --autopilot px4 --dem` adds to a real plan, the shipped old-town map
for 3 drones over tests/test_plan_terrain.py's hill (40 m high, radius 120 m, on a 230 m plain, centred on the
map; a GeoTIFF of 5 m pixels written in a temporary folder), with the product's 2 m tolerance and the cut for
PX4's turns: per drone, the waypoints the planner made (report.json), the waypoints of its .plan, the ones
added, and the worst departure from the height asked for along its legs flown straight between its sea-level
altitudes (flown_heights, every metre, on the plan folder's copy of the ground), from the launch point over
the take-off to the last waypoint. Run by hand:

    .venv/bin/python bench/terrain_legs_bench.py [--tolerances 1,2,5] [--spacing 30] [--height 40]
                                                 [--step 5] [--repeat 5] [--map old-town] [--uavs 3]
                                                 [--write-doc FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from missionplan.bridge.formats.mission_items import CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.cli.app import main as missionplan
from missionplan.geo.dem import read_ground
from missionplan.maps.catalog import load_shipped
from missionplan.mission.georef import shipped_frame
from missionplan.mission.plan_record import read_plan_record
from missionplan.mission.terrain_legs import amsl_track, flown_heights, sample_legs
from missionplan.testing.dem_files import hill, write_geotiff

import doctable  # bench/doctable.py: --write-doc

LAT0, LON0 = 44.41, 8.93  # Genoa
SIDE_M = 1000.0  # the survey square's side: 1 km^2
M_PER_DEG_LAT = 111_132.0  # near 44 degrees north; the bench needs no better
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))
PEAKS = ((300.0, 350.0, 80.0, 150.0), (720.0, 650.0, 55.0, 110.0))  # east m, north m, height m, sigma m
PLAIN_M = 150.0
# The hill tests/test_plan_terrain.py plans the old-town map over: centred on the map, on dem_files.hill's plain.
TEST_HILL_PEAK_M, TEST_HILL_RADIUS_M, TEST_HILL_PAD_DEG, TEST_HILL_PIXEL_M = 40.0, 120.0, 0.05, 5.0


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
    parser.add_argument("--map", default="old-town", help="shipped map planned over the test hill for PX4")
    parser.add_argument("--uavs", type=int, default=3, help="drones of that plan")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args) or plan_table(args.map, args.uavs)


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


def plan_table(map_name: str, uavs: int) -> int:
    """`missionplan plan --autopilot px4 --dem` of a shipped map over the test hill: the waypoints it adds."""
    box = shipped_frame(load_shipped(map_name)).latlon_box()
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)

    def ground(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return hill(lat, lon, centre, peak_m=TEST_HILL_PEAK_M, radius_m=TEST_HILL_RADIUS_M)

    pad = TEST_HILL_PAD_DEG
    with tempfile.TemporaryDirectory(prefix="terrain-legs-bench-") as tmp:
        dem = write_geotiff(Path(tmp) / "hill.tif", ground, (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad),
                            TEST_HILL_PIXEL_M)
        out, reference = Path(tmp) / "plan", Path(tmp) / "ardupilot"
        started = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            code = missionplan(["plan", "--map", map_name, "--uavs", str(uavs), "--autopilot", "px4", "--dem",
                                str(dem), "--quiet", "--out", str(out)])
        took = time.perf_counter() - started
        with contextlib.redirect_stdout(io.StringIO()):  # the same tracks, unsplit: ArduPilot follows the terrain
            code = code or missionplan(["plan", "--map", map_name, "--uavs", str(uavs), "--dem", str(dem), "--quiet",
                                        "--out", str(reference)])
        if code != 0:
            return code
        unsplit = {d.id: d.waypoints for d in read_plan_record(reference).drones or ()}
        record = read_plan_record(out)
        terrain = record.georeference.terrain if record.georeference is not None else None
        assert terrain is not None, "a plan over a DEM records its ground"
        plan_ground = read_ground([out / f for f in terrain.files], box, margin_m=0)
        print(f"\n{map_name}, {uavs} drones, `plan --autopilot px4 --dem` over a {TEST_HILL_PEAK_M:g} m hill "
              f"(radius {TEST_HILL_RADIUS_M:g} m) in {took:.1f} s; 2 m tolerance")
        print(f"{'drone':>5} {'height m':>8} {'planned':>7} {'in .plan':>8} {'added':>5} {'added %':>7}"
              f" {'worst off m':>11} {'ground m':>9}")
        total_planned = total_written = 0
        for drone in record.drones or ():
            mission = read_mission_file(out / f"uav{drone.id}.plan").mission
            assert mission.home is not None
            takeoff = next(item for item in mission.items if item.command == CMD_NAV_TAKEOFF)
            waypoints = [item for item in mission.items if item.command == CMD_NAV_WAYPOINT]
            lat = np.array([mission.home[0]] + [w.x for w in waypoints])
            lon = np.array([mission.home[1]] + [w.y for w in waypoints])
            amsl = np.array([mission.home[2] + takeoff.z] + [w.z for w in waypoints])
            above = flown_heights(lat, lon, amsl, plan_ground.height_amsl, 1.0)
            under = plan_ground.height_amsl(*sample_legs(lat, lon, 1.0)[:2])
            planned, written = unsplit[drone.id], len(waypoints)
            total_planned, total_written = total_planned + planned, total_written + written
            print(f"{'uav' + str(drone.id):>5} {takeoff.z:>8g} {planned:>7} {written:>8} {written - planned:>5}"
                  f" {100 * (written - planned) / planned:>7.0f} {np.abs(above - takeoff.z).max():>11.2f}"
                  f" {under.min():>4.0f}-{under.max():.0f}")
        added = total_written - total_planned
        print(f"{'all':>5} {'':>8} {total_planned:>7} {total_written:>8} {added:>5} {100 * added / total_planned:>7.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
