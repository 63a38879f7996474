"""link: the ground station's MAVLink link to its vehicles.

May import: missionplan.bridge.errors, .formats.
  connection     pymavlink connections: URL checks, heartbeats, finding a vehicle by system id, commands
  shared_link    one connection per URL shared by every vehicle on it (a reader thread, per-vehicle views)
  signing        MAVLink 2 signing keys: loading and applying them, never printing them
  params         parameter get / set, and WPNAV_RADIUS from a plan's acceptance radius (ArduCopter)
  readiness      telemetry streams, readiness, launch site, arming, modes, a safe stop
  camera_check   the camera parameters and the MAVLink camera a `--capture camera*` plan needs of a vehicle
"""
