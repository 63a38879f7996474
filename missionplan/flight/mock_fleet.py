"""The mock fleet `missionplan demo` and the integration tests fly against: one in-process mock
autopilot (missionplan.bridge.sim.mock) per drone of a plan folder, on 127.0.0.1, each at its drone's launch point."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from missionplan.bridge.errors import BridgeUsageError
from missionplan.bridge.formats.missionfile import read_mission_file

WHOLE_COPY_M = 20_000.0  # around the grid: more than the plan folder's ground copy reaches


def start_mock_fleet(plan_dir: Path, speedup: float, flavour: str = "ardupilot", faults: Any = None,
                     sitl_like: bool = True, cameras: bool = True, **options: Any) -> Any:
    """In-process mock autopilots on 127.0.0.1, one per uavK.plan of plan_dir (system id K, home at
    its launch point). Returns the started MockAutopilot; fly against mock.client_url, then mock.stop().
    sitl_like: they fly like ArduCopter SITL (the plan's timeline); cameras: each has its camera
    configured (CAM1_TYPE and a reboot, as a team does once), else it reports no photos; options go
    to MockAutopilot (gps_fix_after, streams_until_asked: SITL-like readiness and streams; homes; ground). A plan
    made over a DEM gives the mocks its ground (their homes on it; ArduPilot mocks ask fly for their terrain)."""
    from missionplan.bridge.sim.mock import MockAutopilot

    homes: dict[int, tuple[float, float, float]] = {}
    for path in sorted(Path(plan_dir).glob("uav*.plan")):
        if not path.stem[3:].isdigit():  # uavK-sJ.plan: a later sortie of drone K, same home
            continue
        home = read_mission_file(path).mission.home
        if home is not None:
            homes[int(path.stem[3:])] = (float(home[0]), float(home[1]), float(home[2]))
    if not homes:
        raise BridgeUsageError(f"{plan_dir}: no uavK.plan files to fly")
    homes = {**homes, **options.pop("homes", {})}
    if "ground" not in options:  # a plan over a DEM: the mocks' world has its ground (the plan folder's copy)
        options["ground"] = plan_ground_of(Path(plan_dir))
    mock = MockAutopilot("udpin:127.0.0.1:0", sysids=sorted(homes), flavour=flavour, speedup=speedup,
                         faults=faults, homes=homes, sitl_like=sitl_like, **options)
    mock.start()
    if sitl_like and cameras:
        mock.configure_cameras()
    return mock


def plan_ground_of(plan_dir: Path) -> Any:
    """The ground a plan folder was planned over (geo.dem.Ground, the whole copy), or None over flat ground."""
    from missionplan.geo.dem_copy import read_ground_copy
    from missionplan.mission.plan_record import PlanRecordError, read_plan_record

    try:
        record = read_plan_record(plan_dir)
    except PlanRecordError:
        return None  # a folder of mission files alone: flat
    georef = record.georeference
    if georef is None or georef.terrain is None:
        return None
    return read_ground_copy(plan_dir, georef.terrain, georef.frame, margin_m=WHOLE_COPY_M)
