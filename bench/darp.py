"""DARP + STC: multi-robot coverage by dividing the area (DARP) and flying a spanning-tree path in each part (STC).

A comparison peer for our planner, one algorithm in one file (PythonRobotics style), written from:

- A. Ch. Kapoutsis, S. A. Chatzichristofis, E. B. Kosmatopoulos, "DARP: Divide Areas Algorithm for
  Optimal Multi-Robot Coverage Path Planning", Journal of Intelligent & Robotic Systems 86 (2017)
  663-680, doi:10.1007/s10846-016-0461-x; and the authors' reference implementation
  (github.com/athakapo/DARP, Java; its Python twin github.com/alice-st/DARP), for the constants and
  the details the paper leaves open;
- Y. Gabriely, E. Rimon, "Spanning-tree based coverage of continuous areas by a mobile robot",
  Annals of Mathematics and Artificial Intelligence 31 (2001) 77-98 (STC).

DARP, on a grid of cells L (the area to cover) with n robots standing on cells of it:

1. every robot i has an evaluation matrix E_i, at first the Euclidean distance from its cell;
2. each iteration assigns every cell to the robot of least E_i (A = argmin_i E_i; a robot's own cell
   stays its own) and counts the region sizes k_i against the fair share f = |L| / n;
3. the stopping rule: every region connected (4-connected) and |k_i - f| <= threshold for every robot
   (threshold 0 when n divides |L|, else 1);
4. otherwise every E_i is updated E_i <- C_i * R * (m_i E_i), elementwise:
   - m_i, the fair-share correction, a scalar per robot: >1 for a robot over its share (its cells get
     dearer), <1 for one under it, 1 inside the band; the step is the reference code's:
     m_i = 1 +- (k_i / sum of the over-share robots' k) * (their summed excess / |L|) / 2, with the
     band [f - thr (n-1)/n, f + thr/n], which guarantees an over-share robot whenever one is short;
   - C_i, the connectivity correction, for a robot whose region falls apart (connected components of
     its region): with d_R the distance to the component holding the robot and d_Q the distance to
     its other components, each scaled to [0, 1], C_i = d_R - d_Q rescaled to [1 - cc, 1 + cc]
     (cc = 0.01): cells near the robot's own piece get cheaper, cells near its stray pieces dearer;
     C_i = 1 for a connected region;
   - R, the random perturbation, uniform in [1 - rl, 1 + rl] per cell (rl = 1e-4), against cycles;
5. after `max_iterations` iterations without meeting the rule the fall-back raises the threshold by
   one and restarts from the distances (as the Java reference does; R keeps perturbing, so the new
   run differs); DARP has converged when the rule is met with threshold <= `max_threshold` (the
   Python twin's default `dcells`, 2). Past it we keep raising (`converged` is then False) so that a
   bench row always gets connected regions and a plan. DARP with Euclidean E_i struggles when robots
   are crowded (several launches in one corner) or the area is a corridor; so does the reference code
   on the same inputs (e.g. Milan_0_256 with 20 drones needs threshold 5 to 7 in both).

STC, per region: a minimum spanning tree of its cells (scipy.sparse.csgraph.minimum_spanning_tree,
edges along one axis cheaper; the axis whose path turns less is kept, as the reference keeps the mode
with fewest turns), then the path circumnavigating the tree on the sub-cells: each cell split into
2 x 2 sub-cells, the 4 sub-cells of a cell joined in a ring, and every tree edge opening the two
facing sides into two links across, which joins all rings into one closed tour visiting every
sub-cell once. The robot starts the tour at its own sub-cell and stops after the last sub-cell (the
tour's way back is not flown).

Our setting: a drone photographs every cell within Chebyshev distance 4 (a 9 x 9 footprint,
missionplan.grid.world.FOOTPRINT_RADIUS) and moves one cell per step, 4-connected. STC's sub-cell is the
footprint: a 9 x 9 block (blocks aligned on cell (0, 0)), photographed from its centre (clipped into
the map at the edges). A block is to cover when it holds a target. DARP's cell is STC's cell, 2 x 2
blocks (18 x 18 cells): DARP divides cells twice the tool's size and each is then cut into four
sub-cells the tool's size for STC, as the reference code does (its paths run on a grid twice as fine
as its division); so the fair share and the threshold count 18 x 18 cells (4 blocks each). A cell is
in the area when any of its blocks is to cover, and then all four of its blocks are flown: that is
DARP+STC's known cost (at the map's edge and round untargeted blocks), kept here. Each drone's robot
cell is the 18 x 18 cell holding its launch cell; it flies from the launch cell to the centre of the
block holding it (taxicab), where its tour starts, and then from block centre to block centre (9 cells
a step); its moves are counted cell by cell. The legs are straight lines: nothing may stand in the way
(open or overflown maps, where no cell is an obstacle); the self-check raises if a flown cell is an
obstacle.

Where our setting needs more than the paper gives (documented deviations): two launches in one
18 x 18 cell (DARP needs distinct robot cells) - the later robot takes the nearest cell of the area no
robot holds; an area that falls apart into pieces (the paper requires a connected one) - the pieces are
joined one by one along shortest 4-connected paths through cells not entirely obstacle, and those cells
are covered too; an 18 x 18 cell entirely obstacle is never in the area. A robot's own cell is in the
area even without a target (DARP's robots stand in the area).

The result checks itself: every cell stepped on (each leg expanded cell by cell) is recounted, and every
target must lie within Chebyshev distance 4 of one of them, or `darp_plan` raises. Run by hand (the four
MovingAI street maps, overflown, with 6 and 20 drones):

    .venv/bin/python bench/darp.py [--uavs 6,20] [--movingai-dir ../shared/maps/movingai] [--seed 0]
"""

from __future__ import annotations

import argparse
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from missionplan.grid.world import FOOTPRINT_RADIUS

Cell = tuple[int, int]

BLOCK = 2 * FOOTPRINT_RADIUS + 1  # a footprint-sized block: STC's sub-cell (9 cells)
MEGA = 2 * BLOCK                  # DARP's cell = STC's cell: 2 x 2 blocks (18 cells)
CC_VARIATION = 0.01               # cc: the connectivity correction's range [1 - cc, 1 + cc] (reference default)
RANDOM_LEVEL = 1e-4               # rl: the random perturbation's range [1 - rl, 1 + rl] (reference default)
MAX_THRESHOLD = 2                 # DARP has failed past this threshold (the Python twin's `dcells`)
MAX_ITERATIONS = 10_000           # iterations per threshold before the fall-back raises it

ROOT = Path(__file__).resolve().parent.parent
MOVINGAI_DIR = ROOT.parent / "shared" / "maps" / "movingai"


@dataclass
class Division:
    """DARP's answer on the cell grid: `owner` per cell (-1 outside the area), the iterations run (over
    every threshold tried), the threshold the stopping rule was met with, and whether that is DARP's
    success (threshold <= max_threshold)."""

    owner: np.ndarray
    iterations: int
    threshold: int
    converged: bool
    fair_share: float


@dataclass
class DarpResult:
    """Per drone: `paths` (every cell stepped on, launch cell first), `tours` (the blocks of its STC
    tour, in order) and `moves`; the fleet's `makespan` (the longest drone's moves) and `total_moves`;
    DARP's `division` on the 18 x 18 cells and `robot_cells` there; `coverage` % of the targets
    (recounted; anything under 100 raises)."""

    paths: list[list[Cell]]
    tours: list[list[Cell]]
    moves: list[int]
    division: Division
    robot_cells: list[Cell]
    coverage: float

    @property
    def makespan(self) -> int:
        return max(self.moves, default=0)

    @property
    def total_moves(self) -> int:
        return sum(self.moves)

    @property
    def iterations(self) -> int:
        return self.division.iterations

    @property
    def converged(self) -> bool:
        return self.division.converged


# --- the grids: blocks and DARP cells ---------------------------------------------------------------------


def _pooled_any(mask: np.ndarray, size: int) -> np.ndarray:
    """Per size x size tile (aligned on (0, 0), the last ones sticking out of the grid): any cell set."""
    rows, cols = -(-mask.shape[0] // size), -(-mask.shape[1] // size)
    padded = np.zeros((rows * size, cols * size), dtype=bool)
    padded[:mask.shape[0], :mask.shape[1]] = mask
    return np.asarray(padded.reshape(rows, size, cols, size).any(axis=(1, 3)))


def _robot_cells(starts: list[Cell], area: np.ndarray, usable: np.ndarray) -> list[Cell]:
    """The DARP cell holding each launch; a cell taken already sends the later robot to the nearest
    free one (of the area if it has one, else any usable cell)."""
    taken: list[Cell] = []
    for r, c in starts:
        cell = (r // MEGA, c // MEGA)
        if cell in taken:
            for pool in (area, usable):
                options = [(int(r), int(c)) for r, c in np.argwhere(pool) if (r, c) not in taken]
                if options:
                    cell = min(options, key=lambda o: ((o[0] - cell[0]) ** 2 + (o[1] - cell[1]) ** 2, o))
                    break
            else:
                raise ValueError("more drones than usable 18 x 18 cells")
        taken.append(cell)
    return taken


def _joined(area: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """`area` with its 4-connected pieces joined through `usable` cells, by shortest paths (breadth first
    from the first piece to the nearest other piece, repeated)."""
    area = area.copy()
    steps = ((1, 0), (-1, 0), (0, 1), (0, -1))
    while True:
        labels, count = ndimage.label(area)
        if count <= 1:
            return area
        parent: dict[Cell, Cell | None] = {(int(r), int(c)): None for r, c in np.argwhere(labels == 1)}
        queue = deque(parent)
        reached = None
        while queue and reached is None:
            r, c = queue.popleft()
            for dr, dc in steps:
                nxt = (r + dr, c + dc)
                if (0 <= nxt[0] < area.shape[0] and 0 <= nxt[1] < area.shape[1] and nxt not in parent
                        and usable[nxt]):
                    parent[nxt] = (r, c)
                    if labels[nxt] > 1:
                        reached = nxt
                        break
                    queue.append(nxt)
        if reached is None:
            raise ValueError("targets lie where no launch can reach (pass reachable targets only)")
        step: Cell | None = reached
        while step is not None:
            area[step] = True
            step = parent[step]


# --- DARP ---------------------------------------------------------------------------------------------


def _connectivity_correction(own_piece: np.ndarray, stray: np.ndarray, cc: float) -> np.ndarray:
    """C_i for a robot whose region is in pieces: distance to its own piece minus distance to its stray
    pieces (each scaled to [0, 1]), rescaled to [1 - cc, 1 + cc]."""
    to_own = ndimage.distance_transform_edt(~own_piece)
    to_stray = ndimage.distance_transform_edt(~stray)
    diff = to_own / max(to_own.max(), 1e-12) - to_stray / max(to_stray.max(), 1e-12)
    low, high = diff.min(), diff.max()
    if high - low < 1e-12:
        return np.ones_like(diff)
    return (diff - low) * (2 * cc / (high - low)) + (1 - cc)


def darp_divide(area: np.ndarray, robots: list[Cell], rng: np.random.Generator,
                max_iterations: int = MAX_ITERATIONS, max_threshold: int = MAX_THRESHOLD,
                cc: float = CC_VARIATION, random_level: float = RANDOM_LEVEL) -> Division:
    """DARP on a boolean grid `area` (4-connected, holding every robot cell): each cell to one robot,
    regions connected and within the threshold of the fair share (see the module)."""
    n = len(robots)
    shape = area.shape
    rr = np.array([r for r, _ in robots])
    rc = np.array([c for _, c in robots])
    yy, xx = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    initial = np.hypot(yy[None] - rr[:, None, None], xx[None] - rc[:, None, None])  # E_i: Euclidean distance
    cells = np.flatnonzero(area)
    robot_flat = rr * shape[1] + rc
    robot_pos = np.searchsorted(cells, robot_flat)  # a robot's cell among `cells`
    size = len(cells)
    fair = size / n
    # 4-adjacent pairs of area cells (flat indices): the edges a region's components are found on
    flat = np.arange(area.size).reshape(shape)
    across = area[:, :-1] & area[:, 1:]
    down = area[:-1, :] & area[1:, :]
    p = np.concatenate([flat[:, :-1][across], flat[:-1, :][down]])
    q = np.concatenate([flat[:, 1:][across], flat[1:, :][down]])
    threshold = 0 if size % n == 0 else 1
    iterations = 0
    while True:
        evaluation = initial.copy()
        for attempt in range(max_iterations + 1):
            owner = np.argmin(evaluation.reshape(n, -1)[:, cells], axis=0)
            owner[robot_pos] = np.arange(n)  # a robot's own cell is always its own
            sizes = np.bincount(owner, minlength=n)
            owner_full = np.full(area.size, -1)
            owner_full[cells] = owner
            same = owner_full[p] == owner_full[q]
            graph = coo_matrix((np.ones(int(same.sum())), (p[same], q[same])), shape=(area.size, area.size))
            _, piece = connected_components(graph, directed=False)
            _, first = np.unique(piece[cells], return_index=True)
            pieces = np.bincount(owner[first], minlength=n)  # connected components per region
            if (pieces == 1).all() and (np.abs(sizes - fair) <= threshold).all():
                return Division(owner_full.reshape(shape), iterations, threshold, threshold <= max_threshold, fair)
            if attempt == max_iterations:
                break
            # m_i: the fair-share correction (the reference code's step and band)
            high, low = fair + threshold / n, fair - threshold * (n - 1) / n
            over, under = sizes > high + 1e-9, sizes < low - 1e-9
            correction = np.ones(n)
            if over.any():
                step = (sizes[over] - high).sum() / size / 2
                share = sizes / sizes[over].sum()
                correction[over] = 1 + share[over] * step
                correction[under] = 1 - share[under] * step
            # C_i: the connectivity correction, for the regions in pieces
            connect = np.ones((n, *shape))
            for i in np.flatnonzero(pieces > 1):
                mine = (owner_full == i).reshape(shape)
                own_piece = (piece == piece[robot_flat[i]]).reshape(shape) & mine
                connect[i] = _connectivity_correction(own_piece, mine & ~own_piece, cc)
            noise = rng.uniform(1 - random_level, 1 + random_level, size=evaluation.shape)  # R
            evaluation = connect * noise * (correction[:, None, None] * evaluation)
            evaluation /= evaluation.max()  # a common scale: the argmin is unchanged, no overflow
            iterations += 1
        threshold += 1  # the fall-back: a looser threshold, from the distances again
        if threshold > fair:
            raise RuntimeError(f"DARP found no connected division of {size} cells among {n} robots")


# --- STC ----------------------------------------------------------------------------------------------


def spanning_tree(region: np.ndarray, cheap_axis: int) -> list[tuple[Cell, Cell]]:
    """A minimum spanning tree of the 4-connected cells of `region` (connected), edges along
    `cheap_axis` (0: vertical, 1: horizontal) weighing 1 and the others 2."""
    cells = [(int(r), int(c)) for r, c in np.argwhere(region)]
    index = {cell: k for k, cell in enumerate(cells)}
    rows, cols, weights = [], [], []
    for (r, c), k in index.items():
        for axis, nxt in ((0, (r + 1, c)), (1, (r, c + 1))):
            if nxt in index:
                rows.append(k)
                cols.append(index[nxt])
                weights.append(1.0 if axis == cheap_axis else 2.0)
    tree = minimum_spanning_tree(coo_matrix((weights, (rows, cols)), shape=(len(cells), len(cells)))).tocoo()
    return [(cells[a], cells[b]) for a, b in zip(tree.row, tree.col)]


def stc_tour(region: np.ndarray, tree: list[tuple[Cell, Cell]], start: Cell) -> list[Cell]:
    """The closed STC tour round `tree` on the sub-cells (2 x 2 per cell of `region`), from the sub-cell
    `start`, every sub-cell once (the way back to `start` left out)."""
    opened: set[tuple[Cell, Cell]] = set()  # (cell, direction) sides crossed by a tree edge
    for a, b in tree:
        d = (b[0] - a[0], b[1] - a[1])
        opened.add((a, d))
        opened.add((b, (-d[0], -d[1])))

    def links(sub: Cell) -> tuple[Cell, Cell]:
        r, c = sub
        cell, a, b = (r // 2, c // 2), r % 2, c % 2
        side = (0, 1 if b else -1)  # the cell's left or right side, next to this sub-cell
        first = (r, c + side[1]) if (cell, side) in opened else (r + (1 if a == 0 else -1), c)
        side = (1 if a else -1, 0)  # its top or bottom side
        second = (r + side[0], c) if (cell, side) in opened else (r, c + (1 if b == 0 else -1))
        return first, second

    count = 4 * int(region.sum())
    tour = [start]
    previous, current = start, links(start)[0]
    while current != start:
        tour.append(current)
        one, other = links(current)
        previous, current = current, (other if one == previous else one)
        if len(tour) > count:
            raise RuntimeError("the STC links do not close into one tour")
    if len(tour) != count:
        raise RuntimeError(f"the STC tour visits {len(tour)} of {count} sub-cells")
    return tour


def _turns(tour: list[Cell]) -> int:
    steps = np.diff(np.array(tour), axis=0)
    return int((np.abs(np.diff(steps, axis=0)).sum(axis=1) > 0).sum())


def region_tour(region: np.ndarray, start: Cell) -> list[Cell]:
    """STC on one region: of the trees favouring rows or columns, the tour with fewer turns."""
    tours = [stc_tour(region, spanning_tree(region, axis), start) for axis in (1, 0)]
    return min(tours, key=_turns)


# --- flying it ----------------------------------------------------------------------------------------


def _leg(a: Cell, b: Cell) -> list[Cell]:
    """The cells after `a` up to `b`, rows first then columns (taxicab, one cell a step)."""
    cells = []
    r, c = a
    while r != b[0]:
        r += 1 if b[0] > r else -1
        cells.append((r, c))
    while c != b[1]:
        c += 1 if b[1] > c else -1
        cells.append((r, c))
    return cells


def block_centre(block: Cell, shape: tuple[int, int]) -> Cell:
    """Where a block is photographed from: its centre, clipped into the map."""
    return (min(block[0] * BLOCK + FOOTPRINT_RADIUS, shape[0] - 1),
            min(block[1] * BLOCK + FOOTPRINT_RADIUS, shape[1] - 1))


def fly(launch: Cell, tour: list[Cell], shape: tuple[int, int]) -> list[Cell]:
    """Every cell the drone steps on: from its launch cell to the first block's centre, then centre to centre."""
    path = [launch]
    for block in tour:
        path += _leg(path[-1], block_centre(block, shape))
    return path


def check_coverage(paths: list[list[Cell]], target: np.ndarray, obstacle: np.ndarray) -> float:
    """Recount: every step 4-connected and on a free cell, and every target within Chebyshev distance
    FOOTPRINT_RADIUS of a cell stepped on; raises if not, else returns the coverage % (100)."""
    seen = np.zeros(target.shape, dtype=bool)
    for path in paths:
        cells = np.array(path)
        if len(cells) > 1 and (np.abs(np.diff(cells, axis=0)).sum(axis=1) != 1).any():
            raise AssertionError("a path jumps: every step must move one cell, 4-connected")
        if obstacle[cells[:, 0], cells[:, 1]].any():
            raise AssertionError("a path crosses an obstacle: the taxicab legs need open ground")
        seen[cells[:, 0], cells[:, 1]] = True
    covered = ndimage.maximum_filter(seen, size=BLOCK, mode="constant", cval=False)
    count = int(target.sum())
    missed = int((target & ~covered).sum())
    if missed:
        raise AssertionError(f"DARP+STC leaves {missed} of {count} targets unphotographed")
    return 100.0


def darp_plan(target: np.ndarray, obstacle: np.ndarray, starts: list[Cell], seed: int = 0,
              max_iterations: int = MAX_ITERATIONS, max_threshold: int = MAX_THRESHOLD) -> DarpResult:
    """DARP on the 18 x 18 cells holding targets, then per drone the STC tour of its region's 9 x 9
    blocks, flown from its launch cell (see the module); checked for coverage before it returns."""
    target = np.asarray(target, dtype=bool)
    obstacle = np.asarray(obstacle, dtype=bool)
    for r, c in starts:
        if not (0 <= r < target.shape[0] and 0 <= c < target.shape[1]) or obstacle[r, c]:
            raise ValueError(f"launch cell {(r, c)} is outside the map or on an obstacle")
    blocks_to_cover = _pooled_any(target & ~obstacle, BLOCK)
    area = _pooled_any(blocks_to_cover, 2)
    usable = _pooled_any(~obstacle, MEGA)  # an 18 x 18 cell entirely obstacle is never in the area
    robots = _robot_cells(starts, area, usable)
    for cell in robots:
        area[cell] = True  # a robot's cell is in its region, targets or not
    area = _joined(area, usable)
    division = darp_divide(area, robots, np.random.default_rng(seed), max_iterations, max_threshold)
    tours, paths = [], []
    for i, (launch, robot) in enumerate(zip(starts, robots)):
        region = division.owner == i
        start = (launch[0] // BLOCK, launch[1] // BLOCK)
        if (start[0] // 2, start[1] // 2) != robot:  # moved off a shared cell: its nearest sub-cell
            subs = [(2 * r + a, 2 * c + b) for r, c in np.argwhere(region) for a in (0, 1) for b in (0, 1)]
            start = min(subs, key=lambda s: (abs(s[0] - start[0]) + abs(s[1] - start[1]), s))
        tour = region_tour(region, (int(start[0]), int(start[1])))
        tours.append(tour)
        paths.append(fly(launch, tour, target.shape))
    coverage = check_coverage(paths, target & ~obstacle, obstacle) if target.any() else 100.0
    return DarpResult(paths, tours, [len(p) - 1 for p in paths], division, robots, coverage)


# --- the bench ------------------------------------------------------------------------------------------


def overflown_map(path: Path) -> tuple[str, np.ndarray, np.ndarray, list[Cell]]:
    """A MovingAI map with every building flown over (bench/sweep_bench.py's `overflown`): no obstacle,
    targets its street cells; with its launch cells (launches.spread_launches, via parse_movingai)."""
    from missionplan.maps.gridmap import read_map_text
    from missionplan.maps.movingai import parse_movingai
    gmap = parse_movingai(read_map_text(path), path.stem)
    return gmap.name, gmap.target & gmap.free, np.zeros_like(gmap.obstacle), list(gmap.launch)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--uavs", default="6,20", help="comma list of fleet sizes")
    parser.add_argument("--movingai-dir", default=str(MOVINGAI_DIR))
    parser.add_argument("--seed", type=int, default=0, help="seed of DARP's random perturbation")
    parser.add_argument("--max-iterations", type=int, default=MAX_ITERATIONS,
                        help="DARP iterations per threshold before the fall-back raises it")
    args = parser.parse_args()
    header = (f"{'map':<14} {'A':>3} {'targets':>8} {'makespan':>8} {'total':>8} {'cov %':>6} {'iters':>6} "
              f"{'conv':>5} {'thr':>3} {'cpu s':>6}")
    print(header)
    print("-" * len(header), flush=True)
    for path in sorted(Path(args.movingai_dir).glob("*.map")):
        name, target, obstacle, launches = overflown_map(path)
        for uavs in (int(u) for u in args.uavs.split(",") if u):
            cpu = time.process_time()
            result = darp_plan(target, obstacle, launches[:uavs], args.seed, args.max_iterations)
            seconds = time.process_time() - cpu
            print(f"{name:<14} {uavs:>3} {int(target.sum()):>8} {result.makespan:>8} {result.total_moves:>8} "
                  f"{result.coverage:>6.1f} {result.iterations:>6} {str(result.converged):>5} "
                  f"{result.division.threshold:>3} {seconds:>6.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
