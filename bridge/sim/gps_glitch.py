"""A GPS glitch on a mock vehicle, as ArduCopter SITL's SIM_GPS1_GLTCH_X / _Y and its EKF answer it.

Owns, for one mock vehicle (mock_vehicle), the glitch: the offset SITL adds to its simulated GPS (SIM_GPS1_GLTCH_X
and _Y, in DEGREES of latitude and longitude, added as they are; _Z, metres, kept but not flown), what
GPS_RAW_INT then reports, and what the vehicle's position estimate (GLOBAL_POSITION_INT, and the position the
mission is flown on) does. Measured on ArduCopter 4.7 SITL with 20 and 30 m offsets set on a 150 m leg and
cleared 5, 10 and 15 s later (docs/wind-model.md, bench/wind_bench.py --glitch):

- GPS_RAW_INT jumps by the offset at once (SITL's 100 ms GPS lag aside);
- the EKF refuses the GPS: the reported position and the flight go on unchanged, and GLITCH_TEXT_S later
  "GPS Glitch or Compass error" (severity CRITICAL);
- a glitch cleared within RESET_S leaves no more trace: "Glitch cleared" (CRITICAL) 10-12 s after it went;
- a glitch still there RESET_S after it came: the EKF takes the GPS again and its estimate jumps by the
  offset. The vehicle flies its mission on that estimate, so GLOBAL_POSITION_INT jumps, the copter turns back
  to its line in the estimate (measured: a 20 m cross-track jump back to the leg within ~5 s), and the true
  track is off by the offset; once the GPS is right again the estimate jumps back RESET_S later (the true
  track offset ends then), and "Glitch cleared" comes CLEARED_S after that. The mission goes on throughout
  (every item reached, RTL and landing where the estimate says home is, within a metre of the truth again).

Here the estimate is the mock's flight state: a jump moves it and the motion flown now is made again from
there (flight_models: from rest, where SITL blended on; measured +2 s on the leg). Not modelled: the EKF's lane
switches and their texts ("EKF3 lane switch", "EKF primary changed"), the altitude glitch (_Z), SIM_GPS1_GLTV
(velocity glitch), the glitch's effect before the GPS fix, the few-second convergence back to the line (the
mock's leg from the jumped estimate is flown straight to the waypoint) and the true track (true_position gives
where the vehicle really is: the estimate less the offset the EKF took).
"""

from __future__ import annotations

import math
from typing import Any

from ..link.connection import mavlink

GLITCH_PARAMS = {"SIM_GPS1_GLTCH_X": 0.0, "SIM_GPS1_GLTCH_Y": 0.0, "SIM_GPS1_GLTCH_Z": 0.0}
GLITCH_TEXT, CLEARED_TEXT = "GPS Glitch or Compass error", "Glitch cleared"
GLITCH_TEXT_S = 2.0  # simulated seconds from the glitch to its text (measured 2.0-2.4)
RESET_S = 10.0       # of disagreement before the EKF takes the GPS again (measured 9.7-10.8)
CLEARED_S = 10.0     # of agreement at no offset before "Glitch cleared" (measured 10-12)
EARTH_RADIUS = 6_378_137.0
SAME_M = 1e-3


def glitch_params(north_m: float, east_m: float, lat: float) -> dict[str, float]:
    """SIM_GPS1_GLTCH_X / _Y for an offset in metres at latitude `lat`: SITL adds them to the GPS in degrees."""
    return {"SIM_GPS1_GLTCH_X": math.degrees(north_m / EARTH_RADIUS),
            "SIM_GPS1_GLTCH_Y": math.degrees(east_m / (EARTH_RADIUS * math.cos(math.radians(lat))))}


class GpsGlitch:
    """One vehicle's GPS glitch: call tick() with its simulated time."""

    def __init__(self, vehicle: Any) -> None:
        self.vehicle = vehicle
        self.on_boot()

    def on_boot(self) -> None:
        self.taken = (0.0, 0.0)  # the offset (north, east m) the position estimate carries
        self._disagree_since: float | None = None
        self._agree_since: float | None = None
        self.announced = False

    def offset(self) -> tuple[float, float]:
        """The glitch now (north, east metres) from SITL's parameters (degrees)."""
        params, lat = self.vehicle.params, self.vehicle.options.home[0]
        north = math.radians(params.get("SIM_GPS1_GLTCH_X", 0.0)) * EARTH_RADIUS
        east = math.radians(params.get("SIM_GPS1_GLTCH_Y", 0.0)) * EARTH_RADIUS * math.cos(math.radians(lat))
        return north, east

    def _moved(self, lat: float, lon: float, north: float, east: float) -> tuple[float, float]:
        lat0 = self.vehicle.options.home[0]
        return (lat + math.degrees(north / EARTH_RADIUS),
                lon + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0)))))

    def raw_position(self, lat: float, lon: float) -> tuple[float, float]:
        """What GPS_RAW_INT reports for the estimate (lat, lon): the truth plus the glitch."""
        north, east = self.offset()
        return self._moved(lat, lon, north - self.taken[0], east - self.taken[1])

    def true_position(self, lat: float, lon: float) -> tuple[float, float]:
        """Where the vehicle really is when its estimate says (lat, lon)."""
        return self._moved(lat, lon, -self.taken[0], -self.taken[1])

    def tick(self, sim_time: float) -> None:
        gps = self.offset()
        if math.dist(gps, self.taken) > SAME_M:  # the GPS and the estimate disagree
            self._agree_since = None
            if self._disagree_since is None:
                self._disagree_since = sim_time
            elapsed = sim_time - self._disagree_since
            if not self.announced and math.hypot(*gps) > SAME_M and elapsed >= GLITCH_TEXT_S:
                self.announced = True
                self.vehicle.telemetry.send_text(GLITCH_TEXT, mavlink.MAV_SEVERITY_CRITICAL)
            if elapsed >= RESET_S:
                self._jump(gps)
            return
        self._disagree_since = None
        if self.announced and math.hypot(*gps) <= SAME_M:
            self._agree_since = sim_time if self._agree_since is None else self._agree_since
            if sim_time - self._agree_since >= CLEARED_S:
                self.announced = False
                self.vehicle.telemetry.send_text(CLEARED_TEXT, mavlink.MAV_SEVERITY_CRITICAL)

    def _jump(self, gps: tuple[float, float]) -> None:
        """The EKF takes the GPS: its estimate (the flight's position) jumps, and the flight goes on from there."""
        flight = self.vehicle.flight
        s = flight.state
        s.lat, s.lon = self._moved(s.lat, s.lon, gps[0] - self.taken[0], gps[1] - self.taken[1])
        self.taken = gps
        self._disagree_since = None
        flight.replan()
