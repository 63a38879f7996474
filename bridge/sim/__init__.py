"""missionplan.bridge.sim: the pure-Python mock autopilot, made to behave like ArduCopter SITL and PX4 SIH.

May import: missionplan.bridge.errors, .formats, .link (pymavlink's set-up and URL parsing), .flight_models.
  mock              the mock's link: one process or thread serving one or many system ids, and link faults
  mock_vehicle      one simulated vehicle: its state, clock, battery and faults, handing each message to its parts
  telemetry         what it sends about itself: heartbeat, streams and their intervals, texts, photos
  mission_server    its side of the mission protocol: the stored mission, fence and rally lists and their transfers
  vehicle_commands  its answers to COMMAND_LONG / COMMAND_INT and SET_MODE
  vehicle_params    its parameter table: PARAM_REQUEST_READ / PARAM_SET
  vehicle_part      what those parts share: the vehicle they belong to, the messages each answers
  mock_flight       its kinematics: a point that flies a mission, on the autopilots' flight models
  mock_log          its onboard DataFlash log, served over MAVLink
  mock_terrain      its terrain database over a ground (ArduPilot): TERRAIN_REQUEST / _DATA / _CHECK / _REPORT
  gps_glitch        a GPS glitch as SITL's SIM_GPS1_GLTCH_X / _Y and its EKF answer it
  link_faults       the link's faults per packet: loss, duplicates, reordering, latency
  sitl_process      real ArduCopter SITL as a process: free instances and ports, readiness, reboot, stop
  udp_relay         a loopback relay between SITL vehicles and a ground station: breaks the link, watches the truth
  sitl_fleet        a SITL fleet for a plan folder behind the relay, configured as a team does
"""
