"""bench/teacher_bench.py's candidates are what they claim: the rollout's imagined flight is the world's own, and
the symmetric network answers a turned world with the turned answer, the sampled one draws from the network."""

from __future__ import annotations

import numpy as np
import pytest

from missionplan.grid.expert import GAMMA, ExpertPolicy
from missionplan.grid.world import ACTION_DELTAS, HOVER, CoverageWorld, turn_weight
from missionplan.learn.features import NUM_SYMMETRIES, transform_actions, transform_cell, transform_grid
from missionplan.maps.gridmap import GridMap
from missionplan.planning.pipeline import plan_map

from teacher_bench import RolloutTeacher, SampledNetwork, SymmetricNetwork, plan_one  # bench/teacher_bench.py


def street_map() -> GridMap:
    """A 40 x 48 map with a few buildings and a wall with a gap: moves get blocked, turns and revisits pay."""
    obstacle = np.zeros((40, 48), dtype=bool)
    obstacle[8:14, 10:30] = True
    obstacle[20:34, 5:9] = True
    obstacle[25, 12:40] = True
    obstacle[25, 30:33] = False
    return GridMap("streets", obstacle, ~obstacle, [(4, 4), (36, 44)])


def test_a_rollout_of_no_move_beyond_the_first_is_the_first_move_then_the_expert_s_look_ahead() -> None:
    """Horizon 0: a move is worth its own reward and, discounted once, the expert's best score after it, both
    read off a real world that made the move (one drone, so nothing else moves)."""
    gmap = street_map()
    expert = ExpertPolicy()
    teacher = RolloutTeacher(0, expert)
    world = CoverageWorld(gmap, gmap.launch[:1])
    rng = np.random.default_rng(3)
    history: list[int] = []  # the moves made so far, replayed into a fresh world for each move tried
    checked = 0
    for _ in range(60):
        scores = teacher.action_scores(world, [0])[0]
        expert_scores = expert.action_scores(world, [0])[0]
        assert np.array_equal(np.isfinite(scores), np.isfinite(expert_scores))  # blocked where the expert is
        for action in np.flatnonzero(np.isfinite(scores)):
            after = CoverageWorld(gmap, gmap.launch[:1])
            for past in history:
                after.step([past])
            target = tuple(after.positions[0] + ACTION_DELTAS[action])
            revisit = bool(after.flown_views(np.array([0]), radius=1)[0][1 + ACTION_DELTAS[action][0],
                                                                        1 + ACTION_DELTAS[action][1]])
            previous = int(after.last_actions[0, 0])
            outcome = after.step([int(action)])
            assert tuple(after.positions[0]) == target
            reward = (outcome.new_cells[0] / 9.0 - expert.turn_weight * (turn_weight(previous, int(action))
                                                                        if previous != HOVER else 0.0)
                      - expert.revisit_weight * revisit)
            look = expert.action_scores(after, [0])[0].max()
            want = reward + GAMMA * (look if np.isfinite(look) else 0.0)
            assert scores[action] == pytest.approx(want, abs=1e-5)
            checked += 1
        history.append(int(rng.choice(np.flatnonzero(np.isfinite(expert_scores)))))
        world.step([history[-1]])
    assert checked > 150


def test_a_deeper_rollout_plans_the_map_to_full_coverage() -> None:
    gmap = street_map()
    run = plan_map(gmap, 2, policy=RolloutTeacher(3)).run
    assert run.success and run.metrics["coverage"] == 100.0


def test_the_symmetric_network_answers_a_turned_world_with_the_turned_answer() -> None:
    gmap = street_map()
    network = SymmetricNetwork()
    zone = np.where(np.arange(gmap.shape[1])[None, :] < 24, 0, 1) * np.ones(gmap.shape, dtype=np.int64)
    base = CoverageWorld(gmap, gmap.launch, zone)
    moves = [[1, 3], [1, 3], [2, 0], [2, 0], [2, 3], [1, 0]]
    for step in moves:
        base.step(step)
    answer = network.action_scores(base, [0, 1])
    for sym in range(NUM_SYMMETRIES):
        launch = [transform_cell(cell, gmap.shape, sym) for cell in gmap.launch]
        turned = GridMap(f"t{sym}", transform_grid(gmap.obstacle, sym), transform_grid(gmap.target, sym), launch)
        world = CoverageWorld(turned, launch, transform_grid(zone, sym))
        for step in moves:
            world.step(transform_actions(step, sym))
        seen = network.action_scores(world, [0, 1])
        for action in range(4):  # action a here is action perm[a] there
            there = int(transform_actions([action], sym)[0])
            assert np.allclose(seen[:, there], answer[:, action], atol=1e-5), (sym, action)


def test_the_sampled_network_draws_its_first_choice_with_the_network_s_probabilities() -> None:
    """Over many draws in one state, each action comes first about as often as the network's softmax says, and a
    seed repeats its draws."""
    from missionplan.planning.pipeline import make_policy

    gmap = street_map()
    world = plan_map(gmap, 2, policy="expert").world  # covered: a fresh world of its map and zones
    world = CoverageWorld(gmap, list(gmap.launch), world.zone_of)
    network, expert = make_policy("nn"), ExpertPolicy()
    # The expert flies both drones until the network is unsure of a drone's next move: a state worth drawing in.
    for _ in range(200):
        probabilities = np.exp(network.action_scores(world, [0, 1]))
        if probabilities.max(axis=1).min() < 0.7:
            break
        world.step(expert.action_scores(world, [0, 1]).argmax(axis=1))
    assert probabilities.max(axis=1).min() < 0.7
    sampled = SampledNetwork(5)
    draws = 4000
    firsts = np.array([sampled.action_scores(world, [0, 1]).argmax(axis=1) for _ in range(draws)])
    for drone in range(2):
        counts = np.bincount(firsts[:, drone], minlength=4) / draws
        assert np.abs(counts - probabilities[drone]).max() < 0.03, (counts, probabilities[drone])
    again = SampledNetwork(5)
    assert np.array_equal(again.action_scores(world, [0, 1]), SampledNetwork(5).action_scores(world, [0, 1]))


def test_the_best_of_k_sampled_plans_is_the_shortest_of_them() -> None:
    best = plan_one("random", 0, 48, 2, 0, "nn-best-3")
    alone = [plan_one("random", 0, 48, 2, 0, "nn-best-1")]
    assert best[1] == 100.0 and best[0] <= alone[0][0]
