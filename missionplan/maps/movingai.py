"""The MovingAI map reader: grid benchmarks in the octile format, read as missionplan maps.

MovingAI maps (N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 2012; the street
maps are rasterised OpenStreetMap street networks) share the `.map` extension with missionplan's own
format; a file is read as MovingAI when its first line is `type <kind>` (no colon, unlike every line
of ours), and only `type octile` is accepted. The file::

    type octile
    height H
    width W
    map
    H rows of W characters

How each terrain character of the format becomes a cell here:

    `.` `G`  passable terrain            -> target: a street to photograph
    `S`      swamp (passable from land)  -> target: a drone flies over it like any open ground
    `@` `O`  out of bounds               -> obstacle
    `T`      trees (impassable)          -> obstacle: too tall to fly the survey height through
    `W`      water (passable only from   -> obstacle: a ground agent cannot cross it from the streets;
             water)                         missionplan treats water as an obstacle everywhere else
                                            (see gridmap), and a no-entry region is what the format means

The map gets no georeference (so `plan` writes report.json and plan.png only), its file stem as name,
a title and the data's credit line in `meta`, and as launch cells `LAUNCH_COUNT` well-spread open
street cells from `launches.spread_launches` (the format has none): `--uavs N` takes the first N.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .gridmap import GridMap, MapError, parse_map, read_map_text
from .launches import spread_launches

# How many launch cells a MovingAI map gets: more than any fleet the planner is used with.
LAUNCH_COUNT = 64
# The credit the data asks for wherever a grid made from it is shown (../shared/maps/README.md): the short
# line goes into the title, the full citation into `credit`.
SHORT_CREDIT = "OpenStreetMap data © OpenStreetMap contributors (ODbL); MovingAI benchmarks, N. Sturtevant 2012"
CREDIT = ("OpenStreetMap data © OpenStreetMap contributors (ODbL 1.0); MovingAI benchmarks: N. Sturtevant, "
          "\"Benchmarks for Grid-Based Pathfinding\", IEEE TCIAIG 2012 (Open Data Commons Attribution)")

PASSABLE = ".GS"
BLOCKED = "@OTW"
_TYPE_LINE = re.compile(r"^\s*type\s+(\S+)\s*$")
_SIZE_LINE = re.compile(r"^\s*(height|width)\s+(\S+)\s*$")


def is_movingai(text: str) -> bool:
    """True when `text` is (meant to be) a MovingAI map: its first line is `type <kind>`."""
    first = text.lstrip("\ufeff").split("\n", 1)[0].rstrip("\r")
    return bool(_TYPE_LINE.match(first))


def load_any_map(path: str | os.PathLike[str]) -> GridMap:
    """A `.map` file in either format, told apart by content: MovingAI octile, else missionplan's own."""
    text = read_map_text(path)
    return parse_movingai(text, str(path)) if is_movingai(text) else parse_map(text, str(path))


def parse_movingai(text: str, source: str = "<map>", launches: int = LAUNCH_COUNT) -> GridMap:
    """Parse the text of a MovingAI octile map; `source` names it in error messages and gives the name."""
    lines = [line.rstrip("\r") for line in text.lstrip("\ufeff").split("\n")]
    kind = _TYPE_LINE.match(lines[0]) if lines else None
    if kind is None:
        raise MapError(f"{source}:1: not a MovingAI map (the first line must be 'type octile')")
    if kind.group(1) != "octile":
        raise MapError(f"{source}:1: MovingAI map type {kind.group(1)!r} is not supported (only 'type octile')")
    size: dict[str, int] = {}
    lineno = 1
    for lineno in range(2, len(lines) + 1):
        line = lines[lineno - 1]
        if line.strip() == "map":
            break
        if not line.strip():  # a blank line (or the file's final newline) is no header line
            continue
        m = _SIZE_LINE.match(line)
        if m is None:
            raise MapError(f"{source}:{lineno}: expected 'height N', 'width N' or 'map', got {line.strip()[:40]!r}")
        key, value = m.groups()
        if key in size:
            raise MapError(f"{source}:{lineno}: '{key}' given twice")
        if not (value.isascii() and value.isdigit()) or int(value) < 1:
            raise MapError(f"{source}:{lineno}: {key} {value[:20]!r} is not a whole number of at least 1")
        size[key] = int(value)
    else:
        raise MapError(f"{source}: no 'map' line after the header")
    for key in ("height", "width"):
        if key not in size:
            raise MapError(f"{source}: the header has no '{key}' line")
    height, width = size["height"], size["width"]
    body = lines[lineno:]
    while body and not body[-1].strip():  # trailing blank lines (a final newline) are not rows
        body.pop()
    if len(body) != height:
        raise MapError(f"{source}: the header says height {height} but {len(body)} rows follow 'map'")
    for i, row in enumerate(body):
        if len(row) != width:
            raise MapError(f"{source}:{lineno + 1 + i}: row {i} has {len(row)} cells, the header says width {width}")
    chars = np.array(body, dtype=f"<U{width}").view("<U1").reshape(height, width)  # one char per cell, no list per row
    known = np.isin(chars, list(PASSABLE + BLOCKED))
    if not known.all():
        r, c = (int(v) for v in np.argwhere(~known)[0])
        raise MapError(f"{source}:{lineno + 1 + r}: unknown cell character {body[r][c]!r} in row {r}, column {c} "
                       f"(MovingAI uses {', '.join(PASSABLE + BLOCKED)})")
    free = np.isin(chars, list(PASSABLE))
    if not free.any():
        raise MapError(f"{source}: no passable cell ('.', 'G' or 'S') in the {height}x{width} grid")
    name = Path(source).stem
    meta = {"title": f"MovingAI street map {name}; {SHORT_CREDIT}", "credit": CREDIT, "source": "MovingAI octile map"}
    return GridMap(name=name, obstacle=~free, target=free, launch=spread_launches(free, launches), meta=meta)
