"""A plan folder's report.json as the flight side reads it: the frame, the grid, the targets to photograph.

The judge (flight_report), the survey ledger, the re-planners and `status` all read a plan the same way;
this module is that one way, and the one photo rule they share (SLACK_CELLS). Nothing here flies or judges.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from missionplan.geo.frame import GridFrame

from ..maps.gridmap import GridMap

# How much of a cell's side may fall outside the photo that counts for it: a quarter cell, the
# waypoint acceptance radius the missions give the autopilot (a vehicle may turn that early), which
# also absorbs the 1e-7 degree (about 1 cm) resolution of reported positions.
SLACK_CELLS = 0.25


def frame_of(report: dict[str, Any]) -> GridFrame:
    """The plan's georeference (report.json `georeference`) on its grid."""
    grid = report["grid"]
    return GridFrame.from_meta({k: str(v) for k, v in report["georeference"].items()}, len(grid), len(grid[0]))


def planned_grid(report: dict[str, Any]) -> GridMap:
    """The grid the plan was made on (report.json `grid`)."""
    return GridMap.from_rows(str(report.get("map", "plan")), report["grid"])


def target_cells(report: dict[str, Any]) -> np.ndarray:
    """(n, 2) cells the plan had to photograph: the map's targets that are reachable."""
    target = planned_grid(report).target.copy()
    unreachable = np.asarray(report.get("unreachable_cells") or [], dtype=np.int64).reshape(-1, 2)
    target[unreachable[:, 0], unreachable[:, 1]] = False
    return np.argwhere(target)


def to_grid_m(frame: GridFrame, lat: Any, lon: Any) -> np.ndarray:
    """lat/lon -> (n, 2) metres in the grid frame (row axis, column axis; cell centres at integers * cell_m)."""
    lat, lon = np.atleast_1d(np.asarray(lat, dtype=float)), np.atleast_1d(np.asarray(lon, dtype=float))
    if len(lat) == 0:
        return np.zeros((0, 2))
    r, c = frame.latlon_to_grid(lat, lon)
    return np.column_stack([np.atleast_1d(r), np.atleast_1d(c)]) * frame.cell_m


def missing_map(report: dict[str, Any], missing: np.ndarray, launch: list[tuple[int, int]],
                suffix: str = "rest") -> GridMap:
    """A plan's grid (report.json) with only `missing` as targets and the given launch cells, its meta from
    the georeference: what `replan` and fly's live re-task plan."""
    base = planned_grid(report)
    target = np.zeros(base.shape, dtype=bool)
    target[missing[:, 0], missing[:, 1]] = True
    meta = {k: str(v) for k, v in report["georeference"].items()}
    return GridMap(f"{base.name}-{suffix}", base.obstacle, target, launch, meta)
