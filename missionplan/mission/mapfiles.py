"""The map files a crew opens and carries away, written from a plan's (or a flight's) layers.

- `NAME.html`: one self-contained page, the layers over the city (missionplan/mission/webmap.py);
- `NAME.gpkg`: a GeoPackage, one named layer each, for QGIS and `ogr2ogr` (geo/gpkg.py);
- `NAME.kmz`: Google Earth, the paths at their altitudes (geo/kml.py);
- and for a plan, `tracks.geojson`: every layer in one GeoJSON file, each feature naming its `layer`.
NAME is `plan` or `flight`. Each file is written whole or not at all (temp file, then rename).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from missionplan.base.atomic import write_text_atomic
from missionplan.geo.gpkg import write_geopackage
from missionplan.geo.kml import write_kmz

from .layers import LAYER_GEOMETRY, Layers, one_collection
from .webmap import write_html_map


def write_map_files(out: Path, name: str, layers: Layers, summary: dict[str, Any],
                    basemap: str | None = None) -> list[Path]:
    """Write out/NAME.html, NAME.gpkg and NAME.kmz (plus tracks.geojson for a plan); returns the paths."""
    colours = {drone["uav"]: drone["colour"] for drone in summary.get("drones") or []}
    written = [out / f"{name}.html", out / f"{name}.gpkg", out / f"{name}.kmz"]
    write_html_map(written[0], layers, summary, basemap=basemap)
    write_geopackage(written[1], layers, geometry_types=LAYER_GEOMETRY)
    write_kmz(written[2], layers, title=summary["title"], colours=colours)
    if name == "plan":
        written.append(out / "tracks.geojson")
        write_text_atomic(written[-1], json.dumps(one_collection(layers)) + "\n")
    return written
