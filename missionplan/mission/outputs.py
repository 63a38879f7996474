"""A plan folder's own files: which ones a previous `plan` wrote there, so a re-plan leaves none stale.

A crew may upload whatever uavK.plan lies in the folder, so re-planning 2 drones where 4 were
planned must not leave uav3.* / uav4.* behind. Only files the project wrote are removed: the ones the
previous report.json lists in `files` (older reports, without that list: the uavK.plan/.waypoints of
their `drones` and tracks.geojson), and only plain names of the kinds `plan` writes. Anything else in
the folder - the user's own files, fly's flight.json - is left alone.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Iterable

# What `plan` writes: report.json, plan.png / .html / .gpkg / .kmz, tracks.geojson, uavK[-sJ].plan / .waypoints.
OUR_FILE = re.compile(r"^(report\.json|plan\.(png|html|gpkg|kmz)|tracks\.geojson|uav\d+(-s\d+)?\.(plan|waypoints))$")


def previous_outputs(out: Path) -> list[str]:
    """The file names the report.json in `out` says `plan` wrote (empty when there is none or it is unreadable)."""
    try:
        report: Any = json.loads((out / "report.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(report, dict):
        return []
    files = report.get("files")
    if isinstance(files, list):
        return [name for name in files if isinstance(name, str)]
    names = []
    for drone in report.get("drones") or []:  # reports written before `files` existed
        if isinstance(drone, dict) and isinstance(drone.get("id"), int):
            names += [f"uav{drone['id']}.plan", f"uav{drone['id']}.waypoints"]
    return names + (["tracks.geojson"] if names else [])


def remove_stale_outputs(out: Path, keep: Iterable[str]) -> list[Path]:
    """Remove the files the previous plan in `out` wrote that the new one does not; returns them."""
    keep = set(keep)
    removed = []
    for name in previous_outputs(out):
        if name in keep or not OUR_FILE.match(name):
            continue
        path = out / name
        if path.is_file() and not path.is_symlink():
            path.unlink()
            removed.append(path)
    return removed
