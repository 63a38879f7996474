"""What other threads tell one drone's follower, and the one way it reaches the drone's record.

A drone's record (record.DroneRecord) and its follower's state are written by the follower's own thread
(drone_flight.DroneFlight) while it runs. Everything another thread has to add (fly's main thread: a
separation alert, a re-plan note, a command sent at Ctrl-C, "not followed to the end"; the journal's
writer: "journal writes paused") is posted here instead, and the follower takes it between two of its
vehicle's messages, in its thread. Once the follower has ended (`close`, the last thing its thread
does), a post is applied at once by the poster, one poster at a time: the record has no other writer
left. A drone that never had a follower (its mission file missing) has a mailbox closed from the start.

Record messages are applied to the record; any other message (events.ShareGivenAway) is an order for
the follower, handed to it by `take`, dropped once it has ended.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from .events import ShareGivenAway
from .record import DroneRecord


@dataclass(frozen=True)
class RecordEvent:
    """A line in the drone's events (t: our wall clock), such as an alert the crew was told."""

    t: float
    text: str


@dataclass(frozen=True)
class RecordNote:
    text: str


@dataclass(frozen=True)
class RecordProblem:
    text: str


RecordMessage = RecordEvent | RecordNote | RecordProblem
Order = ShareGivenAway
Message = RecordMessage | Order


def write(record: DroneRecord, message: RecordMessage) -> None:
    """`message` into the record (and so into the journal)."""
    if isinstance(message, RecordEvent):
        record.add_event(message.t, message.text)
    elif isinstance(message, RecordNote):
        record.add_note(message.text)
    else:
        record.add_problem(message.text)


class Mailbox:
    """One drone's mailbox: `post` from any thread; `take` and `close` from its follower's thread only."""

    def __init__(self, record: DroneRecord, followed: bool = True) -> None:
        self.record = record
        self._lock = threading.Lock()
        self._waiting: list[Message] = []
        self._closed = not followed

    @property
    def closed(self) -> bool:
        return self._closed

    def post(self, message: Message) -> None:
        with self._lock:
            if not self._closed:
                self._waiting.append(message)
                return
            if not isinstance(message, ShareGivenAway):  # an order for a follower that is gone: nothing to do
                write(self.record, message)

    def take(self) -> list[Order]:
        """In the follower's thread: the record messages waiting, written; the orders, returned in order."""
        with self._lock:
            waiting, self._waiting = self._waiting, []
        orders: list[Order] = []
        for message in waiting:
            if isinstance(message, ShareGivenAway):
                orders.append(message)
            else:
                write(self.record, message)
        return orders

    def close(self) -> None:
        """In the follower's thread, as it ends: what waits is written, and later posts are written by their
        posters. fly's main thread closes the mailbox of a follower that did not stop within its bound (its
        record is judged as it stands); closing twice does nothing more."""
        with self._lock:
            self._closed = True
            waiting, self._waiting = self._waiting, []
            for message in waiting:
                if not isinstance(message, ShareGivenAway):
                    write(self.record, message)
