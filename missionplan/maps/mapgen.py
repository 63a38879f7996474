"""Generators of the maps that ship with missionplan (`maps/*.map`).

This module owns the four case-study maps and nothing else: `leonardo`, a hand-laid
reconstruction of the thesis's Case I arena, and three seeded procedural cities shaped
like the thesis's other cases - `grid_city` (an orthogonal centre, like Turin),
`old_town` (medieval lanes on a waterfront, like Genoa) and `river_city` (a city split by
a river with one bridge, like Porto on the Douro). Every generator is deterministic
(numpy's seeded `default_rng` is the only randomness) and returns a `GridMap` with six
launch cells; `python -m missionplan.maps.mapgen` rewrites the shipped files from them, so the
files are never edited by hand.

All generators paint one `kind` array (OBSTACLE / TARGET / FREE per cell) and then pass it
through the same clean-up, which guarantees what the planner relies on: every street is
at least 3 cells wide, and every target cell is reachable from the launch cells (only
Leonardo keeps its deliberate unreachable courtyards, so the planner's report of
unreachable cells has something to show).
"""

from __future__ import annotations

import dataclasses

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from scipy import ndimage

from missionplan.geo.camera import footprint_of_cell

from .gridmap import Cell, GridMap, save_map

# Cell kinds of the painting canvas; FREE is the file format's 'o' (flown over, no photo).
OBSTACLE, TARGET, FREE = 0, 1, 2
LAUNCH_COUNT = 6
CITY_LAUNCH_EDGE_MARGIN = 5  # one footprint radius plus one: the drone's first photo lies inside the map
MEDIAN_WORK_SAMPLES = 2000
MEDIAN_OPTION_SAMPLES = 1000
MIN_STREET_WIDTH = 3
_SQUARE = np.ones((MIN_STREET_WIDTH, MIN_STREET_WIDTH), dtype=bool)

Rect = tuple[int, int, int, int]  # (top row, left col, height, width)
Point = tuple[float, float]  # (row, col), may lie off the grid while painting

GRID_CITY_SEED = 2
OLD_TOWN_SEED = 5
RIVER_CITY_SEED = 11


# --------------------------------------------------------------------------- painting

def fill_rect(kind: np.ndarray, rect: Rect, value: int) -> None:
    """Paint a rectangle, clipped to the grid (negative corners must not wrap around)."""
    top, left, height, width = rect
    kind[max(top, 0):max(top + height, 0), max(left, 0):max(left + width, 0)] = value


def disk_offsets(radius: float) -> np.ndarray:
    """(n, 2) cell offsets of a disk brush; radius 1.5 is the 3x3 square, the thinnest street."""
    reach = int(np.floor(radius))
    dr, dc = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    inside = dr ** 2 + dc ** 2 <= radius ** 2 + 1e-9
    return np.stack([dr[inside], dc[inside]], axis=1)


def polyline_centres(points: Sequence[Point]) -> np.ndarray:
    """Cells along a polyline, consecutive ones at most one step apart in each axis."""
    pieces = []
    for (r0, c0), (r1, c1) in zip(points[:-1], points[1:]):
        samples = int(np.ceil(max(abs(r1 - r0), abs(c1 - c0)))) + 1
        pieces.append(np.stack([np.linspace(r0, r1, samples), np.linspace(c0, c1, samples)], axis=1))
    return np.rint(np.concatenate(pieces)).astype(np.int64)


def paint_polyline(kind: np.ndarray, points: Sequence[Point], radius: float, value: int) -> None:
    """Sweep a disk brush along the polyline (a thick Bresenham-like line)."""
    cells = (polyline_centres(points)[:, None, :] + disk_offsets(radius)[None, :, :]).reshape(-1, 2)
    rows, cols = kind.shape
    on_grid = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
    kind[cells[on_grid, 0], cells[on_grid, 1]] = value


# --------------------------------------------------------------------------- lane networks

def jittered_lattice(rng: np.random.Generator, row_span: tuple[float, float], col_span: tuple[float, float],
                     shape: tuple[int, int], jitter: float) -> np.ndarray:
    """(n_rows, n_cols, 2) node positions: a regular lattice moved by up to `jitter` x spacing.

    A jitter below 0.5 keeps neighbouring nodes in order, so the lattice's edges never cross
    and the street network stays planar.
    """
    rows = np.linspace(*row_span, shape[0])
    cols = np.linspace(*col_span, shape[1])
    step = np.array([rows[1] - rows[0], cols[1] - cols[0]])
    nodes = np.stack(np.meshgrid(rows, cols, indexing="ij"), axis=-1)
    return nodes + rng.uniform(-jitter, jitter, size=nodes.shape) * step


def lattice_edges(rng: np.random.Generator, shape: tuple[int, int], drop_p: float,
                  diagonal_p: float) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Lattice edges (right and down), some dropped, plus at most one diagonal per lattice cell."""
    n_rows, n_cols = shape
    edges = []
    for i in range(n_rows):
        for j in range(n_cols):
            if j + 1 < n_cols and rng.random() >= drop_p:
                edges.append(((i, j), (i, j + 1)))
            if i + 1 < n_rows and rng.random() >= drop_p:
                edges.append(((i, j), (i + 1, j)))
            if i + 1 < n_rows and j + 1 < n_cols and rng.random() < diagonal_p:
                # One diagonal per lattice cell, either way: two would cross each other.
                if rng.random() < 0.5:
                    edges.append(((i, j), (i + 1, j + 1)))
                else:
                    edges.append(((i, j + 1), (i + 1, j)))
    return edges


def bent_polyline(rng: np.random.Generator, start: Point, end: Point, bend: float) -> list[Point]:
    """start -> a midpoint pushed sideways by about `bend` x length -> end, so lanes are not ruler-straight."""
    (r0, c0), (r1, c1) = start, end
    length = float(np.hypot(r1 - r0, c1 - c0)) or 1.0
    normal = np.array([-(c1 - c0), r1 - r0]) / length
    push = rng.normal(0.0, bend) * length
    middle = ((r0 + r1) / 2 + normal[0] * push, (c0 + c1) / 2 + normal[1] * push)
    return [start, middle, end]


def paint_lane_network(kind: np.ndarray, rng: np.random.Generator, nodes: np.ndarray,
                       edges: Sequence[tuple[tuple[int, int], tuple[int, int]]],
                       radii: Sequence[float], bend: float) -> None:
    for a, b in edges:
        path = bent_polyline(rng, tuple(nodes[a]), tuple(nodes[b]), bend)
        paint_polyline(kind, path, float(rng.choice(radii)), TARGET)


# --------------------------------------------------------------------------- clean-up and launch

def enforce_min_street_width(kind: np.ndarray) -> None:
    """Turn into obstacle every free cell that lies in no all-free 3x3 square.

    That is a morphological opening of the free space: what survives is a union of 3x3
    squares, so no passage, sliver or dead end is narrower than a drone can use. Cells
    beyond the map edge count as obstacles, as in the planner.
    """
    free = kind != OBSTACLE
    opened = ndimage.binary_opening(free, structure=_SQUARE, border_value=0)
    kind[free & ~opened] = OBSTACLE


def clear_thin_walls(kind: np.ndarray) -> None:
    """Turn building slivers 1 cell thick (left between two painted lanes) into street.

    An obstacle cell in no all-obstacle 2x2 square is such a sliver; beyond the map edge
    counts as obstacle, so buildings cut by the edge are kept.
    """
    solid = kind == OBSTACLE
    kept = ndimage.binary_opening(solid, structure=np.ones((2, 2), dtype=bool), border_value=1)
    kind[solid & ~kept] = TARGET


def clear_street_specks(kind: np.ndarray, max_cells: int = 12) -> None:
    """Turn tiny obstacle islands standing in a street (painting leftovers) back into street."""
    labels, count = ndimage.label(kind == OBSTACLE, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    for label in np.flatnonzero(sizes[1:] <= max_cells) + 1:
        speck = labels == label
        ring = ndimage.binary_dilation(speck, structure=_SQUARE) & ~speck
        touches_edge = speck[0, :].any() or speck[-1, :].any() or speck[:, 0].any() or speck[:, -1].any()
        if not touches_edge and np.all(kind[ring] == TARGET):
            kind[speck] = TARGET


def main_component(kind: np.ndarray) -> np.ndarray:
    """The 4-connected free region that holds the most target cells."""
    labels, count = ndimage.label(kind != OBSTACLE)
    if count == 0:
        raise ValueError("the map has no free cell")
    targets_per_label = np.bincount(labels[kind == TARGET], minlength=count + 1)
    targets_per_label[0] = 0
    return labels == int(np.argmax(targets_per_label))


def drop_unreachable_targets(kind: np.ndarray) -> None:
    """Targets outside the main region can never be photographed: make them buildings."""
    kind[(kind == TARGET) & ~main_component(kind)] = OBSTACLE


def launch_candidates(kind: np.ndarray, edge_margin: int = 0) -> np.ndarray:
    """Target cells of the main region with targets all around, so a drone does not start against a wall.

    `edge_margin` keeps launch cells that many cells away from the map edge: on a map cut
    out of a bigger city a street at the edge runs on beyond it, an odd place to launch.
    """
    street = kind == TARGET
    roomy = ndimage.binary_erosion(street, structure=_SQUARE, border_value=0)
    if edge_margin:
        inner = np.zeros_like(roomy)
        inner[edge_margin:-edge_margin, edge_margin:-edge_margin] = True
        roomy &= inner
    return roomy & main_component(kind)


def median_launch_cells(candidates: np.ndarray, work: np.ndarray, count: int = LAUNCH_COUNT,
                        first_pools: Sequence[np.ndarray] = ()) -> list[Cell]:
    """Greedy k-median: each next drone goes where it most shortens the work's trip to a drone.

    Drone 1 starts at the candidate with the least total straight-line distance to the
    `work` cells (the middle of the work); each next drone at the candidate that most
    lowers the total distance from every work cell to its nearest drone, i.e. in the
    biggest area still far from everyone. So the first K cells are well spread for every
    K, and no drone wastes its first moves walking in from a corner. `first_pools[k]`,
    when given, restricts drone k+1 to those cells (e.g. one bank of a river).
    Both sets are thinned to a regular subsample to keep this fast on big maps.
    """
    work_cells = thinned(np.argwhere(work), MEDIAN_WORK_SAMPLES)
    nearest = np.full(len(work_cells), np.inf, dtype=np.float32)
    chosen: list[Cell] = []
    for k in range(count):
        pool = candidates & first_pools[k] if k < len(first_pools) else candidates
        options = thinned(np.argwhere(pool), MEDIAN_OPTION_SAMPLES)
        distance = np.linalg.norm(options[:, None, :] - work_cells[None, :, :], axis=2)
        best = int(np.argmin(np.minimum(distance, nearest[None, :]).sum(axis=1)))
        chosen.append((int(options[best, 0]), int(options[best, 1])))
        nearest = np.minimum(nearest, distance[best])
    return chosen


def thinned(cells: np.ndarray, at_most: int) -> np.ndarray:
    """Every n-th cell (row-major order), enough of them to stay under `at_most`, as float32."""
    stride = max(1, -(-len(cells) // at_most))
    return cells[::stride].astype(np.float32)


def to_grid_map(name: str, kind: np.ndarray, launch: list[Cell], meta: dict[str, str]) -> GridMap:
    return GridMap(name=name, obstacle=kind == OBSTACLE, target=kind == TARGET, launch=launch, meta=meta)


def finish_city(name: str, kind: np.ndarray, meta: dict[str, str],
                first_pools: Sequence[np.ndarray] = ()) -> GridMap:
    """The shared last steps of the procedural cities: slivers, widths, reachability, launch cells."""
    clear_thin_walls(kind)
    clear_street_specks(kind)
    enforce_min_street_width(kind)
    drop_unreachable_targets(kind)
    candidates = launch_candidates(kind, CITY_LAUNCH_EDGE_MARGIN)
    launch = median_launch_cells(candidates, kind == TARGET, LAUNCH_COUNT, first_pools)
    return to_grid_map(name, kind, launch, meta)


def parse_rect(text: str) -> tuple[slice, slice]:
    """'r0,c0 r1,c1' (inclusive corners, as stored in map meta) -> (row slice, col slice)."""
    (r0, c0), (r1, c1) = (tuple(int(v) for v in corner.split(",")) for corner in text.split())
    return slice(r0, r1 + 1), slice(c0, c1 + 1)


def format_rect(rows: slice, cols: slice) -> str:
    return f"{rows.start},{cols.start} {rows.stop - 1},{cols.stop - 1}"


# --------------------------------------------------------------------------- Case I: Leonardo arena

LEONARDO_SHAPE = (42, 84)

# The arena floor is 20 x 10 m; the model city stands on it as a 3 x 4 grid of blocks.
# Interior streets: rows 1-3, 13-16, 25-30 (avenue), 38-40; cols 1-3, 19-22, 36-43 (avenue),
# 60-63, 79-82. The block at rows 17-24 west of col 52 is left open: with the avenue it forms
# the plaza. Courtyards are target cells walled in on every side: unreachable pockets.
LEONARDO_BUILDINGS: list[Rect] = [
    (4, 4, 9, 15), (4, 23, 9, 13), (4, 44, 9, 16), (4, 64, 9, 15),      # north row
    (17, 4, 8, 15), (17, 23, 8, 13), (17, 52, 8, 8), (17, 64, 8, 15),   # middle row, plaza west of (17, 52)
    (31, 4, 7, 15), (31, 23, 7, 13), (31, 44, 7, 6), (31, 54, 7, 6),    # south row, a lane at cols 50-53
    (31, 64, 7, 15),
]
LEONARDO_COURTYARDS: list[Rect] = [(7, 50, 3, 4), (19, 9, 4, 5), (33, 27, 3, 4)]


def leonardo() -> GridMap:
    """Thesis Case I: the Leonardo Drone Contest indoor arena, 20 x 10 m as 42 x 84 cells."""
    kind = np.full(LEONARDO_SHAPE, OBSTACLE, dtype=np.int8)
    fill_rect(kind, (1, 1, LEONARDO_SHAPE[0] - 2, LEONARDO_SHAPE[1] - 2), TARGET)  # arena walls: a 1-cell rim
    for building in LEONARDO_BUILDINGS:
        fill_rect(kind, building, OBSTACLE)
    for courtyard in LEONARDO_COURTYARDS:
        fill_rect(kind, courtyard, TARGET)
    before = kind.copy()
    enforce_min_street_width(kind)
    if not np.array_equal(kind, before):  # a hand layout is checked, never silently repaired
        raise ValueError("the Leonardo layout has a street narrower than 3 cells")
    # No drop_unreachable_targets here: the courtyards must stay as unreachable targets.
    meta = {"title": "Leonardo Drone Contest arena (thesis Case I), reconstructed", "cell_m": "0.238"}
    reachable_work = (kind == TARGET) & main_component(kind)  # the courtyards are nobody's work
    return to_grid_map("leonardo", kind, median_launch_cells(launch_candidates(kind), reachable_work), meta)


# --------------------------------------------------------------------------- Case II: grid city

GRID_CITY_SHAPE = (195, 247)


def street_intervals(rng: np.random.Generator, length: int, block_range: tuple[int, int],
                     widths: Sequence[int], avenue_width: int, avenue_p: float) -> list[tuple[int, int]]:
    """[start, stop) of parallel streets across `length` cells, blocks of `block_range` between them."""
    streets = []
    position = -int(rng.integers(0, block_range[0]))  # the map edge cuts through a block
    while True:
        position += int(rng.integers(block_range[0], block_range[1] + 1))
        width = avenue_width if rng.random() < avenue_p else int(rng.choice(widths))
        if position + width > length:
            return streets
        streets.append((position, position + width))
        position += width


def gaps_between(streets: Sequence[tuple[int, int]], length: int) -> list[tuple[int, int]]:
    """The [start, stop) intervals between streets (the blocks), edge pieces included."""
    bounds = [0] + [edge for street in streets for edge in street] + [length]
    return [(a, b) for a, b in zip(bounds[::2], bounds[1::2]) if b > a]


def grid_city(seed: int = GRID_CITY_SEED) -> GridMap:
    """Thesis Case II (Turin, Porta Nuova), 195 x 247 cells of 2 m: a dense orthogonal street grid."""
    rng = np.random.default_rng(seed)
    n_rows, n_cols = GRID_CITY_SHAPE
    # Mostly narrow streets (3-5 cells, 6-10 m) with a few wider ones and rare 9-cell avenues.
    street_widths = (3, 3, 4, 4, 5, 5, 6, 7)
    row_streets = street_intervals(rng, n_rows, (18, 28), street_widths, 9, 0.1)
    col_streets = street_intervals(rng, n_cols, (18, 30), street_widths, 9, 0.1)
    row_blocks, col_blocks = gaps_between(row_streets, n_rows), gaps_between(col_streets, n_cols)

    kind = np.full(GRID_CITY_SHAPE, OBSTACLE, dtype=np.int8)
    for start, stop in row_streets:
        kind[start:stop, :] = TARGET
    for start, stop in col_streets:
        kind[:, start:stop] = TARGET

    # Only blocks wholly inside the map get a special use: at the edge we see part of a block.
    inner = [(i, j) for i, (r0, r1) in enumerate(row_blocks) for j, (c0, c1) in enumerate(col_blocks)
             if r0 > 0 and r1 < n_rows and c0 > 0 and c1 < n_cols]
    order = [inner[k] for k in rng.permutation(len(inner))]
    parks, piazzas, merges, rest = order[:2], order[2:3], order[3:6], order[6:]

    def block_rect(i: int, j: int) -> Rect:
        (r0, r1), (c0, c1) = row_blocks[i], col_blocks[j]
        return (r0, c0, r1 - r0, c1 - c0)

    for i, j in parks:
        fill_rect(kind, block_rect(i, j), FREE)
    for i, j in piazzas:
        fill_rect(kind, block_rect(i, j), TARGET)
    used = set(parks) | set(piazzas)
    for i, j in merges:
        used |= merge_with_neighbour(kind, rng, (i, j), row_blocks, col_blocks, row_streets, col_streets, used)
    lanes = 0
    for i, j in rest:
        if (i, j) in used:
            continue
        rect = block_rect(i, j)
        if lanes < 4 and max(rect[2], rect[3]) >= 20:
            cut_lane(kind, rng, rect)
            lanes += 1
        elif min(rect[2], rect[3]) >= 18 and rng.random() < 0.45:
            carve_courtyard(kind, rng, rect)

    meta = {"title": "Grid city: a dense orthogonal centre (like thesis Case II, Turin Porta Nuova)",
            "cell_m": "2.0", "generator": "missionplan.maps.mapgen.grid_city", "seed": str(seed)}
    return finish_city("grid-city", kind, meta)


def merge_with_neighbour(kind: np.ndarray, rng: np.random.Generator, block: tuple[int, int],
                         row_blocks: list[tuple[int, int]], col_blocks: list[tuple[int, int]],
                         row_streets: list[tuple[int, int]], col_streets: list[tuple[int, int]],
                         used: set[tuple[int, int]]) -> set[tuple[int, int]]:
    """Build over the street between a block and its east or south neighbour (a big complex).

    Returns the blocks now taken, or an empty set when neither neighbour is available.
    Edge blocks may be the neighbour: the merged complex then runs off the map.
    """
    i, j = block
    if block in used:
        return set()
    options = [(i, j + 1), (i + 1, j)]
    for k in rng.permutation(2):
        other = options[k]
        if other in used or other[0] >= len(row_blocks) or other[1] >= len(col_blocks):
            continue
        # The map edge always cuts a block first, so street j runs between blocks j and j + 1.
        if other == (i, j + 1):
            (r0, r1), (c0, c1) = row_blocks[i], col_streets[j]
        else:
            (r0, r1), (c0, c1) = row_streets[i], col_blocks[j]
        kind[r0:r1, c0:c1] = OBSTACLE
        return {block, other}
    return set()


def cut_lane(kind: np.ndarray, rng: np.random.Generator, rect: Rect) -> None:
    """Split a long block in two with a 3-cell lane across its long side."""
    top, left, height, width = rect
    if width >= height:
        col = left + int(rng.integers(7, width - 7 - MIN_STREET_WIDTH + 1))
        fill_rect(kind, (top, col, height, MIN_STREET_WIDTH), TARGET)
    else:
        row = top + int(rng.integers(7, height - 7 - MIN_STREET_WIDTH + 1))
        fill_rect(kind, (row, left, MIN_STREET_WIDTH, width), TARGET)


def carve_courtyard(kind: np.ndarray, rng: np.random.Generator, rect: Rect) -> None:
    """A perimeter block: buildings 5-7 cells deep around an enclosed courtyard (free, not a target)."""
    top, left, height, width = rect
    depth = int(rng.integers(5, 8))
    fill_rect(kind, (top + depth, left + depth, height - 2 * depth, width - 2 * depth), FREE)


# --------------------------------------------------------------------------- Case III: old town

OLD_TOWN_SHAPE = (104, 161)


def coastline(rng: np.random.Generator, n_cols: int, mean_row: float, amplitude: float) -> np.ndarray:
    """First sea row per column: a gently wavy shore (two low-frequency sines)."""
    cols = np.arange(n_cols)
    phases = rng.uniform(0, 2 * np.pi, size=2)
    wave = (np.sin(2 * np.pi * cols / n_cols * 1.3 + phases[0])
            + 0.5 * np.sin(2 * np.pi * cols / n_cols * 2.9 + phases[1]))
    return np.rint(mean_row + amplitude * wave / 1.5).astype(np.int64)


def old_town(seed: int = OLD_TOWN_SEED) -> GridMap:
    """Thesis Case III (Genoa, Porto Antico), 104 x 161 cells of 2 m: medieval lanes, squares, a quay."""
    rng = np.random.default_rng(seed)
    n_rows, n_cols = OLD_TOWN_SHAPE
    sea = coastline(rng, n_cols, mean_row=85, amplitude=3)
    quay_width = int(rng.integers(6, 9))

    kind = np.full(OLD_TOWN_SHAPE, OBSTACLE, dtype=np.int8)
    lattice_shape = (6, 10)
    nodes = jittered_lattice(rng, (-3, 80), (-3, n_cols + 2), lattice_shape, jitter=0.3)
    # The last lattice row sits on the quay, so the lanes run down to the waterfront.
    nodes[-1, :, 0] = sea[np.clip(np.rint(nodes[-1, :, 1]).astype(int), 0, n_cols - 1)] - quay_width / 2
    edges = lattice_edges(rng, lattice_shape, drop_p=0.2, diagonal_p=0.4)
    paint_lane_network(kind, rng, nodes, edges, radii=(1.5, 1.5, 2.0, 2.5), bend=0.12)
    paint_squares(kind, rng, nodes[1:-1, 1:-1].reshape(-1, 2), count=4, size_range=(10, 16))

    rows = np.arange(n_rows)[:, None]
    kind[rows >= sea[None, :]] = OBSTACLE
    kind[(rows >= sea[None, :] - quay_width) & (rows < sea[None, :])] = TARGET
    for pier_col in pier_columns(rng, n_cols, count=2):
        pier_width, pier_length = int(rng.integers(5, 8)), int(rng.integers(9, 14))
        top = int(sea[pier_col:pier_col + pier_width].min())
        fill_rect(kind, (top, pier_col, pier_length, pier_width), TARGET)

    meta = {"title": "Old town: medieval lanes and a waterfront quay (like thesis Case III, Genoa Porto Antico)",
            "cell_m": "2.0", "generator": "missionplan.maps.mapgen.old_town", "seed": str(seed)}
    return finish_city("old-town", kind, meta)


def paint_squares(kind: np.ndarray, rng: np.random.Generator, sites: np.ndarray, count: int,
                  size_range: tuple[int, int]) -> None:
    """Open a few squares centred on lane junctions, so every square has lanes leading in."""
    for k in rng.choice(len(sites), size=count, replace=False):
        height, width = (int(v) for v in rng.integers(size_range[0], size_range[1] + 1, size=2))
        row, col = (int(round(v)) for v in sites[k])
        fill_rect(kind, (row - height // 2, col - width // 2, height, width), TARGET)


def pier_columns(rng: np.random.Generator, n_cols: int, count: int) -> list[int]:
    """Left columns of the piers, spread along the shore and away from the map edges."""
    slots = np.linspace(0.2, 0.8, count) * n_cols
    return [int(slot + rng.integers(-10, 11)) for slot in slots]


# --------------------------------------------------------------------------- Case IV: river city

RIVER_CITY_SHAPE = (133, 199)


def river_city(seed: int = RIVER_CITY_SEED) -> GridMap:
    """Thesis Case IV (Porto and the Douro), 133 x 199 cells of 2 m: two banks, one bridge."""
    rng = np.random.default_rng(seed)
    n_rows, n_cols = RIVER_CITY_SHAPE
    cols = np.arange(n_cols)
    phase = rng.uniform(0, 2 * np.pi, size=2)
    centre = 66 + 9 * np.sin(2 * np.pi * cols / n_cols * 0.9 + phase[0])
    width = 20 + 4 * np.sin(2 * np.pi * cols / n_cols * 1.7 + phase[1])  # 16..24 cells
    river_top = np.rint(centre - width / 2).astype(np.int64)
    river_bottom = np.rint(centre + width / 2).astype(np.int64)  # first row of the south bank
    road_width = int(rng.integers(5, 8))

    kind = np.full(RIVER_CITY_SHAPE, OBSTACLE, dtype=np.int8)
    north_road = river_top - road_width / 2
    south_road = river_bottom + road_width / 2
    paint_bank_streets(kind, rng, (-2.0, float(north_road.mean())), north_road, river_side="bottom")
    paint_bank_streets(kind, rng, (float(south_road.mean()), n_rows + 1.0), south_road, river_side="top")

    rows = np.arange(n_rows)[:, None]
    river = (rows >= river_top[None, :]) & (rows < river_bottom[None, :])
    kind[river] = OBSTACLE
    kind[(rows >= river_top[None, :] - road_width) & (rows < river_top[None, :])] = TARGET
    kind[(rows >= river_bottom[None, :]) & (rows < river_bottom[None, :] + road_width)] = TARGET

    bridge_width = int(rng.integers(4, 7))
    bridge_left = int(n_cols * 0.5) + int(rng.integers(-15, 16))
    bridge_cols = slice(bridge_left, bridge_left + bridge_width)
    bridge_rows = slice(int(river_top[bridge_cols].min()), int(river_bottom[bridge_cols].max()))
    kind[bridge_rows, bridge_cols] = TARGET

    north = rows < centre[None, :]
    off_bridge = np.ones_like(north)
    off_bridge[bridge_rows, bridge_cols] = False
    meta = {"title": "River city: two banks and a single bridge (like thesis Case IV, Porto and the Douro)",
            "cell_m": "2.0", "generator": "missionplan.maps.mapgen.river_city", "seed": str(seed),
            "bridge": format_rect(bridge_rows, bridge_cols)}
    # Drones 1 and 2 on opposite banks, so even a two-drone run needs no early crossing.
    return finish_city("river-city", kind, meta, first_pools=[north & off_bridge, ~north & off_bridge])


def paint_bank_streets(kind: np.ndarray, rng: np.random.Generator, row_span: tuple[float, float],
                       road_rows: np.ndarray, river_side: str) -> None:
    """An irregular grid on one bank: a jittered lattice, few diagonals, streets 3 to 5 cells.

    The lattice row on the river side is pinned to the riverside road (`road_rows` per
    column), so the streets run down to the river instead of stopping short of it.
    """
    n_cols = kind.shape[1]
    height = row_span[1] - row_span[0]
    lattice_shape = (max(2, int(round(height / 17)) + 1), 11)
    nodes = jittered_lattice(rng, row_span, (-3, n_cols + 2), lattice_shape, jitter=0.25)
    river_row = -1 if river_side == "bottom" else 0
    node_cols = np.clip(np.rint(nodes[river_row, :, 1]).astype(int), 0, n_cols - 1)
    nodes[river_row, :, 0] = road_rows[node_cols]
    edges = lattice_edges(rng, lattice_shape, drop_p=0.15, diagonal_p=0.15)
    paint_lane_network(kind, rng, nodes, edges, radii=(1.5, 2.0, 2.0, 2.5), bend=0.06)


# --------------------------------------------------------------------------- shipping

SHIPPED: dict[str, Callable[[], GridMap]] = {
    "leonardo": leonardo,
    "grid-city": grid_city,
    "old-town": old_town,
    "river-city": river_city,
}

SHIPPED_COMMENT = ("Generated by `python -m missionplan.maps.mapgen` (missionplan/maps/mapgen.py).\n"
                   "Do not edit by hand: change the generator and regenerate.")


# Where each shipped map lies and how it is flown, so that `plan --map NAME` writes real
# missions: the top-left grid corner (WGS84), the flight altitude above the launch points and
# the camera's field of view. The footprint side is 9 cells (cell_m from the map), so the
# field of view is the one that gives that footprint at that altitude: 2 H tan(FOV/2) = 9 cell.
SHIPPED_GEOREFERENCE: dict[str, tuple[float, float, float]] = {
    # name: (origin_lat, origin_lon, altitude_m)
    "leonardo": (45.47840, 9.22690, 1.2),     # Politecnico di Milano, Leonardo campus (an indoor arena)
    "grid-city": (45.06600, 7.67000, 10.0),   # central Turin
    "old-town": (44.41250, 8.92600, 10.0),    # Genoa, Porto Antico
    "river-city": (41.14500, -8.62000, 10.0),  # Porto, by the Douro
}


# Field-safety values a shipped map declares for itself (missionplan/mission/safety.py reads them; the
# defaults are 5 m for both). The Leonardo arena is flown by palm-sized drones 1.2 m up between
# walls a few cells apart: 1 m between drones, and the half cell the grid itself keeps from a wall.
# The three cities are the thesis's grids (2 m cells, streets 2-4 cells wide, flown at 10 m): the
# default 5 m clearance would close most streets, so they keep the grid's own half cell, 1 m.
SHIPPED_SAFETY: dict[str, dict[str, str]] = {
    "leonardo": {"min_separation_m": "1", "clearance_m": "0.1"},
    "grid-city": {"clearance_m": "1"},
    "old-town": {"clearance_m": "1"},
    "river-city": {"clearance_m": "1"},
}


def georeference(gmap: GridMap) -> GridMap:
    """A copy of a shipped map with its origin, altitude and camera field of view in the metadata."""
    origin_lat, origin_lon, altitude = SHIPPED_GEOREFERENCE[gmap.name]
    footprint = footprint_of_cell(float(gmap.meta["cell_m"]))
    fov = 2 * np.degrees(np.arctan(footprint / (2 * altitude)))
    meta = {**gmap.meta, "origin_lat": f"{origin_lat:.6f}", "origin_lon": f"{origin_lon:.6f}",
            "altitude_m": f"{altitude:g}", "fov_deg": f"{fov:.4f}", **SHIPPED_SAFETY.get(gmap.name, {})}
    return dataclasses.replace(gmap, meta=meta)


def write_shipped(folder: str | Path) -> None:
    """Write every shipped map to `folder/NAME.map`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, make in SHIPPED.items():
        save_map(georeference(make()), folder / f"{name}.map", comment=SHIPPED_COMMENT)


if __name__ == "__main__":
    from .catalog import MAPS_DIR  # one place knows where the shipped maps live

    write_shipped(MAPS_DIR)
