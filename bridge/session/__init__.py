"""session: one vehicle as a ground station talks to it, each kind of request in one place (as MAVSDK's plugins).

May import: missionplan.bridge.errors, .formats, .link, .transfer, .flight_models; missionplan.base.
  vehicle_session  VehicleSession: the vehicle found on its link, its state as heard, and its plugins; the
                   telemetry streams, the parameters and the onboard log
  action           Action: what moves the vehicle (modes, arming, the mission start, hold, release, return
                   home, land, the safe stop), each command sent from here only
  mission          MissionPlugin: the mission on the vehicle (upload with read-back, MAVSDK's upload, read
                   back, the plan's parameters, replacing it in flight)
  terrain          TerrainServer: the MAVLink terrain protocol (a DEM served to an ArduPilot vehicle that asks;
                   TERRAIN_CHECK / TERRAIN_REPORT read back) and the parameters terrain flight needs
"""
