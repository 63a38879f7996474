"""An independent checker of a plan: replays report.json paths on its grid.

Written without importing the planner, so a bug there cannot hide here. It checks the
rules of SPEC section 2 from the per-step paths alone and recomputes coverage with the
9 x 9 footprint.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import ndimage


def replay(report: dict[str, Any]) -> dict[str, Any]:
    grid = np.array([list(row) for row in report["grid"]])
    obstacle = grid == "#"
    target = grid == "."
    paths = np.array(report["paths"], dtype=int)  # (K, T+1, 2)
    num, length, _ = paths.shape
    rows, cols = grid.shape
    problems: list[str] = []

    inside = (paths[..., 0] >= 0) & (paths[..., 0] < rows) & (paths[..., 1] >= 0) & (paths[..., 1] < cols)
    if not inside.all():
        problems.append("a drone left the map")
        return {"problems": problems}
    if obstacle[paths[..., 0], paths[..., 1]].any():
        problems.append("a drone entered an obstacle cell")
    steps = np.abs(np.diff(paths, axis=1)).sum(axis=2)
    if (steps > 1).any():
        problems.append("a drone jumped more than one cell in a step")
    for t in range(length):
        cells = {tuple(p) for p in paths[:, t]}
        if len(cells) < num:
            problems.append(f"two drones share a cell at step {t}")
            break
    for t in range(1, length):
        before, after = paths[:, t - 1], paths[:, t]
        for i in range(num):
            for j in range(i + 1, num):
                if (before[i] == after[j]).all() and (before[j] == after[i]).all() and (before[i] != before[j]).any():
                    problems.append(f"drones {i + 1} and {j + 1} swap cells at step {t}")

    # Reachable targets: 4-connected to a launch cell through free cells.
    labels, _ = ndimage.label(~obstacle)
    starts = paths[:, 0]
    reach = target & np.isin(labels, [labels[r, c] for r, c in starts])
    photographed = np.zeros_like(target)
    for r, c in paths.reshape(-1, 2):
        photographed[max(r - 4, 0): r + 5, max(c - 4, 0): c + 5] = True
    covered = int((photographed & reach).sum())
    moves = (steps == 1).sum(axis=1)
    return {
        "problems": problems,
        "reachable": int(reach.sum()),
        "unreachable": int((target & ~reach).sum()),
        "coverage": 100.0 * covered / max(int(reach.sum()), 1),
        "mmn": float(moves.mean()),
        "makespan": int(moves.max()),
    }
