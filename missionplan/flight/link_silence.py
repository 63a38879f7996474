"""When a silent drone counts as lost, gone or given up: every silence threshold of a flight, here only.

A follower hears its vehicle's messages; a silence means more the longer it lasts, each meaning with its
own threshold (our monotonic seconds):
- UPLOAD_HEARD_S: heard within this long, a drone can take a re-task's upload now (fly --replan's survivors);
- LINK_LOST_S: silent longer, its link is lost: said to the crew at once, and the drone is still followed;
- GONE_SILENT_S: silent longer mid-mission, it is gone: its share is re-tasked to the others (the default of
  fly --replan-after);
- give_up_at: silent until its mission would be long over (LINK_WAIT_FACTOR times its planned time plus
  LINK_MARGIN_S, on its clock), its follower stops waiting for it.
SilenceRule answers the first three for a silence of a given length. Its thresholds are our seconds; a flight of a
sped-up simulator that should meet them as a crew at 1x would (missionplan verify) gives the rule the vehicles'
time scale, and each threshold is then that many vehicle seconds (never less than MIN_WALL_S of ours: our
threads' own scheduling gaps on a loaded machine are not a link's silence). LinkWatch is one follower's link,
without threads: told when the vehicle is heard and when the follower looks, it says when a silence
begins to matter, when the link is lost and when it is back.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

UPLOAD_HEARD_S = 2.0   # heard within this long: can take a re-task's upload now
LINK_LOST_S = 5.0      # a vehicle silent this long has lost its link (said at once; followed on)
GONE_SILENT_S = 15.0   # silent this long mid-mission: gone, its share re-tasked (fly --replan-after's default)
LINK_WAIT_FACTOR, LINK_MARGIN_S = 1.5, 60.0  # a silent vehicle is waited for until its mission would be long over
MIN_WALL_S = 0.5  # a threshold in vehicle time, scaled down to ours, is never shorter than this


@dataclass(frozen=True)
class SilenceRule:
    """What a silence of `silent_s` of our seconds means; gone_after_s is fly's --replan-after. vehicle_scale: the
    vehicles' seconds per second of ours when the thresholds are vehicle time (None: they are ours, as for fly)."""

    gone_after_s: float = GONE_SILENT_S
    vehicle_scale: float | None = None

    def _ours(self, threshold_s: float) -> float:
        if self.vehicle_scale is None:
            return threshold_s
        return max(threshold_s / self.vehicle_scale, MIN_WALL_S)

    def takes_uploads(self, silent_s: float) -> bool:
        """Heard lately enough to take a re-task's upload now."""
        return silent_s <= self._ours(UPLOAD_HEARD_S)

    def link_lost(self, silent_s: float) -> bool:
        return silent_s > self._ours(LINK_LOST_S)

    def gone(self, silent_s: float) -> bool:
        """Gone for re-tasking: its share goes to the others."""
        return silent_s > self._ours(self.gone_after_s)

    @property
    def matters_after_s(self) -> float:
        """The shortest silence any of these thresholds acts on (our seconds)."""
        return min(self._ours(UPLOAD_HEARD_S), self._ours(LINK_LOST_S), self._ours(self.gone_after_s))


class SilenceStep(Enum):
    """Where a growing silence has just come to (LinkWatch.look)."""

    MATTERS = "matters"  # past the shortest threshold: the re-tasker times it from here
    LOST = "lost"        # past LINK_LOST_S: its link is lost


@dataclass(frozen=True)
class SilenceOver:
    """A silence that mattered, over: how long it lasted and whether the link counted as lost."""

    silent_s: float
    was_lost: bool


class LinkWatch:
    """One follower's link to its vehicle, times on our monotonic clock. Owned by the follower's thread."""

    def __init__(self, rule: SilenceRule, heard_at: float) -> None:
        self.rule = rule
        self.heard_at = heard_at  # the vehicle's last message
        self.matters = False  # the current silence has passed rule.matters_after_s
        self.lost_since: float | None = None  # the last message before the link was lost

    def look(self, now: float) -> list[SilenceStep]:
        """The steps the current silence has just passed (each once per silence)."""
        silent_s = now - self.heard_at
        steps = []
        if not self.matters and silent_s > self.rule.matters_after_s:
            self.matters = True
            steps.append(SilenceStep.MATTERS)
        if self.lost_since is None and self.rule.link_lost(silent_s):
            self.lost_since = self.heard_at
            steps.append(SilenceStep.LOST)
        return steps

    def heard(self, now: float) -> SilenceOver | None:
        """The vehicle was heard at `now`: the silence that ended, when one mattered."""
        over = SilenceOver(now - self.heard_at, self.lost_since is not None) if self.matters else None
        self.heard_at, self.matters, self.lost_since = now, False, None
        return over


def give_up_at(planned_s: float, rate: float, started_ago_s: float, now: float, deadline: float) -> float:
    """Our monotonic time after which a silent vehicle's mission is surely over: its planned time (vehicle
    seconds) LINK_WAIT_FACTOR times over plus LINK_MARGIN_S, at its clock's `rate` (vehicle seconds per
    second of ours), from its start `started_ago_s` ago; never after the deadline."""
    left = (planned_s * LINK_WAIT_FACTOR + LINK_MARGIN_S) / rate - started_ago_s
    # Not clamped at 0: once `left` is negative the moment is past (clamped, it was always "now", and a
    # silent vehicle was waited for until --timeout).
    return min(deadline, now + left)
