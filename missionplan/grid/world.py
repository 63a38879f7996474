"""The multi-drone coverage grid world: one environment with a reset / step interface.

It owns the rules of SPEC section 2 and nothing else: cell states (unexplored target,
explored, obstacle), the 9 x 9 camera footprint explored at every step, drones as moving
obstacles, moves resolved so that no two drones share a cell or swap cells, hovering when
a move is blocked, zone sight (a drone sees as unexplored only its own zone's cells until
that zone is done), the step cap, and how much is left where: per zone, and per free region
a drone launched in (4-connected; drones never leave theirs) and zone, so "is there anything
left that this drone could reach" is one lookup. Who decides the actions (expert, network,
path-finders) is someone else's job: the expert, the training code and the planner all
drive this same class.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..maps.gridmap import Cell, GridMap, MapError

# Actions in the order the network's outputs use: Up, Right, Down, Left.
UP, RIGHT, DOWN, LEFT = 0, 1, 2, 3
HOVER = -1
ACTION_NAMES = ("up", "right", "down", "left")
ACTION_DELTAS = np.array([[-1, 0], [0, 1], [1, 0], [0, -1]], dtype=np.int64)
ACTION_OF_DELTA = {(int(dr), int(dc)): action for action, (dr, dc) in enumerate(ACTION_DELTAS)}


def turn_weight(a: int, b: int) -> float:
    """The thesis's turn weight between two moves: 0 straight (or after a hover), 0.5 for 90 deg, 1 reversed."""
    if a == HOVER or b == HOVER or a == b:
        return 0.0
    return 1.0 if (a - b) % 4 == 2 else 0.5

FOOTPRINT_RADIUS = 4  # 9 x 9 cells centred on the drone
VIEW_RADIUS = 9  # 19 x 19 local view
EXPLORED = -2  # _pad_open_zone of a cell that is not (or no longer) an unexplored target
PAD = 32  # padding of the internal arrays, so any window up to this radius is one slice
_VIEW_DR, _VIEW_DC = np.mgrid[-VIEW_RADIUS:VIEW_RADIUS + 1, -VIEW_RADIUS:VIEW_RADIUS + 1]


def launch_regions(free: np.ndarray, starts: list[Cell]) -> tuple[np.ndarray, np.ndarray]:
    """The 4-connected free regions the drones launch in, numbered 0, 1, ... in label order.

    Returns (region of every cell, -1 outside the launch regions; region of every start,
    -1 for a start on a blocked cell).
    """
    labels, count = ndimage.label(free)  # default structure is 4-connectivity
    start_labels = np.array([labels[cell] for cell in starts], dtype=np.int64)
    launched = np.unique(start_labels[start_labels > 0])
    number = np.full(count + 1, -1, dtype=np.int64)
    number[launched] = np.arange(len(launched))
    return number[labels], number[start_labels]


def reachable_targets(gmap: GridMap, starts: list[Cell]) -> np.ndarray:
    """Target cells 4-connected through free cells to at least one start cell."""
    return gmap.target & (launch_regions(gmap.free, starts)[0] >= 0)


def check_starts(gmap: GridMap, starts: list[Cell]) -> None:
    """Raise MapError with one clear line if the launch cells are unusable."""
    if not starts:
        raise MapError(f"map {gmap.name}: at least one drone is needed")
    for k, cell in enumerate(starts, start=1):
        if not gmap.inside(cell):
            raise MapError(f"map {gmap.name}: launch cell of drone {k} {cell} is outside the "
                           f"{gmap.shape[0]}x{gmap.shape[1]} grid")
        if gmap.obstacle[cell]:
            raise MapError(f"map {gmap.name}: launch cell of drone {k} {cell} is inside an obstacle")
    if len(set(starts)) != len(starts):
        raise MapError(f"map {gmap.name}: two drones share a launch cell")


@dataclass
class StepOutcome:
    """What one step did: per drone, whether it moved and how many cells it newly explored."""

    moved: np.ndarray  # (K,) bool
    blocked: np.ndarray  # (K,) bool: asked to move but could not
    new_cells: np.ndarray  # (K,) int
    done: bool  # every reachable target explored
    truncated: bool  # the step cap was reached first


class CoverageWorld:
    """K drones covering the reachable target cells of a grid map.

    Call `reset()` once, then `step(actions)` with one action per drone
    (UP, RIGHT, DOWN, LEFT or HOVER) until `done` or `truncated`.
    """

    def __init__(self, gmap: GridMap, starts: list[Cell], zone: np.ndarray | None = None,
                 step_cap: int | None = None) -> None:
        check_starts(gmap, starts)
        self.gmap = gmap
        self.starts = [tuple(s) for s in starts]
        self.num_drones = len(starts)
        # Drones move 4-connected over free cells, so each stays in the region it launched in.
        self.region_of, self.drone_region = launch_regions(gmap.free, self.starts)
        self.num_regions = int(self.drone_region.max()) + 1
        self.reachable = gmap.target & (self.region_of >= 0)
        self.unreachable_cells = np.argwhere(gmap.target & ~self.reachable)
        self.num_targets = int(self.reachable.sum())
        if zone is None:
            zone = np.where(self.reachable, 0, -1) if self.num_drones == 1 else None
        if zone is None:
            raise ValueError("a zone map is required for more than one drone")
        self.zone_of = np.where(self.reachable, zone, -1).astype(np.int64)
        free_cells = int(gmap.free.sum())
        self.step_cap = step_cap if step_cap is not None else max(2000, 4 * free_cells)

        rows, cols = gmap.shape
        self._shape = (rows, cols)
        # Padded copies: a window around any cell is a plain slice, outside counts as obstacle.
        self._pad_obstacle = np.ones((rows + 2 * PAD, cols + 2 * PAD), dtype=bool)
        self._pad_obstacle[PAD:-PAD, PAD:-PAD] = gmap.obstacle
        self._pad_zone = np.full(self._pad_obstacle.shape, -1, dtype=np.int64)
        self._pad_zone[PAD:-PAD, PAD:-PAD] = self.zone_of
        # Each reachable cell's (region, zone) counter, flat: region * (K + 1) + zone, the last
        # column for a zone no drone has. One bincount per footprint keeps every count current.
        slot = self.region_of * (self.num_drones + 1) + np.where(
            (self.zone_of >= 0) & (self.zone_of < self.num_drones), self.zone_of, self.num_drones)
        self._pad_slot = np.full(self._pad_obstacle.shape, -1, dtype=np.int32)
        self._pad_slot[PAD:-PAD, PAD:-PAD] = np.where(self.reachable, slot, -1)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        rows, cols = self._shape
        self.t = 0
        self.positions = np.array(self.starts, dtype=np.int64).reshape(-1, 2)
        self._pad_unexplored = np.zeros((rows + 2 * PAD, cols + 2 * PAD), dtype=bool)
        self._pad_unexplored[PAD:-PAD, PAD:-PAD] = self.reachable
        # The zone of each unexplored cell, EXPLORED elsewhere: "does drone k see this cell"
        # is then one gather of one array (the batched views read it for every step).
        self._pad_open_zone = np.where(self._pad_unexplored, self._pad_zone, EXPLORED).astype(np.int32)
        self.remaining = self.num_targets
        self.zone_remaining = np.bincount(self.zone_of[self.reachable], minlength=self.num_drones)[: self.num_drones]
        self.zone_remaining = self.zone_remaining.astype(np.int64)
        self.region_zone_remaining = np.bincount(
            self._pad_slot[PAD:-PAD, PAD:-PAD][self.reachable], minlength=self.num_regions * (self.num_drones + 1)
        ).astype(np.int64).reshape(self.num_regions, self.num_drones + 1)
        self.last_actions = np.full((self.num_drones, 2), HOVER, dtype=np.int64)  # [previous, one before]
        # Whether each drone has flown over each cell, padded like the other arrays: the expert
        # reads it around every asked drone every step, as one gather with no bounds to check.
        self._pad_flown = np.zeros((self.num_drones, rows + 2 * PAD, cols + 2 * PAD), dtype=bool)
        self.truncated = False
        initial = np.zeros(self.num_drones, dtype=np.int64)
        for k in range(self.num_drones):
            self._mark_visit(k)
            initial[k] = self._explore_footprint(k)
        self.initial_new_cells = initial

    @property
    def unexplored(self) -> np.ndarray:
        """Reachable target cells not yet photographed (a view, do not modify)."""
        return self._pad_unexplored[PAD:-PAD, PAD:-PAD]

    @property
    def done(self) -> bool:
        return self.remaining == 0

    @property
    def coverage(self) -> float:
        """Fraction (0-1) of reachable target cells explored."""
        return 1.0 if self.num_targets == 0 else 1.0 - self.remaining / self.num_targets

    def zone_done(self, k: int) -> bool:
        """Drone k's zone is done: all of it, or all of it that lies in k's region (the rest is
        for the drones that can fly there; waiting on it would blind k for good)."""
        return self.num_drones == 1 or self.zone_remaining[k] == 0 or \
            self.region_zone_remaining[self.drone_region[k], k] == 0

    def region_done(self) -> np.ndarray:
        """(K,) bool: nothing unexplored is left in the region each drone stands in (and never will be)."""
        return self.region_zone_remaining.sum(axis=1)[self.drone_region] == 0

    def seen_in_region(self, k: int) -> int:
        """How many cells drone k sees as unexplored in its own region: all it could fly to."""
        left = self.region_zone_remaining[self.drone_region[k]]
        return int(left.sum() if self.zone_done(k) else left[k])

    def sees_unexplored(self) -> np.ndarray:
        """(K,) bool: whether each drone's 19 x 19 view holds a cell it sees as unexplored."""
        drones = np.arange(self.num_drones)
        return self.seen_unexplored_at(drones, self.positions[:, 0, None, None] + _VIEW_DR + PAD,
                                       self.positions[:, 1, None, None] + _VIEW_DC + PAD).any(axis=(1, 2))

    def seen_unexplored_at(self, drones: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Whether each of `drones` sees padded cells (rows, cols) as unexplored; rows/cols are (n, ...)."""
        extra = (1,) * (rows.ndim - 1)
        zone_done = (self.num_drones == 1) | (self.zone_remaining[drones] == 0) | \
            (self.region_zone_remaining[self.drone_region[drones], drones] == 0)
        open_zone = self._pad_open_zone[rows, cols]
        seen = open_zone == drones.reshape(-1, *extra)
        if zone_done.any():
            seen |= (open_zone != EXPLORED) & zone_done.reshape(-1, *extra)
        return seen

    def views(self, drones: np.ndarray | list[int], radius: int = VIEW_RADIUS) -> tuple[np.ndarray, np.ndarray]:
        """Batched view_unexplored and view_blocked: two (n, 2r+1, 2r+1) bool arrays, one gather each."""
        drones = np.asarray(drones, dtype=np.int64).reshape(-1)
        span = np.arange(-radius, radius + 1)
        centre = self.positions[drones] + PAD
        rows = centre[:, 0, None, None] + span[None, :, None]
        cols = centre[:, 1, None, None] + span[None, None, :]
        unexplored = self.seen_unexplored_at(drones, rows, cols)
        blocked = self._pad_obstacle[rows, cols]
        # Other drones are blocked too: every (drone i, other j) pair inside i's view.
        offsets = self.positions[None, :, :] - self.positions[drones][:, None, :] + radius  # (n, K, 2)
        in_view = np.all((offsets >= 0) & (offsets <= 2 * radius), axis=2)
        in_view &= drones[:, None] != np.arange(self.num_drones)[None, :]
        i, j = np.nonzero(in_view)
        blocked[i, offsets[i, j, 0], offsets[i, j, 1]] = True
        return unexplored, blocked

    def flown_views(self, drones: np.ndarray, radius: int = VIEW_RADIUS) -> np.ndarray:
        """(n, 2r+1, 2r+1) bool: where each of `drones` has already flown, around itself (outside
        the map: never)."""
        span = np.arange(-radius, radius + 1)
        centre = self.positions[drones] + PAD
        return self._pad_flown[drones[:, None, None], centre[:, 0, None, None] + span[None, :, None],
                               centre[:, 1, None, None] + span[None, None, :]]

    # ---------------------------------------------------------------- windows
    def _window(self, array: np.ndarray, k: int, radius: int) -> np.ndarray:
        r, c = self.positions[k] + PAD
        return array[r - radius: r + radius + 1, c - radius: c + radius + 1]

    def view_unexplored(self, k: int, radius: int = VIEW_RADIUS) -> np.ndarray:
        """Cells drone k sees as unexplored around it (its zone only, until its zone is done)."""
        window = self._window(self._pad_unexplored, k, radius)
        if self.zone_done(k):
            return window.copy()
        return window & (self._window(self._pad_zone, k, radius) == k)

    def view_blocked(self, k: int, radius: int = VIEW_RADIUS) -> np.ndarray:
        """Cells drone k may not enter: obstacles, outside the map, other drones."""
        blocked = self._window(self._pad_obstacle, k, radius).copy()
        offsets = self.positions - self.positions[k] + radius
        inside = np.all((offsets >= 0) & (offsets <= 2 * radius), axis=1)
        inside[k] = False
        blocked[offsets[inside, 0], offsets[inside, 1]] = True
        return blocked

    def seen_flat(self, k: int) -> Callable[[np.ndarray], np.ndarray]:
        """`flat -> flags`: whether drone k sees cells as unexplored, given their flat numbers in
        the padded arrays (row-major, PAD cells of padding: a FlightSearch with pad=PAD)."""
        open_zone = self._pad_open_zone.ravel()
        if self.zone_done(k):
            return lambda flat: open_zone[flat] != EXPLORED
        return lambda flat: open_zone[flat] == k

    def seen_predicate(self, k: int) -> Callable[[int], bool]:
        """A fast `flat -> bool` for one cell at a time (numbered as in `seen_flat`): whether drone
        k sees it as unexplored, as of now. What Explorative A* asks of every neighbour."""
        open_zone = self._pad_open_zone.ravel().data  # a memoryview: Python-level reads 5x faster than numpy's
        if self.zone_done(k):
            return lambda flat: open_zone[flat] != EXPLORED
        return lambda flat: open_zone[flat] == k

    def unexplored_cells(self) -> np.ndarray:
        """(n, 2) every unexplored cell, row-major (a flat scan of the contiguous padded array)."""
        flat = np.flatnonzero(self._pad_unexplored)
        rows, cols = np.divmod(flat, self._pad_unexplored.shape[1])
        return np.stack([rows - PAD, cols - PAD], axis=1)

    def is_free(self, cell: Cell) -> bool:
        r, c = cell
        return not self._pad_obstacle[r + PAD, c + PAD]

    # ------------------------------------------------------------------- step
    def step(self, actions: np.ndarray | list[int]) -> StepOutcome:
        """Move every drone by its action, then photograph under every drone.

        Moves are resolved together: a drone moves when its target cell is free of
        obstacles and of drones, repeating until nothing changes, so a drone may follow
        one that moves away in the same step. Two drones asking for the same cell: the
        lower index gets it. Swaps and rotations never happen: each needs a cell that is
        still occupied.
        """
        if self.truncated:
            raise RuntimeError("step() after the step cap; call reset()")
        actions = np.asarray(actions, dtype=np.int64).reshape(self.num_drones)
        wants = actions != HOVER
        targets = self.positions.copy()
        targets[wants] += ACTION_DELTAS[actions[wants]]
        occupied = {tuple(p): k for k, p in enumerate(self.positions)}
        moved = np.zeros(self.num_drones, dtype=bool)
        pending = [k for k in range(self.num_drones) if wants[k] and self.is_free(tuple(targets[k]))]
        progress = True
        while pending and progress:
            progress = False
            for k in list(pending):
                cell = tuple(targets[k])
                if cell in occupied:
                    continue
                del occupied[tuple(self.positions[k])]
                occupied[cell] = k
                self.positions[k] = targets[k]
                moved[k] = True
                pending.remove(k)
                progress = True
        self.t += 1
        new_cells = np.zeros(self.num_drones, dtype=np.int64)
        for k in range(self.num_drones):
            if moved[k]:
                self.last_actions[k] = (actions[k], self.last_actions[k, 0])
                self._mark_visit(k)
                new_cells[k] = self._explore_footprint(k)
        if self.t >= self.step_cap and not self.done:
            self.truncated = True
        return StepOutcome(moved=moved, blocked=wants & ~moved, new_cells=new_cells,
                           done=self.done, truncated=self.truncated)

    def _mark_visit(self, k: int) -> None:
        self._pad_flown[k, int(self.positions[k, 0]) + PAD, int(self.positions[k, 1]) + PAD] = True

    def _explore_footprint(self, k: int) -> int:
        r, c = int(self.positions[k, 0]) + PAD, int(self.positions[k, 1]) + PAD
        f = FOOTPRINT_RADIUS
        under = (slice(r - f, r + f + 1), slice(c - f, c + f + 1))  # the footprint, in the padded arrays
        window = self._pad_unexplored[under]
        if not np.count_nonzero(window):  # far cheaper than any() on a 9 x 9 window
            return 0
        zones = self._pad_zone[under][window]
        count = int(zones.size)
        counted = zones[zones < self.num_drones]
        if counted.size and counted.min() >= 0:
            self.zone_remaining -= np.bincount(counted, minlength=self.num_drones)
        else:  # ufunc.at is slow, but wraps a -1 zone the way it always did
            np.subtract.at(self.zone_remaining, counted, 1)
        slots = self._pad_slot[under][window]
        self.region_zone_remaining -= np.bincount(slots, minlength=self.region_zone_remaining.size).reshape(
            self.region_zone_remaining.shape)
        window[:] = False  # a view into _pad_unexplored: marks the cells explored
        self._pad_open_zone[under] = EXPLORED
        self.remaining -= count
        return count
