"""formats: the mission model, what each autopilot stores and accepts, and the mission files.

Pure Python, free of pymavlink: mission_items holds the MAVLink numbers these modules (and the planner) use.

May import: missionplan.bridge.errors, .limits; missionplan.base.
  mission_items  MissionItem, Mission, wire items, flavour rules; the MAVLink numbers of the pymavlink-free modules
  px4_rules      PX4's rules (measured on SIH): item results, stored forms, start refusals
  readback       what a vehicle may legally change in what it stores, per flavour; the read-back comparison
  missionfile    mission files whichever the format: read by suffix or content, written by suffix, checked
                 against the vehicle's autopilot
  qgc_plan       QGroundControl .plan reader and writer (and QGC's legacy .mission reader)
  qgc_wpl        QGC WPL 110 .waypoints reader and writer
  item_checks    what every reader refuses: numbers the wire cannot carry, out-of-range values, DO_JUMP loops
  file_text      a mission file's text: one-line read errors, atomic writes
  qgc_legacy     QGroundControl's older item layouts and legacy .mission files, in the current .plan shape
  terrain_grid   ArduPilot's terrain grid: where each height of the MAVLink terrain protocol lies
"""
