"""What a drone's follower decides and hears in flight, as typed events, and where they are published.

Each drone's follower (drone_flight.DroneFlight, in its own thread) publishes these on the fleet's
FlightEvents as it decides them. Consumers:
- in the follower's own thread, in the order published (event_journal): the journal (the drone's record,
  and so journal.sqlite and the judge's flight.json) and the alerts (the terminal and the journal);
- on a queue read by fly's main thread: the re-tasker (live_replan.Retasker, fly --replan), which knows
  the fleet from these events alone.
`t` is our wall clock (time.time(), as in the record); `heard_at` our monotonic clock (time.monotonic()),
the moment the vehicle was last heard. `item` / `last_seq` say where in its mission the vehicle was.
The messages the other way, to a follower, are not events: ShareGivenAway below and the lines for its
record (follower_mail), and the requests a re-task makes (DroneFlight.ask).
"""

from __future__ import annotations

import queue
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class FlightEvent:
    sysid: int
    t: float


# ------------------------------------------------------------------ what the vehicle reports
@dataclass(frozen=True)
class ModeChanged(FlightEvent):
    mode: str
    in_mission_mode: bool  # ArduPilot AUTO, PX4 AUTO.MISSION


@dataclass(frozen=True)
class ArmingChanged(FlightEvent):
    armed: bool


@dataclass(frozen=True)
class LandedStateChanged(FlightEvent):
    state: int  # MAV_LANDED_STATE


@dataclass(frozen=True)
class VehicleSaid(FlightEvent):
    text: str
    warning: bool  # a failsafe, a fence, the EKF...: the crew hears it at once


@dataclass(frozen=True)
class PhotoTaken(FlightEvent):
    """A photo and where it was taken (t: when), reported over the link ("camera") or read from the
    vehicle's log after landing ("log"); the first word about an index stands."""

    index: int
    lat: float
    lon: float
    up_m: float
    source: str = "camera"
    attitude: tuple[float, float, float] | None = None  # roll, pitch, yaw degrees
    amsl_m: float | None = None
    # A MAVLink camera's record (plan --capture camera*): the file it names ("" when it names none), so that its
    # index is known to be the camera's image_index; None for the autopilot's reports and the log's.
    file_url: str | None = None


# ------------------------------------------------------------------ what the follower decides
@dataclass(frozen=True)
class MissionStarted(FlightEvent):
    """The vehicle accepted the mission start: from now on it flies its mission."""


@dataclass(frozen=True)
class LinkQuiet(FlightEvent):
    """Silent past the shortest threshold anything acts on (link_silence.SilenceRule.matters_after_s)."""

    heard_at: float


@dataclass(frozen=True)
class LinkLost(FlightEvent):
    """Silent past link_silence.LINK_LOST_S: said at once; the drone is still followed."""

    heard_at: float
    item: int
    last_seq: int
    last_position: tuple[float, float, float] | None  # lat, lon, m up


@dataclass(frozen=True)
class LinkBack(FlightEvent):
    """Heard again after a LinkQuiet (was_lost: after a LinkLost too)."""

    silent_s: float
    was_lost: bool
    item: int
    last_seq: int


@dataclass(frozen=True)
class LeftMission(FlightEvent):
    """Switched mid-mission to a mode nobody in this run asked for (RC, another ground station, a failsafe)."""

    mode: str
    heard_at: float
    item: int
    last_seq: int


@dataclass(frozen=True)
class Finished(FlightEvent):
    """On the ground and disarmed with its mission complete (t: when it was last heard)."""


@dataclass(frozen=True)
class EndedEarly(FlightEvent):
    """On the ground and disarmed before the end of its mission (t: when it was last heard)."""

    reason: str
    heard_at: float


@dataclass(frozen=True)
class Rebooted(FlightEvent):
    """Rebooted in flight: its mission is lost, and it is followed no more."""

    item: int
    last_seq: int


@dataclass(frozen=True)
class GaveUpWaiting(FlightEvent):
    """Silent until its mission would be long over (link_silence.give_up_at): followed no more."""

    silent_s: float
    item: int
    last_seq: int


@dataclass(frozen=True)
class TimedOut(FlightEvent):
    """fly's --timeout came before its mission ended."""

    item: int
    last_seq: int


@dataclass(frozen=True)
class FollowingStopped(FlightEvent):
    """Its follower hears it no more (it ended, gave up, or was stopped), heard last at heard_at."""

    heard_at: float


@dataclass(frozen=True)
class SentHome(FlightEvent):
    """Heard again after its share was re-tasked to others: RTL commanded (result: its MAV_RESULT, None
    without an answer)."""

    accepted: bool
    result: int | None


@dataclass(frozen=True)
class PhotosNotConfirmed(FlightEvent):
    """After landing: photos whose reports were lost and that its log did not give back. count: how many
    (None: unknown, those of a link gap); log_error: why the log could not be read ('' when it was)."""

    count: int | None
    log_error: str


@dataclass(frozen=True)
class ShareGivenAway:
    """To a follower, from the re-tasker: its share went to the others; heard again in flight, it goes home."""


Consumer = Callable[[FlightEvent], None]


class FlightEvents:
    """The fleet's events: each published one goes to every consumer subscribed (in the publisher's thread,
    in order), then to every queue (for another thread)."""

    def __init__(self) -> None:
        self._consumers: list[Consumer] = []
        self._queues: list[queue.SimpleQueue[FlightEvent]] = []

    def subscribe(self, consumer: Consumer) -> None:
        """Before any follower starts: called in the publishing thread."""
        self._consumers.append(consumer)

    def new_queue(self) -> queue.SimpleQueue[FlightEvent]:
        """Before any follower starts: a queue of every event from now on, for another thread to read."""
        events: queue.SimpleQueue[FlightEvent] = queue.SimpleQueue()
        self._queues.append(events)
        return events

    def publish(self, event: FlightEvent) -> None:
        for consumer in self._consumers:
            consumer(event)
        for events in self._queues:
            events.put(event)


def drain(events: queue.SimpleQueue[FlightEvent]) -> list[FlightEvent]:
    """Every event waiting on a queue, oldest first, without waiting."""
    out = []
    while True:
        try:
            out.append(events.get_nowait())
        except queue.Empty:
            return out
