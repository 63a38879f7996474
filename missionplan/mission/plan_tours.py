"""report.json `tours`: how a whole fleet on open ground got its block tours (grid/fleet_blocks.py), and at what cost.

A block of the plan record of its own, written only when the fleet flies block tours: which solver made them,
where its block grid lies, how many blocks, each drone's planned tour in moves (from its launch cell to its last
block's centre; the flight may end sooner, when a block's targets are photographed before its centre) and the CPU
seconds it took. An older missionplan reading the plan ignores the block; the plan it describes flies as any other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..grid.block_tours import FleetBlocks
from ..maps.gridmap import Cell

# Our own solver: OR-Tools' routing made longer tours at four times the time, LKH (elkai) shorter ones but is licensed
# for non-commercial use only (docs/planner.md "A whole fleet on open ground").
SOLVER = ("missionplan block tours: 8 snakes and 24 Warnsdorff walks per drone, 2-opt and Or-opt; "
          "split balanced on the tours, then LS-MCPP-style hand-overs")


@dataclass(frozen=True)
class TourPlan:
    """report.json `tours`."""

    solver: str
    grid_origin: Cell  # a corner of the block grid
    blocks: int  # blocks holding a target, each one drone's
    moves: tuple[int, ...]  # each drone's planned tour, in moves
    cpu_s: float  # the split and the tours

    @classmethod
    def of(cls, fleet: FleetBlocks) -> TourPlan:
        return cls(SOLVER, (int(fleet.origin[0]), int(fleet.origin[1])), sum(len(tour) for tour in fleet.tours),
                   tuple(int(m) for m in fleet.moves), round(fleet.cpu_s, 3))

    def to_json(self) -> dict[str, Any]:
        return {"solver": self.solver, "grid_origin": list(self.grid_origin), "blocks": self.blocks,
                "moves": list(self.moves), "cpu_s": self.cpu_s}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> TourPlan:
        row, col = (int(v) for v in doc["grid_origin"])
        return cls(str(doc["solver"]), (row, col), int(doc["blocks"]), tuple(int(m) for m in doc["moves"]),
                   float(doc["cpu_s"]))

    def summary(self) -> str:
        """`block tours: 821 blocks, each drone's tour 1237-1255 moves as planned` (no time: what plan prints is
        compared run to run; report.json has it)."""
        return (f"block tours: {self.blocks} blocks, each drone's tour {min(self.moves, default=0)}-"
                f"{max(self.moves, default=0)} moves as planned")
