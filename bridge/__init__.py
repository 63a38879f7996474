"""bridge: MAVLink mission upload/download, the MAVSDK backend and the mock autopilot.

Knows missions (lists of MAVLink mission items), not grids: nothing here imports the planner.
Modules, one job each:
  errors        BridgeUsageError (bad input, exit 2) and BridgeError (operational failure, exit 1)
  atomic        atomic file output (temp file, then rename), shared with missionplan: bridge is the
                lowest layer that writes files
  mission       the mission model (MissionItem, Mission), wire items, flavour rules; the MAVLink numbers of
                the modules free of pymavlink
  px4           PX4's rules (measured on SIH): item results, stored forms, start refusals
  readback      what a vehicle may legally change in what it stores, per flavour; the read-back comparison
  missionfile   QGroundControl .plan and QGC WPL 110 .waypoints readers and writers (and QGC's .mission)
  qgc_legacy    QGroundControl's older item layouts and legacy .mission files, in the current .plan shape
  signing       MAVLink 2 signing keys: loading and applying them, never printing them
  link          pymavlink connections: URL checks, heartbeats, finding a vehicle by system id
  protocol      the GCS side of the mission protocol over pymavlink (upload, download, clear, set-current)
  mavsdk_backend the same operations through MAVSDK-Python's MissionRaw plugin
  params        parameter get / set, and WPNAV_RADIUS from a plan's acceptance radius (ArduCopter)
  uploader      backend-neutral upload + read-back verification
  mock, mock_vehicle, mock_flight   the pure-Python mock autopilot (link and faults, one vehicle, kinematics)
  commands      the `upload`, `download` and `mock` subcommands for the missionplan CLI
"""

from .errors import BridgeError, BridgeUsageError

__all__ = ["BridgeError", "BridgeUsageError"]

import logging as _logging

# A library logs; the application decides where to. Without this, warnings would reach stderr.
_logging.getLogger("bridge").addHandler(_logging.NullHandler())
