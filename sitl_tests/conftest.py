"""Tests against real autopilots in simulation: ArduCopter SITL (arducopter.py) and PX4 SIH (px4_sih.py) from
../shared, with the helpers the mock-autopilot tests in tests/ share (loopback.py: free ports and bounded waits;
plans.py: plans made for a test).

Tests here start their peers themselves on 127.0.0.1, bound every wait, and stop them.
"""

from loopback import let_children_hear_ctrl_c

let_children_hear_ctrl_c()
