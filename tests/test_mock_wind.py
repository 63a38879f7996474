"""The mock autopilot in wind and with a GPS glitch (flight_models/wind.py, bridge/sim/gps_glitch.py), without SITL.

The kinematic checks fly a FlightSim directly (no link); the checks of what a ground station sees fly a SITL-like
ArduPilot mock over MAVLink with missionplan/testing/wind_flight.py (marked `flight`). sitl_tests/test_wind_sitl.py
flies the same mission on ArduCopter SITL and compares.
"""

from __future__ import annotations

import math

import pytest

from missionplan.bridge.flight_models.copter_model import CopterParams, Motion
from missionplan.bridge.flight_models.wind import (GUST_BOUND, GUST_SCALE, Wind, WindField, current_factor,
                                                   ground_speed_bound)
from missionplan.bridge.link.connection import Link, wait_vehicle
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.sim.gps_glitch import CLEARED_TEXT, GLITCH_TEXT
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.sim.mock_flight import FlightSim
from missionplan.testing.wind_flight import wind_mission, fly_wind_mission

HOME = (45.4643, 9.1895, 120.0)
SPEEDUP = 25.0  # the mock's clock: a 150 s flight in ~6 s


def _fly(wind: WindField | None, speed: float = 10.0, step: float = 0.37) -> tuple[dict[int, float], list[tuple]]:
    """The wind mission flown by a SITL-like FlightSim: (seq -> simulated time reached, the track)."""
    sim = FlightSim(HOME, cruise_speed=speed, copter=CopterParams())
    sim.wind = wind
    sim.load(wind_mission(HOME), 1)
    sim.state.armed = True
    sim.start_mission()
    reached: dict[int, float] = {}
    for _ in range(10_000):
        for event in sim.advance(step):
            if event.kind == "reached":
                reached.setdefault(event.seq, sim.state.sim_time)
        if not sim.state.armed:
            break
    return reached, sim.state.track


def _leg_s(reached: dict[int, float], seq: int) -> float:
    return reached[seq] - reached[seq - 1]


def test_calm_changes_nothing() -> None:
    plain = _fly(None)
    assert _fly(WindField(Wind())) == plain  # calm, SITL's defaults
    assert _fly(WindField(Wind(0.0, 90.0, 0.0), seed=5)) == plain
    legs = [Motion((0, 0, 20), (150, 0, 20), 10.0, 2.5, kind="leg")]
    assert WindField(Wind()).apply(legs) is legs
    assert current_factor((3.0, 4.0), (0.0, 0.0), 0.0) == 1.0 and WindField(Wind()).current_factor(3.0, 4.0) == 1.0
    assert ground_speed_bound(15.0, (1.0, 0.0), (0.0, 0.0)) == 15.0  # a calm flight faster than SITL's bound too


def test_a_headwind_slows_a_leg_only_past_the_lean_limit() -> None:
    calm = _fly(None)[0]
    into = _fly(WindField(Wind(8.0, 0.0)))[0]  # from the north: the first leg (seq 3) flies into it
    assert _leg_s(into, 3) > _leg_s(calm, 3) + 8.0  # SITL: 31.4 s against 20.4 s calm
    assert _leg_s(into, 5) == pytest.approx(_leg_s(calm, 5), abs=0.01)  # with it: no faster than commanded
    slow_calm, slow_into = _fly(None, speed=5.0)[0], _fly(WindField(Wind(4.0, 0.0)), speed=5.0)[0]
    assert _leg_s(slow_into, 3) == pytest.approx(_leg_s(slow_calm, 3), abs=0.01)  # SITL: 5 m/s kept up to 8 m/s
    # The bound itself, against SITL's ground speeds into the wind (10 m/s commanded) and across it.
    for head, measured in ((2, 8.88), (4, 7.73), (6, 6.57), (8, 5.43), (12, 3.11)):
        assert ground_speed_bound(10.0, (1.0, 0.0), (-head, 0.0)) == pytest.approx(measured, abs=0.1)
    assert ground_speed_bound(10.0, (1.0, 0.0), (0.0, 12.0)) == pytest.approx(8.77, abs=0.1)


def test_turbulence_is_bounded_and_repeats_with_its_seed() -> None:
    gusty = Wind(6.0, 45.0, 3.0)
    one, again, other = (_fly(WindField(gusty, seed=s))[1] for s in (7, 7, 8))
    assert one == again and one != other
    field = WindField(gusty, seed=3)
    steady = gusty.air_motion()
    for _ in range(200):
        field.apply([Motion((0, 0, 20), (100, 0, 20), 10.0, 2.5, kind="leg")])
        assert all(abs(a - b) <= GUST_BOUND * GUST_SCALE * gusty.turbulence + 1e-9 for a, b in zip(field.air, steady))


def test_param_set_of_the_wind_reaches_the_flight() -> None:
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[1, 2], homes={1: HOME}, sitl_like=True) as mock:
        with Link(mock.client_url) as link:
            params = ParamClient(link, wait_vehicle(link, 1, timeout=5.0))
            assert params.get("SIM_WIND_DIR") == 180.0  # SITL's default
            assert params.set("SIM_WIND_SPD", 6.0) == 6.0
            assert params.get("SIM_GPS1_GLTCH_X") == 0.0
        assert mock.wait_until(lambda m: m.vehicle(1).wind_field is not None
                               and m.vehicle(1).wind_field.wind.speed == 6.0, 5.0)
        assert mock.vehicle(1).flight.wind is mock.vehicle(1).wind_field
        assert mock.vehicle(2).wind_field is None  # the other vehicle stays calm
        mock.set_wind(3.0, 270.0, 1.0)  # every vehicle
        assert mock.wait_until(lambda m: all(v.wind_field is not None and v.wind_field.wind == Wind(3.0, 270.0, 1.0)
                                             for v in m.vehicles.values()), 5.0)


def _mock_flight(wind: tuple[float, float, float], glitch: tuple[int, float, float, float] | None = None):
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[1], homes={1: HOME}, speedup=SPEEDUP, sitl_like=True,
                       cruise_speed=10.0) as mock:
        record = fly_wind_mission(mock.client_url, 1, HOME, wind, stream_scale=1 / SPEEDUP, timeout_s=60.0,
                                  glitch=glitch)
        return record, mock.vehicle(1).consumed_mah


@pytest.mark.flight
def test_wind_costs_battery_and_time() -> None:
    calm, calm_mah = _mock_flight((0.0, 0.0, 0.0))
    windy, windy_mah = _mock_flight((8.0, 0.0, 0.0))
    assert calm.legs[0].current_a == pytest.approx(10.0)  # the calm current, BATTERY_CURRENT_A
    assert windy.legs[0].ground_speed == pytest.approx(5.4, abs=0.3)  # into the wind (SITL: 5.43 m/s)
    assert windy.legs[2].current_a < 10.0 < windy.legs[0].current_a  # with the wind less, into it more
    assert windy.flight_s > calm.flight_s + 8.0
    assert windy_mah > calm_mah * 1.05  # SITL: +9 % over this mission, mostly the longer flight


@pytest.mark.flight
def test_a_gps_glitch_is_refused_then_taken_then_cleared() -> None:
    short, _ = _mock_flight((0.0, 0.0, 0.0), glitch=(4, 20.0, 0.0, 5.0))
    texts = [text for _, text, _ in short.texts]
    assert GLITCH_TEXT in texts and CLEARED_TEXT in texts
    assert short.legs[1].cross_track_m < 1.0  # refused by the EKF: the reported track never moved
    long, _ = _mock_flight((0.0, 0.0, 0.0), glitch=(4, 20.0, 0.0, 15.0))
    assert long.legs[1].cross_track_m == pytest.approx(20.0, abs=1.0)  # taken after 10 s: the estimate jumped
    assert GLITCH_TEXT in [text for _, text, _ in long.texts]
    assert math.isfinite(long.flight_s) and sorted(long.reached)[-1] == 6  # and the mission flew on to its landing
