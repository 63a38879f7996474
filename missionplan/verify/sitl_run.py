"""One verification run on real ArduCopter SITL (`verify --sim sitl`): the plan folder's fleet started, set up as a
team sets it up, flown by `fly`'s own logic in the run's wind and faults, and read back as the mock run is
(flight_run.fly_on_mock): fly's judgement (flight.json's content) and the simulator's own truth.

The fleet (missionplan.bridge.sim.sitl_fleet): one SITL vehicle per drone (system id K for uavK.plan, home at its
launch point, --speedup the run's time scale capped at MAX_SPEEDUP, -w, each in its own temp folder on free instance
numbers), all sending through a loopback relay (missionplan.bridge.sim.udp_relay) to the port `fly` listens on. The
set-up goes over the relay before the flight, then a reboot: the camera (CAM1_TYPE 1), the wind (SIM_WIND_SPD,
SIM_WIND_DIR, SIM_WIND_TURB) and, for a battery failsafe, BATT_FS_LOW_ACT 2 (RTL) with BATT_LOW_VOLT 10.5 on that
drone. Every process is stopped at the end, whatever happened (process groups killed, bounded waits).

A fault strikes when its drone has reached the fault's mission item, as the relay sees the vehicle say it
(MISSION_ITEM_REACHED, or MISSION_CURRENT past the item): the vehicles' ground truth, never what `fly` says.
- lost-drone: the vehicle's process group SIGKILLed (silent for good, no goodbye);
- battery-failsafe: SIM_BATT_VOLTAGE 10.0 over the vehicle's serial1 (below BATT_LOW_VOLT: ArduCopter's own
  failsafe after BATT_LOW_TIMER, then RTL);
- link-gap: the relay drops everything both ways for fault.seconds of the drone's own (simulated) clock;
- gps-glitch: SIM_GPS1_GLTCH_X / _Y (this 4.7 build's names; DEGREES of latitude / longitude, added to the simulated
  GPS as they are) set to the drawn north / east offset over serial1, and set back to 0 after fault.seconds of the
  drone's clock.
A lasting fault's end is read on the vehicles' own clocks (GLOBAL_POSITION_INT / SYSTEM_TIME time_boot_ms through
the relay, which they keep sending while the relay drops them): over once any of them has run fault.seconds since
the strike (a killed drone's clock stops, the others' go on); should every clock stop, the wall clock at the
nominal speed-up times WALL_SLACK ends it instead.

Battery used: each live vehicle's BATTERY_STATUS current_consumed asked over its serial1 after the flight; for a
killed one, the last the relay heard (BATTERY_STATUS, else SYS_STATUS's current summed over its clock).
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

from missionplan.base.naming import Named
from missionplan.bridge.sim.sitl_fleet import (SitlFleet, configure, set_param_on_serial1, sitl_vehicles,
                                               start_sitl_fleet)
from missionplan.bridge.sim.sitl_process import ArduCopterSitl, sitl_binary_problem

from .conditions import Conditions, Fault
from .fleet_flight import fly_fleet

MAX_SPEEDUP = 10.0  # SITL's --speedup: stable on 2 shared cores (../shared/sitl/README.md)
# The current this SITL copter (--model +, copter.parm's defaults, its simple battery: no SIM_BATT_CAP_AH) draws in
# calm cruise, A. Measured once (2026-12-07) on the Milan block of missionplan/testing/sitl_fleet.py (AREA, the
# first two LAUNCHES, 20 m, planned 194.6 / 198.3 s), 2 drones at --speedup 10, SIM_WIND_SPD 0: each vehicle's
# SYS_STATUS current_battery sampled through the relay every 0.2 s of wall time while it was armed in AUTO at
# mission item 3 or later (survey legs and turns; no take-off, climb or landing), 90 samples per drone: median
# 28.33 A on both (mean 27.96 / 28.26 A, range 26.3-30.0 A but one sample of 0.13 A at disarm). The whole flight's
# BATTERY_STATUS current_consumed, 1488 / 1499 mAh over 193.7 / 195.7 s flown, is 27.7 A on average.
CALM_CURRENT_A = 28.3
SITL_MARGIN_S = 180.0  # wall seconds on top of fly's makespan bound (fleet_flight): boot, set-up and reboot, EKF
# readiness, uploads, a re-task
LOOK_S = 0.02  # wall seconds between looks at the relay's view of the vehicles
WALL_SLACK = 3.0  # a lasting fault on a silent clock ends after this many times its nominal wall time
LOW_BATTERY_V = 10.0  # SIM_BATT_VOLTAGE at the item: below BATT_LOW_VOLT
BATT_LOW_VOLT = 10.5
BATTERY_FAILSAFE_RTL = 2.0  # BATT_FS_LOW_ACT 2: RTL, as a team configures it
METRES_PER_DEGREE = 111_320.0  # of latitude (and of longitude at the equator)
BATTERY_ASK_S = 3.0  # wall seconds to wait for a vehicle's BATTERY_STATUS after the flight


class SitlRunError(RuntimeError):
    """A SITL run that could not be flown as drawn: no simulator, a fault that could not be put on."""


def fly_on_sitl(copy: Path, job: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """The run (flight_run.RunJob) on ArduCopter SITL: fly's judgement and the simulator's truth (battery used per
    drone, the faults as they struck), as fly_on_mock returns them."""
    sitl_dir = Path(job.sitl_dir) if job.sitl_dir else None
    problem = sitl_binary_problem(sitl_dir)
    if problem is not None or sitl_dir is None:
        raise SitlRunError(Named("{sim} sitl: {0}", problem))
    conditions: Conditions = job.conditions
    speedup = min(float(job.time_scale), MAX_SPEEDUP)
    with start_sitl_fleet(copy, sitl_vehicles(sitl_dir), speedup=speedup) as fleet:
        configure(fleet, wind_params(conditions), per_vehicle=fault_params(conditions))
        faults = SitlFaults(fleet, conditions, speedup)
        try:
            faults.start()
            result = fly_fleet(copy, fleet.url, speedup, job.replan, SITL_MARGIN_S)
        finally:
            faults.stop()
        if faults.errors:
            raise SitlRunError("; ".join(faults.errors))
        used = battery_used(fleet)
    return result.doc, {"battery_mah": used, "calm_current_a": CALM_CURRENT_A, "struck": faults.struck}


def wind_params(conditions: Conditions) -> dict[str, float]:
    """SITL's wind for every vehicle: mean speed (m/s), the direction it blows from (degrees), turbulence (m/s)."""
    return {"SIM_WIND_SPD": conditions.wind_mps, "SIM_WIND_DIR": conditions.wind_from_deg,
            "SIM_WIND_TURB": conditions.turbulence_mps}


def fault_params(conditions: Conditions) -> dict[int, dict[str, float]]:
    """What a drone drawn for a battery failsafe is set up with before the flight (RTL on a low battery)."""
    return {f.drone: {"BATT_FS_LOW_ACT": BATTERY_FAILSAFE_RTL, "BATT_LOW_VOLT": BATT_LOW_VOLT}
            for f in conditions.faults if f.kind == "battery-failsafe"}


def glitch_degrees(north_m: float, east_m: float, latitude: float) -> tuple[float, float]:
    """A north / east offset in metres as SIM_GPS1_GLTCH_X / _Y: degrees of latitude and of longitude there."""
    return north_m / METRES_PER_DEGREE, east_m / (METRES_PER_DEGREE * math.cos(math.radians(latitude)))


class SitlFaults:
    """The faults of one run on one SITL fleet; start() before `fly`, stop() after it. `struck` as MockFaults
    records it (kind, drone, at_item, at_s: simulated seconds after start at the nominal speed-up), plus the drone's
    own clock then (vehicle_s); `errors`: faults that could not be put on."""

    def __init__(self, fleet: SitlFleet, conditions: Conditions, speedup: float) -> None:
        self.fleet, self.conditions, self.speedup = fleet, conditions, speedup
        self.struck: list[dict[str, Any]] = []
        self.errors: list[str] = []
        self._pending = [f for f in conditions.faults if f.drone in fleet.sysids]
        self._ends: list[tuple[float, dict[int, float], Fault]] = []  # (wall deadline, the clocks at the strike, fault)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="verify-sitl-faults", daemon=True)
        self._t0 = time.monotonic()

    def start(self) -> SitlFaults:
        self._t0 = time.monotonic()
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop watching and take back what still lasts (the relay passes again, no glitch is left set)."""
        self._stop.set()
        self._thread.join(timeout=15.0)
        for _, _, fault in self._ends:
            self._clear(fault)
        self._ends = []

    def _sim_s(self) -> float:
        return round((time.monotonic() - self._t0) * self.speedup, 1)

    def _clock(self, sysid: int) -> float | None:
        return self.fleet.relay.state(sysid).get("boot_s")

    def _clocks(self) -> dict[int, float]:
        """Every vehicle's clock as the relay last heard it (a killed one's stops)."""
        return {k: c for k in self.fleet.sysids if (c := self._clock(k)) is not None}

    def _watch(self) -> None:
        while not self._stop.wait(LOOK_S):
            for fault in list(self._pending):
                if self._reached(fault):  # asked again after each strike: a drone killed at this item is struck no more
                    self._pending.remove(fault)
                    self._strike(fault)
            now = time.monotonic()
            for end in [e for e in self._ends if self._over(e, now)]:
                self._ends.remove(end)
                self._clear(end[2])
            if not self._pending and not self._ends:
                return

    def _reached(self, fault: Fault) -> bool:
        state = self.fleet.relay.state(fault.drone)
        return self.fleet.vehicle(fault.drone).alive and (
            state.get("reached", -1) >= fault.at_item or state.get("current", -1) > fault.at_item)

    def _over(self, end: tuple[float, dict[int, float], Fault], now: float) -> bool:
        """Whether a lasting fault has lasted its simulated seconds: on any vehicle's clock (they run alike; the
        struck drone's may have stopped, killed during a link gap), or, every clock silent, the wall's backstop."""
        wall, started, fault = end
        clocks = self._clocks()
        return now >= wall or any(clocks[k] - t >= fault.seconds for k, t in started.items() if k in clocks)

    def _strike(self, fault: Fault) -> None:
        vehicle = self.fleet.vehicle(fault.drone)
        clock = self._clock(fault.drone)
        entry: dict[str, Any] = {"kind": fault.kind, "drone": fault.drone, "at_item": fault.at_item,
                                 "at_s": self._sim_s(), "vehicle_s": clock}
        try:
            if fault.kind == "lost-drone":
                vehicle.kill()
            elif fault.kind == "battery-failsafe":
                set_param_on_serial1(vehicle, "SIM_BATT_VOLTAGE", LOW_BATTERY_V)
            elif fault.kind == "link-gap":
                self.fleet.relay.drop()
            elif fault.kind == "gps-glitch":
                self._glitch(vehicle, fault.north_m, fault.east_m)
        except Exception as err:  # noqa: BLE001 - said after the flight: the run did not meet its conditions
            self.errors.append(f"{fault.kind} on uav{fault.drone} at item {fault.at_item} not put on: {err}")
            entry["error"] = str(err)
        self.struck.append(entry)
        if fault.seconds > 0 and "error" not in entry:
            wall = time.monotonic() + fault.seconds / self.speedup * WALL_SLACK
            self._ends.append((wall, self._clocks(), fault))

    def _glitch(self, vehicle: ArduCopterSitl, north_m: float, east_m: float) -> None:
        dlat, dlon = glitch_degrees(north_m, east_m, vehicle.home[0])
        set_param_on_serial1(vehicle, "SIM_GPS1_GLTCH_X", dlat)
        set_param_on_serial1(vehicle, "SIM_GPS1_GLTCH_Y", dlon)

    def _clear(self, fault: Fault) -> None:
        try:
            if fault.kind == "link-gap":
                self.fleet.relay.restore()
            elif fault.kind == "gps-glitch" and self.fleet.vehicle(fault.drone).alive:
                self._glitch(self.fleet.vehicle(fault.drone), 0.0, 0.0)
        except Exception as err:  # noqa: BLE001 - said after the flight
            self.errors.append(f"{fault.kind} on uav{fault.drone} not taken back: {err}")
        for entry in self.struck:
            if entry["kind"] == fault.kind and entry["drone"] == fault.drone and "ended_s" not in entry:
                entry["ended_s"] = self._sim_s()


def battery_used(fleet: SitlFleet) -> dict[int, float]:
    """mAh each vehicle's battery gave: a live vehicle's BATTERY_STATUS asked over its serial1, else (killed, or no
    answer) what the relay last heard from it; a vehicle that said nothing either way is left out."""
    used: dict[int, float] = {}
    for vehicle in fleet.vehicles:
        asked = _ask_consumed(vehicle) if vehicle.alive else None
        heard = fleet.relay.used_mah(vehicle.sysid)
        value = asked if asked is not None else heard
        if value is not None:
            used[vehicle.sysid] = round(float(value), 1)
    return used


def _ask_consumed(vehicle: ArduCopterSitl) -> float | None:
    """BATTERY_STATUS current_consumed (mAh) of a live vehicle, asked over its serial1; None without an answer."""
    from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink, wait_vehicle

    deadline = time.monotonic() + BATTERY_ASK_S
    try:
        with Link(vehicle.serial1_url) as link:
            wait_vehicle(link, vehicle.sysid, timeout=BATTERY_ASK_S)
            link.mav.command_long_send(vehicle.sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                       mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, 0, 0, 0, 0, 0, 0)
            while (msg := link.recv(deadline)) is not None:
                if (msg.get_srcSystem() == vehicle.sysid and msg.get_type() == "BATTERY_STATUS" and int(msg.id) == 0
                        and int(msg.current_consumed) >= 0):
                    return float(msg.current_consumed)
    except Exception:  # noqa: BLE001 - the relay's figure stands in
        return None
    return None
