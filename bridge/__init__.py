"""missionplan.bridge: missions to and from autopilots over MAVLink, and the simulated autopilot they are tested on.

Knows missions (lists of MAVLink mission items), not grids: nothing here imports the planner
(tests/test_layers.py). Installed as missionplan.bridge from the repository's bridge/ folder.
Parts, lowest first; each subpackage's __init__ says what it owns and may import:
  errors         BridgeUsageError (bad input, exit 2) and BridgeError (operational failure, exit 1)
  folder_lock    one owner per folder: the OS lock fly, plan and replan hold on their folder, naming its holder
  flight_models  how ArduCopter and PX4 fly a mission, in time (the planner's timeline and the mock share them)
  formats        the mission model, the per-autopilot rules of what a vehicle stores and accepts, mission files
  link           the ground station's MAVLink link: connections, signing, parameters, readiness and arming
  transfer       the mission protocol (pymavlink and MAVSDK backends), upload with read-back, live re-tasking,
                 onboard log download
  session        one vehicle as the ground station talks to it: its actions, mission, streams, parameters and
                 log, each request in one place
  sim            the pure-Python mock autopilot (its link and faults, one vehicle, kinematics, onboard log)
"""

from .errors import BridgeError, BridgeUsageError

__all__ = ["BridgeError", "BridgeUsageError"]

import logging as _logging

# A library logs; the application decides where to. Without this, warnings would reach stderr.
_logging.getLogger(__name__).addHandler(_logging.NullHandler())
