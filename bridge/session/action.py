"""What moves a vehicle: its modes, arming, the mission start, hold, release, return home, land, the safe stop.

The one place the ground station's COMMAND_LONGs that move a vehicle in flight are built (the numbers
each autopilot takes: missionplan.bridge.link.readiness). Each method sends one command (with
link.connection.command_long's retries) and returns its MAV_RESULT, or None when it was not
acknowledged: what to make of a refusal is the caller's to say. Messages of the vehicle that arrive
while a command waits for its answer go to `observe` (the follower's record), unless a caller asks
for them to be left unread (`observe=False`: fly's abort, after the followers stopped).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..formats.mission_items import Flavour
from ..link.connection import COMMAND_TRIES, COMMAND_WAIT_S, mavlink
from ..link.readiness import (ARDUPILOT_GUIDED, ARDUPILOT_LAND, ARDUPILOT_RTL, PX4_AUTO_MAIN, PX4_LAND_SUB,
                              PX4_LOITER_SUB, PX4_RTL_SUB, Vehicle, mission_mode_params, mode_params)

# How a fleet is sent home or down (fly --on-abort rtl|land): ArduPilot's modes, PX4's AUTO sub-modes.
ARDUPILOT_HOMING_MODES = {"rtl": ARDUPILOT_RTL, "land": ARDUPILOT_LAND}
PX4_HOMING_SUBS = {"rtl": PX4_RTL_SUB, "land": PX4_LAND_SUB}
HOMING = tuple(ARDUPILOT_HOMING_MODES)
USER_MODES = {"GUIDED"}  # what fly itself commands before the start (ArduPilot arms in GUIDED)


class Action:
    """The commands that move one vehicle (a VehicleSession's `action`).

    `commanded` names the modes this run put the vehicle in that are no departure from its mission (a
    follower says any other mode change mid-mission as one): GUIDED before the start, the hold of a
    re-task, the abort's RTL / LAND. A drone sent home by return_to_launch() (its share given to others)
    has left its mission: its RTL is said as such."""

    def __init__(self, link: Any, vehicle: Vehicle) -> None:
        self.link, self.vehicle = link, vehicle
        self.sysid, self.flavour = vehicle.sysid, vehicle.info.flavour
        self.commanded: set[str] = set(USER_MODES)

    def _command(self, command: int, params: list[float], deadline: float, observe: bool = True,
                 done: Callable[[], bool] | None = None, tries: int = COMMAND_TRIES,
                 wait_s: float = COMMAND_WAIT_S) -> int | None:
        result: int | None = self.link.command_long(self.sysid, command, params, deadline,
                                                    other=self.vehicle.take if observe else None, done=done,
                                                    tries=tries, wait_s=wait_s)
        return result

    def guided(self, deadline: float) -> int | None:
        """ArduPilot's GUIDED: where it arms before a mission start (and holds position in flight)."""
        return self._command(mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline)

    def arm(self, deadline: float) -> tuple[bool, str]:
        """Arm, retried while the vehicle says it is not ready yet (readiness.Vehicle.arm); (armed, why not)."""
        return self.vehicle.arm(deadline)

    def start_mission(self, deadline: float, done: Callable[[], bool] | None = None, tries: int = COMMAND_TRIES,
                      wait_s: float = COMMAND_WAIT_S) -> int | None:
        """MAV_CMD_MISSION_START from the first item; `done` says the mission visibly runs (a lost
        acknowledgement is then not worth a repeat), `tries` and `wait_s` how often and how soon it is sent again."""
        return self._command(mavlink.MAV_CMD_MISSION_START, [0.0, 0.0], deadline, done=done, tries=tries,
                             wait_s=wait_s)

    def mission_mode(self, deadline: float) -> int | None:
        """The mode a mission flies in (ArduPilot AUTO, PX4 AUTO.MISSION), from its current item."""
        return self._command(mavlink.MAV_CMD_DO_SET_MODE, mission_mode_params(self.flavour), deadline)

    def hold_mode(self) -> str:
        """The name of the mode hold() commands: ArduPilot GUIDED, PX4 HOLD (AUTO.LOITER)."""
        return "GUIDED" if self.flavour is Flavour.ARDUPILOT else "HOLD"

    def hold(self, deadline: float) -> int | None:
        """Stop where it is: the autopilot brakes and hovers (hold_mode())."""
        self.commanded.add(self.hold_mode())
        params = (mode_params(ARDUPILOT_GUIDED) if self.flavour is Flavour.ARDUPILOT else
                  mode_params(PX4_AUTO_MAIN, PX4_LOITER_SUB))
        return self._command(mavlink.MAV_CMD_DO_SET_MODE, params, deadline)

    def return_to_launch(self, deadline: float) -> int | None:
        """MAV_CMD_NAV_RETURN_TO_LAUNCH: fly home and land there."""
        return self._command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, [], deadline)

    def homing_mode(self, how: str, deadline: float, observe: bool = True) -> int | None:
        """The autopilot's own RTL or LAND mode (`how`: "rtl" or "land")."""
        self.commanded.update({how.upper(), "RTL", "LAND"})
        if self.flavour is Flavour.PX4:
            params = mode_params(PX4_AUTO_MAIN, PX4_HOMING_SUBS[how])
        else:
            params = mode_params(ARDUPILOT_HOMING_MODES[how])
        return self._command(mavlink.MAV_CMD_DO_SET_MODE, params, deadline, observe=observe)

    def make_safe(self, deadline: float) -> str:
        """A vehicle that will not fly: disarmed and out of AUTO (readiness.Vehicle.make_safe); how it was left."""
        return self.vehicle.make_safe(deadline)
