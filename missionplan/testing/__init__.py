"""Test support, shipped with missionplan so that tests/, sitl_tests/, bench/ and a field team's own CI use
the same: real autopilots in simulation, mock fleets, loopback relays, plans made for a test, and the pytest
plugin that hands them out as fixtures (docs/testing.md).

  loopback                free ports, the bounded poll (wait_until), process groups, Ctrl-C for children
  relay                   a loopback relay that breaks a link on purpose and records what crosses it
  simulators              where ArduCopter SITL and PX4 SIH are (../shared, --simulators, MISSIONPLAN_SIMULATORS)
  arducopter, px4_sih     one real ArduCopter SITL / PX4 SIH vehicle, started free and stopped whatever happens
  sitl_fleet              a SITL fleet behind a relay, its set-up, `fly` as a child process
  plans                   plans made for a test, single wire items, comparing two autopilots' answers
  arducopter_mission_session, px4_mission_session
                          the mission sessions the mock is compared on with each autopilot
  limit_cases             out-of-range items and what each autopilot answered
  dem_files               DEM files made in a test: an analytic hill, GeoTIFFs in any CRS, real SRTM tiles
  retask_harness          a survey flown to mid-leg, re-tasked, watched and judged
  wind_flight             a short mission flown in wind (or through a GPS glitch) and recorded leg by leg
  plugin                  the pytest plugin (the pytest11 entry point): fixtures, markers, --simulators

A layer above the whole product: it imports missionplan, nothing of missionplan imports it
(tests/test_layers.py). Importing this package imports nothing.
"""
