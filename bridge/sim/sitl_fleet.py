"""A fleet of ArduCopter SITL vehicles behind a loopback relay, set up as a team sets its drones up: what
`missionplan verify --sim sitl` flies, and what the flight-fault and survey tests fly (missionplan/testing/sitl_fleet.py
builds on it).

The fleet: one SITL vehicle per drone of a plan folder (system id K for uavK.plan, started at its launch point,
`--speedup`, each in its own temp folder, free instance numbers), each sending to a relay (udp_relay.UdpRelay,
`--serial0 udpclient:127.0.0.1:P`) that forwards to the port a ground station listens on (`udpin:127.0.0.1:Q`,
SitlFleet.url). The team's one-time set-up (configure: the camera, CAM1_TYPE = 1, and the parameters a run needs,
then a reboot) goes over the same relay before the flight; set_param_on_serial1 turns a simulator knob (SIM_*) over
a vehicle's own serial1, beside the ground station's link.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from .sitl_process import SPEEDUP, ArduCopterSitl, free_udp_port
from .udp_relay import UdpRelay

CONFIGURE_WAIT_S = 60.0  # wall seconds for a vehicle to be heard at all after its start
PARAM_CLOSE = 1e-3  # a parameter read back within this (relative) of what was set is set

# How a fleet makes a vehicle: (sysid, home, speedup, serial0) -> a vehicle not started yet.
VehicleMaker = Callable[[int, tuple[float, float, float, float], float, str], ArduCopterSitl]


@dataclass
class SitlFleet:
    """The vehicles, the relay in front of them, and where a ground station listens (url)."""

    plan_dir: Path
    relay: UdpRelay
    vehicles: list[ArduCopterSitl]
    url: str  # where the ground station listens (the relay forwards there)

    def vehicle(self, sysid: int) -> ArduCopterSitl:
        return next(v for v in self.vehicles if v.sysid == sysid)

    @property
    def sysids(self) -> list[int]:
        return [v.sysid for v in self.vehicles]


def plan_home(plan_dir: Path, sysid: int) -> tuple[float, float, float, float]:
    """Drone sysid's launch point as SITL's --home (lat, lon, alt, heading), from its uavK.plan."""
    from ..formats.missionfile import read_mission_file

    lat, lon, alt = read_mission_file(plan_dir / f"uav{sysid}.plan").mission.home
    return (float(lat), float(lon), float(alt), 0.0)


def plan_sysids(plan_dir: Path) -> tuple[int, ...]:
    """The drones of a plan folder: K of every uavK.plan (a later sortie, uavK-sJ.plan, is the same drone)."""
    return tuple(sorted(int(p.stem[3:]) for p in plan_dir.glob("uav*.plan") if p.stem[3:].isdigit()))


def sitl_vehicles(sitl_dir: Path) -> VehicleMaker:
    """Vehicles of the SITL folder sitl_dir (arducopter, copter.parm), each killed by the kernel should the thread
    that started it die without stopping it."""
    def make(sysid: int, home: tuple[float, float, float, float], speedup: float, serial0: str) -> ArduCopterSitl:
        return ArduCopterSitl(sysid=sysid, home=home, speedup=speedup, serial0=serial0, sitl_dir=sitl_dir,
                              die_with_parent=True)
    return make


@contextlib.contextmanager
def start_sitl_fleet(plan_dir: Path, make: VehicleMaker, sysids: tuple[int, ...] | None = None,
                     speedup: float = SPEEDUP) -> Iterator[SitlFleet]:
    """One SITL vehicle per drone of plan_dir (or of `sysids`) at its launch point, sending through a relay
    to a free udpin port (SitlFleet.url); every vehicle stopped (its process group killed) and the relay closed
    when the block ends, whatever happened. Not configured: call configure() before flying."""
    port = free_udp_port()
    vehicles: list[ArduCopterSitl] = []
    with UdpRelay(port) as relay:
        try:
            for k in sysids or plan_sysids(plan_dir):
                # start() returns once SITL has bound its ports, so the next vehicle's instance differs
                vehicles.append(make(k, plan_home(plan_dir, k), speedup, f"udpclient:127.0.0.1:{relay.vehicle_port}"))
                vehicles[-1].start(wait=False)
            yield SitlFleet(plan_dir, relay, vehicles, f"udpin:127.0.0.1:{port}")
        finally:
            for vehicle in vehicles:
                vehicle.stop()


def _same(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=PARAM_CLOSE, abs_tol=1e-6)


def configure(fleet: SitlFleet, params: dict[str, float] | None = None,
              per_vehicle: dict[int, dict[str, float]] | None = None) -> None:
    """The team's one-time set-up over the relay: the camera (CAM1_TYPE = 1; without it ArduCopter sends
    no CAMERA_FEEDBACK), `params` on every vehicle and `per_vehicle[sysid]` on that one, then a reboot for them to
    take effect (parameters set are stored: they hold after it). What this sent is then forgotten by the relay: only
    the flight's own messages count. A parameter the vehicle does not take (unknown, or read back otherwise) is a
    RuntimeError naming it."""
    from ..link.connection import mavlink, wait_vehicle
    from ..link.params import ParamClient
    from ..link.shared_link import SharedLink

    with SharedLink(fleet.url) as shared:
        for sysid in fleet.sysids:
            wanted = {"CAM1_TYPE": 1.0, **(params or {}), **(per_vehicle or {}).get(sysid, {})}
            view = shared.vehicle(sysid)
            client = ParamClient(view, wait_vehicle(view, sysid, timeout=CONFIGURE_WAIT_S))
            for name, value in wanted.items():
                got = client.set(name, value)
                if got is None or not _same(float(got), value):
                    raise RuntimeError(f"vehicle {sysid} did not take {name} = {value:g} (read back {got})")
        for sysid in fleet.sysids:
            result = shared.vehicle(sysid).command_long(sysid, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0],
                                                        time.monotonic() + 10.0)
            if result != mavlink.MAV_RESULT_ACCEPTED:
                raise RuntimeError(f"vehicle {sysid} refused the reboot (MAV_RESULT {result})")
    fleet.relay.forget()


def set_param_on_serial1(vehicle: ArduCopterSitl, name: str, value: float, timeout: float = 10.0) -> float:
    """PARAM_SET over the vehicle's own serial1 (TCP 5762 + 10 I), beside the ground station's link: the
    simulator's knob, not something a ground station would send. Returns the value read back."""
    from ..link.connection import Link, wait_vehicle
    from ..link.params import ParamClient

    with Link(vehicle.serial1_url) as link:
        info = wait_vehicle(link, vehicle.sysid, timeout=timeout)  # it speaks MAVLink there: its HEARTBEAT
        got = ParamClient(link, info).set(name, value)
    if got is None or not _same(float(got), value):
        raise RuntimeError(f"vehicle {vehicle.sysid} did not take {name} = {value:g} on serial1 (read back {got})")
    return float(got)
