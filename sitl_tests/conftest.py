"""Integration tests against mock autopilots on loopback (the planner -> files -> MAVLink path).

Tests here start their peers themselves on 127.0.0.1, bound every wait, and stop them.
"""
