"""`fly` as every verification run calls it, on whichever simulated fleet: the fleet's link, the speed-up, live
re-tasking or not, a bound of the plan's makespan TIMEOUT_FACTOR times over plus the simulator's own start-up
margin, and every silence counted in the vehicles' seconds (link_silence.SilenceRule's vehicle scale), so a run at
20x meets fly's thresholds where a crew at 1x would. flight_run (the mock) and sitl_run (ArduCopter SITL) share it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

TIMEOUT_FACTOR = 3.0  # a run may take this many times the plan's makespan (simulated) before fly gives up


def planned_makespan_s(plan_dir: Path) -> float:
    """The plan's busiest drone's flight time (report.json, through the plan record)."""
    from missionplan.mission.plan_record import read_plan_record

    record = read_plan_record(plan_dir)
    return max((float(d.flight_s) for d in record.drones or () if d.flight_s is not None), default=0.0)


def fly_fleet(plan_dir: Path, url: str, speedup: float, replan: bool, margin_s: float) -> Any:
    """Fly plan_dir's fleet at `url` (sped up `speedup` times) with `fly`'s own logic; its FlightResult.
    margin_s: wall seconds on top of the makespan bound for what the simulator needs before and after flying."""
    from missionplan.flight.fly import fly
    from missionplan.planning.retask import retask_planner

    timeout_s = planned_makespan_s(plan_dir) * TIMEOUT_FACTOR / speedup + margin_s
    return fly(plan_dir, url, timeout_s=timeout_s, progress=False, time_scale=speedup,
               replan=retask_planner if replan else None, silences_in_vehicle_time=True)
