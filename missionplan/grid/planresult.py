"""`PlanResult`: what one grid planning run produced (map, starts, zones, world, the planner's run).

Its own module so that the mission files, the report and the picture can read a plan without
importing `pipeline`, the entry point that also builds the neural policy (it sits above them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..maps.gridmap import Cell, GridMap
from .planner import PlanRun
from .world import CoverageWorld
from .zones import Zones


@dataclass
class PlanResult:
    gmap: GridMap
    starts: list[Cell]
    policy: str
    zones: Zones
    world: CoverageWorld
    run: PlanRun
    zone_seconds: float

    @property
    def unreachable(self) -> np.ndarray:
        """(n, 2) target cells no drone can reach (set to explored and reported)."""
        return self.world.unreachable_cells
