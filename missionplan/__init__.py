"""missionplan: photo-coverage missions for several drones over a city.

Pipeline: map -> zones -> multi-drone grid coverage (policy + A*) -> metrics and files.
The one library call is `missionplan.pipeline.plan_map`.

Layout, one stage per subpackage (imports run one way: cli -> flight -> mission -> learn -> grid -> maps):
  maps/     the map type and .map format, the shipped maps, their generator
  grid/     the grid planner: world, zones, A*, expert, planning loop, metrics
  learn/    the neural policy: features, network + weights, imitation training
  mission/  georeferenced missions and the plan's files (.plan, report.json, plan.png)
  flight/   flying the missions and judging the flight (flight.json)
  top       cli (the command line), pipeline (plan_map), fieldplan (plan_field)
"""

__version__ = "0.1.0"
