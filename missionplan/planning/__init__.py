"""missionplan.planning: making a plan, from a map or an area to a plan folder, and making one again.

May import: missionplan.flight (a re-plan reads the survey's ledger), .mission, .learn, .grid, .maps, .geo,
.bridge, .base; only the command line (missionplan.cli) and the test support import it
(tests/test_layers.py).

  pipeline     plan_map: map -> zones -> coverage plan -> metrics, in memory
  field_plan   plan_field: a georeferenced plan made field-safe (clearance, sorties, altitude layers)
  plan_folder  write_plan_folder: plan and write a plan folder (plan, replan and demo call it)
  replan       after landing: who flies a re-plan of what the survey still misses, with the stored settings
  retask       in flight: fly --replan's planner, a lost drone's share given to the survivors
  errors       PlanningError and one error per stage, saying what could not be planned
"""
