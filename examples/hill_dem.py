"""Write a GeoTIFF of a smooth hill under a shipped map: a DEM to try `plan --dem` with, made here, not downloaded.

    python examples/hill_dem.py MAP FILE [--peak 40] [--radius 120]

MAP is a shipped map's name (or a .map file with an origin); the hill (missionplan.testing.dem_files.hill) sits
under its middle and the file reaches 6 km beyond it, farther than ArduPilot asks for terrain (docs/terrain.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from missionplan.testing.dem_files import hill_under_map


def main() -> int:
    parser = argparse.ArgumentParser(description="write a GeoTIFF of a smooth hill under a shipped map (a test DEM)")
    parser.add_argument("map", help="a shipped map's name, or a .map file with an origin")
    parser.add_argument("file", type=Path, help="the GeoTIFF to write")
    parser.add_argument("--peak", type=float, default=40.0, help="the hill's height above its base, m (default 40)")
    parser.add_argument("--radius", type=float, default=120.0, help="the hill's radius, m (default 120)")
    args = parser.parse_args()
    args.file.parent.mkdir(parents=True, exist_ok=True)
    path = hill_under_map(args.map, args.file, args.peak, args.radius)
    print(f"wrote {path}: a {args.peak:g} m hill of radius {args.radius:g} m under {args.map}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
