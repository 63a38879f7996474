"""missionplan.grid: the grid planner: world, zones, A*, expert, planning loop, metrics.

The grid planner: the coverage world, zones, path-finding, the expert policy, the planning loop, its
metrics and its result.

May import: missionplan.maps. Never learn/: the neural policy reaches the planner as a Policy object
(missionplan.planning.pipeline.make_policy builds it).
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  expert          The algorithmic expert: the policy the neural network imitates (SPEC section 5).
  metrics         The evaluation metrics of SPEC section 6 (thesis 5.1), as plain functions of a run.
  pathfinding     Path-finders for drones with nothing unexplored in view (SPEC section 4, thesis 4.4).
  planner         The multi-drone planning loop (SPEC section 4, thesis flowchart 4.5).
  planresult      `PlanResult`: what one grid planning run produced (map, starts, zones, world, the
                  planner's run).
  world           The multi-drone coverage grid world: one environment with a reset / step interface.
  zones           Splitting the target cells among the drones (SPEC section 3, thesis 4.3).
"""
