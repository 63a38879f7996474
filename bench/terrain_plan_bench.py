"""What a DEM costs `plan`: the wall time of planning a 1 km x 1 km open field for 4 drones with and without a
DEM under it, for ArduPilot (terrain-frame waypoints) and PX4 (altitudes above sea level, legs split where the
ground departs from them by more than 2 m), and the waypoints the DEM adds (PX4's split legs).

Run by hand: `.venv/bin/python bench/terrain_plan_bench.py [--peak 60] [--radius 300] [--runs 3] [--write-doc FILE]`.
The field: a .map of 200 x 200 cells of 5 m, the camera's footprint 45 m at 25 m, launch points on its edges;
the hill: missionplan.testing.dem_files.hill under its middle, written as a 10 m GeoTIFF reaching 4 km beyond.
Each row is the least wall time of --runs plans (`missionplan plan ... --quiet`, in this process).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import tempfile
import time
from pathlib import Path

import doctable  # bench/doctable.py: --write-doc
from missionplan.cli.app import main as missionplan
from missionplan.mission.plan_record import read_plan_record
from missionplan.testing.dem_files import M_PER_DEG, hill, write_geotiff

ORIGIN = (45.05, 7.65)  # the field's north-west corner
CELLS, CELL_M = 200, 5.0


def write_field(path: Path) -> None:
    rows = ["." * CELLS for _ in range(CELLS)]
    launch = f"0,0  0,{CELLS - 1}  {CELLS - 1},0  {CELLS - 1},{CELLS - 1}"
    path.write_text("\n".join([
        "# A 1 km x 1 km open field for bench/terrain_plan_bench.py", "name: km-field",
        f"cell_m: {CELL_M}", f"origin_lat: {ORIGIN[0]}", f"origin_lon: {ORIGIN[1]}", "altitude_m: 25",
        "fov_deg: 83.9744", f"launch: {launch}", "grid:", *rows]) + "\n")


def write_hill(path: Path, peak_m: float, radius_m: float) -> None:
    side_deg = CELLS * CELL_M / M_PER_DEG
    centre = (ORIGIN[0] - side_deg / 2, ORIGIN[1] + side_deg / 2 / math.cos(math.radians(ORIGIN[0])))
    pad = 4_000.0 / M_PER_DEG
    write_geotiff(path, lambda lat, lon: hill(lat, lon, centre, peak_m=peak_m, radius_m=radius_m),
                  (ORIGIN[0] - side_deg - pad, ORIGIN[1] - 2 * pad, ORIGIN[0] + pad, ORIGIN[1] + 2 * side_deg + 2 * pad),
                  10.0)


def plan_once(field: Path, out: Path, autopilot: str, dem: Path | None) -> float:
    args = ["plan", "--map", str(field), "--uavs", "4", "--autopilot", autopilot, "--out", str(out), "--quiet"]
    if dem is not None:
        args += ["--dem", str(dem)]
    started = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = missionplan(args)
    took = time.perf_counter() - started
    if code != 0:
        raise SystemExit(f"plan {' '.join(args)} exited {code}")
    return took


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--peak", type=float, default=60.0, help="the hill's height, m (default 60)")
    parser.add_argument("--radius", type=float, default=300.0, help="the hill's radius, m (default 300)")
    parser.add_argument("--runs", type=int, default=3)
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__), tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        field, dem = root / "field.map", root / "hill.tif"
        write_field(field)
        write_hill(dem, args.peak, args.radius)
        print(f"1 km x 1 km open field, 4 drones, {CELL_M:g} m cells, 25 m above the ground; hill {args.peak:g} m "
              f"high, radius {args.radius:g} m; least of {args.runs} runs")
        print(f"{'autopilot':<10} {'ground':<6} {'plan s':>7} {'waypoints':>10} {'added':>6}")
        for autopilot in ("ardupilot", "px4"):
            flat_count = 0
            for ground in (None, dem):
                out = root / f"{autopilot}-{'dem' if ground else 'flat'}"
                took = min(plan_once(field, out / str(k), autopilot, ground) for k in range(args.runs))
                record = read_plan_record(out / "0")
                written = sum(sum(1 for line in (out / "0" / f"uav{d.id}.plan").read_text().splitlines()
                                  if '"command": 16' in line) for d in record.drones or ())  # NAV_WAYPOINT items
                flat_count = written if ground is None else flat_count
                added = "" if ground is None else f"{written - flat_count:>6}"
                print(f"{autopilot:<10} {'DEM' if ground else 'flat':<6} {took:>7.2f} {written:>10} {added:>6}")


if __name__ == "__main__":
    main()
