"""missionplan: photo-coverage missions for several drones over a city.

Pipeline: map -> zones -> multi-drone grid coverage (policy + A*) -> metrics and files.
The one library call is `missionplan.pipeline.plan_map`.
"""

__version__ = "0.1.0"
