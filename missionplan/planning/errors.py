"""The planning package's errors: one base, PlanningError, and one subclass per stage, so a caller can tell
what could not be planned. Each is a MapError too (what the command line prints as one line, exit 2)."""

from __future__ import annotations

from ..flight.retask_planner import RetaskPlanningError as RetaskRefused
from ..maps.gridmap import MapError


class PlanningError(MapError):
    """A plan that cannot be made as asked; the message says why, naming the setting or the file."""


class PlanRequestError(PlanningError):
    """The request itself cannot be planned: an unknown policy or zone method, more drones than launch cells."""


class PlanFolderError(PlanningError):
    """The output folder cannot take the plan (the root, home, a flown folder, not writable, disk full), or a
    file of the plan (a basemap) cannot be read."""


class ReplanError(PlanningError):
    """A re-plan after landing whose drones or launch points do not fit the survey."""


class RetaskPlanningError(PlanningError, RetaskRefused):
    """A live re-task that cannot be planned; the survivors fly on with their own missions (fly's re-tasker
    catches it as the flight side's RetaskPlanningError)."""
