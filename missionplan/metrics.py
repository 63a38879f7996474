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
step is not kept afterwards.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

STEADY_LOW, STEADY_HIGH = 0.40, 0.70


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
    upper = np.triu_indices(len(positions), k=1)
    return float(dist[upper].mean())


def mean_distance_to_nearest(cells: np.ndarray, positions: np.ndarray) -> float:
    """Mean over `cells` of the Euclidean distance to the nearest position."""
    cells = np.asarray(cells, dtype=np.float32).reshape(-1, 2)
    if len(cells) == 0:
        return 0.0
    positions = np.asarray(positions, dtype=np.float32)
    best = np.full(len(cells), np.inf, dtype=np.float32)
    for p in positions:  # K is small; keeps memory at one vector per drone
        np.minimum(best, np.hypot(cells[:, 0] - p[0], cells[:, 1] - p[1]), out=best)
    return float(best.mean())


@dataclass
class SteadyStateSampler:
    """Collects MUD and MDU at every step whose coverage lies in [40 %, 70 %]."""

    mud: list[float] = field(default_factory=list)
    mdu: list[float] = field(default_factory=list)

    def observe(self, coverage: float, positions: np.ndarray, unexplored: np.ndarray) -> None:
        if STEADY_LOW <= coverage <= STEADY_HIGH:
            self.mud.append(mean_pairwise_distance(positions))
            self.mdu.append(mean_distance_to_nearest(np.argwhere(unexplored), positions))


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
    te = 100.0 * float(new_cells.sum()) / 9.0 / denom if denom else 0.0
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
