"""The neural policy: network shape, weights file, numpy inference against torch, dataset cleaning and split,
fitting, demonstrations.

Planning runs the network in numpy (missionplan.learn.network); training builds it in torch
(missionplan.learn.training). The tests that need torch skip without it; `make test` installs it.
"""

import zipfile

import numpy as np
import pytest

from missionplan.learn.dataset import build_dataset
from missionplan.learn.demos import _play_job, fleet_starts, play_map
from missionplan.grid.expert import ExpertPolicy
from missionplan.learn.features import STATE_SIZE, encode_states, transform_actions, transform_states
from missionplan.learn.network import (SHIPPED_WEIGHTS, WEIGHT_SHAPES, NeuralPolicy, PolicyWeights, load_weights,
                                       save_weights)
from missionplan.learn.trainmaps import training_maps
from missionplan.grid.world import CoverageWorld, reachable_targets
from missionplan.grid.zones import split_zones
from missionplan.maps.catalog import load_shipped
from missionplan.planning.pipeline import plan_map

try:
    import torch
except ModuleNotFoundError:
    torch = None
needs_torch = pytest.mark.skipif(torch is None, reason="PyTorch is not installed (pip install 'missionplan[train]'; "
                                                       "make test installs it)")


def _random_weights(seed: int) -> PolicyWeights:
    rng = np.random.default_rng(seed)
    return PolicyWeights.from_arrays({name: rng.normal(0, 0.1, shape).astype(np.float32)
                                      for name, shape in WEIGHT_SHAPES.items()})


def _random_states(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(-1, 2, size=(n, STATE_SIZE)).astype(np.float32)


def test_feature_length_and_parameter_count():
    assert STATE_SIZE == 376
    shipped = load_weights()
    assert shipped.parameter_count() == 106_684
    assert [a.shape for a in shipped.arrays().values()] == [(280, 376), (280,), (4, 280), (4,)]
    assert all(a.dtype == np.float32 for a in shipped.arrays().values())


@needs_torch
def test_the_torch_network_has_the_same_shape():
    from missionplan.learn.training import PolicyNet, count_parameters

    net = PolicyNet()
    assert count_parameters(net) == 106_684
    assert {name: tuple(t.shape) for name, t in net.state_dict().items()} == WEIGHT_SHAPES


def test_probabilities_are_a_softmax_over_four_actions():
    for weights in (_random_weights(0), load_weights()):
        probabilities = weights.probabilities(_random_states(7, 0))
        assert probabilities.shape == (7, 4)
        assert np.all(probabilities >= 0)
        assert np.allclose(probabilities.sum(axis=1), 1.0, atol=1e-6)


@needs_torch
def test_numpy_inference_equals_torch_on_the_shipped_weights():
    from missionplan.learn.training import PolicyNet, to_weights

    torch.set_num_threads(1)
    shipped = load_weights()
    net = PolicyNet()
    net.load_state_dict({name: torch.from_numpy(array) for name, array in shipped.arrays().items()})
    # to_weights hands the torch network back bit for bit
    assert all(np.array_equal(a, b) for a, b in zip(to_weights(net).arrays().values(), shipped.arrays().values()))
    # Every batch a real plan asks for (Leonardo, 5 drones: 1 to 5 rows a step): within 1e-6.
    batches = _states_asked(load_shipped("leonardo"), 5)
    assert len(batches) > 50  # the policy is asked on most of the plan's 104 steps
    for states in batches:
        expected = net.probabilities(states)
        assert np.abs(shipped.probabilities(states) - expected).max() <= 1e-6
        assert np.array_equal(shipped.probabilities(states).argmax(axis=1), expected.argmax(axis=1))
    # Random states, busier than any view the planner meets, push the logits further: float32
    # rounding in another summation order then reaches 2e-6 with some BLAS builds (numpy 2.0's).
    states = _random_states(4000, 3)
    expected = net.probabilities(states)
    assert np.abs(shipped.probabilities(states) - expected).max() <= 1e-5
    assert np.array_equal(shipped.probabilities(states).argmax(axis=1), expected.argmax(axis=1))


def _states_asked(gmap, uavs: int) -> list[np.ndarray]:
    """The encoded states of every step's batch the network is asked about in a plan."""
    asked: list[np.ndarray] = []

    class Recording(NeuralPolicy):
        def action_scores(self, world, drones):
            if drones:
                asked.append(encode_states(world, drones))
            return super().action_scores(world, drones)

    assert plan_map(gmap, uavs, policy=Recording()).run.success
    return asked


def test_weights_round_trip(tmp_path):
    weights = _random_weights(1)
    path = tmp_path / "w.pt"  # any name: the format is .npz whatever the file is called
    save_weights(weights, path)
    loaded = load_weights(path)
    assert all(np.array_equal(a, b) for a, b in zip(loaded.arrays().values(), weights.arrays().values()))
    states = _random_states(5, 1)
    assert np.array_equal(loaded.probabilities(states), weights.probabilities(states))
    assert [p.name for p in tmp_path.iterdir()] == ["w.pt"]  # no temp file left behind, no ".npz" appended
    with np.load(path, allow_pickle=False) as archive:  # plain numpy reads it, no pickle
        assert sorted(archive.files) == sorted(WEIGHT_SHAPES)


def test_a_file_that_is_not_weights_gives_one_line(tmp_path):
    bad = tmp_path / "bad.pt"
    bad.write_text("not a weights file")
    wrong_arrays = tmp_path / "wrong.npz"
    np.savez(wrong_arrays, hidden=np.zeros((280, 376), np.float32))
    wrong_shape = tmp_path / "shape.npz"
    np.savez(wrong_shape, **{**_random_weights(2).arrays(), "output.bias": np.zeros(5, np.float32)})
    pickled = tmp_path / "pickled.npz"  # an object array needs pickle, which is never loaded
    np.savez(pickled, **{**_random_weights(2).arrays(), "output.bias": np.array([print], dtype=object)})
    for path in (bad, wrong_arrays, wrong_shape, pickled):
        with pytest.raises(ValueError, match=rf"{path.stem}\.\w+: not a missionplan policy weights file") as error:
            load_weights(path)
        assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="no such weights file"):
        load_weights(tmp_path / "missing.pt")


def test_shipped_weights_load_and_drive_a_batch():
    assert SHIPPED_WEIGHTS.is_file() and SHIPPED_WEIGHTS.name == "policy.npz"
    assert zipfile.is_zipfile(SHIPPED_WEIGHTS)
    gmap = training_maps(3, 1)[0]
    world = CoverageWorld(gmap, [gmap.launch[0]])
    scores = NeuralPolicy().action_scores(world, [0])
    assert scores.shape == (1, 4) and np.all(np.isfinite(scores))
    assert NeuralPolicy().action_scores(world, []).shape == (0, 4)


def _pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.integers(-1, 2, size=(n, STATE_SIZE)).astype(np.int8), rng.integers(0, 4, size=n).astype(np.int8)


def test_dataset_augments_cleans_and_splits_without_leaks():
    states, actions = _pairs(400, 0)
    # A duplicated pair, and a state recorded with two different actions (a tie: dropped).
    states = np.concatenate([states, states[:1], states[1:2]])
    actions = np.concatenate([actions, actions[:1], [(actions[1] + 1) % 4]]).astype(np.int8)
    data = build_dataset(states, actions, seed=0)
    stats = data.stats
    assert stats["raw"] == 402 and stats["augmented"] == 8 * 402
    assert stats["unique"] == 8 * 400  # random states have no symmetric twins
    assert stats["dropped_ties"] == 8 and stats["clean"] == 8 * 399
    assert stats["train"] + stats["validation"] + stats["test"] == stats["clean"]
    assert stats["train"] / stats["clean"] == pytest.approx(0.75, abs=0.03)
    assert stats["test"] / stats["clean"] == pytest.approx(0.10, abs=0.03)
    keys = [{row.tobytes() for row in split.states} for split in (data.train, data.validation, data.test)]
    assert not (keys[0] & keys[1]) and not (keys[0] & keys[2]) and not (keys[1] & keys[2])
    # every symmetric version of a test state is in the test split too
    for row in data.test.states[:20]:
        for sym in range(8):
            assert transform_states(row[None].astype(np.float32), sym).astype(np.int8).tobytes() in keys[2]


def test_dataset_keeps_the_majority_label():
    states, actions = _pairs(10, 1)
    actions[0] = 0
    # state 0 recorded four times: actions 0, 0, 0, 2 -> label 0
    states = np.concatenate([states, states[:1], states[:1], states[:1]])
    actions = np.concatenate([actions, [0, 0, 2]]).astype(np.int8)
    data = build_dataset(states, actions, seed=0)
    assert data.stats["conflicting"] == 8 and data.stats["dropped_ties"] == 0
    target = states[0].tobytes()
    found = [split.actions[i] for split in (data.train, data.validation, data.test)
             for i, row in enumerate(split.states) if row.tobytes() == target]
    assert found == [0]


@needs_torch
def test_fit_learns_a_rule_and_is_repeatable():
    from missionplan.learn.training import fit, to_weights

    rng = np.random.default_rng(2)
    states = rng.integers(-1, 2, size=(3000, STATE_SIZE)).astype(np.int8)
    # A rule that survives the x8 augmentation: go where the one "unexplored further" detector is on.
    actions = rng.integers(0, 4, size=len(states)).astype(np.int8)
    states[:, 368:372] = 0
    states[np.arange(len(states)), 368 + actions.astype(np.int64)] = 1
    data = build_dataset(states, actions, seed=0)
    first = fit(data, seed=5, progress=False, max_epochs=6)
    second = fit(data, seed=5, progress=False, max_epochs=6)
    for a, b in zip(first.net.state_dict().values(), second.net.state_dict().values()):
        assert torch.equal(a, b)
    test_states = data.test.states.astype(np.float32)
    predicted = first.net.probabilities(test_states).argmax(axis=1)
    assert (predicted == data.test.actions).mean() > 0.8
    # what training hands to planning decides as the torch network does
    assert np.array_equal(to_weights(first.net).probabilities(test_states).argmax(axis=1), predicted)


def test_demonstrations_record_the_expert_choice_for_every_asked_state():
    gmap = training_maps(7, 1)[0]
    demos, run = play_map(gmap)
    assert run.success and len(demos) > 50
    # Replay: the expert, asked again in the same world states, picks the recorded labels.
    world = CoverageWorld(gmap, [gmap.launch[0]])
    expert = ExpertPolicy()
    state0 = encode_states(world, [0])[0]
    assert np.array_equal(demos.states[0], state0.astype(np.int8))
    assert demos.actions[0] == np.argmax(expert.action_scores(world, [0])[0])
    assert set(np.unique(demos.actions)) <= {0, 1, 2, 3}
    assert np.array_equal(transform_actions(np.array([0, 1, 2, 3]), 0), [0, 1, 2, 3])


def test_dagger_worker_lets_the_network_drive_and_the_expert_label():
    gmap = training_maps(7, 1)[0]
    expert_only, _ = play_map(gmap)
    demos, run = _play_job((gmap, load_weights(), 0.0, 1))  # the network alone drives; no torch needed
    assert run.success and len(demos) > 50
    # the network drove elsewhere than the expert would, and the expert labelled what it saw there
    assert demos.states.tobytes() != expert_only.states.tobytes()
    world = CoverageWorld(gmap, [gmap.launch[0]])
    assert demos.actions[0] == np.argmax(ExpertPolicy().action_scores(world, [0])[0])


def test_fleet_demonstrations_see_zone_borders_and_other_drones():
    gmap = training_maps(7, 1)[0]
    starts = fleet_starts(gmap, 3)
    assert len(starts) == 3 and len(set(starts)) == 3 and starts[0] == gmap.launch[0]
    assert all(gmap.free[cell] for cell in starts)
    fleet, run = play_map(gmap, uavs=3)
    alone, _ = play_map(gmap)
    assert run.success and len(fleet) > 50
    assert run.floor == pytest.approx(gmap.target.sum() / 9 / 3)
    assert fleet.states.tobytes() != alone.states.tobytes()
    # The recorded labels are still the expert's: replaying the first asked state gives the same label.
    world = CoverageWorld(gmap, starts, split_zones(reachable_targets(gmap, starts), gmap.free, starts,
                                                    balance=True).zone)
    asked = [k for k in range(3) if np.isfinite(ExpertPolicy().action_scores(world, [k])[0]).any()]
    assert np.array_equal(fleet.states[: len(asked)], encode_states(world, asked).astype(np.int8))


@needs_torch
def test_dagger_rounds_keep_the_network_with_the_fewest_held_out_moves(monkeypatch):
    from missionplan.learn import training

    # A small run: 4 training maps, 2 held-out small maps, one 70 x 70 held-out city, two rounds.
    monkeypatch.setattr(training, "DAGGER_ROUNDS", 2)
    monkeypatch.setattr(training, "EVAL_MAPS", 2)
    monkeypatch.setattr(training, "HELDOUT_CITIES", 1)
    real_cities = training.heldout_cities
    monkeypatch.setattr(training, "heldout_cities", lambda seed, count: real_cities(seed, count, side=70))
    fitted = []
    real_fit = training.fit

    def recording_fit(dataset, seed, progress, desc=""):
        result = real_fit(dataset, seed, progress, max_epochs=3, desc=desc)
        fitted.append(training.to_weights(result.net))
        return result

    monkeypatch.setattr(training, "fit", recording_fit)
    weights, report = training.train_policy(num_maps=4, workers=1, progress=False, log=lambda line: None)
    rounds = report["dagger"]["rounds"]
    assert len(rounds) == 2 and len(fitted) == 3
    assert [r["expert_share"] for r in rounds] == [0.5, 0.25]
    assert all(r["states"] > 0 for r in rounds)
    # each round trains on every pair so far: the recorded pairs only grow
    assert report["samples"]["raw"] < rounds[0]["samples"]["raw"] < rounds[1]["samples"]["raw"]
    kept = report["dagger"]["kept_round"]
    scores = [report["dagger"]["heldout_network_moves_per_floor"]] + [r["heldout_moves_per_floor"] for r in rounds]
    assert scores[kept] == min(scores) and scores.index(min(scores)) == kept  # the first best wins ties
    assert np.array_equal(weights.probabilities(_random_states(64, 3)), fitted[kept].probabilities(_random_states(64, 3)))
