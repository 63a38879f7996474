"""Live re-tasking on real autopilots: missionplan.bridge.transfer.retask.replace_mission_in_flight on one ArduCopter
SITL vehicle and one PX4 SIH vehicle flying a survey, and the mock compared with them.

Each vehicle (a free instance, its own temp folder, killed in teardown: sitl_tests/arducopter.py,
sitl_tests/px4_sih.py) flies take-off, A1..A8 (a 60 x 60 m lawnmower north of home), RTL in AUTO / mission
mode, flown and watched by bench/retask_bench.py's harness (the bench measures every strategy with it:
docs/live-retasking.md). Mid-leg to A6 its mission is replaced, as fly's re-plans do it, by take-off,
DO_CHANGE_SPEED, B1..B3 (a lost drone's waypoints, west of it and behind it), RTL, to continue at the
DO_CHANGE_SPEED (resume_seq): renumbered, so the item it flies is past the new end; a new geofence (a 600
m square around home) goes up with it. Required: the new mission confirmed (read back, MISSION_CURRENT at
resume_seq or at B1 it leads to, armed in AUTO / mission mode again); the vehicle armed and above 5 m
until it reached B1, B2, B3 in order, each reported (MISSION_ITEM_REACHED) where it is; MISSION_CURRENT
never below resume_seq from the change on (no return to the take-off or to item 0/1); the fence held.

The mock is held to the same (the same function, the same assertions; its SITL-like flight): flown the
same way, it must answer a mission replaced in flight as the real autopilot did. Skipped with a reason
when ../shared/sitl/arducopter or ../shared/px4/bin/px4 is absent.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import pytest
from arducopter import arducopter  # noqa: F401  (the fixture)
from px4_sih import px4  # noqa: F401  (the fixture)

from missionplan.bridge.link.connection import Link
from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    FRAME_GLOBAL,
    Flavour,
    MissionType,
    WireItem,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.retask import RetaskReport, replace_mission_in_flight

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
import retask_bench as rb  # noqa: E402  (the harness: fly to mid-leg, watch, judge)

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

RETASK_S = 30.0  # wall seconds for replace_mission_in_flight
SPEED_M_S = 5.0  # the re-plan's DO_CHANGE_SPEED
FENCE_HALF_M = 300.0


def square_fence(home: tuple[float, float, float]) -> list[WireItem]:
    """An inclusion polygon (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION) 2 x FENCE_HALF_M wide around home."""
    h = FENCE_HALF_M
    corners = [rb.offset(home[:2], n, e) for n, e in ((-h, -h), (-h, h), (h, h), (h, -h))]
    return [WireItem(k, FRAME_GLOBAL, CMD_FENCE_POLYGON_VERTEX_INCLUSION, 0, 1, 4.0, 0.0, 0.0, 0.0, round(lat * 1e7),
                     round(lon * 1e7), 0.0, MissionType.FENCE)
            for k, (lat, lon) in enumerate(corners)]


def retask_and_follow(link: Any, sysid: int, flavour: Flavour, home: tuple[float, float, float],
                      speedup: float) -> tuple[RetaskReport, rb.Row, rb.Flight, float]:
    """Fly to mid-leg, replace the mission (renumbered), follow until B3 is reached or it lands."""
    flight = rb.start_flying(link, sysid, flavour, home, speedup, short=True, say=lambda text: None, speed=SPEED_M_S)
    started = time.monotonic()
    report = replace_mission_in_flight(flight.backend, flight.link, sysid, flavour, flight.new, flight.resume,
                                       started + RETASK_S, fence=square_fence(home))
    b3 = flight.b1 + len(rb.LOST) - 1
    obs = flight.observer
    rb.listen_for(flight.link, lambda: any(seq == b3 and t >= started for t, seq in obs.reached)
                  or bool(obs.beats and not obs.beats[-1][1]), time.monotonic() + rb.AFTER_S[flavour] / speedup)
    row = rb.judge(flight, "product", rb.Outcome(ack="ACCEPTED", upload_wall=(started, started + report.upload_s)),
                   time.monotonic())
    held = flight.backend.download(MissionType.FENCE)
    assert compare_wire(square_fence(home), held, skip_home=False, flavour=flavour) == [], held
    return report, row, flight, started


def check(report: RetaskReport, row: rb.Row, flight: rb.Flight, started: float) -> None:
    """What must hold on every autopilot, the mock included."""
    said = f"{report.summary()}\n{row}\n{rb.timeline(flight, rb.Outcome(upload_wall=(0.0, 0.0)))[-3000:]}"
    assert report.confirmed, said
    assert report.continued_at in (flight.resume, flight.b1) and report.read_back, said
    assert row.reached == len(rb.LOST), said  # B1, B2, B3, each where the vehicle was
    assert row.armed_airborne, said  # armed, above 5 m, until B1
    seqs = [int(s) for s in row.seq_path.split(">") if s]
    assert seqs and min(seqs) >= flight.resume, said  # never back to the take-off or item 0/1
    b = [flight.b1 + k for k in range(len(rb.LOST))]
    reached = [seq for t, seq in flight.observer.reached if t >= started and seq in b]
    assert list(dict.fromkeys(reached)) == b, said  # in order (PX4 repeats each report)


def test_arducopter_sitl_takes_a_new_mission_in_flight_and_flies_it(arducopter) -> None:  # noqa: F811
    vehicle = arducopter(sysid=1, speedup=rb.ARDUCOPTER_SPEEDUP)
    with Link(vehicle.url) as link:
        report, row, flight, started = retask_and_follow(link, 1, Flavour.ARDUPILOT, vehicle.home[:3],
                                                         rb.ARDUCOPTER_SPEEDUP)
    print(report.summary(), rb.line(row), sep="\n")
    check(report, row, flight, started)
    assert report.mode == "AUTO"


def test_px4_sih_takes_a_new_mission_in_flight_and_flies_it(px4) -> None:  # noqa: F811
    vehicle = px4()
    with Link(vehicle.gcs_url) as link:
        report, row, flight, started = retask_and_follow(link, vehicle.sysid, Flavour.PX4, vehicle.home, 1.0)
    print(report.summary(), rb.line(row), sep="\n")
    check(report, row, flight, started)
    assert report.mode == "MISSION"


@pytest.mark.parametrize("flavour", [Flavour.ARDUPILOT, Flavour.PX4], ids=["ardupilot", "px4"])
def test_the_mock_takes_a_new_mission_in_flight_as_the_autopilots_do(flavour: Flavour) -> None:
    """The same function and assertions against the mock's SITL-like flight (no real autopilot started:
    the SITL-side rows are the two tests above)."""
    home = (45.4643, 9.1895, 120.0)
    with MockAutopilot(homes={1: home}, flavour=flavour, speedup=10.0, sitl_like=True,
                       streams_until_asked=True, request_interval=0.1).start() as mock:
        with Link(mock.client_url) as link:
            report, row, flight, started = retask_and_follow(link, 1, flavour, home, 10.0)
    print(report.summary(), rb.line(row), sep="\n")
    check(report, row, flight, started)
