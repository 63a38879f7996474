"""The mission on a vehicle: upload with read-back, MAVSDK's own upload, read back, the plan's parameters,
and the mission replaced in flight (a re-task).

The one place a VehicleSession moves missions (missionplan.bridge.transfer does the protocol): what
arrives from the vehicle meanwhile goes to the session's observer, as in every plugin.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..formats.mission_items import Mission, WireItem
from ..link.readiness import Vehicle
from ..link.signing import SigningKey
from ..transfer.protocol import Timeouts
from ..transfer.retask import RetaskReport, replace_mission_in_flight
from ..transfer.uploader import (MissionBackend, UploadReport, open_backend, read_back_differences, set_plan_params,
                                 upload_plan)


class MissionPlugin:
    """One vehicle's mission (a VehicleSession's `mission`)."""

    def __init__(self, backend: MissionBackend, vehicle: Vehicle) -> None:
        self.backend, self.vehicle = backend, vehicle

    def upload(self, parts: list[Mission], verify: bool = True, terrain_spacing: int | None = None) -> UploadReport:
        """Mission, fence and rally, proven by read-back (transfer.uploader.upload_plan)."""
        return upload_plan(self.backend, parts, verify=verify, terrain_spacing=terrain_spacing)

    def upload_qgc_plan_by_mavsdk(self, plan_path: Path, url: str, key: SigningKey | None, connect_s: float,
                                  timeouts: Timeouts) -> None:
        """MAVSDK's own QGroundControl importer opens the .plan and MAVSDK uploads what it read, on a link
        of its own beside this one."""
        mavsdk: Any = open_backend("mavsdk", url, self.vehicle.sysid, key=key, timeouts=timeouts,
                                   connect_timeout=connect_s)
        try:
            mavsdk.upload_qgc_plan(str(plan_path))
        finally:
            mavsdk.close()

    def differences(self, wire: list[WireItem]) -> list[str]:
        """What the vehicle's mission differs in from `wire`, item by item ([]: it holds exactly that)."""
        return read_back_differences(self.backend, 0, wire)

    def set_plan_params(self, mission: Mission, terrain_spacing: int | None = None) -> list[str]:
        """What the vehicle needs to fly `mission` as written (WPNAV_RADIUS on ArduCopter; the terrain's)."""
        return set_plan_params(self.backend, mission, terrain_spacing)

    def replace_in_flight(self, wire: list[WireItem], resume_seq: int, deadline: float,
                          fence: list[WireItem] | None) -> RetaskReport:
        """A held vehicle's new mission (and fence), current at resume_seq, left holding
        (transfer.retask.replace_mission_in_flight, held=True, resume=False): the caller releases it."""
        return replace_mission_in_flight(self.backend, self.vehicle.link, self.vehicle.sysid, self.vehicle.info.flavour,
                                         wire, resume_seq, deadline, fence=fence, observe=self.vehicle.take,
                                         held=True, resume=False)
