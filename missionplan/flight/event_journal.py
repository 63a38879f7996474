"""What each flight event writes into its drone's record and says to the crew.

The consumer of flight events that runs in the publishing follower's own thread (events.FlightEvents.subscribe),
so a drone's record is written by its own thread only, in the order things happened: facts and events
into the record (and through its sink into the journal, from which the judge writes flight.json), problems
into its problems, and what a crew must hear at once as an alert (the terminal, and "alert: ..." in the
record's events). One line of text per event kind, here.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from missionplan.bridge.link.connection import mavlink

from .events import (ArmingChanged, EndedEarly, FlightEvent, Finished, GaveUpWaiting, LandedStateChanged, LeftMission,
                     LinkBack, LinkLost, MissionStarted, ModeChanged, PhotosNotConfirmed, PhotoTaken, Rebooted, SentHome,
                     TimedOut, VehicleSaid)
from .link_silence import LINK_LOST_S
from .record import DroneRecord

LANDED_STATE_NAMES = {mavlink.MAV_LANDED_STATE_ON_GROUND: "on ground", mavlink.MAV_LANDED_STATE_IN_AIR: "in air",
                      mavlink.MAV_LANDED_STATE_TAKEOFF: "taking off", mavlink.MAV_LANDED_STATE_LANDING: "landing"}


def refused(what: str, result: int | None) -> str:
    return f"{what} {'not acknowledged' if result is None else f'refused (MAV_RESULT {result})'}"


def journal(rec: DroneRecord, event: FlightEvent) -> None:
    """What `event` changes in its drone's record (nothing for an event only others act on)."""
    if isinstance(event, ModeChanged):
        rec.add_event(event.t, f"mode {event.mode}")
    elif isinstance(event, ArmingChanged):
        rec.add_event(event.t, "armed" if event.armed else "disarmed")
    elif isinstance(event, LandedStateChanged):
        rec.add_landed(event.t, event.state)
        rec.add_event(event.t, f"landed state {LANDED_STATE_NAMES.get(event.state, event.state)}")
    elif isinstance(event, VehicleSaid):
        rec.add_event(event.t, f"says: {event.text}")
    elif isinstance(event, PhotoTaken):
        rec.add_photo(event.index, event.t, event.lat, event.lon, event.up_m, source=event.source,
                      attitude=event.attitude, amsl=event.amsl_m, file_url=event.file_url)
    elif isinstance(event, MissionStarted):
        rec.set(started=True, t_start=event.t)
    elif isinstance(event, Finished):
        rec.set(finished=True, t_end=event.t)
    elif isinstance(event, EndedEarly):
        rec.set(ended_early=event.reason, t_end=event.t)
    problem = problem_text(event)
    if problem:
        rec.add_problem(f"uav{event.sysid}: {problem}")


def problem_text(event: FlightEvent) -> str:
    """What the flight's problems say of `event` ('' for none)."""
    if isinstance(event, EndedEarly):
        return f"ended its mission early: {event.reason}"
    if isinstance(event, Rebooted):
        return f"rebooted in flight at item {event.item} of {event.last_seq} (mission lost)"
    if isinstance(event, GaveUpWaiting):
        return (f"link lost for {event.silent_s:.0f} s since item {event.item} of {event.last_seq}; its mission "
                "should have ended by now: last known position in flight.json")
    if isinstance(event, TimedOut):
        return f"mission not finished within the time-out (item {event.item} of {event.last_seq})"
    return ""


def alert_text(event: FlightEvent) -> str:
    """What the crew hears of `event` at once ('' for nothing)."""
    if isinstance(event, VehicleSaid) and event.warning:
        return f"says: {event.text}"
    if isinstance(event, LinkLost):
        where = ""
        if event.last_position is not None:
            lat, lon, up = event.last_position
            where = f", last at {lat:.6f}, {lon:.6f}, {up:.1f} m up"
        return (f"link lost: nothing heard for {LINK_LOST_S:g} s at item {event.item} of {event.last_seq}{where}; "
                "still waiting for it")
    if isinstance(event, LinkBack) and event.was_lost:
        return f"link back after {event.silent_s:.1f} s, at item {event.item} of {event.last_seq}"
    if isinstance(event, LeftMission):
        return (f"mode changed to {event.mode} at item {event.item} of {event.last_seq}, not by fly (RC, another "
                "ground station or a failsafe)")
    if isinstance(event, EndedEarly):
        return f"landed and disarmed before the end of its mission: {event.reason}"
    if isinstance(event, Rebooted):
        return f"rebooted in flight at item {event.item} of {event.last_seq}"
    if isinstance(event, SentHome):
        return ("heard again after its share was re-tasked to the others: sent home (RTL)" if event.accepted else
                f"heard again after its share was re-tasked: {refused('RTL', event.result)}; bring it home by hand")
    if isinstance(event, PhotosNotConfirmed):
        if not event.log_error:
            return f"{event.count} photos not confirmed: neither reported nor in its log"
        if event.count is None:
            return f"photos taken while it was not heard not confirmed (its log could not be read: {event.log_error})"
        return (f"{event.count} photos not confirmed (their reports were lost and its log could not be read: "
                f"{event.log_error})")
    return ""


class EventJournal:
    """The consumer: each event into its drone's record, then its alert to the crew (fleet's `alert`)."""

    def __init__(self, records: dict[int, DroneRecord], alert: Callable[[str], None]) -> None:
        self.records, self.alert = records, alert

    def __call__(self, event: FlightEvent) -> None:
        rec = self.records[event.sysid]
        journal(rec, event)
        text = alert_text(event)
        if text:
            say_now(rec, self.alert, text)


def say_now(rec: DroneRecord, alert: Callable[[str], None], text: str) -> None:
    """One line now, on the terminal and in the journal."""
    rec.add_event(time.time(), f"alert: {text}")
    alert(f"uav{rec.id}: {text}")
