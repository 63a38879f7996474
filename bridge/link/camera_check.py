"""Whether a vehicle can take a plan's photos with a MAVLink camera (`plan --capture camera`, `camera-interval`).

A plan whose photos a MAVLink camera takes needs two things of the vehicle, both checked before anything is
uploaded or armed, neither set by us:
- the autopilot parameter that hands its triggers to a camera of the camera protocol (camera_params): ArduPilot
  CAM1_TYPE 6 (MAVLinkCamV2; 5, the older MAVLink type, sends DO_DIGICAM_CONTROL, which such a camera does not
  take) for both modes, since ArduPilot times a mission's IMAGE_START_CAPTURE itself through that backend; PX4
  TRIG_MODE 4 and TRIG_INTERFACE 3 for `camera` (its distance triggers go to the camera as IMAGE_START_CAPTURE),
  nothing for `camera-interval` (it forwards the mission's IMAGE_START_CAPTURE to the camera as it is). Both take
  effect only at boot, and a ground station does not reboot a vehicle its crew did not ask it to: the refusal
  says what to set;
- a MAVLink camera on the vehicle's link: a HEARTBEAT of MAV_TYPE_CAMERA from a camera component
  (MAV_COMP_ID_CAMERA .. CAMERA6, 100..105), which the autopilot routes to the ground station (VehicleState.cameras
  keeps who sent one).

Owns camera_params, read_camera_params (the values over a ParamClient), camera_problem (the one line that says
what is missing and how to fix it, '' when nothing is), wait_camera (a bounded wait for the camera's heartbeat) and
check_camera, all of it for one vehicle: the parameters first (a vehicle that lacks one is refused at once, with
whether a camera was heard so far), then the camera, waited for until the caller's deadline (fly: its readiness
bound; upload: its --timeout).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from ..formats.mission_items import Flavour
from .connection import mavlink
from .params import ParamClient, read_params

CAMERA_MODES = ("camera", "camera-interval")  # `plan --capture` modes whose photos a MAVLink camera takes
# The component ids a MAVLink camera speaks from (MAV_COMP_ID_CAMERA .. CAMERA6).
CAMERA_COMPONENTS = range(mavlink.MAV_COMP_ID_CAMERA, mavlink.MAV_COMP_ID_CAMERA6 + 1)
ARDUPILOT_MAVLINK_CAMERA_V1 = 5.0  # CAM1_TYPE 5: the older MAVLink backend (DO_DIGICAM_CONTROL)


@dataclass(frozen=True)
class CameraParam:
    """A parameter the vehicle must hold for the capture mode: its name, the value, what that value means."""

    name: str
    value: float
    meaning: str


def camera_params(flavour: Flavour, capture: str) -> list[CameraParam]:
    """What the vehicle must hold to hand a `capture` plan's photos to a MAVLink camera ([] for the relay, for a
    PX4 camera-interval plan, and for an autopilot whose parameters we do not know)."""
    if capture not in CAMERA_MODES:
        return []
    if flavour is Flavour.ARDUPILOT:
        return [CameraParam("CAM1_TYPE", 6.0, "MAVLinkCamV2")]
    if flavour is Flavour.PX4 and capture == "camera":
        return [CameraParam("TRIG_MODE", 4.0, "distance-triggered by the mission"),
                CameraParam("TRIG_INTERFACE", 3.0, "MAVLink")]
    return []


def read_camera_params(client: ParamClient, needed: list[CameraParam]) -> dict[str, float]:
    """The values the vehicle reports for the needed parameters (a name it does not answer for is left out)."""
    return read_params(client, [p.name for p in needed], give_up_after=len(needed)) if needed else {}


def _wrong(param: CameraParam, values: dict[str, float]) -> str:
    """What is wrong with one parameter, '' when it holds the wanted value."""
    value = values.get(param.name)
    if value is None:
        return f"the vehicle has no {param.name} parameter (it did not answer for it)"
    if math.isclose(value, param.value, abs_tol=1e-6):
        return ""
    if param.name == "CAM1_TYPE" and math.isclose(value, ARDUPILOT_MAVLINK_CAMERA_V1, abs_tol=1e-6):
        return ("CAM1_TYPE is 5 (the older MAVLink camera type: it sends DO_DIGICAM_CONTROL, which a camera of the "
                "camera protocol does not take)")
    return f"{param.name} is {value:g}"


def camera_problem(capture: str, needed: list[CameraParam], values: dict[str, float], heard: bool,
                   waited_s: float | None = None) -> str:
    """One line: what a vehicle lacks to fly a `capture` plan with a MAVLink camera, and how to fix it ('' when it
    lacks nothing). values: what it reported for `needed`; heard: a camera's HEARTBEAT was heard (within waited_s,
    said when the camera was waited for)."""
    if capture not in CAMERA_MODES:
        return ""
    wrong = [(p, text) for p in needed if (text := _wrong(p, values))]
    missing = [text for _, text in wrong]
    fixes = []
    if wrong:
        settings = " and ".join(f"{p.name} {p.value:g} ({p.meaning})" for p, _ in wrong)
        fixes.append(f"set {settings} and reboot")
    if not heard:
        within = f" within {waited_s:.0f} s" if waited_s is not None else ""
        missing.append(f"no MAVLink camera was heard (no HEARTBEAT of MAV_TYPE_CAMERA from components "
                       f"{CAMERA_COMPONENTS.start}-{CAMERA_COMPONENTS.stop - 1}{within})")
        fixes.append("connect the camera")
    if not missing:
        return ""
    return (f"the plan captures with a MAVLink camera (--capture {capture}) and {' and '.join(missing)}: "
            f"{', and '.join(fixes)}")


def is_camera_heartbeat(msg: Any) -> bool:
    """A HEARTBEAT of a MAVLink camera: MAV_TYPE_CAMERA from a camera component."""
    return (msg.get_type() == "HEARTBEAT" and int(msg.type) == mavlink.MAV_TYPE_CAMERA
            and msg.get_srcComponent() in CAMERA_COMPONENTS)


def wait_camera(vehicle: Any, deadline: float) -> bool:
    """Take the vehicle's messages (a readiness.Vehicle: its state keeps the cameras heard) until one of its
    MAVLink cameras has been heard, or the deadline; whether one was."""
    while not vehicle.state.cameras:
        now = time.monotonic()
        if now >= deadline:
            return False
        vehicle.listen(min(deadline, now + 0.25))
    return True


def check_camera(vehicle: Any, capture: str, deadline: float, heard_since: float) -> str:
    """The vehicle's camera set-up for a `capture` plan (camera_problem's line, '' when it has what it needs).
    vehicle: a readiness.Vehicle on its link, whose state has taken every message since heard_since (our monotonic
    clock: when it was found)."""
    if capture not in CAMERA_MODES:
        return ""
    needed = camera_params(vehicle.info.flavour, capture)
    values = read_camera_params(ParamClient(vehicle.link, vehicle.info), needed)
    if any(_wrong(p, values) for p in needed):  # refused whatever the camera: said as heard so far
        return camera_problem(capture, needed, values, bool(vehicle.state.cameras))
    return camera_problem(capture, needed, values, wait_camera(vehicle, deadline), time.monotonic() - heard_since)
