"""Where a flight's time went: its phases as flown, next to the same phases as planned.

A survey flight has four phases, each ended by something the vehicle itself reports (fly.py records it):
- take-off: from the mission start until the vehicle reports its first mission item reached;
- survey: until it reports the mission's last waypoint reached;
- return: until its landing begins (EXTENDED_SYS_STATE landed state LANDING: ArduCopter's RTL in its
  land stage, PX4 after "RTL: land at destination");
- landing: until the flight ends (on the ground and disarmed).
A vehicle that reports no landed state has one phase "return and landing" instead of the last two.

Flown times are on the vehicle's own clock (its time_boot_ms, the ruler of flight_s: the phases add up
to it); the planned ones are the flight model's motions (missionplan.bridge.flight_models.copter_model,
missionplan.bridge.flight_models.px4_model) for the mission as uploaded, grouped by their kind, with the parameters the
vehicle reported. A flight that took far longer than planned then says where: a landing that took minutes is not a slow
survey.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from missionplan.bridge.flight_models.copter_model import Motion
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.px4_rules import reached_item

from .record import DroneRecord

PHASES = ("take-off", "survey", "return", "landing")
MERGED = "return and landing"  # a vehicle that reports no landed state
# The flight model's motion kinds (Motion.kind), by the phase they belong to.
PHASE_OF_KIND = {"spool": "take-off", "takeoff": "take-off", "settle": "take-off",
                 "turn": "survey", "leg": "survey",
                 "rtl": "return", "climb": "return", "home": "return", "loiter": "return",
                 "descent": "landing", "land": "landing", "touchdown": "landing"}
# A phase that took this much longer than planned (and this share of it) is worth saying.
SLOW_PHASE_S, SLOW_PHASE_SHARE = 10.0, 0.5
MAX_EVENTS = 400  # per drone in flight.json: a long flight keeps its last ones


def planned_phases(motions: list[Motion]) -> dict[str, float]:
    """Seconds per phase of a planned flight."""
    out = dict.fromkeys(PHASES, 0.0)
    for motion in motions:
        out[PHASE_OF_KIND.get(motion.kind, "survey")] += motion.duration
    return out


def flown_bounds(rec: DroneRecord) -> list[float | None]:
    """Our clock's times of the phase ends: [start, take-off done, survey done, landing begun, end].
    None where the vehicle never reported it (the landing: it reports no landed state)."""
    last_seq = len(rec.wire) - 1
    start = rec.t_start
    end = rec.t_end if rec.t_end is not None else (rec.samples[-1][0] if rec.samples else None)
    if start is None or end is None:
        return [start, None, None, None, end]
    reached = [(t, seq) for t, seq in rec.reached if start <= t <= end]
    took_off = min((t for t, _ in reached), default=None)
    last_waypoint = max((int(getattr(item, "seq", k)) for k, item in enumerate(rec.wire)
                         if int(item.command) == mavlink.MAV_CMD_NAV_WAYPOINT), default=last_seq)
    surveyed = min((t for t, seq in reached if seq >= last_waypoint), default=None)
    after = surveyed if surveyed is not None else start
    landing = next((t for t, state in rec.landed
                    if after <= t <= end and state == mavlink.MAV_LANDED_STATE_LANDING), None)
    return [start, took_off, surveyed, landing, end]


def on_vehicle_clock(rec: DroneRecord, times: list[float], scale: float) -> np.ndarray:
    """Our clock's times -> seconds since the mission start on the vehicle's clock (its time_boot_ms
    in the samples: flight_report.flown_seconds is this at the end), or our clock times `scale` without a record."""
    samples = np.array(rec.samples) if rec.samples else np.zeros((0, 7))
    start = rec.t_start if rec.t_start is not None else 0.0
    end = max(times) if times else start
    inside = samples[(samples[:, 0] >= start) & (samples[:, 0] <= end)] if len(samples) else samples
    if len(inside) >= 2 and np.all(np.diff(inside[:, 5]) >= 0):
        return np.interp(times, inside[:, 0], inside[:, 5]) - inside[0, 5]
    return (np.asarray(times, dtype=float) - start) * scale


def phase_rows(rec: DroneRecord, motions: list[Motion] | None, scale: float) -> list[dict[str, Any]]:
    """flight.json's `phases` of one drone: [{"phase", "flown_s", "planned_s"}], flown None where
    the flight never got there; planned from `motions` (the uploaded mission as the flight model flies
    it, flight_report.mission_motions; None: not known)."""
    bounds = flown_bounds(rec)
    planned = planned_phases(motions) if motions else {}
    names = list(PHASES)
    if bounds[3] is None and bounds[4] is not None and bounds[2] is not None and rec.finished:
        names, bounds = [*PHASES[:2], MERGED], [*bounds[:3], bounds[4]]  # no landed state reported
        if planned:
            planned[MERGED] = planned["return"] + planned["landing"]
    known = [b for b in bounds if b is not None]
    clock = dict(zip(known, on_vehicle_clock(rec, known, scale).tolist())) if rec.t_start is not None else {}
    rows = []
    for k, name in enumerate(names):
        a, b = bounds[k], bounds[k + 1]
        flown = round(clock[b] - clock[a], 2) if a is not None and b is not None else None
        rows.append({"phase": name, "flown_s": flown,
                     "planned_s": round(planned[name], 2) if name in planned else None})
    return rows


def slow_phase(rows: list[dict[str, Any]]) -> str:
    """The phase that took much longer than planned, in words ("" when none did)."""
    late = [(r["flown_s"] - r["planned_s"], r) for r in rows
            if r["flown_s"] is not None and r["planned_s"] is not None]
    worst = max(late, key=lambda pair: pair[0], default=None)
    if worst is None:
        return ""
    extra, row = worst
    if extra < SLOW_PHASE_S or extra < SLOW_PHASE_SHARE * row["planned_s"]:
        return ""
    return f"its {row['phase']} took {row['flown_s']:.1f} s (planned {row['planned_s']:.1f} s)"


def event_rows(rec: DroneRecord, scale: float) -> list[list[Any]]:
    """flight.json's `events` of one drone: [seconds since the mission start on the vehicle's clock,
    what happened] for every item reached and every change of mode, arming and landed state, and every
    STATUSTEXT, from the mission start command on (at most MAX_EVENTS, the last ones)."""
    if rec.t_start is None:
        return []
    happened = sorted([(t, f"reached item {seq}") for t, seq in rec.reached] + list(rec.events))
    happened = happened[-MAX_EVENTS:]
    if not happened:
        return []
    # What came between the start command and its acknowledgement counts as at the start.
    clock = on_vehicle_clock(rec, [max(t, rec.t_start) for t, _ in happened], scale)
    return [[round(float(s), 2), text] for s, (_, text) in zip(clock, happened)]


# The landed states PX4 reports through a survey flight, in order (PX4 SIH v1.15.4, and the mock's PX4).
# SIH sometimes goes from "on ground" straight to "in air" (1 vehicle in 27 measured; it then climbed
# faster): PX4_LANDED_STATES_QUICK.
PX4_LANDED_STATES = ["on ground", "taking off", "in air", "landing", "on ground"]
PX4_LANDED_STATES_QUICK = ["on ground", "in air", "landing", "on ground"]


def landed_states(row: dict[str, Any]) -> list[str]:
    """The landed states a flight.json drone row's events went through, in order."""
    return [text.removeprefix("landed state ") for _, text in row.get("events", []) if text.startswith("landed state ")]


def reached_items(row: dict[str, Any]) -> list[int]:
    """The MISSION_ITEM_REACHED seqs a flight.json drone row's events hold, in order."""
    return [int(text.removeprefix("reached item ")) for _, text in row.get("events", [])
            if text.startswith("reached item ")]


def reached_navigation_items(row: dict[str, Any], commands: list[int]) -> list[int]:
    """The navigation items a flight.json drone row's MISSION_ITEM_REACHED were about
    (missionplan.bridge.formats.px4_rules.reached_item: PX4 may report a waypoint by the seq of the DO_ items after it),
    in order, each once; `commands`: the uploaded mission's commands by seq."""
    items = [reached_item(commands, seq) for seq in reached_items(row)]
    return [k for i, k in enumerate(items) if i == 0 or k != items[i - 1]]
