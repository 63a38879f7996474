"""How wide a map's streets are, in cells: what the benches print beside a city's figures.

A street cell on a street's ridge (no 4-neighbour farther from a wall) lies d cells from the
nearest wall by taxicab distance, so the street there is 2d - 1 cells wide (an even width w
reads as w - 1: its two middle cells are both ridge cells at w / 2). The map's edge is not a
wall. Crossings, open squares and parks count as wide streets; the median over all ridge cells
says what a drone meets most often, the 90th percentile how wide the open places get.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def ridge_widths(free: np.ndarray) -> np.ndarray:
    """Street width (cells) at every ridge cell of `free`, flat."""
    free = np.asarray(free, dtype=bool)
    if not free.any() or free.all():
        return np.zeros(0, dtype=np.int64)
    to_wall = ndimage.distance_transform_cdt(free, metric="taxicab")  # the array's edge is no background
    neighbours_max = ndimage.maximum_filter(to_wall, footprint=np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], bool),
                                            mode="nearest")
    ridge = free & (to_wall >= neighbours_max)
    return (2 * to_wall[ridge] - 1).astype(np.int64)


def street_width_summary(free: np.ndarray) -> str:
    """`median/p90` street width in cells, e.g. "5/11"; "-" for a map with no wall or no street."""
    widths = ridge_widths(free)
    if not widths.size:
        return "-"
    return f"{int(np.median(widths))}/{int(np.percentile(widths, 90))}"
