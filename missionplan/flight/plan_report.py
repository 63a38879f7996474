"""A plan folder's plan record as the flight side reads it: the frame, the grid, the targets to photograph.

The judge (flight_report), the survey ledger, the re-planners and `status` all read a plan the same way
(mission.plan_record.read_plan_record); this module is what they ask of it, and the one photo rule they
share (SLACK_CELLS). Nothing here flies or judges.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import Georeference

from ..maps.gridmap import GridMap, MapError
from ..mission.plan_record import PlanRecord

# How much of a cell's side may fall outside the photo that counts for it: a quarter cell, the
# waypoint acceptance radius the missions give the autopilot (a vehicle may turn that early), which
# also absorbs the 1e-7 degree (about 1 cm) resolution of reported positions.
SLACK_CELLS = 0.25


def georeference_of(record: PlanRecord) -> Georeference:
    """The plan's georeference; MapError for a plan of a map without origin (nothing was flown)."""
    if record.georeference is None:
        raise MapError(f"plan {record.map}: no georeference (a map without origin): nothing to fly or survey")
    return record.georeference


def frame_of(record: PlanRecord) -> GridFrame:
    """The plan's georeference (report.json `georeference`) on its grid."""
    return georeference_of(record).frame


def trigger_distance_m(record: PlanRecord) -> float:
    """The distance the plan takes photos at along a track (0 when it says none)."""
    return float(georeference_of(record).trigger_distance_m or 0.0)


def asked_overlaps(record: PlanRecord) -> tuple[float | None, float | None]:
    """(front, side) overlap the plan asked, as fractions (None: not asked): the front overlap of its mission
    settings (else what its trigger distance and footprint give), the side overlap its report recorded."""
    front: float | None = None
    if record.settings is not None:
        front = float(record.settings.mission.overlap)
    elif trigger_distance_m(record) > 0:
        front = 1.0 - trigger_distance_m(record) / georeference_of(record).footprint_m
    recorded = record.coverage.overlap if record.coverage is not None else None
    return front, (recorded.asked_side if recorded is not None else None)


def planned_grid(record: PlanRecord) -> GridMap:
    """The grid the plan was made on (report.json `grid`)."""
    return GridMap.from_rows(record.map, list(record.grid))


def target_cells(record: PlanRecord) -> np.ndarray:
    """(n, 2) cells the plan had to photograph: the map's targets that are reachable."""
    target = planned_grid(record).target.copy()
    unreachable = np.asarray(record.unreachable_cells, dtype=np.int64).reshape(-1, 2)
    target[unreachable[:, 0], unreachable[:, 1]] = False
    return np.argwhere(target)


def to_grid_m(frame: GridFrame, lat: Any, lon: Any) -> np.ndarray:
    """lat/lon -> (n, 2) metres in the grid frame (row axis, column axis; cell centres at integers * cell_m)."""
    lat, lon = np.atleast_1d(np.asarray(lat, dtype=float)), np.atleast_1d(np.asarray(lon, dtype=float))
    if len(lat) == 0:
        return np.zeros((0, 2))
    r, c = frame.latlon_to_grid(lat, lon)
    return np.column_stack([np.atleast_1d(r), np.atleast_1d(c)]) * frame.cell_m


def missing_map(record: PlanRecord, missing: np.ndarray, launch: list[tuple[int, int]],
                suffix: str = "rest") -> GridMap:
    """A plan's grid with only `missing` as targets and the given launch cells, on the plan's georeference:
    what `replan` and fly's live re-task plan."""
    base = planned_grid(record)
    target = np.zeros(base.shape, dtype=bool)
    target[missing[:, 0], missing[:, 1]] = True
    return GridMap(f"{base.name}-{suffix}", base.obstacle, target, launch, georef=georeference_of(record),
                   roof=base.roof)
