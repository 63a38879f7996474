"""The neural policy: network shape, weights file, dataset cleaning and split, fitting, demonstrations."""

import numpy as np
import pytest
import torch

from missionplan.learn.dataset import build_dataset
from missionplan.learn.demos import play_single
from missionplan.grid.expert import ExpertPolicy
from missionplan.learn.features import STATE_SIZE, encode_states, transform_actions, transform_states
from missionplan.learn.network import (SHIPPED_WEIGHTS, NeuralPolicy, PolicyNet, count_parameters, load_weights,
                                 save_weights)
from missionplan.learn.trainmaps import training_maps
from missionplan.learn.training import fit
from missionplan.grid.world import CoverageWorld


def test_feature_length_and_parameter_count():
    assert STATE_SIZE == 376
    net = PolicyNet()
    assert count_parameters(net) == 106_684
    assert [tuple(p.shape) for p in net.parameters()] == [(280, 376), (280,), (4, 280), (4,)]


def test_probabilities_are_a_softmax_over_four_actions():
    torch.manual_seed(0)
    states = np.random.default_rng(0).integers(-1, 2, size=(7, STATE_SIZE)).astype(np.float32)
    probabilities = PolicyNet().probabilities(states)
    assert probabilities.shape == (7, 4)
    assert np.allclose(probabilities.sum(axis=1), 1.0, atol=1e-6)


def test_weights_round_trip(tmp_path):
    torch.manual_seed(1)
    net = PolicyNet()
    path = tmp_path / "w.pt"
    save_weights(net, path)
    states = np.random.default_rng(1).integers(-1, 2, size=(5, STATE_SIZE)).astype(np.float32)
    assert np.array_equal(load_weights(path).probabilities(states), net.probabilities(states))
    assert [p.name for p in tmp_path.iterdir()] == ["w.pt"]  # no temp file left behind


def test_a_file_that_is_not_weights_gives_one_line(tmp_path):
    bad = tmp_path / "bad.pt"
    bad.write_text("not a torch file")
    with pytest.raises(ValueError, match=r"bad\.pt: not a missionplan policy weights file") as error:
        load_weights(bad)
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="no such weights file"):
        load_weights(tmp_path / "missing.pt")


def test_shipped_weights_load_and_drive_a_batch():
    assert SHIPPED_WEIGHTS.is_file()
    world = CoverageWorld(training_maps(3, 1)[0], [training_maps(3, 1)[0].launch[0]])
    scores = NeuralPolicy().action_scores(world, [0])
    assert scores.shape == (1, 4) and np.all(np.isfinite(scores))


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


def test_fit_learns_a_rule_and_is_repeatable():
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
    predicted = first.net.probabilities(data.test.states.astype(np.float32)).argmax(axis=1)
    assert (predicted == data.test.actions).mean() > 0.8


def test_demonstrations_record_the_expert_choice_for_every_asked_state():
    gmap = training_maps(7, 1)[0]
    demos, run = play_single(gmap)
    assert run.success and len(demos) > 50
    # Replay: the expert, asked again in the same world states, picks the recorded labels.
    world = CoverageWorld(gmap, [gmap.launch[0]])
    expert = ExpertPolicy()
    state0 = encode_states(world, [0])[0]
    assert np.array_equal(demos.states[0], state0.astype(np.int8))
    assert demos.actions[0] == np.argmax(expert.action_scores(world, [0])[0])
    assert set(np.unique(demos.actions)) <= {0, 1, 2, 3}
    assert np.array_equal(transform_actions(np.array([0, 1, 2, 3]), 0), [0, 1, 2, 3])
