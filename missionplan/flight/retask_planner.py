"""What fly --replan asks of a re-task planner, and what it gets back: the contract between flying and planning.

The flight side (live_replan.Retasker) holds the survivors, hands the planner where they are and the
photos confirmed so far, and puts each survivor's share of the result on its vehicle. The planner is the
planning side's (missionplan.planning.retask.retask_planner, handed over by the command line): this layer plans
nothing itself. A planner that will not re-task raises RetaskPlanningError with the reason, which the
crew hears; the survivors then fly on with the missions they have.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from missionplan.bridge.formats.mission_items import Mission

from ..mission.plan_record import PlanRecord


@dataclass(frozen=True)
class Survivor:
    """A drone still flying its mission when the re-task is planned, held where it hovers."""

    sysid: int
    lat: float
    lon: float
    up_m: float
    home: tuple[float, float]  # where its RTL goes: its launch point
    flown_s: float  # seconds of flight so far (vehicle time), against its endurance


@dataclass(frozen=True)
class RetaskPlan:
    """The survivors' new missions, proven for endurance, separation and fences before any upload."""

    missions: dict[int, Mission]  # sysid -> the new mission (seq order as in a .plan: takeoff first)
    fences: dict[int, Mission]  # sysid -> its new inclusion fence
    resume_index: dict[int, int]  # sysid -> index in missions[sysid].items to continue at (after the take-off)
    flight_s: dict[int, float]  # sysid -> planned seconds of the new flight, from now to landing
    photos: dict[int, int]  # sysid -> photos the new mission plans
    targets_left: int  # target cells no confirmed photo had covered when it was planned
    separation_m: float | None  # closest approach of the new tracks (None with one survivor)
    plan_s: float  # seconds spent planning

    def request(self, sysid: int) -> RetaskRequest:
        """Survivor `sysid`'s share, as its follower puts it on its vehicle."""
        return RetaskRequest(self.missions[sysid], self.fences.get(sysid), self.resume_index[sysid],
                             self.photos[sysid])


@dataclass(frozen=True)
class RetaskRequest:
    """One survivor's new mission (its RetaskPlan share), for its follower to put on its vehicle."""

    mission: Mission
    fence: Mission | None  # inclusion fence, or None
    resume_index: int  # index in mission.items to continue at
    photos: int  # photos the new mission plans


class RetaskPlanningError(Exception):
    """The planner will not re-task (a check failed, or the plan could not be made); the message says why."""


class RetaskPlanner(Protocol):
    """Plans what is left for the survivors, from where they are: None when nothing is left to photograph;
    RetaskPlanningError when it will not. plan_dir: the plan folder; record: its plan record as this flight
    is judged (fly.flight_view); photos_latlon: (n, 2) lat, lon of every photo confirmed in this flight."""

    def __call__(self, plan_dir: Path, record: PlanRecord, survivors: Sequence[Survivor],
                 photos_latlon: np.ndarray) -> RetaskPlan | None: ...
