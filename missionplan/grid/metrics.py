"""The evaluation metrics of SPEC section 6 (thesis 5.1), as plain functions of a run.

A = drones, M_i = moves of drone i (a hover is not a move), E_{i,t} = cells newly
photographed by drone i at step t >= 1 (the launch footprint at t = 0 is not a move's
work, so it is left out of TE), T_{i,t} = turn between drone i's consecutive moves,
weighted 0.5 for 90 deg and 1 for 180 deg.

    MMN = sum_i M_i / A
    TE  = sum_{i,t} (E_{i,t} / 9) / (A * MMN)        in %
    MNT = sum_{i,t} k * T_{i,t} / (A * MMN)          in %
    MUD* = mean over steady-state steps of the mean pairwise Euclidean drone distance (cells)
    MDU* = mean over steady-state steps of the mean, over unexplored target cells, of the
           Euclidean distance to the nearest drone (cells)

Steady state = the steps after which coverage is between 40 % and 70 % (both included).
`SteadyStateSampler` collects MUD and MDU during a run, since the unexplored set at each
step is not kept afterwards. MUD* is sampled at every steady-state step; MDU* too on maps
of up to MDU_EVERY_STEP_TARGETS targets, and at every `mdu_stride(U)`-th steady-state step
on bigger ones (each sample exact: one Euclidean distance transform).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from missionplan.geo.camera import CELLS_PER_FOOTPRINT

STEADY_LOW, STEADY_HIGH = 0.40, 0.70
MDU_EVERY_STEP_TARGETS = 20_000  # maps up to this many targets (every shipped one) get MDU* at every step
MDU_STRIDE_TARGETS = 10_000  # bigger maps: every (U // this)-th steady-state step


def move_count(path: np.ndarray) -> int:
    """Moves in a per-step cell path (a repeated cell is a hover)."""
    path = np.asarray(path)
    return int(np.any(path[1:] != path[:-1], axis=1).sum())


def turn_sum(path: np.ndarray) -> float:
    """Weighted turns between consecutive moves: 0.5 for 90 deg, 1 for 180 deg (hovers skipped)."""
    path = np.asarray(path)
    steps = path[1:] - path[:-1]
    steps = steps[np.any(steps != 0, axis=1)]
    if len(steps) < 2:
        return 0.0
    dots = np.sum(steps[1:] * steps[:-1], axis=1)  # unit moves: 1 straight, 0 at 90 deg, -1 reversed
    return float(np.sum(np.where(dots == 0, 0.5, np.where(dots < 0, 1.0, 0.0))))


def mean_pairwise_distance(positions: np.ndarray) -> float:
    positions = np.asarray(positions, dtype=float)
    if len(positions) < 2:
        return 0.0
    diff = positions[:, None, :] - positions[None, :, :]
    dist = np.sqrt((diff ** 2).sum(axis=2))
    return float(dist[_upper_triangle(len(positions))].mean())


@lru_cache(maxsize=16)
def _upper_triangle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """np.triu_indices(n, k=1), made once per fleet size: the steady state asks at every step."""
    return np.triu_indices(n, k=1)


# Cost of the two exact ways, per cell (measured on a 256² map): a distance transform ~40 ns
# per cell of its box; the direct way ~1.6 ns per (unexplored cell, drone) pair.
DIRECT_PAIRS_PER_BOX_CELL = 16


def mean_distance_to_nearest(unexplored: np.ndarray, positions: np.ndarray,
                             scratch: DistanceScratch | None = None) -> float:
    """Mean over the True cells of `unexplored` of the Euclidean distance to the nearest position.

    Exact either way, whichever is cheaper: squared distances from every cell to every drone
    (few drones, few cells), or one Euclidean distance transform over the box that holds the
    cells and the drones (positions may lie outside the mask's grid). Both take the square root
    of the same integer and average the cells in row-major order, so they give the same float.
    `scratch` (one per run) lends the direct way its arrays.
    """
    unexplored = np.asarray(unexplored, dtype=bool)
    positions = np.asarray(positions, dtype=np.int64).reshape(-1, 2)
    cell_rows, cell_cols = (scratch or DistanceScratch()).cells(unexplored)  # row-major
    cells = len(cell_rows)
    if not cells:
        return 0.0
    rows, cols = (int(cell_rows[0]), int(cell_rows[-1])), (int(cell_cols.min()), int(cell_cols.max()))  # bounding box
    r0, c0 = min(rows[0], positions[:, 0].min()), min(cols[0], positions[:, 1].min())
    r1, c1 = max(rows[-1], positions[:, 0].max()), max(cols[-1], positions[:, 1].max())
    if cells * len(positions) <= DIRECT_PAIRS_PER_BOX_CELL * (r1 - r0 + 1) * (c1 - c0 + 1):
        return _mean_distance_direct(unexplored.shape, cell_rows, cell_cols, positions, scratch)
    canvas = np.ones((r1 - r0 + 1, c1 - c0 + 1), dtype=bool)
    canvas[positions[:, 0] - r0, positions[:, 1] - c0] = False  # the transform measures to the zeros
    dist = ndimage.distance_transform_edt(canvas)
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    inside = dist[rows[0] - r0: rows[-1] + 1 - r0, cols[0] - c0: cols[-1] + 1 - c0]
    return float(inside[unexplored[box]].mean())


class DistanceScratch:
    """Arrays mean_distance_to_nearest reuses from call to call (a run's, on one grid).

    A steady-state sample handles tens of thousands of cells: fresh arrays that big are pages the
    allocator hands back to the system after each call and faults in again on the next, which
    cost several times the arithmetic. Here every array is made once and then only rewritten."""

    def __init__(self) -> None:
        self._shape: tuple[int, ...] = ()
        self._arrays: dict[str, np.ndarray] = {}

    def array(self, name: str, size: int, dtype: npt.DTypeLike) -> np.ndarray:
        """The first `size` entries of a kept array of `dtype`, grown when too short."""
        kept = self._arrays.get(name)
        if kept is None or len(kept) < size or kept.dtype != dtype:
            kept = self._arrays[name] = np.empty(max(size, 1024), dtype=dtype)
        return kept[:size]

    def cells(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows and columns of the True cells of a 2-D mask, row-major (kept arrays: use before the next call)."""
        if mask.shape != self._shape:
            self._shape = mask.shape
            kind = np.int32 if max(mask.shape) < 2 ** 31 else np.int64
            rows, cols = np.indices(mask.shape, dtype=kind)
            self._arrays["row_of"], self._arrays["col_of"] = rows.ravel(), cols.ravel()
        flat = mask.ravel()
        count = int(np.count_nonzero(flat))
        row_of, col_of = self._arrays["row_of"], self._arrays["col_of"]
        cell_rows: np.ndarray = np.compress(flat, row_of, out=self.array("rows", count, row_of.dtype))
        cell_cols: np.ndarray = np.compress(flat, col_of, out=self.array("cols", count, col_of.dtype))
        return cell_rows, cell_cols


def _mean_distance_direct(shape: tuple[int, ...], cell_rows: np.ndarray, cell_cols: np.ndarray,
                          positions: np.ndarray, scratch: DistanceScratch | None = None) -> float:
    """mean_distance_to_nearest by squared integer distances from every cell (row-major, as the
    transform's mask reads them) to every drone."""
    # In place and in int32 where the squares fit (a third faster than int64 temporaries); the
    # integers, and so the float, are the same.
    scratch = scratch or DistanceScratch()
    span = max(shape) + int(np.abs(positions).max())
    kind = np.int32 if span < 2 ** 15 else np.int64
    count = len(cell_rows)
    nearest, across = scratch.array("nearest", count, kind), scratch.array("across", count, kind)
    distance = scratch.array("distance", count, kind)
    for k, (r, c) in enumerate(positions.tolist()):
        squares = nearest if k == 0 else distance
        np.subtract(cell_rows, r, out=squares, casting="unsafe")  # |difference| < 2^15: exact in int32
        squares *= squares
        np.subtract(cell_cols, c, out=across, casting="unsafe")
        across *= across
        squares += across
        if k:
            np.minimum(nearest, squares, out=nearest)
    return float(np.sqrt(nearest, out=scratch.array("root", count, np.float64)).mean())


def mdu_stride(num_targets: int) -> int:
    """Every how many steady-state steps MDU* is sampled: 1 up to MDU_EVERY_STEP_TARGETS targets, then U // 10,000.

    Past that, one distance transform per step would cost more than the planning
    itself; sampling every n-th step changes MDU* by well under 1 % (docs/scale.md).
    """
    return 1 if num_targets <= MDU_EVERY_STEP_TARGETS else max(1, num_targets // MDU_STRIDE_TARGETS)


@dataclass
class SteadyStateSampler:
    """Collects MUD at every step whose coverage lies in [40 %, 70 %], and MDU at every `stride`-th of them."""

    mud: list[float] = field(default_factory=list)
    mdu: list[float] = field(default_factory=list)
    stride: int = 1
    window_steps: int = 0
    scratch: DistanceScratch = field(default_factory=DistanceScratch, repr=False, compare=False)

    def observe(self, coverage: float, positions: np.ndarray, unexplored: np.ndarray) -> None:
        if STEADY_LOW <= coverage <= STEADY_HIGH:
            self.mud.append(mean_pairwise_distance(positions))
            if self.window_steps % self.stride == 0:
                self.mdu.append(mean_distance_to_nearest(unexplored, positions, self.scratch))
            self.window_steps += 1


def compute_metrics(paths: np.ndarray, new_cells: np.ndarray, sampler: SteadyStateSampler,
                    coverage: float, hover_steps: int) -> dict[str, float | None]:
    """All SPEC metrics of a run.

    paths: (A, T+1, 2) cell of each drone at each step, the start included.
    new_cells: (A, T) cells newly photographed by each drone at steps 1..T.
    coverage: final fraction of reachable targets explored (0-1).
    MUD and MDU are None when no step fell in the steady-state window.
    """
    num_drones = paths.shape[0]
    moves = np.array([move_count(p) for p in paths])
    mmn = float(moves.mean()) if num_drones else 0.0
    denom = num_drones * mmn
    te = 100.0 * float(new_cells.sum()) / CELLS_PER_FOOTPRINT / denom if denom else 0.0
    mnt = 100.0 * sum(turn_sum(p) for p in paths) / denom if denom else 0.0
    return {
        "MMN": mmn,
        "TE": te,
        "MNT": mnt,
        "MUD": float(np.mean(sampler.mud)) if sampler.mud else None,
        "MDU": float(np.mean(sampler.mdu)) if sampler.mdu else None,
        "coverage": 100.0 * coverage,
        "makespan": int(moves.max()) if num_drones else 0,
        "hover_steps": int(hover_steps),
    }
