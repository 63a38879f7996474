"""What the drones' followers share: the links, the gates where they meet, the stop flag, the events.

fly makes one FleetStart for a flight and hands it to every drone's follower (drone_flight.DroneFlight):
the links (one shared connection per URL), the arm and start gates (FleetGate), the stop flag Ctrl-C
sets, how to say things (progress lines, alerts), the events each follower publishes (events.FlightEvents),
the rule of what a silence means (link_silence.SilenceRule) and, for a plan over a DEM, the ground each
ArduPilot vehicle is served (terrain_service.FleetTerrain).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from missionplan.bridge.link.readiness import DEFAULT_LAUNCH_OFFSET_M
from missionplan.bridge.link.shared_link import LinkPool
from missionplan.bridge.link.signing import SigningKey

from .events import FlightEvents
from .link_silence import SilenceRule
from .terrain_service import FleetTerrain

DEFAULT_READY_S = 120.0  # a real vehicle's GPS and EKF may take a minute or two after power-on


class FleetGate:
    """Where the drones' threads meet: nobody goes on before every drone has checked in once (or the wait ran
    out). fly has two: nobody arms before every drone is ready, uploaded and site-checked (arm_gate), and the
    armed drones start their missions together (start_gate). A drone that failed checks in without waiting,
    so the rest are not held up by it. A drone may check in with a veto (its site check failed, it was found
    armed): a wrong site, swapped system ids or a vehicle already flying is a fleet problem, and every drone
    hears the vetoes, so the fleet starts together or not at all."""

    def __init__(self, parties: int) -> None:
        self._waiting_for = parties
        self.vetoes: list[str] = []
        self._all_in = threading.Condition()

    def check_in(self, wait_s: float, veto: str = "") -> list[str]:
        """Check in (waiting up to wait_s for the others); the vetoes heard, [] when the fleet may go on."""
        with self._all_in:
            self._waiting_for -= 1
            if veto:
                self.vetoes.append(veto)
            if self._waiting_for <= 0:
                self._all_in.notify_all()
            elif wait_s > 0:
                self._all_in.wait_for(lambda: self._waiting_for <= 0, timeout=wait_s)
            return list(self.vetoes)


@dataclass
class FleetStart:
    """What the drones' threads share: the links, both gates, the stop flag, how to say things, the events."""

    pool: LinkPool
    arm_gate: FleetGate  # nobody arms before all are ready (or vetoed)
    start_gate: FleetGate  # the armed drones start together
    stop: threading.Event  # set on Ctrl-C: stop following, command nothing
    key: SigningKey | None = None  # for the links fly opens beside the pool (MAVSDK's upload)
    ready_s: float = DEFAULT_READY_S
    max_offset_m: float = DEFAULT_LAUNCH_OFFSET_M
    say: Callable[[str], None] = lambda text: None      # progress lines
    alert: Callable[[str], None] = lambda text: None    # what a crew must hear at once
    resume: bool = False
    time_scale: float | None = None  # vehicle seconds per second of ours, when known (a sped-up simulator)
    planned_s: dict[int, float] = field(default_factory=dict)  # each drone's planned flight, vehicle seconds
    # Until everything the records handed to the journal is committed; whether it is (fly: Journal.flush).
    # Asked before each arm command: a vehicle whose start cannot be recorded is not armed.
    commit: Callable[[], bool] = lambda: True
    # One log read at a time per link: three vehicles' LOG_DATA bursts into one ground-station socket at
    # once overflowed it, and ArduCopter SITL's downloads stalled half-way ("log incomplete").
    log_locks: dict[str, threading.Lock] = field(default_factory=dict)
    events: FlightEvents = field(default_factory=FlightEvents)  # what the followers decide and hear
    silence: SilenceRule = field(default_factory=SilenceRule)  # what a silence means (fly --replan-after)
    terrain: FleetTerrain | None = None  # a plan over a DEM: the ground its ArduPilot vehicles are served
    camera_records: bool = False  # plan --capture camera*: a MAVLink camera's CAMERA_IMAGE_CAPTURED are the photos
    capture: str = "relay"  # plan --capture: camera modes check each vehicle's camera before the upload (camera_check)

    def log_lock(self, url: str) -> threading.Lock:
        return self.log_locks.setdefault(url, threading.Lock())  # atomic: one lock per url, whoever asks first
