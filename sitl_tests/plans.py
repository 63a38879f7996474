"""Plans for the real-autopilot tests: a small area given as a GeoJSON ring, planned by the CLI."""

from __future__ import annotations

import json
from pathlib import Path

from missionplan.cli import main


def plan_area(base: Path, ring: list[list[float]], launches: tuple[str, ...], altitude_m: float = 20.0,
              fov_deg: float = 84.0) -> Path:
    """`missionplan plan --area` of the [lon, lat] ring with one drone per "lat,lon" launch, into base/plan."""
    area = base / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    args = ["plan", "--area", str(area), "--altitude", f"{altitude_m:g}", "--fov", f"{fov_deg:g}",
            "--out", str(base / "plan"), "--quiet"]
    for point in launches:
        args += ["--launch", point]
    assert main(args) == 0
    return base / "plan"
