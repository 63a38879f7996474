"""A plan folder's own files: which ones a previous `plan` wrote there, so a re-plan leaves none stale and
removes nothing else.

A crew may upload whatever uavK.plan lies in the folder, so re-planning 2 drones where 4 were
planned must not leave uav3.* / uav4.* behind. A file is removed only when it is exactly what an
earlier plan wrote in this folder: its name is one the previous report.json lists (`files`), of the
kinds `plan` writes, and its content still has the sha256 that report recorded (`files_sha256`). A
file changed since (the crew edited it), a report.json copied in from elsewhere that lists files of
the same names, or an older report that recorded no checksums: the file is kept, and said. Anything
else in the folder - the user's own files, fly's flight.json - is never looked at.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from .plan_record import listed_files

# What `plan` writes: report.json, plan.png / .html / .gpkg / .kmz, tracks.geojson, uavK[-sJ].plan / .waypoints.
OUR_FILE = re.compile(r"^(report\.json|plan\.(png|html|gpkg|kmz)|tracks\.geojson|uav\d+(-s\d+)?\.(plan|waypoints))$")


def file_sha256(path: Path) -> str:
    """The hex sha256 of a file's content (what report.json records for each file a plan wrote)."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


@dataclass
class PreviousOutputs:
    """What the report.json in a folder says `plan` wrote there: the file names, and the sha256 of each
    (empty for a report written before checksums were recorded)."""

    names: list[str] = field(default_factory=list)
    sha256: dict[str, str] = field(default_factory=dict)


def previous_outputs(out: Path) -> PreviousOutputs:
    """The files the report.json in `out` says `plan` wrote (nothing when there is none or it is unreadable)."""
    names, sha256 = listed_files(out)
    return PreviousOutputs(names, sha256)


@dataclass
class StaleOutputs:
    """The previous plan's files the new plan does not write: removed, or kept because they are not
    (any more) exactly what that plan wrote."""

    removed: list[Path] = field(default_factory=list)
    kept: list[Path] = field(default_factory=list)


def remove_stale_outputs(out: Path, keep: Iterable[str]) -> StaleOutputs:
    """Remove the files the previous plan in `out` wrote that the new one does not (`keep`: the new plan's
    names), each only when its content is still what that plan recorded; see the module docstring."""
    keep = set(keep)
    previous = previous_outputs(out)
    stale = StaleOutputs()
    for name in previous.names:
        if name in keep or not OUR_FILE.match(name):
            continue
        path = out / name
        if not path.is_file() or path.is_symlink():
            continue
        if previous.sha256.get(name) == file_sha256(path):
            path.unlink()
            stale.removed.append(path)
        else:
            stale.kept.append(path)
    return stale
