"""Random cities for the training maps: streets of varied widths, blocks of varied shapes, one launch cell.

`random_city(rng, shape)` paints a fresh random city in one of four styles - a recursive subdivision of the
map (T-junctions, blocks of every size), an orthogonal grid of streets of varied widths, an organic lattice of
bent, possibly rotated, lanes, or a street grid turned by any angle and rasterised cell by cell (the staircase
block edges of real street maps) - then dresses the blocks (L-shapes, alleys, courtyards, squares, parks) and
adds a few overlays (diagonal avenue, river, plaza, big park, towers). `finish` gives it, and every other
training map (trainmaps.py), the guarantees they all keep: streets at least MIN_STREET_WIDTH wide, every
target reachable from the launch cell, the launch cell on a street away from the edge when possible.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..grid.world import FOOTPRINT_RADIUS
from ..maps.gridmap import Cell, GridMap
from ..maps.mapgen import (FREE, MIN_STREET_WIDTH, OBSTACLE, TARGET, Rect, bent_polyline, clear_street_specks,
                           clear_thin_walls, drop_unreachable_targets, enforce_min_street_width, fill_rect,
                           gaps_between, jittered_lattice, lattice_edges, launch_candidates, main_component,
                           merge_with_neighbour, paint_lane_network, paint_polyline, paint_squares, street_intervals)

LAUNCH_EDGE_MARGIN = FOOTPRINT_RADIUS + 1  # the drone's first photo lies inside the map
CELL_M = "2.0"

# Street width sets (cells): each random city draws one, so some cities are all lanes.
WIDTH_SETS = ((3, 3, 3, 4, 4, 5), (3, 4, 5, 6, 7), (4, 5, 6, 7, 8, 9))
WIDTH_SET_P = (0.4, 0.4, 0.2)
AVENUE_WIDTHS = (8, 13)  # [low, high) of an avenue's width
LANE_RADII = ((1.5, 1.5, 2.0), (1.5, 2.0, 2.5, 3.0), (2.0, 2.5, 3.0, 4.0))  # organic style, same idea


# --------------------------------------------------------------------------- the guarantees

def pick_launch(kind: np.ndarray, rng: np.random.Generator) -> Cell:
    """A random launch cell of the main region: on a street away from the edge when there is one."""
    for pool in (launch_candidates(kind, LAUNCH_EDGE_MARGIN), launch_candidates(kind),
                 (kind == TARGET) & main_component(kind), main_component(kind)):
        cells = np.argwhere(pool)
        if len(cells):
            r, c = cells[int(rng.integers(len(cells)))]
            return int(r), int(c)
    raise ValueError("the map has no free cell")


def finish(name: str, kind: np.ndarray, rng: np.random.Generator, meta: dict[str, str]) -> GridMap:
    """Widths, reachability and the launch cell: the guarantees every training map keeps."""
    enforce_min_street_width(kind)
    if not (kind == TARGET).any():
        raise ValueError(f"map {name}: no target cell left")
    drop_unreachable_targets(kind)
    enforce_min_street_width(kind)  # free non-target cells left beside dropped targets may now be slivers
    launch = pick_launch(kind, rng)
    return GridMap(name=name, obstacle=kind == OBSTACLE, target=kind == TARGET, launch=[launch], meta=meta)


# --------------------------------------------------------------------------- block dressing

def clip_rect(rect: Rect, shape: tuple[int, int]) -> tuple[Rect, bool]:
    """The part of a rectangle on the grid, and whether it touches the map edge."""
    top, left, height, width = rect
    r0, c0 = max(top, 0), max(left, 0)
    r1, c1 = min(top + height, shape[0]), min(left + width, shape[1])
    at_edge = r0 == 0 or c0 == 0 or r1 == shape[0] or c1 == shape[1]
    return (r0, c0, max(r1 - r0, 0), max(c1 - c0, 0)), at_edge


def notch(kind: np.ndarray, rng: np.random.Generator, rect: Rect) -> None:
    """Open a corner or a forecourt of a block to the street: an L- or U-shaped building."""
    top, left, height, width = rect
    deep = int(rng.integers(3, height - 2))  # the building keeps at least 3 cells
    wide = int(rng.integers(3, width - 2))
    where = int(rng.integers(6))
    if where < 4:  # a corner
        row = top if where % 2 == 0 else top + height - deep
        col = left if where < 2 else left + width - wide
    elif where == 4:  # a forecourt on the north or south side
        wide = min(wide, width - 6) if width >= 9 else 0
        row = top if rng.random() < 0.5 else top + height - deep
        col = left + 3 + int(rng.integers(0, max(width - 6 - wide, 0) + 1))
    else:  # a forecourt on the west or east side
        deep = min(deep, height - 6) if height >= 9 else 0
        row = top + 3 + int(rng.integers(0, max(height - 6 - deep, 0) + 1))
        col = left if rng.random() < 0.5 else left + width - wide
    if deep >= 3 and wide >= 3:
        fill_rect(kind, (row, col, deep, wide), TARGET)


def alley(kind: np.ndarray, rng: np.random.Generator, rect: Rect) -> None:
    """Cut a 3-4 cell lane across a block's long side: through, or a dead end half way."""
    top, left, height, width = rect
    lane = int(rng.integers(MIN_STREET_WIDTH, MIN_STREET_WIDTH + 2))
    along_rows = width >= height  # the lane runs north-south across a wide block
    span = width if along_rows else height
    across = height if along_rows else width
    offset = int(rng.integers(4, span - 4 - lane + 1))
    length = across if rng.random() < 0.6 else int(across * rng.uniform(0.4, 0.75))
    start = 0 if rng.random() < 0.5 else across - length
    if along_rows:
        fill_rect(kind, (top + start, left + offset, length, lane), TARGET)
    else:
        fill_rect(kind, (top + offset, left + start, lane, length), TARGET)


def courtyard(kind: np.ndarray, rng: np.random.Generator, building: np.ndarray) -> None:
    """Hollow a building out: a walled-in courtyard, free but not a target (never reachable)."""
    depth = int(rng.integers(3, 6))
    inner = ndimage.binary_erosion(building, structure=np.ones((3, 3), dtype=bool), iterations=depth)
    if inner.sum() >= MIN_STREET_WIDTH ** 2:
        kind[inner] = FREE


# Uses of a block and their chances (at full richness); any other block stays one plain building.
BLOCK_USES = (("notch", 0.20), ("alley", 0.12), ("courtyard", 0.14), ("square", 0.07), ("park", 0.03))
BUILDING_USES = (("courtyard", 0.18), ("square", 0.07), ("park", 0.03))


def pick_use(rng: np.random.Generator, uses: tuple[tuple[str, float], ...], richness: float) -> str:
    """One use drawn from `uses` (chances scaled by `richness`), or "plain"."""
    roll = rng.random()
    for use, chance in uses:
        if roll < chance * richness:
            return use
        roll -= chance * richness
    return "plain"


def dress_blocks(kind: np.ndarray, rng: np.random.Generator, blocks: list[Rect], richness: float) -> None:
    """Give rectangular blocks their use: building, L-shape, alley, courtyard, square or park.

    `richness` (0-1) scales how many blocks are anything but a plain building. Squares
    and parks only replace blocks wholly inside the map (at the edge we see part of one).
    """
    for rect in blocks:
        (top, left, height, width), at_edge = clip_rect(rect, kind.shape)
        short, long = min(height, width), max(height, width)
        use = pick_use(rng, BLOCK_USES, richness)
        clipped = (top, left, height, width)
        building = np.zeros(kind.shape, dtype=bool)
        building[top:top + height, left:left + width] = True
        if use == "notch" and short >= 8:
            notch(kind, rng, clipped)
            if rng.random() < 0.3:
                notch(kind, rng, clipped)
        elif use == "alley" and long >= 16 and short >= 6:
            alley(kind, rng, clipped)
        elif use == "courtyard" and short >= 12:
            courtyard(kind, rng, building)
        elif use == "square" and short >= 6 and not at_edge:
            kind[building] = TARGET
        elif use == "park" and short >= 6 and not at_edge:
            kind[building] = FREE  # flown over, no photo needed


def dress_buildings(kind: np.ndarray, rng: np.random.Generator, richness: float) -> None:
    """The same for irregular blocks (organic style): courtyards, squares and parks."""
    labels, count = ndimage.label(kind == OBSTACLE)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    edge_labels = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])).tolist())
    for label in range(1, count + 1):
        if sizes[label] < 40:
            continue
        use = pick_use(rng, BUILDING_USES, richness)
        building = labels == label
        if use == "courtyard" and sizes[label] >= 150:
            courtyard(kind, rng, building)
        elif use == "square" and label not in edge_labels:
            kind[building] = TARGET
        elif use == "park" and label not in edge_labels:
            kind[building] = FREE


# --------------------------------------------------------------------------- street styles

def street_width(rng: np.random.Generator, widths: tuple[int, ...], avenue_p: float) -> int:
    """One of `widths`, or with chance `avenue_p` an avenue (8-12 cells)."""
    if rng.random() < avenue_p:
        return int(rng.integers(*AVENUE_WIDTHS))
    return int(rng.choice(widths))


def subdivided_city(kind: np.ndarray, rng: np.random.Generator, widths: tuple[int, ...]) -> list[Rect]:
    """Cut the map in two by a street, again and again: T-junctions and blocks of every size.

    Early cuts are the long streets and may be avenues; now and then a street stops half
    way, so the blocks on its two sides join into one L- or U-shaped block.
    """
    rows, cols = kind.shape
    block_min = int(rng.integers(6, 10))
    # Blocks of up to half the map's short side: several blocks even on a small map.
    block_max = float(rng.uniform(12, max(14.0, min(34.0, min(rows, cols) / 2))))
    avenue_p = float(rng.uniform(0.0, 0.4))
    partial_p = float(rng.uniform(0.0, 0.3))
    pad = int(rng.integers(0, 8))
    blocks: list[Rect] = []
    stack: list[tuple[Rect, int]] = [((-pad, -pad, rows + 2 * pad, cols + 2 * pad), 0)]
    while stack:
        (top, left, height, width), depth = stack.pop()
        limit = block_max * rng.uniform(0.7, 1.4)
        if max(height, width) <= limit:
            blocks.append((top, left, height, width))
            continue
        street = street_width(rng, widths, avenue_p if depth < 2 else avenue_p / 4)
        # A horizontal street cuts a rect too tall, a vertical one a rect too wide;
        # when it is both, the cut goes more likely across the long side.
        if height > limit and width > limit:
            cut_rows = bool(rng.random() < height / (height + width))
        else:
            cut_rows = height > limit
        length = height if cut_rows else width
        room = length - 2 * block_min - street
        if room < 0:
            blocks.append((top, left, height, width))
            continue
        at = block_min + int(rng.integers(0, room + 1))
        across = width if cut_rows else height
        reach, start = across, 0
        if depth > 0 and rng.random() < partial_p:  # a street that stops short
            reach = int(across * rng.uniform(0.45, 0.8))
            start = 0 if rng.random() < 0.5 else across - reach
        if cut_rows:
            fill_rect(kind, (top + at, left + start, street, reach), TARGET)
            stack.append(((top, left, at, width), depth + 1))
            stack.append(((top + at + street, left, height - at - street, width), depth + 1))
        else:
            fill_rect(kind, (top + start, left + at, reach, street), TARGET)
            stack.append(((top, left, height, at), depth + 1))
            stack.append(((top, left + at + street, height, width - at - street), depth + 1))
    return blocks


def grid_streets(kind: np.ndarray, rng: np.random.Generator, widths: tuple[int, ...]) -> list[Rect]:
    """Orthogonal streets crossing the whole map, each its own width; some blocks merged."""
    rows, cols = kind.shape
    longest = max(12, min(rows, cols) // 3)  # a few blocks across even a small map
    low = int(rng.integers(8, max(9, min(22, longest - 3))))
    block_range = (low, min(low + int(rng.integers(4, 16)), longest))
    avenue_p = float(rng.uniform(0.0, 0.25))
    avenue = int(rng.integers(*AVENUE_WIDTHS))
    long_range = (block_range[0] + 6, block_range[1] + min(12, longest // 2))
    row_range, col_range = block_range, block_range
    if rng.random() < 0.5:  # long blocks, one way or the other
        row_range, col_range = (block_range, long_range) if rng.random() < 0.5 else (long_range, block_range)
    row_streets = street_intervals(rng, rows, row_range, widths, avenue, avenue_p)
    col_streets = street_intervals(rng, cols, col_range, widths, avenue, avenue_p)
    for start, stop in row_streets:
        kind[start:stop, :] = TARGET
    for start, stop in col_streets:
        kind[:, start:stop] = TARGET
    row_blocks, col_blocks = gaps_between(row_streets, rows), gaps_between(col_streets, cols)
    used: set[tuple[int, int]] = set()
    cells = [(i, j) for i in range(len(row_blocks)) for j in range(len(col_blocks))]
    merges = int(len(cells) * rng.uniform(0.0, 0.2))
    for k in rng.permutation(len(cells))[:merges]:
        used |= merge_with_neighbour(kind, rng, cells[k], row_blocks, col_blocks, row_streets, col_streets, used)
    return [(r0, c0, r1 - r0, c1 - c0) for i, (r0, r1) in enumerate(row_blocks)
            for j, (c0, c1) in enumerate(col_blocks) if (i, j) not in used]


def organic_lanes(kind: np.ndarray, rng: np.random.Generator, radii: tuple[float, ...]) -> None:
    """A jittered lattice of bent lanes, sometimes turned as a whole, with squares at junctions."""
    rows, cols = kind.shape
    low = max(12.0, 4 * max(radii) + 6)  # blocks stay wider than the widest lane
    spacing = float(rng.uniform(low, max(low + 2, min(26.0, min(rows, cols) / 2.5))))
    angle = float(rng.uniform(-np.pi / 4, np.pi / 4)) if rng.random() < 0.5 else 0.0
    centre = np.array([rows / 2, cols / 2])
    # Half the lattice's extent: a turned lattice must still cover the map's corners.
    half = (np.full(2, np.hypot(rows, cols) / 2) if angle else centre) + spacing
    lattice = tuple(int(np.ceil(2 * h / spacing)) + 1 for h in half)
    jitter = float(rng.uniform(0.0, 0.3))
    nodes = jittered_lattice(rng, (centre[0] - half[0], centre[0] + half[0]),
                             (centre[1] - half[1], centre[1] + half[1]), lattice, jitter)
    if angle:
        turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        nodes = (nodes - centre) @ turn.T + centre
    edges = lattice_edges(rng, lattice, drop_p=float(rng.uniform(0.0, 0.15)),
                          diagonal_p=float(rng.uniform(0.0, 0.3)))
    paint_lane_network(kind, rng, nodes, edges, radii=radii, bend=float(rng.uniform(0.0, 0.12)))
    inner = nodes.reshape(-1, 2)
    inner = inner[(inner[:, 0] > 8) & (inner[:, 0] < rows - 8) & (inner[:, 1] > 8) & (inner[:, 1] < cols - 8)]
    squares = min(len(inner), int(rng.integers(0, 3)))
    if squares:
        paint_squares(kind, rng, inner, count=squares, size_range=(9, 18))


def turned_blocks(kind: np.ndarray, rng: np.random.Generator, widths: tuple[int, ...]) -> None:
    """Buildings as rectangles on a street grid turned by any angle, rasterised cell by cell.

    Real street maps rasterised from OpenStreetMap look like this: block edges that
    staircase because the streets are not aligned with the grid, streets and setbacks of
    every width, and open squares where a block was never built.
    """
    rows, cols = kind.shape
    angle = float(rng.uniform(0.0, np.pi / 2))
    centre = np.array([rows / 2, cols / 2])
    r, c = np.mgrid[0:rows, 0:cols].astype(np.float64)
    # (u, v): the cell centre in the turned street grid's frame.
    u = (r + 0.5 - centre[0]) * np.cos(angle) + (c + 0.5 - centre[1]) * np.sin(angle)
    v = -(r + 0.5 - centre[0]) * np.sin(angle) + (c + 0.5 - centre[1]) * np.cos(angle)
    half = np.hypot(rows, cols) / 2 + 40
    block_low = int(rng.integers(10, 18))
    block_high = block_low + int(rng.integers(4, 24))
    u_edges = street_intervals(rng, int(2 * half), (block_low, block_high), widths,
                               int(rng.integers(*AVENUE_WIDTHS)), float(rng.uniform(0.0, 0.25)))
    v_edges = street_intervals(rng, int(2 * half), (block_low, block_high), widths,
                               int(rng.integers(*AVENUE_WIDTHS)), float(rng.uniform(0.0, 0.25)))
    u_blocks, v_blocks = gaps_between(u_edges, int(2 * half)), gaps_between(v_edges, int(2 * half))
    open_p = float(rng.uniform(0.0, 0.15))
    setback_p = float(rng.uniform(0.0, 0.5))
    # Each block's building [a0, a1) x [b0, b1) in (u, v); a block never built keeps an empty one.
    building = np.zeros((len(u_blocks), len(v_blocks), 4))
    for i, (u0, u1) in enumerate(u_blocks):
        for j, (v0, v1) in enumerate(v_blocks):
            if rng.random() < open_p:
                continue  # an open square
            # A building set back from the street on some sides: wider streets here and there.
            inset = rng.integers(0, 4, size=4) * (rng.random(4) < setback_p)
            a0, a1 = u0 - half + inset[0], u1 - half - inset[1]
            b0, b1 = v0 - half + inset[2], v1 - half - inset[3]
            if a1 - a0 >= 3 and b1 - b0 >= 3:
                building[i, j] = a0, a1, b0, b1
    # A building lies inside its block, so a cell can only be in the one of the block its (u, v)
    # falls in: look that block up instead of testing every building against every cell.
    i = np.clip(np.searchsorted([u0 - half for u0, _ in u_blocks], u, side="right") - 1, 0, None)
    j = np.clip(np.searchsorted([v0 - half for v0, _ in v_blocks], v, side="right") - 1, 0, None)
    a0, a1, b0, b1 = np.moveaxis(building[i, j], -1, 0)
    built = (u >= a0) & (u < a1) & (v >= b0) & (v < b1)
    kind[:] = np.where(built, OBSTACLE, TARGET)


# --------------------------------------------------------------------------- overlays

def diagonal_avenue(kind: np.ndarray, rng: np.random.Generator) -> None:
    """A slightly bent street from one side of the map to the opposite side."""
    rows, cols = kind.shape
    if rng.random() < 0.5:
        start, end = (-2.0, float(rng.uniform(0, cols))), (rows + 1.0, float(rng.uniform(0, cols)))
    else:
        start, end = (float(rng.uniform(0, rows)), -2.0), (float(rng.uniform(0, rows)), cols + 1.0)
    paint_polyline(kind, bent_polyline(rng, start, end, 0.08), float(rng.choice((1.5, 2.0, 2.5, 3.0))), TARGET)


def river(kind: np.ndarray, rng: np.random.Generator) -> None:
    """A wavy river across the map with a quay on each bank and one to three bridges."""
    view = kind if rng.random() < 0.5 else kind.T  # a view: painting it paints `kind`
    rows, cols = view.shape
    at = np.arange(cols)
    phase = rng.uniform(0, 2 * np.pi, size=2)
    centre = rng.uniform(0.3, 0.7) * rows + rng.uniform(0, 0.08) * rows * np.sin(
        2 * np.pi * at / cols * rng.uniform(0.5, 1.5) + phase[0])
    width = rng.uniform(5, 12) + 1.5 * np.sin(2 * np.pi * at / cols * 1.7 + phase[1])
    top = np.rint(centre - width / 2).astype(np.int64)
    bottom = np.rint(centre + width / 2).astype(np.int64)
    quay = int(rng.integers(MIN_STREET_WIDTH, 6))
    row = np.arange(rows)[:, None]
    view[(row >= top - quay) & (row < bottom + quay)] = TARGET
    view[(row >= top) & (row < bottom)] = OBSTACLE
    bridges = int(rng.integers(1, 4))
    for slot in (np.arange(bridges) + rng.uniform(0.2, 0.8, size=bridges)) / bridges:
        bridge = int(rng.integers(MIN_STREET_WIDTH, 7))
        left = int(np.clip(slot * cols, 0, cols - bridge))
        span = slice(left, left + bridge)
        view[int(top[span].min()):int(bottom[span].max()), span] = TARGET


def plaza(kind: np.ndarray, rng: np.random.Generator) -> None:
    """An open square centred on a street cell, big enough for a tower in it."""
    streets = np.argwhere(kind == TARGET)
    if not len(streets):
        return
    row, col = streets[int(rng.integers(len(streets)))]
    height, width = (int(v) for v in rng.integers(11, 23, size=2))
    fill_rect(kind, (int(row) - height // 2, int(col) - width // 2, height, width), TARGET)


def big_park(kind: np.ndarray, rng: np.random.Generator) -> None:
    """A park over several blocks and streets: free, not a target, with paths left as targets."""
    rows, cols = kind.shape
    height = int(rng.integers(12, max(13, min(26, rows // 3))))
    width = int(rng.integers(12, max(13, min(26, cols // 3))))
    top, left = int(rng.integers(0, max(rows - height, 1))), int(rng.integers(0, max(cols - width, 1)))
    fill_rect(kind, (top, left, height, width), FREE)
    if rng.random() < 0.5:  # a path across it still wants photos
        fill_rect(kind, (top + height // 2 - 1, left, MIN_STREET_WIDTH, width), TARGET)


def towers(kind: np.ndarray, rng: np.random.Generator, count: int) -> None:
    """Small isolated obstacles (towers, monuments) where the street is wide: 3 free cells all round."""
    for _ in range(count):
        half_rows, half_cols = (int(v) for v in rng.integers(1, 3, size=2))  # 3 or 5 cells a side
        ring = MIN_STREET_WIDTH
        clearance = np.ones((2 * (half_rows + ring) + 1, 2 * (half_cols + ring) + 1), dtype=bool)
        room = np.argwhere(ndimage.binary_erosion(kind == TARGET, structure=clearance, border_value=0))
        if not len(room):
            return
        row, col = room[int(rng.integers(len(room)))]
        tower = (int(row) - half_rows, int(col) - half_cols, 2 * half_rows + 1, 2 * half_cols + 1)
        fill_rect(kind, tower, OBSTACLE)


# --------------------------------------------------------------------------- random city

STYLES = ("subdivided", "grid", "organic", "turned")
STYLE_P = (0.35, 0.2, 0.2, 0.25)


def random_city(rng: np.random.Generator, shape: tuple[int, int], *, name: str = "random") -> GridMap:
    """A random city of `shape` cells: streets of varied widths, blocks of varied shapes, one launch cell.

    Every free cell is a target except parks (reachable, flown over) and walled-in
    courtyards (unreachable pockets); every target is reachable from the launch cell.
    """
    kind = np.full(shape, OBSTACLE, dtype=np.int8)
    style = str(rng.choice(STYLES, p=STYLE_P))
    width_set = int(rng.choice(len(WIDTH_SETS), p=WIDTH_SET_P))
    richness = float(rng.uniform(0.3, 1.0))
    if style == "subdivided":
        dress_blocks(kind, rng, subdivided_city(kind, rng, WIDTH_SETS[width_set]), richness)
    elif style == "grid":
        dress_blocks(kind, rng, grid_streets(kind, rng, WIDTH_SETS[width_set]), richness)
    elif style == "organic":
        organic_lanes(kind, rng, LANE_RADII[width_set])
        dress_buildings(kind, rng, richness)
    else:
        turned_blocks(kind, rng, WIDTH_SETS[width_set])
        dress_buildings(kind, rng, richness)
    extras = []
    if rng.random() < 0.2:
        diagonal_avenue(kind, rng)
        extras.append("diagonal")
    if rng.random() < 0.12 and min(shape) >= 50:
        river(kind, rng)
        extras.append("river")
    for _ in range(int(rng.choice(3, p=(0.7, 0.22, 0.08) if style == "organic" else (0.8, 0.17, 0.03)))):
        plaza(kind, rng)
        extras.append("plaza")
    if rng.random() < 0.07:
        big_park(kind, rng)
        extras.append("park")
    clear_thin_walls(kind)
    clear_street_specks(kind)
    towers(kind, rng, int(rng.choice(4, p=(0.45, 0.3, 0.15, 0.1))))
    meta = {"title": f"Random {style} city", "cell_m": CELL_M, "generator": "missionplan.learn.trainmaps.random_city",
            "style": style, "streets": ",".join(map(str, sorted(set(WIDTH_SETS[width_set])))),
            "extras": ",".join(extras) or "none"}
    return finish(name, kind, rng, meta)
