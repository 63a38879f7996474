"""The policy's input: one fixed-length state vector per drone, and its x8 symmetry.

This module owns two things and nothing else:

1. `encode_states`: what a drone "sees" at one step of a `CoverageWorld`, as a
   `STATE_SIZE` (376) float32 vector. Layout, in this order:

   * 360 values - the 19 x 19 view centred on the drone (VIEW_RADIUS = 9), row by row,
     row 0 to the north (top), the centre cell (the drone itself) left out:
     +1 a cell the drone sees as unexplored (the zone-sight rule of
     `CoverageWorld.view_unexplored`), -1 a blocked cell (obstacle, outside the map,
     another drone; as `CoverageWorld.view_blocked`), 0 otherwise. Blocked wins.
   * 8 values - memory: one-hot of the previous action over (up, right, down, left),
     then one-hot of the action before it. HOVER (no move yet) is all zeros.
   * 8 values - detectors beyond the view, each quadruple in action order
     (up, right, down, left):
       - "unexplored further along" (4): 1.0 when the band that starts just outside
         the view and runs DETECTOR_RANGE (20) cells further in that direction, as wide
         as the view (its 19 columns for up/down, its 19 rows for left/right), holds a
         cell the drone sees as unexplored (same zone-sight rule as the view).
       - "obstacle ahead" (4): 1.0 when the single cell on the drone's centre line just
         beyond the view, at distance VIEW_RADIUS + 1 in that direction, is a static
         obstacle or outside the map. Other drones do not count: they move.
     The spec leaves the detectors' exact rule open; the above is our documented choice.

2. The x8 symmetry of the square (the dihedral group), used to augment training data:
   symmetry `sym` in 0..7 is `np.rot90(grid, sym % 4)` (counter-clockwise quarter turns)
   applied after `np.fliplr` when `sym >= 4`. `transform_grid`, `transform_cell`,
   `transform_actions` and `transform_states` all follow that one definition, so that
   encoding a transformed world equals transforming the encoding of the original.

Everything here is numpy; the network code turns the arrays into tensors itself.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..grid.world import ACTION_DELTAS, HOVER, PAD, VIEW_RADIUS, CoverageWorld

VIEW_SIDE = 2 * VIEW_RADIUS + 1  # 19
VIEW_CELLS = VIEW_SIDE * VIEW_SIDE - 1  # 360: the centre (the drone itself) is left out
NUM_ACTIONS = 4
DETECTOR_RANGE = 20  # depth of the "unexplored further along" band, beyond the view

# Offsets of the slices inside the state vector.
VIEW_SLICE = slice(0, VIEW_CELLS)
MEMORY_SLICE = slice(VIEW_CELLS, VIEW_CELLS + 2 * NUM_ACTIONS)
UNEXPLORED_DETECTOR_SLICE = slice(MEMORY_SLICE.stop, MEMORY_SLICE.stop + NUM_ACTIONS)
OBSTACLE_DETECTOR_SLICE = slice(UNEXPLORED_DETECTOR_SLICE.stop, UNEXPLORED_DETECTOR_SLICE.stop + NUM_ACTIONS)
STATE_SIZE = OBSTACLE_DETECTOR_SLICE.stop
assert STATE_SIZE == 376

# Every cell read by encode_states must lie in the padded arrays, so all reads are
# plain indexing with no bounds checks.
assert VIEW_RADIUS + 1 + DETECTOR_RANGE <= PAD

NUM_SYMMETRIES = 8

# ----------------------------------------------------------------- encoding tables
_SPAN = np.arange(-VIEW_RADIUS, VIEW_RADIUS + 1)
# Flat indices (into the 361 window cells) kept in the state: all but the centre.
_VIEW_KEEP = np.delete(np.arange(VIEW_SIDE * VIEW_SIDE), VIEW_SIDE * VIEW_SIDE // 2)


def _band_offsets() -> np.ndarray:
    """(4, 20 * 19, 2) offsets of the detector bands, one band per action direction."""
    along = np.arange(VIEW_RADIUS + 1, VIEW_RADIUS + 1 + DETECTOR_RANGE)  # 10..29
    bands = []
    for delta in ACTION_DELTAS:
        across = delta[::-1]  # perpendicular to the direction; its sign does not matter
        a, b = np.meshgrid(along, _SPAN, indexing="ij")
        bands.append(a.reshape(-1, 1) * delta + b.reshape(-1, 1) * across)
    return np.stack(bands)


_BAND_OFFSETS = _band_offsets()
_AHEAD_OFFSETS = (VIEW_RADIUS + 1) * ACTION_DELTAS  # (4, 2)


def encode_states(world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
    """(len(drones), STATE_SIZE) float32: the state vector of each requested drone."""
    drones = np.asarray(drones, dtype=np.int64).reshape(-1)
    n = drones.size
    centre = world.positions[drones] + PAD  # (n, 2) positions in the padded arrays
    # --- view: (n, 19, 19) windows gathered in one fancy index (zone sight, other drones blocked).
    unexplored, blocked = world.views(drones)
    view = np.where(blocked, -1.0, unexplored.astype(np.float32)).astype(np.float32)

    states = np.zeros((n, STATE_SIZE), dtype=np.float32)
    states[:, VIEW_SLICE] = view.reshape(n, VIEW_SIDE * VIEW_SIDE)[:, _VIEW_KEEP]

    # --- memory: one-hot of the last two actions; HOVER (-1) matches no column.
    last = world.last_actions[drones]  # (n, 2)
    states[:, MEMORY_SLICE] = (last[:, :, None] == np.arange(NUM_ACTIONS)).reshape(n, 2 * NUM_ACTIONS)

    # --- detectors beyond the view.
    band_rows = centre[:, 0, None, None] + _BAND_OFFSETS[None, :, :, 0]  # (n, 4, 380)
    band_cols = centre[:, 1, None, None] + _BAND_OFFSETS[None, :, :, 1]
    states[:, UNEXPLORED_DETECTOR_SLICE] = world.seen_unexplored_at(drones, band_rows, band_cols).any(axis=2)
    ahead = centre[:, None, :] + _AHEAD_OFFSETS[None, :, :]  # (n, 4, 2)
    states[:, OBSTACLE_DETECTOR_SLICE] = world._pad_obstacle[ahead[..., 0], ahead[..., 1]]
    return states


# ------------------------------------------------------------------- symmetries
def _check_sym(sym: int) -> None:
    if not 0 <= sym < NUM_SYMMETRIES:
        raise ValueError(f"symmetry index must be in 0..{NUM_SYMMETRIES - 1}, got {sym}")


def inverse_symmetry(sym: int) -> int:
    """The symmetry that undoes `sym`: the opposite turn, or the same mirror."""
    _check_sym(sym)
    return sym if sym >= 4 else (-sym) % 4  # every mirrored symmetry is its own inverse


def transform_grid(array2d: np.ndarray, sym: int) -> np.ndarray:
    """The grid seen under symmetry `sym`: fliplr if sym >= 4, then rot90 (sym % 4) times."""
    _check_sym(sym)
    grid = np.fliplr(array2d) if sym >= 4 else array2d
    return np.ascontiguousarray(np.rot90(grid, sym % 4))


def transform_cell(cell: tuple[int, int], shape: tuple[int, int], sym: int) -> tuple[int, int]:
    """Where cell (row, col) of a grid of `shape` lands in `transform_grid(grid, sym)`."""
    _check_sym(sym)
    r, c = int(cell[0]), int(cell[1])
    rows, cols = int(shape[0]), int(shape[1])
    if sym >= 4:
        c = cols - 1 - c
    for _ in range(sym % 4):
        # One counter-clockwise quarter turn: (r, c) -> (cols-1-c, r), the shape swaps.
        r, c = cols - 1 - c, r
        rows, cols = cols, rows
    return r, c


def _action_permutations() -> np.ndarray:
    """(8, 4): ACTION_PERMS[sym, a] is action a seen under sym.

    Derived from transform_cell, not written by hand, so it cannot disagree with it:
    move from the centre of a 3 x 3 grid and see where the neighbour lands.
    """
    perms = np.zeros((NUM_SYMMETRIES, NUM_ACTIONS), dtype=np.int64)
    for sym in range(NUM_SYMMETRIES):
        for a, (dr, dc) in enumerate(ACTION_DELTAS):
            r, c = transform_cell((1 + dr, 1 + dc), (3, 3), sym)
            delta = np.array([r - 1, c - 1])
            perms[sym, a] = int(np.flatnonzero(np.all(ACTION_DELTAS == delta, axis=1))[0])
    return perms


ACTION_PERMS = _action_permutations()


def transform_actions(actions: np.ndarray | Sequence[int], sym: int) -> np.ndarray:
    """Action indices seen under symmetry `sym`; HOVER stays HOVER."""
    _check_sym(sym)
    actions = np.asarray(actions, dtype=np.int64)
    # clip keeps HOVER (-1) a valid index; np.where then puts HOVER back.
    return np.where(actions == HOVER, HOVER, ACTION_PERMS[sym][np.clip(actions, 0, None)])


def _state_permutations() -> np.ndarray:
    """(8, STATE_SIZE): transform_states(s, sym) == s[:, STATE_PERMS[sym]].

    Entry i of a row names the source index whose value lands at index i.
    """
    full = np.arange(VIEW_SIDE * VIEW_SIDE).reshape(VIEW_SIDE, VIEW_SIDE)
    # Map a full-window index back to its place among the 360 kept view values
    # (the centre never moves under a symmetry of the square, so it is never asked for).
    kept_position = np.full(VIEW_SIDE * VIEW_SIDE, -1, dtype=np.int64)
    kept_position[_VIEW_KEEP] = np.arange(VIEW_CELLS)
    perms = np.zeros((NUM_SYMMETRIES, STATE_SIZE), dtype=np.int64)
    for sym in range(NUM_SYMMETRIES):
        # Transforming a grid of source indices tells, for each output cell, its source.
        source = transform_grid(full, sym).reshape(-1)[_VIEW_KEEP]
        perms[sym, VIEW_SLICE] = kept_position[source]
        # Direction-indexed blocks: the value for action a moves to ACTION_PERMS[sym, a],
        # so output column b reads input column inverse[b].
        inverse = np.argsort(ACTION_PERMS[sym])
        for block in (MEMORY_SLICE.start, MEMORY_SLICE.start + NUM_ACTIONS,
                      UNEXPLORED_DETECTOR_SLICE.start, OBSTACLE_DETECTOR_SLICE.start):
            perms[sym, block:block + NUM_ACTIONS] = block + inverse
    return perms


STATE_PERMS = _state_permutations()


def transform_states(states: np.ndarray, sym: int) -> np.ndarray:
    """(n, STATE_SIZE) states as they would be encoded in the world seen under `sym`."""
    _check_sym(sym)
    return states[:, STATE_PERMS[sym]]


def augment(states: np.ndarray, actions: np.ndarray | Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """All 8 symmetric copies: ((8n, STATE_SIZE) states, (8n,) actions), symmetry-major.

    Rows sym * n .. (sym + 1) * n - 1 hold transform_states(states, sym) and
    transform_actions(actions, sym).
    """
    states = np.asarray(states)
    actions = np.asarray(actions, dtype=np.int64).reshape(-1)
    n = states.shape[0]
    if actions.shape[0] != n:
        raise ValueError(f"augment: {n} states but {actions.shape[0]} actions")
    # One gather per symmetry written straight into its block: no (n, 8, 376) temporary
    # to transpose, which matters at 100k states (1.2 GB once augmented).
    big_states = np.empty((NUM_SYMMETRIES * n, STATE_SIZE), dtype=states.dtype)
    for sym in range(NUM_SYMMETRIES):
        np.take(states, STATE_PERMS[sym], axis=1, out=big_states[sym * n:(sym + 1) * n])
    big_actions = np.concatenate([transform_actions(actions, sym) for sym in range(NUM_SYMMETRIES)])
    return big_states, big_actions
