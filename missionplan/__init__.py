"""missionplan: photo-coverage missions for several drones over a city.

Pipeline: map -> zones -> multi-drone grid coverage (policy + A*) -> metrics and files.
Library calls: `missionplan.planning.pipeline.plan_map` plans a grid in memory; `missionplan.planning.plan_folder.write_plan_folder`
plans and writes a plan folder (report, missions, map files, pictures).

Layout, one stage per subpackage (imports run one way: cli -> planning -> flight -> mission -> learn -> grid -> maps
-> geo -> bridge -> base; geo and bridge are the repository's top-level geo/ and bridge/ folders, installed here):
  cli/      the command line, the one front door: argparse, every subcommand, typed requests, printing
  maps/     the map type and .map format, the shipped maps, their generator
  grid/     the grid planner: world, zones, A*, expert, planning loop, metrics
  learn/    the neural policy: features, network + weights, imitation training
  mission/  georeferenced missions and the plan's files (.plan, report.json, plan.png)
  flight/   flying the missions and judging the flight (flight.json)
  geo/      world <-> grid: camera footprint, projection, rasterising, area files, GIS files
  bridge/   missions to and from autopilots over MAVLink, and the mock autopilot
  base/     below every layer: atomic file writes (atomic), how an error names a setting (naming)
  testing/  test support and the pytest plugin (fixtures for SITL, PX4 SIH, mock fleets); nothing else imports it
  planning/ making a plan: pipeline (plan_map), field_plan (plan_field), plan_folder (write_plan_folder),
            replan (after landing), retask (in flight); PlanningError and one error per stage
"""

__version__ = "0.1.0"
