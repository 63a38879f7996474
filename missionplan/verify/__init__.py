"""`missionplan verify PLAN_DIR`: a plan flown many times on simulated fleets, in wind and with faults, before the
field day; the answer is a distribution per promise.

  conditions     what each run meets (wind, which fault on which drone at which mission item), drawn from the
                 crew's ranges and a seed per run derived from the base seed and the run's index
  sim_faults     the faults put on a mock fleet as the vehicles reach the drawn mission items
  flight_run     one run: a copy of the plan folder flown by `fly`'s own logic on mock autopilots (or ArduCopter
                 SITL), read back into one row
  fleet_flight   `fly` as every run calls it: the bound on its time, re-tasking, silences in the vehicles' seconds
  engines        where the runs go: in this process, a local process pool, or Ray (local or a cluster); a worker
                 that dies is retried once and counted apart
  worker         the process pool's worker: one run per process, its row on stdout
  summary        the rows made into percentiles, the share of runs that kept each promise, and one verdict line
  verify_files   verify.json written as runs finish (so a stopped verify keeps them and --resume continues),
                 verify.png and verify.html
  verify         the whole command: the folder held, the runs fanned out, progress, the files
"""
