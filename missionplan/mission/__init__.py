"""missionplan.mission: georeferenced missions and the plan's files (.plan, report.json, the maps).

Georeferenced missions from a grid plan: georeference, corrector, clearance, sorties, altitude
separation, geofence, timeline, the .plan / .waypoints files, report.json, and the maps a crew
looks at: plan.png, plan.html, plan.gpkg, plan.kmz, tracks.geojson.

May import: missionplan.learn, .grid, .maps, .geo, .bridge (the mission model and files, the flight models).
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  clearance       Clearance from obstacles: the band drones may not fly in, and how far each track
                  really stays out.
  corrector       Trajectory corrector: a drone's cell path -> a few waypoints a real drone flies well
                  (SPEC section 8).
  coverage_check  Coverage honesty: what a plan covers of ALL the targets, and warnings when that is
                  much less.
  drone_missions  From a smoothed track to one MAVLink mission per drone (SPEC section 9).
  flightplan      Grid plan -> smoothed tracks -> missions -> mission files (`uavK.plan`,
                  `uavK.waypoints`).
  geofence        Each drone's geofence: an inclusion polygon around its whole flight, and a ceiling.
  georef          Georeferenced inputs for `missionplan plan`: an area file, or a shipped map's own
                  georeference.
  layers          A plan's map layers: what plan.html, plan.gpkg, plan.kmz and tracks.geojson draw.
  mapfiles        The map files a crew opens and carries away, written from a plan's (or a flight's)
                  layers.
  outputs         A plan folder's own files: which ones a previous `plan` wrote there, so a re-plan
                  leaves none stale.
  overlap_fill    Overlap fill: short detours that give reachable target points the photos the overlaps
                  imply (plan --overlap-fill).
  plan_blocks     The typed blocks of a plan record: what each drone flies, the safety promise, the
                  coverage and its warnings, the files read, the settings, the planner's figures.
  plan_record     The plan as data: `PlanRecord`, what report.json holds, and the one way it is written
                  and read.
  plot            plan.png: zones, every drone's track in its own colour, and how coverage grew.
  report          The grid plan's part of a plan record (`build_report`).
  safety          The field-safety settings of a georeferenced plan, from the command line and the map:
                  one checked value object.
  separation      Separation by construction: the altitude layers that keep every two drones
                  --min-separation apart.
  sorties         Battery sorties: one drone's survey route cut into flights that each fit its
                  endurance.
  timeline        Where every drone is when: planned missions as timed 3-D tracks, and the closest
                  approach of two tracks.
  track_missions  Tracks -> missions: the ways out and home round the obstacles, and a drone's mission from
                  its tracks (the stage `plan` and the live re-task end with).
  webmap          plan.html / flight.html: one self-contained page, the layers over the city (Leaflet
                  inlined, webmap_assets/).
"""
