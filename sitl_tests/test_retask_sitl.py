"""Live re-tasking on real autopilots: missionplan.bridge.transfer.retask.replace_mission_in_flight on one ArduCopter
SITL vehicle and one PX4 SIH vehicle flying a survey, and the mock compared with them.

Each vehicle (a free instance, its own temp folder, killed in teardown: the `arducopter` and `px4`
fixtures) flies take-off, A1..A8 (a 60 x 60 m lawnmower north of home), RTL in AUTO / mission mode, flown
and watched by the re-task harness, missionplan/testing/retask_harness.py (bench/retask_bench.py measures
every strategy with it: docs/live-retasking.md). Mid-leg to A6 its mission is replaced, as fly's re-plans do it, by take-off,
DO_CHANGE_SPEED, B1..B3 (a lost drone's waypoints, west of it and behind it), RTL, to continue at the
DO_CHANGE_SPEED (resume_seq): renumbered, so the item it flies is past the new end; a new geofence (a 600
m square around home) goes up with it. Required: the new mission confirmed (read back, MISSION_CURRENT at
resume_seq or at B1 it leads to, armed in AUTO / mission mode again); the vehicle armed and above 5 m
until it reached B1, B2, B3 in order, each reported (MISSION_ITEM_REACHED) where it is; MISSION_CURRENT
never below resume_seq from the change on (no return to the take-off or to item 0/1); the fence held.

The mock is held to the same (the same function, the same assertions; its SITL-like flight) in
tests/test_mock_as_autopilots.py. Skipped with a reason when ../shared/sitl/arducopter or
../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

import pytest

from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.connection import Link
from missionplan.testing import retask_harness as harness
from missionplan.testing.retask_harness import check, retask_and_follow

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def test_arducopter_sitl_takes_a_new_mission_in_flight_and_flies_it(arducopter) -> None:
    vehicle = arducopter(sysid=1, speedup=harness.ARDUCOPTER_SPEEDUP)
    with Link(vehicle.url) as link:
        report, row, flight, started = retask_and_follow(link, 1, Flavour.ARDUPILOT, vehicle.home[:3],
                                                         harness.ARDUCOPTER_SPEEDUP)
    print(report.summary(), harness.line(row), sep="\n")
    check(report, row, flight, started)
    assert report.mode == "AUTO"


def test_px4_sih_takes_a_new_mission_in_flight_and_flies_it(px4) -> None:
    vehicle = px4()
    with Link(vehicle.gcs_url) as link:
        report, row, flight, started = retask_and_follow(link, vehicle.sysid, Flavour.PX4, vehicle.home, 1.0)
    print(report.summary(), harness.line(row), sep="\n")
    check(report, row, flight, started)
    assert report.mode == "MISSION"
