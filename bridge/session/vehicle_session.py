"""One vehicle as the ground station talks to it: found on its link, its state as heard, and its plugins.

A VehicleSession is opened on a vehicle's link (a link.connection.Link, or in fly its view of a shared
link) and owns every request the ground station makes of that vehicle, one place each, as MAVSDK's
plugins do:
- action (session.action.Action): modes, arming, the mission start, hold, release, return, land;
- mission (session.mission.MissionPlugin): upload with read-back, read back, replace in flight;
- telemetry (request_streams here): the streams a follower reads, asked for by SET_MESSAGE_INTERVAL;
- parameters (navigation_params here): the navigation parameters a vehicle flies with;
- logs (photos_from_log here): the photos read from the vehicle's own log after landing;
- terrain (serve_terrain here, session.terrain): the ground served to an ArduPilot vehicle that asks.
Everything the vehicle sends while one of these waits goes to the session's `take` (its readiness
state, then `observe`: a follower's record), so nothing it says is dropped.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from typing import Any

from ..flight_models.copter_model import PARAMETERS as COPTER_PARAMETERS
from ..flight_models.px4_model import FLOAT_PARAMETERS as PX4_PARAMETERS
from ..formats.mission_items import Flavour
from ..link.params import ParamClient, read_params
from ..link.readiness import Say, Vehicle, VehicleState, request_streams, stream_rates
from ..transfer.onboard_log import LoggedPhoto, recover_photos
from ..transfer.protocol import Timeouts
from ..transfer.uploader import MissionBackend, open_backend
from .action import Action
from .mission import MissionPlugin
from .terrain import TerrainServer

# The parameters a vehicle's flight is re-timed with (its autopilot's flight model), by autopilot.
NAVIGATION_PARAMETERS = {Flavour.ARDUPILOT: list(COPTER_PARAMETERS), Flavour.PX4: list(PX4_PARAMETERS)}


class VehicleSession:
    """One vehicle on its link: `action`, `mission`, and the streams, parameters and log it is asked for."""

    def __init__(self, backend: MissionBackend, vehicle: Vehicle) -> None:
        self.backend, self.vehicle = backend, vehicle
        self.link: Any = vehicle.link
        self.sysid, self.flavour = vehicle.sysid, vehicle.info.flavour
        self.action = Action(self.link, vehicle)
        self.mission = MissionPlugin(backend, vehicle)
        self.terrain_server: TerrainServer | None = None

    @classmethod
    def open(cls, link: Any, sysid: int, connect_s: float, timeouts: Timeouts, say: Say | None = None,
             observe: Callable[[Any], None] | None = None) -> VehicleSession:
        """Find vehicle `sysid` on `link` (its HEARTBEAT within connect_s; BridgeError naming it otherwise).
        say: progress lines (what the vehicle says, what it waits for); observe: every message of the
        vehicle taken while a request waits (after its readiness state has taken it)."""
        backend = open_backend("pymavlink", link.url, sysid, timeouts=timeouts, connect_timeout=connect_s, link=link)
        return cls(backend, Vehicle(link, backend.vehicle, say, also=observe))

    @property
    def state(self) -> VehicleState:
        """What the vehicle's telemetry says: armed, mode, landed state, readiness, what it said."""
        return self.vehicle.state

    def take(self, msg: Any) -> None:
        """One message heard from the vehicle: its state, then the observer."""
        self.vehicle.take(msg)

    def recv(self, deadline: float) -> Any | None:
        """The next message on the link (any system's on a plain link), None once deadline passes."""
        return self.link.recv(deadline)

    def listen(self, until: float) -> None:
        """Take the vehicle's messages until then."""
        self.vehicle.listen(until)

    def wait_heartbeat(self, until: float) -> None:
        """Until a HEARTBEAT said whether it is armed (or until then)."""
        while self.state.armed is None and (msg := self.recv(until)) is not None:
            self.take(msg)

    def wait_ready(self, deadline: float) -> list[str]:
        """GPS, EKF, home and pre-arm checks (readiness.Vehicle.wait_ready): what is still missing."""
        return self.vehicle.wait_ready(deadline)

    def reboots(self) -> int:
        """How many times the link has seen this vehicle reboot (a boot heartbeat, its clock restarted)."""
        reboots: int = self.link.reboots.get(self.sysid, 0)
        return reboots

    def ack_rtt_s(self) -> float | None:
        """The slowest command round trip this vehicle's link has shown (None: none measured yet)."""
        rtt: float | None = self.link.ack_rtt_s.get(self.sysid)
        return rtt

    def signing_hint(self) -> str:
        """Why the vehicle may not answer, when MAVLink 2 signing is the likely reason ('' otherwise)."""
        hint: str = self.link.signing_hint(self.sysid)
        return hint

    def serve_terrain(self, server: TerrainServer | None) -> None:
        """From now on answer the vehicle's TERRAIN_REQUESTs from `server` in every wait that reads it
        (readiness, commands, a follower's loop: they all go through the vehicle's `take`); None stops.
        Messages read by the mission transfers and parameter requests are not taken: a request lost
        there is asked again by the vehicle (every 2 s of its clock)."""
        self.terrain_server = server
        self.vehicle.terrain = None if server is None else partial(server.answer, self.link)

    # ------------------------------------------------------------------ telemetry, parameters, logs
    def request_streams(self, telemetry_hz: float, deadline: float) -> list[str]:
        """Every stream a follower reads (positions at telemetry_hz); the names of those not accepted."""
        return request_streams(self.link, self.sysid, stream_rates(telemetry_hz, self.flavour), deadline,
                               other=self.vehicle.take)

    def navigation_params(self) -> dict[str, float] | None:
        """The navigation parameters it will fly with, as it reports them (None: an autopilot without a
        flight model here)."""
        names = NAVIGATION_PARAMETERS.get(self.flavour)
        if names is None:
            return None
        return read_params(ParamClient(self.link, self.backend.vehicle), names)

    def photos_from_log(self, deadline: float, wanted: set[int] | None, since_utc: float | None,
                        save_dir: str | os.PathLike[str]) -> list[LoggedPhoto]:
        """The photos the vehicle logged (transfer.onboard_log.recover_photos; it must be disarmed)."""
        return recover_photos(self.link, self.sysid, self.flavour, deadline, wanted=wanted, since_utc=since_utc,
                              save_dir=save_dir)

    def close(self) -> None:
        self.backend.close()
