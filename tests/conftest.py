"""The tests' shared set-up. Their fixtures for SITL, PX4 SIH and mock fleets come from missionplan's pytest
plugin (missionplan/testing/plugin.py); the checkers beside them (tests/) and the benches (bench/) are on
the path through pyproject.toml's `pythonpath`."""

from missionplan.testing.loopback import let_children_hear_ctrl_c

let_children_hear_ctrl_c()
