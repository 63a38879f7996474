"""`missionplan cameras`: the shipped catalogue of survey cameras (geo/camera_catalogue.py), one line each with
the GSD it gives at 100 m, for `plan --camera NAME`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from missionplan.geo.camera_catalogue import CATALOGUE
from missionplan.geo.capture import gsd_cm, shown

from .parsing import runs

GSD_HEIGHT_M = 100.0  # the height the table's GSD column is for


@dataclass(frozen=True)
class CamerasRequest:
    """`cameras` takes no arguments."""


def register(sub: Any) -> None:
    """Add `cameras`."""
    cameras = sub.add_parser("cameras", help="list the survey cameras `plan --camera` knows")
    cameras.set_defaults(handler=runs(CamerasRequest, cmd_cameras))


def cmd_cameras(request: CamerasRequest) -> int:
    rows = [("name", "sensor mm", "image px", "focal mm", "interval s", f"GSD at {GSD_HEIGHT_M:g} m", "camera")]
    for row in CATALOGUE:
        interval = "-" if row.capture_interval_s is None else f"{row.capture_interval_s:g}"
        rows.append((row.id, f"{row.sensor_width_mm:g} x {row.sensor_height_mm:g}",
                     f"{row.image_width_px} x {row.image_height_px}", f"{row.focal_length_mm:g}", interval,
                     f"{shown(gsd_cm(row.camera(), GSD_HEIGHT_M))} cm/px", row.title))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
    for r in rows:
        print("  ".join(cell.ljust(width) for cell, width in zip(r, widths)) + "  " + r[-1])
    print("interval: the shortest time between two photos (-: not known, give --capture-interval S); "
          "GSD: the worse of width and height")
    return 0
