"""flight_models: how each autopilot flies a mission, in time.

Owns the kinematic models of ArduCopter (copter_model) and of a PX4 multicopter (px4_model): navigation
parameters and the timed motion of each phase. The planner's timeline and the mock autopilot's flight
both use them, so the planner reaches them without importing the ground station's link.

May import: nothing else from missionplan.bridge.
  copter_model   ArduCopter's navigation parameters and phase timings (the shared Motion pieces)
  px4_model      PX4's, built from the same pieces
  wind           wind as ArduCopter SITL flies in it: a leg's ground speed bound, the current, seeded gusts
"""
