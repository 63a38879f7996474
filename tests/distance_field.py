"""The expert's first distance search, kept as the reference its bitboard search (expert.end_distances) is checked
against: steps from every cell to the nearest goal through open cells, for a stack of views at once, in numpy."""

from __future__ import annotations

import math

import numpy as np


def flight_distance_field(goals: np.ndarray, blocked: np.ndarray, limit: int,
                          needed: np.ndarray | None = None) -> np.ndarray:
    """Steps from every cell to the nearest `goals` cell through unblocked cells (capped at `limit`).

    Works on one (rows, cols) grid or a stack (..., rows, cols) of independent grids at
    once, as the expert ran it for every drone of a step. With `needed` (a
    (rows, cols) mask), the search stops once every needed open cell has its distance:
    the field is then exact on the needed cells only.
    """
    *stack, rows, cols = goals.shape
    count, width = math.prod(stack), cols + 1
    # Every grid laid out flat, row after row, each row followed by one closed cell and the
    # stack framed by a closed row of `width` above and below: the four neighbours of every
    # cell are then the flat array shifted by 1 or `width`, so each shift is a contiguous
    # slice (several times faster per call than 2-D strided slices; the loop is all calls).
    size = count * (rows + 1) * width + 2 * width
    padded = np.zeros(size + 2 * width, dtype=bool)  # the frontier, with a margin for the shifts
    frontier = padded[width: width + size]
    up, down = padded[:size], padded[2 * width:]
    left, right = padded[width - 1: width - 1 + size], padded[width + 1: width + 1 + size]
    open_cells = np.zeros(size, dtype=bool)
    open_grids = _grids(open_cells, count, rows, cols)
    np.logical_not(blocked.reshape(count, rows, cols), out=open_grids)
    np.logical_and(goals.reshape(count, rows, cols), open_grids, out=_grids(frontier, count, rows, cols))
    fresh = open_cells ^ frontier  # open cells not reached yet
    grown = np.empty_like(fresh)
    # A cell's distance is the number of rings grown before it was reached, so each ring
    # adds one to every open cell still unreached (one add, not a masked write per ring).
    dist = np.zeros(size, dtype=np.uint8 if limit < 256 else np.int32)
    pending = None
    if needed is not None:
        pending = np.zeros(size, dtype=bool)
        np.logical_and(needed, open_grids, out=_grids(pending, count, rows, cols))
    for ring in range(limit):
        # The early stops are checked every other ring: stopping a ring late changes no
        # distance the field promises, and saves three calls on every other ring.
        if ring % 2 == 0:
            if not np.count_nonzero(frontier):  # count_nonzero: far cheaper than any() on small arrays
                break
            if pending is not None:
                pending &= fresh
                if not np.count_nonzero(pending):
                    break
        dist += fresh
        np.bitwise_or(up, down, out=grown)
        grown |= left
        grown |= right
        grown &= fresh
        fresh ^= grown
        frontier[...] = grown
    dist[fresh] = limit  # never reached (or not searched for: only `needed` is exact)
    field = _grids(dist, count, rows, cols).astype(np.float32).reshape(goals.shape)
    field[blocked] = limit
    return field


def _grids(flat: np.ndarray, count: int, rows: int, cols: int) -> np.ndarray:
    """The (count, rows, cols) cells of flight_distance_field's flat layout, as a view."""
    width = cols + 1
    return flat[width: width + count * (rows + 1) * width].reshape(count, rows + 1, width)[:, :rows, :cols]
