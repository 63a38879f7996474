"""Two speeds in one mission on the real autopilots: a resumed sortie built by drone_missions.build_mission with a
transit speed (out and home at TRANSIT m/s, the survey at SURVEY m/s, DO_CHANGE_SPEED items where the phase
changes), flown by ArduCopter SITL and by PX4 SIH, and by the mock of each.

From the vehicle's own reports (GLOBAL_POSITION_INT: its clock, position and ground velocity) each leg's cruise
ground speed (the 90th percentile between 10 % and 90 % of the leg) must be the speed timeline.leg_speeds gives that leg, the
flown time (mission start to disarm, on the vehicle's clock) must be the planned timeline's (planned_motions with
those leg speeds) within the tolerance of the other timeline tests, and the mock, flying the same items, must
fly the same leg speeds and end within that tolerance of the autopilot's time. Legs of 100 m: long enough to
reach 5 m/s and cruise at it. Skips with a reason when a simulator is absent.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pytest

from missionplan.bridge.flight_models.copter_model import total_time
from missionplan.bridge.flight_models.px4_model import Px4Params
from missionplan.bridge.formats.mission_items import Flavour, Mission
from missionplan.bridge.link.connection import Link, mavlink
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.sim.mock_flight import EARTH_RADIUS
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.mission.drone_missions import DroneMission, MissionSettings, build_mission
from missionplan.mission.timeline import FlightModel, leg_speeds, planned_motions
from missionplan.testing.sim_flight import fly_sim

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

HOME = (45.4643, 9.1895, 120.0)  # lat, lon, altitude above sea level (Milan)
ALTITUDE_M = 20.0
SURVEY, TRANSIT = 2.0, 5.0  # m/s: the transit speed is the plans' default (the cruise speed)
# North, east metres from home: out 100 m north, onto the survey 100 m east, the survey leg 100 m south, home.
OUT = np.array([[100.0, 0.0]])
SURVEY_WAYPOINTS = np.array([[100.0, 100.0], [0.0, 100.0]])
BACK = np.array([[0.0, 0.0]])
TOLERANCE = 0.15  # the timeline tests' promise: planned within 15 % of flown
TELEMETRY_HZ = 10.0
M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS


def _latlon(points_m: np.ndarray) -> np.ndarray:
    return np.column_stack([HOME[0] + points_m[:, 0] / M_PER_DEG_LAT,
                            HOME[1] + points_m[:, 1] / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))])


def _local_m(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """(n, 2) north, east metres from HOME."""
    return np.column_stack([(lat - HOME[0]) * M_PER_DEG_LAT,
                            (lon - HOME[1]) * M_PER_DEG_LAT * math.cos(math.radians(HOME[0]))])


def _settings(autopilot: str) -> MissionSettings:
    return MissionSettings(altitude_m=ALTITUDE_M, footprint_m=18.0, speed_m_s=SURVEY, transit_speed_m_s=TRANSIT,
                           autopilot=autopilot)


def _mission(autopilot: str) -> DroneMission:
    """The resumed sortie: out with the camera off, the survey, home, RTL."""
    return build_mission(0, HOME[:2], _latlon(SURVEY_WAYPOINTS), SURVEY_WAYPOINTS, np.zeros(2), _settings(autopilot),
                         resumes=True, transit=(_latlon(OUT), OUT), back=(_latlon(BACK), BACK))


def _model(autopilot: str) -> FlightModel:
    settings = _settings(autopilot)
    return FlightModel.for_autopilot(autopilot, settings.speed_m_s, settings.acceptance_m, settings.transit_speed_m_s)


def _planned(autopilot: str) -> tuple[np.ndarray, float]:
    """The speed of the leg into each waypoint and the planned flight's duration (take-off to disarm)."""
    model = _model(autopilot)
    speeds = leg_speeds(model, len(OUT), len(SURVEY_WAYPOINTS), len(BACK), resumes=True)
    motions = planned_motions(np.zeros(2), np.vstack([OUT, SURVEY_WAYPOINTS, BACK]), ALTITUDE_M, "rtl", model, speeds)
    return speeds, total_time(motions)


@dataclass
class Flown:
    """One flight as the vehicle reported it: rows of (t s from the mission start, north m, east m, ground speed m/s)."""

    track: np.ndarray
    seconds: float  # mission start to disarm

    def cruise_speeds(self) -> list[float]:
        """The speed each leg cruises at: the 90th percentile of the ground speed between 10 % and 90 % of the leg
        into each waypoint (NaN: no sample there). Not the median: PX4 SIH creeps up to its set speed over a leg."""
        corners = np.vstack([np.zeros(2), OUT, SURVEY_WAYPOINTS, BACK])
        out = []
        for a, b in zip(corners[:-1], corners[1:]):
            along = b - a
            share = (self.track[:, 1:3] - a) @ along / (along @ along)
            rel = self.track[:, 1:3] - a
            off = np.abs(rel[:, 0] * along[1] - rel[:, 1] * along[0]) / np.linalg.norm(along)
            middle = (share > 0.1) & (share < 0.9) & (off < 5.0)
            out.append(float(np.percentile(self.track[middle, 3], 90)) if middle.any() else math.nan)
        return out


def _fly_vehicle(url: str, sysid: int, mission: Mission, timeout_s: float) -> Flown:
    """Upload, arm (ArduPilot in GUIDED), MISSION_START (retried while PX4 has not taken the new mission), and
    the vehicle's positions until it disarms."""
    deadline = time.monotonic() + timeout_s
    with Link(url) as link:
        session = VehicleSession.open(link, sysid, 30.0, Timeouts())
        assert "GLOBAL_POSITION_INT" not in session.request_streams(TELEMETRY_HZ, deadline)  # PX4 refuses some others
        assert session.wait_ready(min(deadline, time.monotonic() + 120.0)) == []
        session.mission.upload([mission])
        if session.flavour is Flavour.ARDUPILOT:
            session.action.guided(deadline)
        armed, why = session.action.arm(deadline)
        assert armed, why
        start_by = min(deadline, time.monotonic() + 20.0)
        while (result := session.action.start_mission(deadline)) != mavlink.MAV_RESULT_ACCEPTED:
            assert time.monotonic() < start_by, f"MISSION_START refused: {result}"
            session.listen(time.monotonic() + 0.5)
        rows: list[tuple[float, float, float, float]] = []
        flying = True
        while flying and (msg := session.recv(deadline)) is not None:
            session.take(msg)
            if msg.get_srcSystem() != sysid:
                continue
            if msg.get_type() == "GLOBAL_POSITION_INT":
                north, east = _local_m(np.array([msg.lat / 1e7]), np.array([msg.lon / 1e7]))[0]
                rows.append((msg.time_boot_ms / 1000.0, north, east, math.hypot(msg.vx, msg.vy) / 100.0))
            elif msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1:
                flying = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        assert not flying, "the vehicle did not disarm in time"
        session.close()
    track = np.array(rows)
    track[:, 0] -= track[0, 0]
    return Flown(track, float(track[-1, 0]))


def _fly_mock(mission: Mission, autopilot: str) -> Flown:
    """The mock's SITL-like flight of the same items (the autopilot's flavour), MISSION_START to disarm:
    t, north, east, ground speed."""
    flown = fly_sim(mission, (*HOME[:2], 0.0), px4=Px4Params() if autopilot == "px4" else None)
    return Flown(flown[:, [0, 1, 2, 4]], float(flown[-1, 0]))


def _check(autopilot: str, name: str, flown: Flown) -> None:
    speeds, planned_s = _planned(autopilot)
    assert speeds.tolist() == [TRANSIT, TRANSIT, SURVEY, TRANSIT]  # out, onto the survey, the survey, home
    mocked = _fly_mock(_mission(autopilot).mission, autopilot)
    real, mock = flown.cruise_speeds(), mocked.cruise_speeds()
    print(f"\n{name}: leg speeds set {speeds.tolist()}, flown {np.round(real, 2).tolist()}, "
          f"mock {np.round(mock, 2).tolist()}; flown {flown.seconds:.1f} s, planned {planned_s:.1f} s, "
          f"mock {mocked.seconds:.1f} s")
    assert np.allclose(real, speeds, rtol=TOLERANCE), f"{name} flew legs at {real}, the mission set {list(speeds)}"
    assert abs(planned_s - flown.seconds) <= TOLERANCE * flown.seconds, (planned_s, flown.seconds)
    assert np.allclose(mock, real, rtol=TOLERANCE), f"the mock flew legs at {mock}, {name} at {real}"
    assert abs(mocked.seconds - flown.seconds) <= TOLERANCE * flown.seconds, (mocked.seconds, flown.seconds)


def test_arducopter_flies_the_way_out_and_home_at_the_transit_speed_and_the_survey_at_its_own(arducopter) -> None:
    vehicle = arducopter(sysid=1, home=(*HOME, 0.0))
    flown = _fly_vehicle(vehicle.url, 1, _mission("ardupilot").mission, timeout_s=300.0)
    _check("ardupilot", "ArduCopter", flown)


def test_px4_flies_the_way_out_and_home_at_the_transit_speed_and_the_survey_at_its_own(px4) -> None:
    vehicle = px4(home=HOME)
    flown = _fly_vehicle(vehicle.offboard_url, vehicle.sysid, _mission("px4").mission, timeout_s=400.0)
    _check("px4", "PX4", flown)
