"""flight.png: what a flown fleet photographed, on the map, and how long each drone flew.

The map is plan.png's map view (mission.plot.MapView): metres east/north of the grid's origin
corner with a scale bar, north arrow and the origin's lat/lon. On it: buildings, the targets the
photos covered (green) and missed (red), the plan's unreachable targets, the tracks each drone
really flew (from its telemetry) in its colour, and, faint, the waypoint lines it was given. Beside
it, the flight time per drone, and, for a plan over a DEM, each drone's height above the ground along its
survey against the planned height and its tolerance band (above_ground.py).
flight_report.judge decides what was covered; this module only draws.
matplotlib is imported when a picture is drawn, not when flight_report is imported.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np

from missionplan.base.atomic import atomic_path

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from missionplan.geo.frame import GridFrame

    from ..maps.gridmap import GridMap

BUILDING = (0.25, 0.25, 0.25)
FREE = (1.0, 1.0, 1.0)
UNJUDGED_TARGET = (0.80, 0.80, 0.80)  # a target outside the reachable set: nobody was sent there
COVERED = (0.62, 0.87, 0.62)
MISSED = (0.95, 0.35, 0.35)
# sysid -> (seconds of the vehicle's clock since its survey began, height above the ground m, planned m, tolerance m)
HeightProfiles = dict[int, tuple[np.ndarray, np.ndarray, float, float]]


def flight_figure(gmap: GridMap, frame: GridFrame | None, targets: np.ndarray, covered: np.ndarray,
                  tracks_m: dict[int, np.ndarray], flight_s: dict[int, float], coverage_pct: float, *,
                  paths_latlon: list[np.ndarray] | None = None, heights: HeightProfiles | None = None) -> Figure:
    """The flight.png figure (see draw_flight); `gmap`: the grid the plan was made on (plan_report.planned_grid);
    the caller closes it."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from ..mission.plot import HALO, TRACK_COLOURS, MapView, below_axes

    view = MapView(frame, gmap.shape)
    targets = np.asarray(targets, dtype=np.int64).reshape(-1, 2)
    covered = np.asarray(covered, dtype=bool).reshape(-1)
    codes = np.zeros(gmap.shape, dtype=np.int8)
    codes[gmap.obstacle] = 1
    codes[gmap.target] = 2  # targets outside the reachable set stay grey
    codes[targets[covered, 0], targets[covered, 1]] = 3
    codes[targets[~covered, 0], targets[~covered, 1]] = 4

    x, y = view.corners()
    aspect = float(np.ptp(y) / max(np.ptp(x), 1e-9))
    height = min(max(6.0, 8.5 * aspect + 3.2), 16.0)
    if heights is None:
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(12.5, height), gridspec_kw={"width_ratios": [4, 1]},
                                     constrained_layout=True)
    else:  # a plan over a DEM: the heights above the ground under the flight times
        fig, axes = plt.subplot_mosaic([["map", "time"], ["map", "heights"]], figsize=(14.0, height),
                                       width_ratios=[4, 1.5], constrained_layout=True)
        ax, bx = axes["map"], axes["time"]
    view.cells(ax, codes, [FREE, BUILDING, UNJUDGED_TARGET, COVERED, MISSED])
    ids = sorted(flight_s) if flight_s else sorted(tracks_m)
    colour_of = {uid: TRACK_COLOURS[k % len(TRACK_COLOURS)] for k, uid in enumerate(sorted(set(ids) | set(tracks_m)))}
    if paths_latlon is not None and frame is not None:  # the plan, faint: where a track strayed from it shows
        for k, latlon in enumerate(paths_latlon):
            lat, lon = np.asarray(latlon, dtype=float).reshape(-1, 2).T
            px, py = view.latlon_xy(lat, lon)
            ax.plot(px, py, color=TRACK_COLOURS[k % len(TRACK_COLOURS)], lw=0.8, ls="--", alpha=0.45, zorder=2,
                    gid=f"planned-{k + 1}")
    for uid, pts in sorted(tracks_m.items()):
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        if not len(pts):
            continue
        cell = frame.cell_m if frame is not None else 1.0
        tx, ty = view.grid_xy(pts[:, 0] / cell, pts[:, 1] / cell)  # tracks_m: metres along the grid's row, column
        line, = ax.plot(tx, ty, "-", lw=1.1, color=colour_of[uid], label=f"uav{uid}", zorder=3, gid=f"track-uav{uid}")
        line.set_path_effects(HALO)
        ax.plot(tx[0], ty[0], "o", ms=5, color=colour_of[uid], mec="black", zorder=4)
    view.decorate(ax)
    ax.set_title(f"flown coverage {coverage_pct:.2f} % (green photographed, red missed)",
                 pad=16 if frame is not None else 6)
    handles: list[Any] = [Line2D([], [], color=colour_of[uid], lw=1.6, label=f"uav{uid} flown")
                          for uid in sorted(tracks_m) if len(tracks_m[uid])][:len(TRACK_COLOURS)]
    if handles:
        handles.append(Line2D([], [], color="0.3", marker="o", mec="black", ls="none", label="first sample"))
    if paths_latlon is not None and frame is not None:
        handles.append(Line2D([], [], color="0.3", lw=0.8, ls="--", alpha=0.6, label="planned waypoint lines"))
    n_covered = int(covered.sum())
    handles += [Patch(fc=COVERED, ec="0.5", label=f"photographed target ({n_covered})"),
                Patch(fc=MISSED, ec="0.5", label=f"missed target ({len(covered) - n_covered})"),
                Patch(fc=UNJUDGED_TARGET, ec="0.5", label="unreachable target (not judged)"),
                Patch(fc=BUILDING, ec="0.5", label="buildings / obstacles")]
    ax.legend(handles=handles, ncol=3, fontsize=7, framealpha=0.9, **below_axes(ax))
    bx.bar([f"uav{i}" for i in ids], [flight_s.get(i, 0.0) for i in ids],
           color=[colour_of[i] for i in ids])
    bx.set_ylabel("flight time (s, simulated)")
    bx.set_title("flight time")
    bx.tick_params(axis="x", labelrotation=45, labelsize=8)
    if heights is not None:
        _draw_heights(axes["heights"], heights, colour_of)
    return fig


def _draw_heights(hx: Any, heights: HeightProfiles, colour_of: dict[int, Any]) -> None:
    """Each drone's height above the ground along its survey, with its planned height and tolerance band."""
    for uid, (seconds, above, planned, tolerance) in sorted(heights.items()):
        colour = colour_of.get(uid, "0.3")
        if len(seconds):
            hx.axhspan(planned - tolerance, planned + tolerance, color=colour, alpha=0.12, lw=0)
            hx.plot(seconds, above, "-", lw=0.9, color=colour, label=f"uav{uid}", gid=f"height-uav{uid}")
        hx.axhline(planned, color=colour, lw=0.6, ls="--")
    hx.set_xlabel("s of its survey (vehicle clock)", fontsize=8)
    hx.set_ylabel("height above the ground (m)", fontsize=8)
    hx.set_title("height above the ground (band: tolerance)", fontsize=9)
    hx.tick_params(labelsize=7)


def draw_flight(path: str | os.PathLike[str], gmap: GridMap, frame: GridFrame | None, targets: np.ndarray,
                covered: np.ndarray, tracks_m: dict[int, np.ndarray], flight_s: dict[int, float],
                coverage_pct: float, *, paths_latlon: list[np.ndarray] | None = None,
                heights: HeightProfiles | None = None) -> None:
    """Write flight.png of the plan's grid `gmap`. `targets` (n, 2) the judged target cells, `covered` (n,) which a photo covered;
    `tracks_m`: sysid -> (m, 2) recorded positions in metres along the grid's row and column axes
    (plan_report.to_grid_m); `flight_s`: sysid -> seconds flown; `paths_latlon`: per drone (launch
    order), the planned waypoints' lat/lon, drawn faint; `heights`: a plan over a DEM's heights above the
    ground per drone (HeightProfiles), drawn in a panel of their own."""
    import matplotlib.pyplot as plt

    fig = flight_figure(gmap, frame, targets, covered, tracks_m, flight_s, coverage_pct, paths_latlon=paths_latlon,
                        heights=heights)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight", pad_inches=0.15)  # legend hangs below
    finally:
        plt.close(fig)
