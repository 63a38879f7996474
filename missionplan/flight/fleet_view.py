"""What fly --replan knows of each drone, from its follower's events alone: gone, or able to take more.

The re-tasker (live_replan.Retasker) reads the followers' events on its own queue (events.FlightEvents)
and keeps one DroneView per drone: started, finished or ended early, its mode and arming, since when it
is silent, the photos it confirmed. Whether a drone is gone, or still flying its mission and able to take
a re-task's upload, is decided from that view and link_silence.SilenceRule, at the moment asked: no other
thread's state is read. No threads here: events in, decisions out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .events import (ArmingChanged, EndedEarly, FlightEvent, Finished, FollowingStopped, LeftMission, LinkBack,
                     LinkLost, LinkQuiet, MissionStarted, ModeChanged, PhotoTaken)
from .link_silence import SilenceRule
from .telemetry_record import RETURN_MODES


@dataclass
class DroneView:
    """One drone as its events tell it (times: our monotonic clock)."""

    sysid: int
    started: bool = False
    finished: bool = False
    ended_early: str = ""  # why, when it landed before the end of its mission
    left_mission: str = ""  # the mode someone else switched it to mid-mission
    armed: bool = True  # as last reported
    in_mission_mode: bool = False  # ArduPilot AUTO, PX4 AUTO.MISSION, as last reported
    silent_since: float | None = None  # heard last then, and not since (None: heard lately)
    heard_at: float | None = None  # when it was last heard, as its latest event about a silence or an end said
    photos: dict[int, tuple[float, float]] = field(default_factory=dict)  # index -> lat, lon: the first word stands

    def take(self, event: FlightEvent) -> None:
        if isinstance(event, MissionStarted):
            self.started = True
        elif isinstance(event, ModeChanged):
            self.in_mission_mode = event.in_mission_mode
        elif isinstance(event, ArmingChanged):
            self.armed = event.armed
        elif isinstance(event, PhotoTaken):
            self.photos.setdefault(event.index, (event.lat, event.lon))
        elif isinstance(event, (LinkQuiet, LinkLost, FollowingStopped)):
            if self.silent_since is None:
                self.silent_since = self.heard_at = event.heard_at
        elif isinstance(event, LinkBack):
            self.silent_since = None
        elif isinstance(event, LeftMission):
            self.left_mission, self.heard_at = event.mode, event.heard_at
        elif isinstance(event, Finished):
            self.finished = True
        elif isinstance(event, EndedEarly):
            self.ended_early, self.heard_at = event.reason, event.heard_at

    def gone(self, now: float, rule: SilenceRule) -> bool:
        """Mid-mission: ended it early, switched to a return (a failsafe's RTL or LAND, not by fly), or
        silent for the rule's gone_after_s."""
        if not self.started or self.finished:
            return False
        return (bool(self.ended_early) or self.left_mission in RETURN_MODES
                or (self.silent_since is not None and rule.gone(now - self.silent_since)))

    def flying(self, now: float, rule: SilenceRule) -> bool:
        """Still flying its mission, armed, in its mission mode (not RTL, not a pilot's mode), and heard
        lately enough to take an upload now: can take more."""
        if not self.started or self.finished or self.ended_early or not self.armed:
            return False
        if self.silent_since is not None and not rule.takes_uploads(now - self.silent_since):
            return False  # a drone in a link gap cannot take an upload now
        return self.in_mission_mode

    def why_gone(self) -> str:
        return self.ended_early or (f"switched to {self.left_mission}" if self.left_mission else "not heard")


def confirmed_photos(views: list[DroneView]) -> np.ndarray:
    """(n, 2) lat, lon of every photo the drones confirmed so far."""
    return np.array([latlon for view in views for latlon in view.photos.values()], dtype=float).reshape(-1, 2)
