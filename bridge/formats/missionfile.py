"""Mission files, whichever the format: read by suffix or content, written by suffix, and checked against the
vehicle's autopilot.

QGroundControl `.plan` (JSON, with fence and rally points; formats.qgc_plan) and QGC WPL 110 `.waypoints`
(formats.qgc_wpl) are read and written; QGroundControl's legacy `.mission` is read. Which reader runs:
`.plan`, `.mission` and `.waypoints` by suffix; any other name (Mission Planner's `.waypoints.txt` / `.txt`)
by content, the `QGC WPL 110` header or a JSON plan or mission. What every reader refuses, and why, is
formats.item_checks. Bad files raise BridgeUsageError naming the file, the item and the problem, and nothing
else. Writes are atomic (temp file, then rename) with LF line endings (formats.file_text).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import BridgeError, BridgeUsageError
from .file_text import read_text
from .mission_items import Flavour
from .qgc_plan import (PlanFile, looks_like_mission_file, plan_from_document, plan_from_mission_file, read_json,
                       read_plan, read_qgc_mission, write_plan)
from .qgc_wpl import WPL_HEADER, read_waypoints, write_waypoints

SUFFIXES = (".plan", ".waypoints")
SNIFF_CHARS = 4096  # how much of a file of another suffix is read to tell its format


class FirmwareMismatch(BridgeUsageError, BridgeError):
    """A .plan written for one autopilot, about to go to the other: bad input (exit 2 for `upload`),
    and a BridgeError too, so that a fleet flight fails that vehicle like any other upload failure."""


AUTOPILOT_NAMES = {Flavour.ARDUPILOT: "ArduPilot", Flavour.PX4: "PX4"}


def check_firmware(plan: PlanFile, path: str | os.PathLike[str], flavour: Flavour | None,
                   sysid: int | None = None) -> None:
    """FirmwareMismatch when `plan` says (its .plan firmwareType) it was written for ArduPilot and the
    vehicle is PX4, or the other way round. A file that names no autopilot (a .waypoints, a generic
    firmwareType) and a vehicle of another flavour are not checked."""
    written = plan.firmware
    if written not in AUTOPILOT_NAMES or flavour not in AUTOPILOT_NAMES or written is flavour:
        return
    vehicle = "the vehicle" if sysid is None else f"vehicle {sysid}"
    raise FirmwareMismatch(f"{path}: written for {AUTOPILOT_NAMES[written]} (firmwareType {written.autopilot}), but "
                           f"{vehicle} is {AUTOPILOT_NAMES[flavour]}: plan it again with `missionplan plan "
                           f"--autopilot {flavour.value}` (docs/px4-missions.md)")


def read_mission_file(path: str | os.PathLike[str]) -> PlanFile:
    """Read a `.plan`, `.mission` or `.waypoints` file: by suffix, or for any other name by its content."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        return read_plan(path)
    if suffix == ".mission":
        return read_qgc_mission(path)
    if suffix == ".waypoints":
        return PlanFile(mission=read_waypoints(path))
    # Mission Planner and QGroundControl also save QGC WPL files as `.waypoints.txt` or `.txt`: told by
    # their first characters, without reading the whole file.
    start = read_text(path, SNIFF_CHARS).lstrip()
    if start.startswith("QGC WPL"):
        return PlanFile(mission=read_waypoints(path))
    if start.startswith("{"):
        doc = read_json(path)
        if isinstance(doc, dict) and doc.get("fileType") != "Plan" and looks_like_mission_file(doc):
            return plan_from_mission_file(doc, path)
        return plan_from_document(doc, path)
    raise BridgeUsageError(f"{path}: not a mission file (expected a QGroundControl .plan or a file whose first line "
                           f"is \"{WPL_HEADER}\")")


def output_format(path: str | os.PathLike[str]) -> str:
    """"plan" or "waypoints": what write_mission_file writes to this name; BridgeUsageError otherwise."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".plan":
        return "plan"
    if suffix in (".waypoints", ".txt"):  # .txt: Mission Planner's other name for a QGC WPL file
        return "waypoints"
    raise BridgeUsageError(f"{path}: unknown mission file type {path.suffix!r} (expected .plan, .waypoints "
                           "or .txt)")


def write_mission_file(path: str | os.PathLike[str], plan: PlanFile) -> None:
    """Write a `.plan` or `.waypoints` (or `.txt`) file, chosen by its suffix (.waypoints keeps only the mission)."""
    if output_format(path) == "plan":
        write_plan(path, plan)
    else:
        write_waypoints(path, plan.mission)

