"""The occupancy-grid map and its plain-text file format.

A `GridMap` is what every planning stage reads: which cells are obstacles, which are
targets (streets to photograph), where the drones launch, where the grid lies on the Earth
(`georef`, a missionplan.geo.georeference.Georeference, or None) and free-form metadata (title,
credit, the map's declared safety values). It knows nothing about drones moving.

File format (`*.map`, UTF-8 text, meant to be written by hand as easily as by code)::

    # comment lines start with '#'
    name: leonardo
    title: Leonardo Drone Contest arena (thesis Case I), reconstructed
    cell_m: 0.238
    launch: 40,2  40,8  1,40          <- row,col of drone 1, 2, ... (0-based, row 0 on top)
    grid:
    ##########
    #....o...#
    ##########

Header lines are `key: value`, each key once (a key given twice is refused, naming both lines).
`name`, `launch` and `grid:` are required; every other key is kept as a string in `GridMap.meta`, in the
file's order, so a map saved again keeps its header lines byte for byte. The georeference's lines
(origin_lat, origin_lon, cell_m, altitude_m, fov_deg, ...: Georeference.from_header) are read once,
into `GridMap.georef`; code reads them there, never from the strings. After `grid:` every line is one row
of the grid, all rows the same length, one character per cell:

    `#`  obstacle (building, water, no-fly) - never entered
    `.`  target cell: free, to be photographed
    `o`  free cell that is not a target (flown over, never needs a photo)
    `r`  target cell on a roof low enough to overfly (`plan --targets roofs|all`: geo/roofs.py); a map
         with none has no roof layer
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from missionplan.base.atomic import write_text_atomic
from missionplan.geo.georeference import Georeference

OBSTACLE_CHAR = "#"
TARGET_CHAR = "."
FREE_CHAR = "o"
ROOF_CHAR = "r"
_KNOWN_CHARS = {OBSTACLE_CHAR, TARGET_CHAR, FREE_CHAR, ROOF_CHAR}


class MapError(ValueError):
    """A map file or map value is wrong; the message names the file and the problem."""


Cell = tuple[int, int]


@dataclass
class GridMap:
    """An occupancy grid: `obstacle` and `target` are boolean (rows, cols) arrays; `roof` marks the targets
    that are roofs (None or all False: the map has no roof layer, every target is a street cell).

    `meta` holds the map file's header lines as text (the file's spelling, the georeference's lines
    included); `georef` is the georeference they give, read once: given without its lines in `meta`, its
    lines are added there, so the map saves with them."""

    name: str
    obstacle: np.ndarray
    target: np.ndarray
    launch: list[Cell] = field(default_factory=list)
    meta: dict[str, str] = field(default_factory=dict)
    georef: Georeference | None = None
    roof: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.obstacle = np.asarray(self.obstacle, dtype=bool)
        self.target = np.asarray(self.target, dtype=bool) & ~self.obstacle
        if self.roof is not None:
            roof = np.asarray(self.roof, dtype=bool)
            if roof.shape != self.target.shape:
                raise MapError(f"map {self.name}: the roof layer must be the grid's shape")
            roof = roof & self.target  # only a target is a roof target; a map without one keeps no layer
            self.roof = roof if roof.any() else None
        if self.obstacle.ndim != 2 or self.obstacle.shape != self.target.shape:
            raise MapError(f"map {self.name}: obstacle and target grids must be 2-D and the same shape")
        self.launch = [(int(r), int(c)) for r, c in self.launch]
        if self.georef is None:
            self.georef = Georeference.from_header(self.meta, *self.shape)
        else:
            self.meta = {**self.meta, **{k: v for k, v in self.georef.to_header().items() if k not in self.meta}}

    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = self.obstacle.shape  # 2-D, checked on construction
        return rows, cols

    @property
    def free(self) -> np.ndarray:
        return ~self.obstacle

    @property
    def cell_m(self) -> float | None:
        """A cell's side on the ground in metres, from the georeference (None: the map lies nowhere)."""
        return self.georef.cell_m if self.georef is not None else None

    @property
    def roofs(self) -> np.ndarray:
        """The target cells that are roofs (all False without a roof layer)."""
        return self.roof if self.roof is not None else np.zeros(self.shape, dtype=bool)

    def inside(self, cell: Cell) -> bool:
        r, c = cell
        return 0 <= r < self.shape[0] and 0 <= c < self.shape[1]

    def rows_text(self) -> list[str]:
        """The grid as one string per row (`#`, `.`, `o`, `r`), as report.json stores it."""
        chars = np.full(self.shape, FREE_CHAR, dtype="<U1")
        chars[self.target] = TARGET_CHAR
        chars[self.roofs] = ROOF_CHAR
        chars[self.obstacle] = OBSTACLE_CHAR
        return ["".join(row) for row in chars]

    @classmethod
    def from_rows(cls, name: str, rows: list[str], launch: list[Cell] | None = None,
                  meta: dict[str, str] | None = None, georef: Georeference | None = None) -> "GridMap":
        """Build a map from `#`/`.`/`o`/`r` strings (the inverse of `rows_text`)."""
        if not rows:
            raise MapError(f"map {name}: the grid is empty")
        width = len(rows[0])
        for i, row in enumerate(rows):
            if len(row) != width:
                raise MapError(f"map {name}: grid row {i} has {len(row)} cells, row 0 has {width}")
            bad = set(row) - _KNOWN_CHARS
            if bad:
                raise MapError(f"map {name}: grid row {i} has unknown cell character {sorted(bad)[0]!r} "
                               f"(use '#', '.', 'o' or 'r')")
        chars = np.array([list(row) for row in rows])
        roof = chars == ROOF_CHAR
        return cls(name=name, obstacle=chars == OBSTACLE_CHAR, target=(chars == TARGET_CHAR) | roof,
                   launch=list(launch or []), meta=dict(meta or {}), georef=georef, roof=roof)


def _parse_launch(text: str, where: str) -> list[Cell]:
    cells: list[Cell] = []
    for token in text.split():
        try:
            r, c = (int(v) for v in token.split(","))
        except ValueError:
            raise MapError(f"{where}: launch cell {token!r} is not 'row,col'") from None
        cells.append((r, c))
    return cells


def parse_map(text: str, source: str = "<map>") -> GridMap:
    """Parse the text of a `.map` file; `source` names it in error messages."""
    header: dict[str, str] = {}
    header_line: dict[str, int] = {}  # where each key was given: a key given twice is refused, not "last wins"
    rows: list[str] | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip("\r\n")
        if rows is not None:
            if line.strip():
                rows.append(line.strip())
            continue
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if stripped == "grid:":
            rows = []
            continue
        key, sep, value = stripped.partition(":")
        if not sep:
            raise MapError(f"{source}:{lineno}: expected 'key: value' or 'grid:', got {stripped[:40]!r}")
        key = key.strip()
        if key in header_line:
            raise MapError(f"{source}:{lineno}: header key {key!r} given twice (lines {header_line[key]} and {lineno}); "
                           "keep one")
        header[key], header_line[key] = value.strip(), lineno
    if rows is None:
        raise MapError(f"{source}: no 'grid:' section")
    name = header.pop("name", "") or Path(source).stem
    launch = _parse_launch(header.pop("launch", ""), source)
    try:
        gmap = GridMap.from_rows(name, rows, launch, header)
    except MapError as err:
        raise MapError(f"{source}: {err}") from None
    for k, cell in enumerate(gmap.launch, start=1):
        if not gmap.inside(cell):
            raise MapError(f"{source}: launch cell {k} {cell} is outside the {gmap.shape[0]}x{gmap.shape[1]} grid")
        if gmap.obstacle[cell]:
            raise MapError(f"{source}: launch cell {k} {cell} is inside an obstacle")
    return gmap


def read_map_text(path: str | os.PathLike[str]) -> str:
    """A map file's text; MapError naming the file when it cannot be read or is not UTF-8."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError as err:
        raise MapError(f"{path}: cannot read map file ({err.strerror})") from None
    except UnicodeDecodeError as err:
        raise MapError(f"{path}: not a map file (not UTF-8 text: byte {err.start})") from None


def load_map(path: str | os.PathLike[str]) -> GridMap:
    return parse_map(read_map_text(path), str(path))


def format_map(gmap: GridMap) -> str:
    lines = [f"name: {gmap.name}"]
    lines += [f"{key}: {value}" for key, value in gmap.meta.items()]
    lines.append("launch: " + "  ".join(f"{r},{c}" for r, c in gmap.launch))
    lines.append("grid:")
    lines += gmap.rows_text()
    return "\n".join(lines) + "\n"


def save_map(gmap: GridMap, path: str | os.PathLike[str], comment: str = "") -> None:
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    write_text_atomic(path, head + format_map(gmap))
