"""formats: the mission model, what each autopilot stores and accepts, and the mission files.

Pure Python, free of pymavlink: mission_items holds the MAVLink numbers these modules (and the planner) use.

May import: missionplan.bridge.errors, .limits; missionplan.base.
  mission_items  MissionItem, Mission, wire items, flavour rules; the MAVLink numbers of the pymavlink-free modules
  px4_rules      PX4's rules (measured on SIH): item results, stored forms, start refusals
  readback       what a vehicle may legally change in what it stores, per flavour; the read-back comparison
  missionfile    QGroundControl .plan and QGC WPL 110 .waypoints readers and writers (and QGC's .mission)
  qgc_legacy     QGroundControl's older item layouts and legacy .mission files, in the current .plan shape
"""
