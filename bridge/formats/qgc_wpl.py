"""QGC WPL 110 `.waypoints` files (QGroundControl's and Mission Planner's plain-text missions), read and written.

First line "QGC WPL 110", then one tab-separated line of 12 columns per item; line 0 is the home position
(Mission Planner's convention), so mission items are lines 1..n and a DO_JUMP names its target by line number,
the model's 1-based item number. Read line by line, every item through formats.item_checks; a file holds a
mission only (no fence or rally points).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from ..errors import BridgeUsageError
from ..limits import MAX_MISSION_ITEMS
from .file_text import check_file, write_text
from .item_checks import check_home, check_item, check_jumps, default_home, refuse_terrain_altitude, too_many
from .mission_items import CMD_NAV_WAYPOINT, FRAME_GLOBAL, Mission, MissionItem, MissionType

WPL_HEADER = "QGC WPL 110"
MAX_WAYPOINTS_LINE = 4096  # characters: a QGC WPL line of 12 numbers is under 400


def read_waypoints(path: str | os.PathLike[str]) -> Mission:
    """A QGC WPL 110 file: line 0 is home, lines 1..n the mission items.

    Read line by line: a file of more items than MAVLink can carry is refused at the first item too many,
    and a line longer than any QGC WPL line at its first MAX_WAYPOINTS_LINE characters, so no file is ever
    held whole in memory."""
    path = Path(path)
    check_file(path)
    try:
        with path.open(encoding="utf-8-sig") as stream:
            return _parse_waypoints(stream, path)
    except UnicodeDecodeError:
        raise BridgeUsageError(f"{path}: not a text file (expected a .plan or .waypoints mission)") from None
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None


def _lines(stream: TextIO, path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of each line that is not blank, none longer than MAX_WAYPOINTS_LINE."""
    number = 0
    while line := stream.readline(MAX_WAYPOINTS_LINE + 1):
        number += 1
        if len(line) > MAX_WAYPOINTS_LINE and not line.endswith("\n"):
            raise BridgeUsageError(f"{path}: line {number} is longer than {MAX_WAYPOINTS_LINE:,} characters: not a "
                                   "waypoints file")
        if line.strip():
            yield number, line.rstrip("\r\n")


def _parse_waypoints(stream: TextIO, path: Path) -> Mission:
    lines = _lines(stream, path)
    header = next(lines, (0, ""))[1].strip()
    if not header.startswith("QGC WPL"):
        raise BridgeUsageError(f"{path}: not a waypoints file (first line is not \"{WPL_HEADER}\")")
    if header.split()[-1] != "110":
        raise BridgeUsageError(f"{path}: unsupported waypoints version {header.split()[-1]!r} (expected 110)")
    items: list[MissionItem] = []
    wheres: list[str] = []
    home: tuple[float, float, float] | None = None
    for position, (line_no, line) in enumerate(lines):
        if position > MAX_MISSION_ITEMS:
            raise too_many(path, "mission", MAX_MISSION_ITEMS, f"line {line_no}: ")
        fields = [f.strip() for f in (line.split("\t") if "\t" in line else line.split())]
        if len(fields) != 12:
            raise BridgeUsageError(f"{path}: line {line_no}: expected 12 tab-separated columns, got {len(fields)}")
        try:
            index, _current, frame, command = (int(fields[0]), int(fields[1]), int(fields[2]), int(fields[3]))
            p1, p2, p3, p4, x, y, z = (float(v) for v in fields[4:11])
            autocontinue = int(float(fields[11]))
        except (ValueError, OverflowError):
            raise BridgeUsageError(f"{path}: line {line_no}: a column is not a number") from None
        if index != position:
            raise BridgeUsageError(f"{path}: line {line_no}: item index {index}, expected {position}")
        if not (0 <= frame <= 255 and 0 <= command <= 65535):
            raise BridgeUsageError(f"{path}: line {line_no}: frame {frame} or command {command} out of range")
        if position == 0:
            home = None if (x, y, z) == (0.0, 0.0, 0.0) else check_home((x, y, z), f"line {line_no} (home)", path)
            continue
        item = MissionItem(command=command, frame=frame, param1=p1, param2=p2, param3=p3, param4=p4, x=x, y=y, z=z,
                           autocontinue=bool(autocontinue))
        where = f"line {line_no} (item {position})"
        refuse_terrain_altitude(item, where, path)
        items.append(check_item(item, where, path))
        wheres.append(where)
    check_jumps(items, wheres, path)
    return Mission(items=items, mission_type=MissionType.MISSION, home=home)


def _wpl_number(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return f"{value:.8f}"


def waypoints_text(mission: Mission) -> str:
    lat, lon, alt = default_home(mission)
    rows = [WPL_HEADER,
            "\t".join(["0", "1", str(FRAME_GLOBAL), str(CMD_NAV_WAYPOINT)] + [_wpl_number(0.0)] * 4
                      + [_wpl_number(lat), _wpl_number(lon), _wpl_number(alt), "1"])]
    for number, item in enumerate(mission.items, start=1):
        rows.append("\t".join([str(number), "0", str(int(item.frame)), str(int(item.command))]
                              + [_wpl_number(v) for v in item.params] + ["1" if item.autocontinue else "0"]))
    return "\n".join(rows) + "\n"


def write_waypoints(path: str | os.PathLike[str], mission: Mission) -> None:
    if mission.mission_type != MissionType.MISSION:
        raise BridgeUsageError(f"{path}: a .waypoints file holds a mission, not {mission.mission_type.label} items")
    write_text(Path(path), waypoints_text(mission))

