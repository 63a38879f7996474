"""Lanes: a zone of open ground swept in footprint-wide lanes, as sweep and spanning-tree planners fly it.

Where nothing blocks a drone (open ground, or a city whose buildings are low enough to fly over),
exploring cell by cell loses to the classic answer: cut the zone into footprint-sized blocks,
photograph each block holding a target once from its centre, and visit the centres in a snake
(boustrophedon), lane after lane one footprint apart. On an obstacle-free grid that is also the
path a spanning-tree planner (DARP, STC) flies over the same blocks.

- `zone_is_open` / `open_zones`: whether a drone's zone, its launch cell and every photo centre
  lie in one obstacle-free box (then every leg below is flyable), for one zone or every zone;
  `obstacle_shares` / `sweepable` / `sweepable_zones`: how much of each box is obstacle, and whether
  it is little enough (MAX_OBSTACLE_SHARE: a few tall buildings among low ones flown over) to sweep
  round it;
- `block_centres` (`centres_of_blocks`) / `snake_order`: the blocks of a zone (aligned on its corner, or on the map's
  when the whole fleet sweeps) and the shortest of the eight snakes through their centres (by block
  rows or columns, from any corner);
- the lane spacing: lanes lie one footprint (BLOCK cells) apart unless a side overlap asks for closer
  ones (`spacing` cells, 1 .. BLOCK). Then a block is `spacing` cells across the lanes and still a
  footprint along them (the photos along a lane are the trigger distance's, not the lanes'), the lanes
  run the way whose snake is shorter, and the sweep flies every lane even where earlier lanes have
  photographed all of it already: that repeat is the side overlap (the planner keeps such a drone
  flying until its sweep is over);
- `fleet_zones`: when every zone is open, the zones redrawn block by block on the map's block grid
  (no block shared, so none photographed twice) and balanced by local search on the longest snake,
  as LS-MCPP does on its decomposition;
- `LaneSweep`: one drone's sweep as the planner flies it, cell by cell: an L-shaped leg to the
  next centre (the corner placed where it turns least), skipping every block that is photographed
  already (by its own passes or another drone's), so on open ground it never flies longer than the
  snake. Round obstacles, a leg takes the other corner or else the shortest way round (A*), and a
  block whose centre is an obstacle or out of reach is left for the drone to explore once its sweep
  is over.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import product

import numpy as np
from scipy import ndimage

from ..maps.gridmap import Cell
from .pathfinding import FlightSearch
from .world import ACTION_OF_DELTA, FOOTPRINT_RADIUS, HOVER, turn_weight

BLOCK = 2 * FOOTPRINT_RADIUS + 1  # the footprint's side in cells
# A zone whose box holds at most this share of obstacle cells is still swept in lanes (around them);
# past it, exploring cell by cell won in trials (the MovingAI maps with every second building standing).
MAX_OBSTACLE_SHARE = 0.05


def _heading(delta_r: int, delta_c: int) -> int:
    """The action of a straight move along one axis (HOVER for no move)."""
    return ACTION_OF_DELTA.get((int(np.sign(delta_r)), int(np.sign(delta_c))), HOVER)


def _box(low: np.ndarray, high: np.ndarray, start: Cell, shape: tuple[int, int]) -> tuple[slice, slice]:
    """The box from a zone's lowest to highest cell, grown to hold the launch cell and every photo
    centre (a centre lies at most FOOTPRINT_RADIUS past the zone, clipped into the map)."""
    low = np.minimum(low, start)
    high = np.minimum(np.maximum(high + FOOTPRINT_RADIUS, start), np.array(shape) - 1)
    return slice(int(low[0]), int(high[0]) + 1), slice(int(low[1]), int(high[1]) + 1)


def zone_is_open(obstacle: np.ndarray, zone_cells: np.ndarray, start: Cell) -> bool:
    """Whether the drone can sweep this zone in lanes: a zone with targets, in an obstacle-free box."""
    if not len(zone_cells):
        return False
    return not obstacle[_box(zone_cells.min(axis=0), zone_cells.max(axis=0), start, obstacle.shape)].any()


def obstacle_shares(obstacle: np.ndarray, zone: np.ndarray, starts: list[Cell]) -> list[float | None]:
    """The share of obstacle cells in every drone's box (zone labels 0 .. len(starts) - 1 in `zone`;
    None for a zone without targets), the boxes found in one pass over the map instead of one per drone."""
    boxes = ndimage.find_objects(np.where(zone >= 0, zone + 1, 0), max_label=len(starts))
    out: list[float | None] = []
    for box, start in zip(boxes, starts):
        if box is None:
            out.append(None)  # no targets: nothing to sweep
            continue
        low, high = np.array([box[0].start, box[1].start]), np.array([box[0].stop - 1, box[1].stop - 1])
        out.append(float(obstacle[_box(low, high, start, obstacle.shape)].mean()))
    return out


def open_zones(obstacle: np.ndarray, zone: np.ndarray, starts: list[Cell]) -> list[bool]:
    """zone_is_open for every drone's zone (labels 0 .. len(starts) - 1 in `zone`)."""
    return [share == 0.0 for share in obstacle_shares(obstacle, zone, starts)]


def sweepable(share: float | None) -> bool:
    """Whether a zone whose box is `share` obstacle (None: no targets) is swept in lanes: open ground,
    or low buildings flown over with a few tall ones left to fly around."""
    return share is not None and share <= MAX_OBSTACLE_SHARE


def sweepable_zones(obstacle: np.ndarray, zone: np.ndarray, starts: list[Cell]) -> list[bool]:
    """`sweepable` for every drone's zone."""
    return [sweepable(share) for share in obstacle_shares(obstacle, zone, starts)]


def _block_grid(spacing: int, across: int) -> tuple[np.ndarray, np.ndarray]:
    """A block's size (rows, cols) and the offset of the block grid from its corner, for lanes `spacing`
    cells apart along axis `across` (0: lanes are block rows): the lane centres lie FOOTPRINT_RADIUS + k *
    spacing from the corner, each block the cells nearest its lane. At BLOCK cells apart: footprint-sized
    blocks from the corner."""
    size = np.array([BLOCK, BLOCK])
    size[across] = spacing
    shift = np.zeros(2, dtype=np.int64)
    shift[across] = FOOTPRINT_RADIUS - spacing // 2
    return size, shift


def block_centres(zone_cells: np.ndarray, shape: tuple[int, int], origin: Cell | None = None,
                  spacing: int = BLOCK, across: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) photo centres, one per block (aligned on `origin`, by default the zone's corner) holding a
    zone cell, clipped into the map, and (n, 2) those blocks' (row, col) numbers. A block is footprint-sized,
    or `spacing` cells across the lanes (axis `across`) when lanes are closer than a footprint.
    A centre clipped at the map's edge still sees all of its block that lies inside the map."""
    corner = zone_cells.min(axis=0) if origin is None else np.asarray(origin)
    size, shift = _block_grid(spacing, across)
    blocks = np.unique((zone_cells - corner - shift) // size, axis=0)
    return centres_of_blocks(blocks, corner, shape, spacing, across), blocks


def centres_of_blocks(blocks: np.ndarray, corner: Cell | np.ndarray, shape: tuple[int, int], spacing: int = BLOCK,
                      across: int = 0) -> np.ndarray:
    """(n, 2) photo centres of the (n, 2) block numbers of the block grid on `corner` (block_centres' rule)."""
    size, shift = _block_grid(spacing, across)
    return np.clip(np.asarray(corner) + shift + blocks * size + size // 2, 0, np.array(shape) - 1)


def snake_order(start: Cell, centres: np.ndarray, blocks: np.ndarray,
                majors: tuple[int, ...] = (0, 1)) -> tuple[int, np.ndarray]:
    """The shortest snake through the centres from `start` (by block rows or columns, or only the
    `majors` given, from any of the four corners, taxicab legs): (its moves, the centres' order)."""
    best: tuple[int, np.ndarray] | None = None
    for major, flip_major, flip_minor in product(majors, (False, True), (False, True)):
        minor = 1 - major
        lane = blocks[:, major] * (-1 if flip_major else 1)
        parts = []
        for i, value in enumerate(np.unique(lane)):
            members = np.flatnonzero(lane == value)
            along = blocks[members, minor] * (-1 if flip_minor ^ (i % 2 == 1) else 1)
            parts.append(members[np.argsort(along, kind="stable")])
        order = np.concatenate(parts)
        path = np.vstack([np.asarray(start)[None, :], centres[order]])
        moves = int(np.abs(np.diff(path, axis=0)).sum())
        if best is None or moves < best[0]:
            best = (moves, order)
    assert best is not None
    return best


LOCAL_SEARCH_MOVES = 400  # block hand-overs at most (each shortens the longest snake)
LOCAL_SEARCH_CANDIDATES = 24  # the longest drone's border blocks tried per hand-over, farthest from its launch first


def _snake_moves(start: Cell, centres: np.ndarray, blocks: np.ndarray) -> int:
    return snake_order(start, centres, blocks)[0] if len(blocks) else 0


def fleet_zones(zone: np.ndarray, targets: np.ndarray, starts: list[Cell]) -> np.ndarray:
    """The zones redrawn for a fleet that sweeps all of them: each block of the map's block grid (aligned
    on cell (0, 0)) holding a target goes whole to the zone holding most of its targets, then, while
    handing one of the longest snake's border blocks to a neighbouring drone makes both snakes shorter
    than the longest, the best such block is handed over (local search on the makespan, as LS-MCPP).
    Returns the zone map with every target cell labelled by its block's drone (other cells as given)."""
    cells = np.argwhere(targets)
    if not len(cells):
        return zone
    shape = targets.shape
    blocks, inverse = np.unique(cells // BLOCK, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    votes = np.zeros((len(blocks), len(starts)), dtype=np.int64)
    np.add.at(votes, (inverse, np.clip(zone[cells[:, 0], cells[:, 1]], 0, len(starts) - 1)), 1)
    owner = votes.argmax(axis=1)
    centres = np.minimum(blocks * BLOCK + FOOTPRINT_RADIUS, np.array(shape) - 1)
    number = {(int(r), int(c)): i for i, (r, c) in enumerate(blocks)}
    neighbours = [[number[n] for n in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)) if n in number]
                  for r, c in blocks.tolist()]
    launch = np.asarray(starts)

    def cost(k: int) -> int:
        mine = owner == k
        return _snake_moves(starts[k], centres[mine], blocks[mine])

    costs = [cost(k) for k in range(len(starts))]
    for _ in range(LOCAL_SEARCH_MOVES):
        longest = int(np.argmax(costs))
        border = [int(b) for b in np.flatnonzero(owner == longest) if any(owner[n] != longest for n in neighbours[b])]
        border.sort(key=lambda b: -int(np.abs(centres[b] - launch[longest]).sum()))
        best: tuple[int, int, int, int, int] | None = None  # (new longest of the two, block, to, their costs)
        for b in border[:LOCAL_SEARCH_CANDIDATES]:
            for j in sorted({int(owner[n]) for n in neighbours[b]} - {longest}):
                owner[b] = j
                pair = (cost(longest), cost(j))
                owner[b] = longest
                if max(pair) < costs[longest] and (best is None or max(pair) < best[0]):
                    best = (max(pair), b, j, *pair)
        if best is None:
            break
        _, b, j, costs[longest], costs[j] = best
        owner[b] = j
    out = zone.copy()
    out[cells[:, 0], cells[:, 1]] = owner[inverse]
    return out


def longest_snake(zone: np.ndarray, starts: list[Cell]) -> int:
    """The longest of the drones' snakes through their zones' blocks of the map's block grid (fleet_zones' zones)."""
    longest = 0
    for k, start in enumerate(starts):
        cells = np.argwhere(zone == k)
        if len(cells):
            longest = max(longest, _snake_moves(start, *block_centres(cells, zone.shape, (0, 0))))
    return longest


def l_leg(start: Cell, goal: Cell, heading: int = HOVER, next_heading: int = HOVER,
          other_corner: bool = False) -> list[Cell]:
    """Cells from `start` (left out) to `goal`: straight, or an L whose corner costs the fewest turns
    coming in at `heading` and leaving at `next_heading` (rows first on a tie); `other_corner`: the
    L round the other corner (an obstacle stands on the first)."""
    (r0, c0), (r1, c1) = start, goal
    dr, dc = r1 - r0, c1 - c0
    rows_dir, cols_dir = _heading(dr, 0), _heading(0, dc)
    rows_first = True
    if dr and dc:
        cost_rows = turn_weight(heading, rows_dir) + turn_weight(cols_dir, next_heading)
        cost_cols = turn_weight(heading, cols_dir) + turn_weight(rows_dir, next_heading)
        rows_first = (cost_rows <= cost_cols) != other_corner
    step_r, step_c = int(np.sign(dr)), int(np.sign(dc))
    along_rows = [(r0 + step_r * i, c0) for i in range(1, abs(dr) + 1)]
    along_cols = [(r0, c0 + step_c * i) for i in range(1, abs(dc) + 1)]
    if rows_first:
        return along_rows + [(r1, c0 + step_c * i) for i in range(1, abs(dc) + 1)]
    return along_cols + [(r0 + step_r * i, c1) for i in range(1, abs(dr) + 1)]


@dataclass
class LaneSweep:
    """One drone's sweep of its zone: the photo centres still to visit, in snake order (or a whole fleet's
    block tours: grid/fleet_blocks.py), and the leg it is flying to the first of them."""

    centres: list[Cell]
    blocks: list[tuple[slice, slice]]  # each centre's block, to skip one photographed already
    leg: list[Cell] = field(default_factory=list)  # cells still to fly to centres[0], next first
    heading: int = HOVER  # the direction of the last leg's last move (HOVER: none yet)
    around_obstacles: bool = False  # obstacles stand in the zone's box: legs and centres are checked
    every_lane: bool = False  # lanes closer than a footprint: no block is skipped for being photographed

    @classmethod
    def plan(cls, zone_cells: np.ndarray, start: Cell, shape: tuple[int, int], origin: Cell | None = None,
             free: np.ndarray | None = None, spacing: int = BLOCK) -> LaneSweep:
        """The sweep of a zone from `start`, its lanes `spacing` cells apart (1 .. BLOCK). With `free` (the
        map's free cells, where the zone's box holds obstacles) a block whose centre is an obstacle is left
        out: exploration photographs it once the sweep is over."""
        if not 1 <= spacing <= BLOCK:
            raise ValueError(f"lane spacing {spacing!r} cells: must be 1 to {BLOCK}")
        around = free is not None
        best: tuple[int, np.ndarray, np.ndarray, np.ndarray, int] | None = None
        # Footprint-wide lanes: one block grid, either way. Closer lanes: blocks narrow across the lanes, so
        # each way has its own grid; the shorter snake wins (rows first on a tie).
        for across in ((0,) if spacing == BLOCK else (0, 1)):
            centres, blocks = block_centres(zone_cells, shape, origin, spacing, across)
            if free is not None:
                flyable = free[centres[:, 0], centres[:, 1]]
                centres, blocks = centres[flyable], blocks[flyable]
            if not len(centres):
                continue
            moves, order = snake_order(start, centres, blocks, (0, 1) if spacing == BLOCK else (across,))
            if best is None or moves < best[0]:
                best = (moves, order, centres, blocks, across)
        if best is None:
            return cls([], [], around_obstacles=around, every_lane=spacing < BLOCK)
        _, order, centres, blocks, across = best
        corner = zone_cells.min(axis=0) if origin is None else np.asarray(origin)
        size, shift = _block_grid(spacing, across)
        low = corner + shift + blocks * size
        spans = [(slice(max(int(r), 0), int(r) + int(size[0])), slice(max(int(c), 0), int(c) + int(size[1])))
                 for r, c in low[order]]
        return cls([(int(r), int(c)) for r, c in centres[order]], spans, around_obstacles=around,
                   every_lane=spacing < BLOCK)

    @classmethod
    def along(cls, centres: list[Cell], shape: tuple[int, int], origin: Cell = (0, 0)) -> LaneSweep:
        """The sweep of a tour through blocks of a block grid over the map (`origin` one of its corners), one centre
        each: a block's centre, or for a block the map's edge cuts, the nearest cell on the map to it."""
        def span(at: int, corner: int, size: int) -> slice:
            low = corner + (at - corner) // BLOCK * BLOCK
            return slice(max(low, 0), min(low + BLOCK, size))
        spans = [(span(r, origin[0], shape[0]), span(c, origin[1], shape[1])) for r, c in centres]
        return cls(list(centres), spans)

    @property
    def finished(self) -> bool:
        return not self.centres

    def over_at(self, position: Cell) -> bool:
        """Nothing left to fly from `position`: no centre left, or only the one the drone is on."""
        return not self.centres or (len(self.centres) == 1 and self.centres[0] == position)

    def _photographed(self, unexplored: np.ndarray) -> bool:
        """The first block is photographed already and may be skipped (never with every_lane)."""
        return not self.every_lane and not unexplored[self.blocks[0]].any()

    def next_cell(self, position: Cell, unexplored: np.ndarray, search: FlightSearch | None = None) -> Cell | None:
        """The cell to fly to next from `position`; None once every block is photographed.

        `unexplored` is the world's mask of targets not photographed yet: a block with none left
        is skipped, however it got photographed. `search` (a FlightSearch of the map's free cells) is
        read only by a sweep planned round obstacles: a leg that an L-shape cannot fly goes the
        other way round the corner, else the shortest way around (A*), and a centre that cannot be
        reached is left to exploration."""
        check = search if self.around_obstacles else None
        if self.leg and self.leg[0] == position:
            self.leg.pop(0)
        if self.leg and abs(self.leg[0][0] - position[0]) + abs(self.leg[0][1] - position[1]) != 1:
            self.leg = []  # pushed off the leg (it made way for another drone): fly a new one
        if self.centres and self._photographed(unexplored):
            self.leg = []  # this block is done already: on to the next one from here
        while not self.leg:
            while self.centres and (self.centres[0] == position or self._photographed(unexplored)):
                self._drop_first()
            if not self.centres:
                return None
            goal = self.centres[0]
            if check is not None and not _same_region(check, position, goal):
                self._drop_first()  # walled off from here (a courtyard): exploration's, no search needed
                continue
            after = self.centres[1] if len(self.centres) > 1 else None
            next_heading = HOVER
            if after is not None:  # along the goal's lane, when the next centre lies on it
                dr, dc = after[0] - goal[0], after[1] - goal[1]
                next_heading = _heading(dr, dc) if dr == 0 or dc == 0 else HOVER
            self.leg = l_leg(position, goal, self.heading, next_heading)
            if check is not None and not _flyable(check, self.leg):
                self.leg = l_leg(position, goal, self.heading, next_heading, other_corner=True)
                if not _flyable(check, self.leg):
                    around = check.path(position, goal)
                    self.leg = around[1:] if around else []
                    if not self.leg:
                        self._drop_first()  # out of reach from here: exploration's
                        continue
            if len(self.leg) >= 2:
                last, before = self.leg[-1], self.leg[-2]
            else:
                last, before = self.leg[-1], position
            self.heading = _heading(last[0] - before[0], last[1] - before[1])
        return self.leg[0]

    def _drop_first(self) -> None:
        self.centres.pop(0)
        self.blocks.pop(0)


def _same_region(search: FlightSearch, a: Cell, b: Cell) -> bool:
    """Whether b can be flown to from a (the same free region)."""
    regions = search.region(search.flat_index(np.array([a, b])))
    return bool(regions[0] == regions[1] and regions[0] != 0)


def _flyable(search: FlightSearch, leg: list[Cell]) -> bool:
    """Whether every cell of the leg is free."""
    return bool(search.is_free(np.asarray(leg).reshape(-1, 2)).all())
