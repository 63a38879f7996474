"""missionplan.flight: flying the missions and judging the flight (flight.json).

Flying the planned missions: fly (upload, start, record), the flight report (flight.json, flight.png),
the mock-fleet demo.

May import: missionplan.mission, .learn, .grid, .maps; geo; bridge.
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  fleet_demo      `missionplan demo`: the whole flow on the embedded default, in one command (what `make
                  demo` runs).
  flight_report   Judging a flown fleet from its recordings: coverage, separation, times, problems;
                  flight.json and flight.png.
  fly             Fly a planned fleet over MAVLink and record it: `missionplan fly DIR --connect URL`.
"""
