"""missionplan.flight: flying the missions and judging the flight (flight.json).

Flying the planned missions: fly (upload, start, record), the flight report (flight.json, flight.png),
the mock fleet the demo flies.

May import: missionplan.mission, .learn, .grid, .maps, .geo, .bridge.
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  display         What a crew sees while flying: progress bars or plain lines, alerts, the final summary.
  drone_flight    One drone of a fleet flight, in its own thread: find, check, upload, arm, start, follow
                  to its landing (or re-attach to it: fly --resume), alerts, photos from its log.
  flight_report   Judging a flown fleet from its records: coverage, separation, times, problems;
                  flight.json, flight.png and missed.geojson.
  fly             `missionplan fly DIR`: the fleet, the journal, the live separation watch, Ctrl-C, the
                  judgement.
  journal         The flight journal (DIR/journal.sqlite): everything heard, written as it happens.
  mock_fleet      Mock autopilots standing where a plan's drones launch (demo, tests, bench).
  phases          Where a drone's flight time went (take-off, survey, return, landing).
  plan_report     A plan folder's report.json as the flight side reads it: frame, grid, targets, photo slack.
  record          One drone's record of a flight (DroneRecord), every change handed to the journal.
"""
