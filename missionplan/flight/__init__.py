"""missionplan.flight: flying the missions and judging the flight (flight.json).

Flying the planned missions: fly (upload, start, record), the flight report (flight.json, flight.png),
the mock fleet the demo flies.

May import: missionplan.mission, .learn, .grid, .maps, .geo, .bridge.
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  after_landing   After a drone landed: the photos whose reports never arrived, from its log; its mission read back.
  disk_space      How much disk a flight's record takes, checked before fly opens a link.
  display         What a crew sees while flying: progress bars or plain lines, alerts, the final summary.
  drone_flight    One drone of a fleet flight, in its own thread: find, check, upload, arm, start, follow
                  to its landing (or re-attach to it: fly --resume), every request through its vehicle
                  session (missionplan.bridge.session), what it decides published as events.
  event_journal   What each flight event writes into its drone's record and says to the crew.
  events          What a drone's follower decides and hears in flight, as typed events, and where they go.
  fleet_start     What the drones' followers share: the links, the arm and start gates, the stop flag, the events.
  fleet_view      What fly --replan knows of each drone from its events alone: gone, or able to take more.
  flight_report   Judging a flown fleet from its records: coverage, separation, times, problems;
                  flight.json, flight.png and missed.geojson.
  fly             `missionplan fly DIR`: the fleet, the journal, the live separation watch, Ctrl-C, the
                  judgement.
  journal         The flight journal (DIR/journal.sqlite) written: everything heard, as it happens; paused
                  (not lost) when the disk refuses writes; a lost -wal file proven.
  journal_db      The journal's database: file names, tables, connections, a record's change as a row.
  journal_read    A journal read back: a flight's DroneRecords replayed from its rows.
  journal_repair  A damaged journal moved aside and what can be read of it copied into a new one.
  link_silence    When a silent drone counts as lost, gone or given up: every silence threshold, here only.
  live_replan     fly --replan: a drone gone in flight, its share re-tasked to the drones still flying.
  ledger_repair   A survey ledger missing, damaged or read-only: rebuilt from the journals, said in one line.
  mock_fleet      Mock autopilots standing where a plan's drones launch (demo, tests, bench).
  phases          Where a drone's flight time went (take-off, survey, return, landing).
  photo_positions Where each photo was taken, and the rows the survey ledger keeps of them.
  plan_report     A plan folder's plan record as the flight side reads it: frame, grid, targets, photo slack.
  record          One drone's record of a flight (DroneRecord), every change handed to the journal.
  retask_actions  A survivor's part in a live re-task, run by its follower: held, its new mission on board, released.
  retask_planner  The contract of fly --replan's planner: typed survivors in, a typed plan out, its own error.
  salvage         SQLite files on a bad disk: a damaged one read row by row, a read-only one read as it is.
  telemetry_record One followed vehicle's messages into its record, and as events where someone acts on them.
  terrain_service The plan's ground served to its ArduPilot vehicles (fly, upload) until they report it loaded.
"""
