"""The mock's flight model flown on its own, without MAVLink: a mission's items from MISSION_START to disarm,
the track the tests set against the planned timeline and against the real autopilots' flights."""

from __future__ import annotations

import math

import numpy as np

from missionplan.bridge.flight_models.copter_model import CopterParams
from missionplan.bridge.flight_models.px4_model import Px4Params
from missionplan.bridge.formats.mission_items import Flavour, Mission, to_wire
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS, FlightSim


def fly_sim(mission: Mission, home: tuple[float, float, float], px4: Px4Params | None = None,
            dt: float = 0.05, limit_s: float = 900.0) -> np.ndarray:
    """(n, 5) t, north, east (metres from `home`), up and ground speed of the SITL-like FlightSim flying
    `mission` (ArduCopter's flight model, PX4's with `px4`) from MISSION_START until it disarms; AssertionError
    when it is still armed after `limit_s` simulated seconds."""
    sim = FlightSim(home, cruise_speed=5.0, copter=CopterParams(), px4=px4, track_interval=0.0)
    sim.load(to_wire(mission, Flavour.PX4), 0)  # PX4's wire: no home item, seq 0 is the take-off
    sim.state.armed = True
    sim.start_mission()
    lat0, lon0 = math.radians(home[0]), math.radians(home[1])
    rows = [(0.0, 0.0, 0.0, 0.0, 0.0)]
    while sim.state.armed and sim.state.sim_time < limit_s:
        sim.advance(dt)
        s = sim.state
        rows.append((s.sim_time, (math.radians(s.lat) - lat0) * EARTH_RADIUS,
                     (math.radians(s.lon) - lon0) * EARTH_RADIUS * math.cos(lat0), s.alt, math.hypot(s.vn, s.ve)))
    assert not sim.state.armed, "the SITL-like flight did not end disarmed"
    return np.array(rows)
