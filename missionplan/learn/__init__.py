"""missionplan.learn: the neural policy: features, network + weights, imitation training.

The neural policy learned by imitation of the expert: state features, the network and its shipped
weights (weights/), demonstrations, dataset, training, training maps.

May import: missionplan.grid, missionplan.maps; missionplan.base.
Layers, one way: cli -> flight -> mission -> learn -> grid -> maps (tests/test_layers.py).

  dataset         From recorded demonstrations to the train / validation / test sets (SPEC section 5).
  demos           Demonstrations: (state, expert action) pairs recorded from coverage runs.
  features        The policy's input: one fixed-length state vector per drone, and its x8 symmetry.
  network         The neural policy: the 376 -> 280 -> 4 network, its weights file, and the planner's
                  Policy.
  random_cities   Random cities for the training maps: four street styles, dressed blocks, overlays; the
                  guarantees every training map keeps.
  training        Training the neural policy by imitation of the expert, then DAgger rounds.
  trainmaps       Training maps: the varied cities on which the expert plays to make imitation-learning
                  data.
  weights/        (data)
"""
