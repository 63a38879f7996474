"""missionplan.maps: the map type and .map format, the shipped maps, their generator.

The maps: the GridMap type and its .map file format, the generated shipped maps, the catalog of maps/.

May import: nothing else from missionplan (the lowest stage) but missionplan.base, for atomic writes.
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  catalog         The shipped maps: the `*.map` files in the repository's top-level `maps/` folder.
  gridmap         The occupancy-grid map and its plain-text file format.
  launches        Launch points for grids that come without any: a well-spread sequence in the open.
  mapgen          Generators of the maps that ship with missionplan (`maps/*.map`).
  movingai        The MovingAI map reader: grid benchmarks in the octile format, read as missionplan maps.
"""
