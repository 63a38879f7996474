"""plan.png: zones, every drone's track in its own colour, and how coverage grew."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")  # files only, no screen needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402

from bridge.atomic import atomic_path  # noqa: E402
from ..grid.planresult import PlanResult  # noqa: E402

TRACK_COLOURS = plt.get_cmap("tab10").colors


def draw_plan(result: PlanResult, path: str | os.PathLike[str], sortie_starts: list[np.ndarray] | None = None) -> None:
    """`sortie_starts`: per drone, (J, 2) grid points where each battery sortie's survey starts; sorties 2
    and later are marked with their number."""
    gmap, run = result.gmap, result.run
    rows, cols = gmap.shape
    num = len(result.starts)
    colours = [TRACK_COLOURS[k % len(TRACK_COLOURS)] for k in range(num)]
    map_width = 8.0
    height = max(5.5, map_width * rows / cols + 1.2)  # room for the two-line title
    fig = plt.figure(figsize=(map_width + 4.5, height), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=[2.2, 1])
    ax_map = fig.add_subplot(grid[:, 0])
    ax_cov = fig.add_subplot(grid[0, 1])
    ax_dec = fig.add_subplot(grid[1, 1])

    # Background: obstacles dark, non-target free cells light grey, zones as pale tints.
    background = np.ones((rows, cols, 3))
    background[~gmap.target & gmap.free] = 0.88
    for k in range(num):
        tint = 0.72 + 0.28 * np.array(colours[k])
        background[result.zones.zone == k] = tint
    background[gmap.obstacle] = 0.18
    if len(result.unreachable):
        background[tuple(result.unreachable.T)] = (0.55, 0.55, 0.55)
    ax_map.imshow(background, interpolation="nearest")
    for k in range(num):
        track = run.paths[k]
        ax_map.plot(track[:, 1], track[:, 0], color=colours[k], lw=1.1, label=f"UAV {k + 1}")
        ax_map.plot(*track[0][::-1], marker="^", ms=8, color=colours[k], mec="black")
        for j, (r, c) in enumerate((sortie_starts[k] if sortie_starts else [])[1:], start=2):
            ax_map.plot(c, r, marker="o", ms=9, color="white", mec=colours[k], mew=2)
            ax_map.annotate(f"{j}", (c, r), ha="center", va="center", fontsize=6, color="black")
    status = "100 % covered" if run.success else f"FAILED: {run.failure}"
    m = run.metrics
    ax_map.set_title(f"{gmap.name}: {num} UAVs, policy {result.policy}, zones {result.zones.method} - {status}\n"
                     f"MMN {m['MMN']:.1f}  TE {m['TE']:.1f} %  MNT {m['MNT']:.2f} %  makespan {m['makespan']}",
                     fontsize=10)
    ax_map.legend(loc="upper right", fontsize=7, framealpha=0.8)
    ax_map.set_xticks([])
    ax_map.set_yticks([])

    explored = np.cumsum(run.new_cells.sum(axis=0)) + result.world.initial_new_cells.sum()
    coverage = 100.0 * explored / max(result.world.num_targets, 1)
    ax_cov.plot(np.arange(1, len(coverage) + 1), coverage, color="black")
    ax_cov.axhspan(40, 70, color="tab:orange", alpha=0.15, label="steady state (40-70 %)")
    ax_cov.set_ylabel("coverage %")
    ax_cov.set_ylim(0, 101)
    ax_cov.legend(fontsize=7, loc="lower right")
    ax_cov.grid(alpha=0.3)

    steps = np.arange(1, len(run.policy_decisions) + 1)
    series = [run.policy_decisions, run.pathfinder_decisions, run.idle_decisions]
    window = max(1, len(steps) // 100)  # long runs: a moving mean keeps the plot readable
    if window > 1:
        kernel = np.ones(window) / window
        series = [np.convolve(s.astype(float), kernel, mode="same") for s in series]
    ax_dec.stackplot(steps, *series,
                     labels=[f"policy ({result.policy})", "A* / Explorative A*", "parked (done)"],
                     colors=["tab:orange", "tab:blue", "0.8"], step="pre")
    ax_dec.set_xlabel("step")
    ax_dec.set_ylabel("drones" + (f" (mean of {window} steps)" if window > 1 else ""))
    ax_dec.yaxis.get_major_locator().set_params(integer=True)
    ax_dec.legend(fontsize=7, loc="lower left")
    ax_dec.set_ylim(0, num)

    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
