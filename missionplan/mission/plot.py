"""plan.png, and the map view it shares with flight.png.

`MapView` owns where a grid's cells and points land on a map axes and what makes the picture
placeable: with a `GridFrame`, metres east/north of the grid's origin corner (cells drawn by their
true corners, so a rotated grid lies rotated), a scale bar, a north arrow and the origin corner's
lat/lon; without one, plain cell units (column, row). `plan_figure` draws plan.png: the cells by
category (buildings, the clearance band, zones, unreachable targets by cause), the corrected
waypoint lines each drone flies, how coverage grew and what the planner decided; `draw_plan` saves it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only, no screen needed
import matplotlib.patheffects as patheffects  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.collections import QuadMesh  # noqa: E402
from matplotlib.colors import ListedColormap, to_rgb  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.font_manager import FontProperties  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.transforms import ScaledTranslation  # noqa: E402
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar  # noqa: E402

from missionplan.base.atomic import atomic_path  # noqa: E402
from missionplan.bridge.terminal_text import printable  # noqa: E402
from missionplan.geo.frame import GridFrame  # noqa: E402
from ..grid.planresult import PlanResult  # noqa: E402

TRACK_COLOURS = plt.get_cmap("tab10").colors  # drone k draws in TRACK_COLOURS[k % 10]

# Cell colours. Buildings dark; the clearance band (free, but no drone may enter it) a sand colour of
# its own, so the streets it closes stay visible; cells not to photograph light grey; zones pale tints.
BUILDING = (0.18, 0.18, 0.18)
BAND = "#cdb98f"
NOT_TARGET = (0.88, 0.88, 0.88)
OPEN_TARGET = (1.0, 1.0, 1.0)  # a target in no zone
# Unreachable targets by cause (a colour-blind safe set, away from the pale tints). A cause not listed
# here takes the next of EXTRA_CAUSE_COLOURS.
CAUSE_COLOURS = {"clearance band": "#ffb000", "unknown-height buildings": "#dc267f", "pocket": "#785ef0",
                 "unreachable": "#fe6100"}
EXTRA_CAUSE_COLOURS = ("#fe6100", "#648fff", "#8c510a", "#01665e")
HALO = [patheffects.Stroke(linewidth=2.6, foreground="white", alpha=0.8), patheffects.Normal()]
NORTH_ARROW_GID = "north-arrow"
ORIGIN_TEXT_GID = "origin-latlon"


def below_axes(ax: Axes) -> dict[str, Any]:
    """Legend keywords that hang it under an axes' tick labels and axis label (a fixed offset in points,
    whatever the axes' size)."""
    return {"loc": "upper left", "bbox_to_anchor": (0.0, 0.0),
            "bbox_transform": ax.transAxes + ScaledTranslation(0, -36 / 72, ax.figure.dpi_scale_trans)}


def zone_tint(colour: Any) -> tuple[float, float, float]:
    """The pale tint of a drone's colour that paints its zone."""
    return tuple(0.72 + 0.28 * np.asarray(to_rgb(colour)))  # type: ignore[return-value]


def nice_length(span: float) -> float:
    """A round scale-bar length (1, 2 or 5 times a power of ten) of about a fifth of `span`."""
    target = max(span, 1e-9) / 5.0
    power = 10.0 ** math.floor(math.log10(target))
    return max(step * power for step in (1.0, 2.0, 5.0) if step * power <= target)


class MapView:
    """Where a rows x cols grid's cells and points go on a map axes.

    With a frame: x, y are ground metres east and north of the grid's origin corner (the top-left
    corner of cell (0, 0)). UTM metres are divided by the frame's point scale, so a cell is exactly
    cell_m on the picture and the scale bar measures ground metres. Without a frame: x = column,
    y = row (row 0 at the top), in cells.
    """

    def __init__(self, frame: GridFrame | None, shape: tuple[int, int]) -> None:
        self.frame = frame
        self.shape = (int(shape[0]), int(shape[1]))
        self._corners: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def georeferenced(self) -> bool:
        return self.frame is not None

    def grid_xy(self, rows: Any, cols: Any) -> tuple[np.ndarray, np.ndarray]:
        """Float grid (row, col), integers = cell centres -> map (x, y)."""
        r, c = np.asarray(rows, dtype=float), np.asarray(cols, dtype=float)
        if self.frame is None:
            return c, r
        e, n = self.frame.grid_to_en(r, c)
        return (e - self.frame.origin_e) / self.frame.scale, (n - self.frame.origin_n) / self.frame.scale

    def latlon_xy(self, lat: Any, lon: Any) -> tuple[np.ndarray, np.ndarray]:
        """(lat, lon) degrees -> map (x, y); needs the frame."""
        if self.frame is None:
            raise ValueError("lat/lon points need a georeferenced map")
        r, c = self.frame.latlon_to_grid(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float))
        return self.grid_xy(r, c)

    def corners(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows + 1, cols + 1) map x, y of every cell corner (computed once: a million on a 1024 grid)."""
        if self._corners is None:
            rows, cols = self.shape
            r, c = np.meshgrid(np.arange(rows + 1) - 0.5, np.arange(cols + 1) - 0.5, indexing="ij")
            self._corners = self.grid_xy(r, c)
        return self._corners

    def cells(self, ax: Axes, codes: np.ndarray, colours: list[Any]) -> QuadMesh:
        """Paint every cell in colours[codes[cell]]: one quad mesh on the true corners, rasterized (a
        1024 x 1024 grid is one artist, not a million patches)."""
        x, y = self.corners()
        return ax.pcolormesh(x, y, codes, cmap=ListedColormap(colours), vmin=-0.5, vmax=len(colours) - 0.5,
                             shading="flat", rasterized=True, antialiased=False, linewidth=0, zorder=0)

    def decorate(self, ax: Axes) -> None:
        """Axis labels, equal aspect; with a frame also the scale bar, north arrow and origin corner."""
        ax.set_aspect("equal")
        ax.set_anchor("N")  # spare height of the layout box goes below, where the legend hangs
        if self.frame is None:
            ax.set_xlabel("column")
            ax.set_ylabel("row")
            if not ax.yaxis_inverted():
                ax.invert_yaxis()  # row 0 at the top, as the map file reads
            return
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        x, y = self.corners()
        span = float(max(x.max() - x.min(), y.max() - y.min()))
        length = nice_length(span)
        label = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
        bar = AnchoredSizeBar(ax.transData, length, label, loc="lower left", pad=0.35, borderpad=0.6, sep=3,
                              frameon=True, size_vertical=span / 250, color="black",
                              fontproperties=FontProperties(size=8))
        bar.patch.set_alpha(0.85)
        ax.add_artist(bar)
        # Straight up is grid north of the UTM zone; the few tenths of a degree of meridian convergence
        # between grid and true north are ignored (invisible at this scale).
        arrow = ax.annotate("N", xy=(0.955, 0.80), xytext=(0.955, 0.955), xycoords="axes fraction",
                            ha="center", va="center", fontsize=10, fontweight="bold",
                            arrowprops={"arrowstyle": "<|-", "color": "black", "lw": 1.6, "shrinkA": 7},
                            bbox={"boxstyle": "circle,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85})
        arrow.set_gid(NORTH_ARROW_GID)
        # The origin corner: the point (0, 0), marked and named, makes the picture placeable on the Earth.
        lat, lon = self.frame.corner_latlon()
        mark, = ax.plot([0.0], [0.0], marker="+", ms=11, mew=1.8, color="black", zorder=6, clip_on=False)
        mark.set_path_effects(HALO)
        rotation = f", grid turned {self.frame.rotation_deg:g}° clockwise" if self.frame.rotation_deg else ""
        text = ax.annotate(f"+ (0, 0): grid origin corner at {abs(lat):.6f}°{'N' if lat >= 0 else 'S'} "
                           f"{abs(lon):.6f}°{'E' if lon >= 0 else 'W'} (WGS84; UTM EPSG:{self.frame.utm_epsg}"
                           f"{rotation}); north up",
                           xy=(0.0, 1.0), xycoords="axes fraction", xytext=(0, 4), textcoords="offset points",
                           ha="left", va="bottom", fontsize=7.5, color="0.2", annotation_clip=False)
        text.set_gid(ORIGIN_TEXT_GID)


def _plan_codes(result: PlanResult, obstacle: np.ndarray, band: np.ndarray | None,
                causes: dict[str, np.ndarray], colours: list[Any]) -> tuple[np.ndarray, list[Any], list[Patch]]:
    """Category code per cell, the colour of each code, and the legend patches of the cells shown."""
    gmap, num = result.gmap, len(result.starts)
    palette: list[Any] = [OPEN_TARGET, NOT_TARGET, BUILDING, BAND]
    codes = np.zeros(gmap.shape, dtype=np.int16)
    free = ~obstacle
    codes[free & ~gmap.target] = 1
    tints = min(num, len(TRACK_COLOURS))
    palette += [zone_tint(colours[k]) for k in range(tints)]
    zone = result.zones.zone
    for k in range(num):
        codes[(zone == k) & free & gmap.target] = 4 + k % len(TRACK_COLOURS)
    legend: list[Patch] = []
    if band is not None and (band & free).any():
        codes[band & free] = 3
        legend.append(Patch(fc=BAND, ec="0.5", label=f"clearance band, no flying ({int((band & free).sum())} cells)"))
    codes[obstacle] = 2
    legend.insert(0, Patch(fc=BUILDING, ec="0.5", label="buildings / obstacles"))
    if (codes == 1).any():
        legend.append(Patch(fc=NOT_TARGET, ec="0.5", label="free, not to photograph"))
    extra = iter(EXTRA_CAUSE_COLOURS * (1 + len(causes)))
    for label, mask in causes.items():
        colour = CAUSE_COLOURS.get(label) or next(extra)
        palette.append(colour)
        mask = np.asarray(mask, dtype=bool)
        codes[mask] = len(palette) - 1
        name = "unreachable" if label == "unreachable" else f"unreachable: {label}"
        if mask.any():  # a cause with no cell is no news
            legend.append(Patch(fc=colour, ec="0.5", label=f"{name} ({int(mask.sum())})"))
    return codes, palette, legend


def plan_figure(result: PlanResult, sortie_starts: list[np.ndarray] | None = None, *,
                frame: GridFrame | None = None, paths_latlon: list[np.ndarray] | None = None,
                obstacle: np.ndarray | None = None, band: np.ndarray | None = None,
                unreachable_causes: dict[str, np.ndarray] | None = None,
                ground: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> Figure:
    """The plan.png figure (see draw_plan); the caller closes it."""
    gmap, run = result.gmap, result.run
    num = len(result.starts)
    colours = [TRACK_COLOURS[k % len(TRACK_COLOURS)] for k in range(num)]
    view = MapView(frame, gmap.shape)
    if obstacle is None:  # the planner's map counts the band as obstacle: give the band back its own colour
        obstacle = gmap.obstacle & ~band if band is not None else gmap.obstacle
    if unreachable_causes is None:
        mask = np.zeros(gmap.shape, dtype=bool)
        if len(result.unreachable):
            mask[tuple(np.asarray(result.unreachable).T)] = True
        unreachable_causes = {"unreachable": mask}

    x, y = view.corners()
    aspect = float(np.ptp(y) / max(np.ptp(x), 1e-9))
    map_width = 8.0
    height = min(max(6.5, map_width * aspect + 3.2), 16.0)  # room for the title, labels and legend
    fig = plt.figure(figsize=(map_width + 4.5, height), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=[2.2, 1])
    ax_map = fig.add_subplot(grid[:, 0])
    ax_cov = fig.add_subplot(grid[0, 1])
    ax_dec = fig.add_subplot(grid[1, 1])

    codes, palette, cell_legend = _plan_codes(result, obstacle, band, unreachable_causes, colours)
    view.cells(ax_map, codes, palette)
    if ground is not None and frame is not None:
        _contours(ax_map, view, frame, gmap.shape, ground)
    flown = paths_latlon is not None and frame is not None
    for k in range(num):
        uploaded = flown and k < len(paths_latlon)  # type: ignore[arg-type]
        if uploaded:  # the corrected waypoint lines, as uploaded: what the drones fly
            lat, lon = np.asarray(paths_latlon[k], dtype=float).reshape(-1, 2).T  # type: ignore[index]
            px, py = view.latlon_xy(lat, lon)
        else:  # no georeferenced missions: the grid path is all there is
            px, py = view.grid_xy(run.paths[k][:, 0], run.paths[k][:, 1])
        line, = ax_map.plot(px, py, color=colours[k], lw=1.2, label=f"UAV {k + 1}", zorder=3,
                            marker="." if uploaded else None, ms=2.5)
        line.set_gid(f"path-uav{k + 1}")
        line.set_path_effects(HALO)
        sx, sy = view.grid_xy(*np.asarray(result.starts[k], dtype=float))
        ax_map.plot(sx, sy, marker="^", ms=9, color=colours[k], mec="black", zorder=5, ls="none")
        for j, (r, c) in enumerate((sortie_starts[k] if sortie_starts else [])[1:], start=2):
            jx, jy = view.grid_xy(r, c)
            ax_map.plot(jx, jy, marker="o", ms=10, color="white", mec=colours[k], mew=2, zorder=5)
            ax_map.annotate(f"{j}", (float(jx), float(jy)), ha="center", va="center", fontsize=6, color="black",
                            zorder=6)
    view.decorate(ax_map)
    status = "100 % covered" if run.success else f"FAILED: {run.failure}"
    m = run.metrics
    ax_map.set_title(f"{printable(gmap.name)}: {num} UAVs, policy {result.policy}, zones {result.zones.method} - "
                     f"{status}\n"
                     f"MMN {m['MMN']:.1f}  TE {m['TE']:.1f} %  MNT {m['MNT']:.2f} %  makespan {m['makespan']}",
                     fontsize=10, pad=16 if frame is not None else 6)  # room for the origin line
    if gmap.meta.get("credit"):  # the map data's licence asks for it wherever a picture of it is shown
        fig.text(0.01, 0.003, gmap.meta["credit"], fontsize=6.5, color="0.35", va="bottom")
    what = "waypoint lines as uploaded" if flown else "grid paths"
    drone_handles: list[Any] = [Line2D([], [], color=colours[k], lw=1.6, label=f"UAV {k + 1}")
                                for k in range(min(num, len(TRACK_COLOURS)))]
    if num > len(TRACK_COLOURS):
        drone_handles.append(Line2D([], [], color="none", label="UAV k: colour of UAV (k-1) mod 10 + 1"))
    drone_handles.append(Line2D([], [], color="0.3", marker="^", mec="black", ls="none", label="launch point"))
    if sortie_starts and any(len(s) > 1 for s in sortie_starts):
        drone_handles.append(Line2D([], [], color="white", marker="o", mec="0.3", mew=2, ls="none",
                                    label="sortie start (number)"))
    zone_patch = Patch(fc=zone_tint(colours[0]) if num else OPEN_TARGET, ec="0.5", label="zone (pale tint)")
    ax_map.legend(handles=drone_handles + [zone_patch] + cell_legend, title=f"{what}; cells",
                  title_fontsize=7.5, ncol=3, fontsize=7, framealpha=0.9, **below_axes(ax_map))

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
    return fig


def _contours(ax: Any, view: MapView, frame: GridFrame, shape: tuple[int, int],
              ground: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> None:
    """The ground of a plan over a DEM, as labelled contour lines (metres above sea level) under the tracks."""
    rows, cols = np.meshgrid(np.arange(shape[0], dtype=float), np.arange(shape[1], dtype=float), indexing="ij")
    heights = ground(*frame.grid_to_latlon(rows, cols))
    if not np.isfinite(heights).any() or np.nanmax(heights) - np.nanmin(heights) < 1.0:
        return
    x, y = view.grid_xy(rows, cols)
    # Light on the dark buildings and on the zones' pale tints alike; labelled in metres above sea level.
    lines = ax.contour(x, y, heights, levels=8, colors="#d9a441", linewidths=0.8, alpha=0.95, zorder=2)
    ax.clabel(lines, fontsize=6.5, fmt="%.0f m")
    lines.set_label("ground (m above sea level)")


def draw_plan(result: PlanResult, path: str | os.PathLike[str], sortie_starts: list[np.ndarray] | None = None, *,
              frame: GridFrame | None = None, paths_latlon: list[np.ndarray] | None = None,
              obstacle: np.ndarray | None = None, band: np.ndarray | None = None,
              unreachable_causes: dict[str, np.ndarray] | None = None,
              ground: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> None:
    """Write plan.png: the map (see MapView) with zones, the waypoint lines flown, launch points and
    unreachable targets by cause; coverage growth; the planner's decisions.

    `sortie_starts`: per drone, (J, 2) grid points where each battery sortie's survey starts; sorties 2
    and later are marked with their number. `paths_latlon`: per drone, (n, 2) lat/lon of the uploaded
    missions' waypoints in flying order (drawn instead of the grid path; needs `frame`). `obstacle`: the
    buildings (default: the planner's obstacles without `band`); `band`: the clearance band's free cells;
    `unreachable_causes`: cause -> cell mask (default: every unreachable target as "unreachable"); `ground`: a
    plan over a DEM, drawn as contour lines."""
    fig = plan_figure(result, sortie_starts, frame=frame, paths_latlon=paths_latlon, obstacle=obstacle, band=band,
                      unreachable_causes=unreachable_causes, ground=ground)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight", pad_inches=0.15)  # legend hangs below
    finally:
        plt.close(fig)
