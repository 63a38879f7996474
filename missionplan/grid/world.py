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

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from missionplan.geo.camera import CELLS_PER_FOOTPRINT

from ..maps.gridmap import Cell, GridMap, MapError
from .pathfinding import SeenLookup

# Actions in the order the network's outputs use: Up, Right, Down, Left.
UP, RIGHT, DOWN, LEFT = 0, 1, 2, 3
HOVER = -1
ACTION_NAMES = ("up", "right", "down", "left")
ACTION_DELTAS = np.array([[-1, 0], [0, 1], [1, 0], [0, -1]], dtype=np.int64)
ACTION_OF_DELTA = {(int(dr), int(dc)): action for action, (dr, dc) in enumerate(ACTION_DELTAS)}
ACTION_STEPS = [tuple(d) for d in ACTION_DELTAS.tolist()]  # (dr, dc) per action, as Python ints


def turn_weight(a: int, b: int) -> float:
    """The thesis's turn weight between two moves: 0 straight (or after a hover), 0.5 for 90 deg, 1 reversed."""
    if a == HOVER or b == HOVER or a == b:
        return 0.0
    return 1.0 if (a - b) % 4 == 2 else 0.5

FOOTPRINT_RADIUS = CELLS_PER_FOOTPRINT // 2  # 9 x 9 cells centred on the drone
VIEW_RADIUS = 9  # 19 x 19 local view
EXPLORED = -2  # _pad_open_zone of a cell that is not (or no longer) an unexplored target
PAD = 32  # padding of the internal arrays, so any window up to this radius is one slice


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
        self._top_zone = max(int(self.zone_of.max(initial=0)), self.num_drones)
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
        # Windows read as flat takes from the padded arrays: about twice as fast as indexing by
        # row and column arrays, on the few hundred cells of a step.
        self._pad_width = cols + 2 * PAD
        self._every_drone = np.arange(self.num_drones)
        self._obstacle_view = self._pad_obstacle.ravel().data  # is_free's reads: a memoryview is the fastest one at a time
        self._window_offsets: dict[int, np.ndarray] = {}  # radius -> flat offsets from the centre (_view_cells)
        span = np.arange(-FOOTPRINT_RADIUS, FOOTPRINT_RADIUS + 1)
        self._footprint_offsets = (span[:, None] * self._pad_width + span[None, :]).ravel()
        self._scratch = np.zeros(self._pad_obstacle.size, dtype=np.int32)  # _explore_footprints' overlap check
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        rows, cols = self._shape
        self.t = 0
        self.positions = np.array(self.starts, dtype=np.int64).reshape(-1, 2)
        self._windows: dict[int, np.ndarray] = {}  # radius -> every drone's window (_view_cells), until a move
        self._centre_cells: np.ndarray | None = None  # _centres of every drone, until a move
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
        self._last_view = self.last_actions.reshape(-1).data  # step's writes, one drone at a time
        # Whether each drone has flown over each cell, padded like the other arrays: the expert
        # reads it around every asked drone every step, as one gather with no bounds to check.
        self._pad_flown = np.zeros((self.num_drones, rows + 2 * PAD, cols + 2 * PAD), dtype=bool)
        self.truncated = False
        # The obstacles with every drone on them: a view's blocked cells are one gather of it.
        self._pad_occupied = self._pad_obstacle.copy()
        self._pad_occupied[self.positions[:, 0] + PAD, self.positions[:, 1] + PAD] = True
        self._occupied_view = self._pad_occupied.ravel().data  # _resolve_moves writes one cell at a time
        initial = np.zeros(self.num_drones, dtype=np.int64)
        for k in range(self.num_drones):
            drone = np.array([k])
            centre = self._centres(drone)
            self._mark_visits(drone, centre)
            initial[k] = self._explore_footprints(drone, centre)[0]
        self.initial_new_cells = initial
        self._seen_views: np.ndarray | None = None  # sees_unexplored's (K, 361) gather, until the next step
        self._unexplored_flat: tuple[int, np.ndarray] | None = None  # (step, unexplored_flat's answer)

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
        # Kept until the next step: the policy's views of this step are rows of it.
        gathered = self._pad_open_zone.reshape(-1).take(self._view_cells(None, VIEW_RADIUS))
        self._seen_views = self._seen_in(self._every_drone, gathered)
        return self._seen_views.any(axis=1)

    def seen_unexplored_at(self, drones: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Whether each of `drones` sees padded cells (rows, cols) as unexplored; rows/cols are (n, ...)."""
        return self._seen_in(drones, self._pad_open_zone[rows, cols])

    def _seen_in(self, drones: np.ndarray, open_zone: np.ndarray) -> np.ndarray:
        """Whether each of `drones` sees as unexplored the cells whose `_pad_open_zone` values, (n, ...),
        were gathered for it: its own zone's, or any zone's once its zone is done."""
        extra = (1,) * (open_zone.ndim - 1)
        zone_done = (self.num_drones == 1) | (self.zone_remaining[drones] == 0) | \
            (self.region_zone_remaining[self.drone_region[drones], drones] == 0)
        seen = open_zone == drones.reshape(-1, *extra)
        if zone_done.any():
            seen |= (open_zone != EXPLORED) & zone_done.reshape(-1, *extra)
        return seen

    def _view_cells(self, drones: np.ndarray | None, radius: int) -> np.ndarray:
        """(n, (2r+1)^2) flat numbers, in the padded arrays, of the window of radius r around each
        drone (every drone with None), row-major: its view, or its footprint."""
        # Made for every drone once per radius between moves: a step asks for the views three
        # times (who sees something, the policy's views, where it has flown).
        windows = self._windows.get(radius)
        if windows is None:
            offsets = self._window_offsets.get(radius)
            if offsets is None:
                span = np.arange(-radius, radius + 1)
                offsets = self._window_offsets[radius] = (span[:, None] * self._pad_width + span[None, :]).ravel()
            windows = self._windows[radius] = self._centres(None)[:, None] + offsets[None, :]
        return windows if drones is None else windows[drones]

    def views(self, drones: np.ndarray | list[int], radius: int = VIEW_RADIUS) -> tuple[np.ndarray, np.ndarray]:
        """Batched view_unexplored and view_blocked: two (n, 2r+1, 2r+1) bool arrays, one gather each."""
        drones = np.asarray(drones, dtype=np.int64).reshape(-1)
        side = 2 * radius + 1
        cells = self._view_cells(drones, radius)
        if radius == VIEW_RADIUS and self._seen_views is not None:  # sees_unexplored gathered them this step
            unexplored = self._seen_views[drones].reshape(-1, side, side)
        else:
            unexplored = self._seen_in(drones, self._pad_open_zone.reshape(-1).take(cells)).reshape(-1, side, side)
        # Other drones are blocked too; the drone itself stands on a free cell, its view's centre.
        blocked = self._pad_occupied.reshape(-1).take(cells).reshape(-1, side, side)
        blocked[:, radius, radius] = False
        return unexplored, blocked

    def flown_views(self, drones: np.ndarray, radius: int = VIEW_RADIUS) -> np.ndarray:
        """(n, 2r+1, 2r+1) bool: where each of `drones` has already flown, around itself (outside
        the map: never)."""
        side = 2 * radius + 1
        plane = self._pad_obstacle.size
        cells = self._view_cells(drones, radius) + (drones * plane)[:, None]
        return self._pad_flown.reshape(-1).take(cells).reshape(-1, side, side)

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

    def seen_lookup(self, k: int) -> SeenLookup:
        """What drone k sees as unexplored, as of now, for the path-finders to read without a call per cell: the
        zone array (padded, flat: numbered as a FlightSearch with pad=PAD numbers cells) and, per value, whether
        drone k sees a cell holding it."""
        flags = [False] * (self._top_zone + 3)  # zones 0..top, then EXPLORED (-2) and -1 from the end
        if self.zone_done(k):
            flags = [True] * len(flags)
            flags[EXPLORED] = False
        else:
            flags[k] = True
        return SeenLookup(self._pad_open_zone.reshape(-1), flags)

    def unexplored_flat(self) -> np.ndarray:
        """Every unexplored cell as a flat number in the padded arrays (a FlightSearch with pad=PAD), ascending."""
        # Cells are only ever photographed, never un-photographed: the last answer, filtered, is this
        # one, and far cheaper than a scan of the whole grid once most of it is photographed.
        kept = self._unexplored_flat
        if kept is not None and kept[0] == self.t:
            return kept[1]
        if kept is None:
            cells = np.flatnonzero(self._pad_unexplored)
        else:
            cells = kept[1][self._pad_unexplored.reshape(-1).take(kept[1])]
        self._unexplored_flat = (self.t, cells)
        return cells

    def is_free(self, cell: Cell) -> bool:
        r, c = cell
        return not self._obstacle_view[(r + PAD) * self._pad_width + c + PAD]

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
        listed = np.asarray(actions, dtype=np.int64).reshape(self.num_drones).tolist()
        self._seen_views = None
        movers = self._resolve_moves(listed)
        self.t += 1
        moved = [False] * self.num_drones
        new_cells = np.zeros(self.num_drones, dtype=np.int64)
        if movers:
            last = self._last_view  # per drone [previous, one before], written in place
            for k in movers:
                moved[k] = True
                last[2 * k + 1] = last[2 * k]
                last[2 * k] = listed[k]
            drones = np.array(movers, dtype=np.int64)
            centres = self._centres(drones)
            self._mark_visits(drones, centres)
            new_cells[drones] = self._explore_footprints(drones, centres)
        if self.t >= self.step_cap and not self.done:
            self.truncated = True
        return StepOutcome(moved=np.array(moved), new_cells=new_cells, done=self.done, truncated=self.truncated,
                           blocked=np.array([a != HOVER and not m for a, m in zip(listed, moved)], dtype=bool))

    def _resolve_moves(self, actions: list[int]) -> list[int]:
        """Move the drones whose target cell is free (see `step`); the drones that moved, in index order.

        Plain Python on tuples: a handful of drones, where numpy's per-call cost would dominate."""
        before = [tuple(p) for p in self.positions.tolist()]
        positions = list(before)
        occupied = {cell: k for k, cell in enumerate(positions)}
        is_free = self.is_free
        targets: dict[int, Cell] = {}
        for k, action in enumerate(actions):
            if action != HOVER:
                dr, dc = ACTION_STEPS[action]
                cell = (positions[k][0] + dr, positions[k][1] + dc)
                if is_free(cell):
                    targets[k] = cell
        movers: list[int] = []
        pending = list(targets)  # index order: two drones asking for one cell, the lower index gets it
        progress = True
        while pending and progress:
            progress = False
            for k in list(pending):
                cell = targets[k]
                if cell in occupied:
                    continue
                del occupied[positions[k]]
                occupied[cell] = k
                positions[k] = cell
                movers.append(k)
                pending.remove(k)
                progress = True
        if movers:
            movers.sort()
            occupancy, width = self._occupied_view, self._pad_width
            for k in movers:
                occupancy[(before[k][0] + PAD) * width + before[k][1] + PAD] = False
            for k in movers:
                occupancy[(positions[k][0] + PAD) * width + positions[k][1] + PAD] = True
            self.positions[:] = positions
            self._windows.clear()
            self._centre_cells = np.array([(r + PAD) * width + c + PAD for r, c in positions], dtype=np.int64)
        return movers

    def _centres(self, drones: np.ndarray | None) -> np.ndarray:
        """Flat numbers, in the padded arrays, of the cells `drones` (every drone with None) stand on."""
        if self._centre_cells is None:  # kept until a drone moves
            self._centre_cells = (self.positions[:, 0] + PAD) * self._pad_width + self.positions[:, 1] + PAD
        return self._centre_cells if drones is None else self._centre_cells[drones]

    def _mark_visits(self, drones: np.ndarray, centres: np.ndarray) -> None:
        self._pad_flown.reshape(-1)[drones * self._pad_obstacle.size + centres] = True

    def _explore_footprints(self, drones: np.ndarray, centres: np.ndarray) -> np.ndarray:
        """Photograph under each of `drones` (standing on padded flat numbers `centres`, in index
        order: a cell two footprints share counts for the first); the cells each newly explored.
        One gather for all of them."""
        under = centres[:, None] + self._footprint_offsets[None, :]  # (n, 81)
        unexplored = self._pad_unexplored.reshape(-1)  # views: writes below mark the world
        hit = unexplored.take(under)
        counts = hit.sum(axis=1)
        cells = under[hit]  # drone by drone, in index order
        if not cells.size:
            return counts
        if len(drones) > 1:
            # A cell listed twice fails this check whichever write lands (cheaper than np.unique).
            order = np.arange(cells.size)
            self._scratch[cells] = order
            if not (self._scratch[cells] == order).all():  # footprints overlap: a shared cell is the first drone's
                _, first = np.unique(cells, return_index=True)
                owner = np.repeat(np.arange(len(drones)), counts)[first]
                counts = np.bincount(owner, minlength=len(drones))
                cells = cells[first]
        slots = self._pad_slot.reshape(-1)[cells]
        done = np.bincount(slots, minlength=self.region_zone_remaining.size).reshape(self.region_zone_remaining.shape)
        self.region_zone_remaining -= done
        self.zone_remaining -= done[:, : self.num_drones].sum(axis=0)  # every region's share of each drone's zone
        unexplored[cells] = False
        self._pad_open_zone.reshape(-1)[cells] = EXPLORED
        self.remaining -= len(cells)
        return counts
