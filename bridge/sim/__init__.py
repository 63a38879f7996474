"""sim: the pure-Python mock autopilot, made to behave like ArduCopter SITL and PX4 SIH.

May import: missionplan.bridge.errors, .formats, .link (pymavlink's set-up and URL parsing), .flight_models.
  mock           the mock's link: one process or thread serving one or many system ids, and link faults
  mock_vehicle   one simulated vehicle: telemetry, the mission protocol, commands, parameters
  mock_flight    its kinematics: a point that flies a mission, on the autopilots' flight models
  mock_log       its onboard DataFlash log, served over MAVLink
"""
