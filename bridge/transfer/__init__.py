"""transfer: missions and logs moved over a link.

May import: missionplan.bridge.errors, .formats, .link; missionplan.base.
  protocol        the ground station's side of the mission protocol over pymavlink (upload, download, clear,
                  set-current)
  mavsdk_backend  the same operations through MAVSDK-Python's MissionRaw plugin
  uploader        backend-neutral upload with read-back verification
  retask          replacing a flying vehicle's mission, and having it carry on
  onboard_log     MAVLink log download and the photos recovered from a vehicle's own log
"""
