"""missionplan.flight.phases, where a flight's time went, on synthetic recordings: the PX4 SIH flight
that sat armed on the ground for minutes must say so (tests/test_readiness_estimate.py: such a start
no longer happens)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from missionplan.bridge.flight_models import px4_model as pm
from missionplan.bridge.formats.mission_items import CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT
from missionplan.flight import phases
from missionplan.flight.flight_report import flown_seconds
from missionplan.flight.record import DroneRecord

T0 = 5000.0  # our clock at the mission start
BOOT0 = 40.0  # the vehicle's clock then
# take-off, the 4 waypoints, RTL: the end is the last item (5), the last waypoint 4
WIRE = [SimpleNamespace(command=c) for c in (CMD_NAV_TAKEOFF, *[CMD_NAV_WAYPOINT] * 4, CMD_NAV_RETURN_TO_LAUNCH)]


def _record(durations: tuple[float, float, float, float], landed_states: bool = True,
            clock_rate: float = 1.0) -> DroneRecord:
    """A finished flight whose phases took `durations` seconds of the vehicle's clock (ours at
    1 / clock_rate), reported as PX4 reports it: items reached, landed state at each change."""
    bounds = T0 + np.cumsum([0.0, *durations]) / clock_rate
    start, took_off, surveyed, landing, end = bounds.tolist()
    rec = DroneRecord(id=1, wire=list(WIRE), t_start=start, t_end=end, finished=True)
    rec.reached = [(took_off, 1), (took_off + 0.5 * (surveyed - took_off), 2), (surveyed, 4)]
    if landed_states:
        rec.landed = [(start, 1), (start + 0.5, 3), (took_off, 2), (landing, 4), (end, 1)]
    times = np.arange(start, end + 1e-9, 0.1)
    rec.samples = [(t, 45.0, 9.0, 10.0, 0.0, BOOT0 + (t - start) * clock_rate, 0.0) for t in times]
    return rec


PLANNED = pm.flight((0.0, 0.0, 0.0), 20.0, [(0.0, 40.0, 20.0), (40.0, 40.0, 20.0), (0.0, 0.0, 20.0)], "rtl",
                    5.0, pm.Px4Params())


def test_flown_phases_add_up_to_the_flight_and_sit_next_to_the_planned_ones() -> None:
    rec = _record((19.5, 48.0, 7.6, 22.6))
    rows = phases.phase_rows(rec, PLANNED, 1.0)
    assert [r["phase"] for r in rows] == ["take-off", "survey", "return", "landing"]
    assert [r["flown_s"] for r in rows] == pytest.approx([19.5, 48.0, 7.6, 22.6], abs=0.11)
    assert sum(r["flown_s"] for r in rows) == pytest.approx(flown_seconds(rec, 1.0), abs=0.01)
    planned = phases.planned_phases(PLANNED)
    assert [r["planned_s"] for r in rows] == pytest.approx([planned[p] for p in phases.PHASES], abs=0.01)
    assert sum(planned.values()) == pytest.approx(sum(m.duration for m in PLANNED))
    assert planned["take-off"] > 15.0 and planned["landing"] > 15.0  # a 20 m climb at 1.5 m/s, and back down
    assert phases.slow_phase(rows) == ""


def test_a_vehicle_that_sat_armed_on_the_ground_says_its_take_off_took_minutes() -> None:
    # PX4 SIH, uav3 of the fleet test: 220 s armed on the ground before it climbed, the rest as planned.
    rows = phases.phase_rows(_record((240.0, 48.0, 7.6, 22.6)), PLANNED, 1.0)
    said = phases.slow_phase(rows)
    assert said.startswith("its take-off took 240.0 s (planned ") and "survey" not in said
    # A landing a few seconds slower than planned is not worth a word (the land detector varies by 8 s).
    assert phases.slow_phase(phases.phase_rows(_record((19.5, 48.0, 7.6, 30.0)), PLANNED, 1.0)) == ""


def test_phases_run_on_the_vehicles_clock() -> None:
    # A simulator twice as fast as our clock: the phases are its seconds, as flight_s is.
    rows = phases.phase_rows(_record((19.5, 48.0, 7.6, 22.6), clock_rate=2.0), PLANNED, 2.0)
    assert [r["flown_s"] for r in rows] == pytest.approx([19.5, 48.0, 7.6, 22.6], abs=0.21)


def test_without_a_landed_state_return_and_landing_are_one_phase() -> None:
    rows = phases.phase_rows(_record((19.5, 48.0, 7.6, 22.6), landed_states=False), PLANNED, 1.0)
    planned = phases.planned_phases(PLANNED)
    assert [r["phase"] for r in rows] == ["take-off", "survey", "return and landing"]
    assert rows[2]["flown_s"] == pytest.approx(30.2, abs=0.11)
    assert rows[2]["planned_s"] == pytest.approx(planned["return"] + planned["landing"], abs=0.01)


def test_an_unfinished_flight_has_no_time_for_the_phases_it_never_reached() -> None:
    rec = _record((19.5, 48.0, 7.6, 22.6))
    rec.reached = rec.reached[:1]  # only the first waypoint before it stopped answering
    rec.landed, rec.t_end, rec.finished = rec.landed[:3], None, False
    rows = phases.phase_rows(rec, PLANNED, 1.0)
    assert rows[0]["flown_s"] == pytest.approx(19.5, abs=0.11)
    assert [r["flown_s"] for r in rows[1:]] == [None, None, None]


def test_events_are_on_the_vehicles_clock_from_the_start() -> None:
    rec = _record((19.5, 48.0, 7.6, 22.6))
    rec.events = [(T0 - 0.2, "armed"), (T0 + 19.5, "landed state in air"), (T0 + 97.7, "disarmed")]
    events = phases.event_rows(rec, 1.0)
    assert events[0] == [0.0, "armed"]  # before the start's acknowledgement: at the start
    at = {text: t for t, text in events}
    assert at["reached item 1"] == pytest.approx(19.5, abs=0.11) and at["disarmed"] == pytest.approx(97.7, abs=0.11)
    assert [e[0] for e in events] == sorted(e[0] for e in events)
