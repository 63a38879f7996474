"""The planning loop: deadlocks broken, failures reported, the expert's manners."""

import numpy as np

from missionplan.grid.expert import ExpertPolicy, sequence_tables
from missionplan.maps.gridmap import GridMap
from missionplan.grid import planner as planner_module
from missionplan.grid.planner import POLICY_PATIENCE, Planner
from missionplan.grid.world import DOWN, HOVER, RIGHT, UP, CoverageWorld
from replay_check import replay


def corridor_map(rows=9, cols=60, width=3):
    """A street `width` cells wide with open squares at both ends."""
    obstacle = np.ones((rows, cols), dtype=bool)
    mid = rows // 2
    obstacle[mid - width // 2: mid + width // 2 + 1, :] = False
    obstacle[:, :6] = False
    obstacle[:, -6:] = False
    return GridMap("corridor", obstacle, ~obstacle, [])


def as_report(world, run):
    return {"grid": world.gmap.rows_text(), "paths": run.paths.tolist()}


def alley_map(length=40, square=20):
    """Two 7 x `square` yards (targets) joined by a one-lane alley (free, not a target)."""
    cols = square + length + square
    obstacle = np.ones((7, cols), dtype=bool)
    obstacle[:, :square] = obstacle[:, -square:] = False
    obstacle[3, square:-square] = False
    target = ~obstacle
    target[3, square:-square] = False
    return GridMap("alley", obstacle, target, [])


def test_head_on_in_a_one_lane_alley_one_drone_retreats():
    gmap = alley_map()
    zone = np.full(gmap.shape, -1)
    zone[:, :20] = 1  # the left yard is drone 2's zone ...
    zone[:, -20:] = 0  # ... and the right one drone 1's: both must cross the alley at once
    # Both start inside the alley, each facing the yard it must cover.
    world = CoverageWorld(gmap, [(3, 26), (3, 53)], zone)
    planner = Planner(world, ExpertPolicy(), seed=3)
    run = planner.run()
    assert run.success, run.failure
    assert planner.deadlocks_broken >= 1  # they met head-on in the alley ...
    checked = replay(as_report(world, run))
    assert checked["problems"] == []  # ... and passed without sharing or swapping cells
    # Crossing (~60 moves), a retreat and covering a yard: bounded, no endless dithering.
    assert run.steps < 300


def test_step_cap_is_reported_as_failure():
    gmap = corridor_map()
    world = CoverageWorld(gmap, [(4, 0)], step_cap=5)
    run = Planner(world, ExpertPolicy()).run()
    assert not run.success
    assert "step cap of 5 steps" in run.failure
    assert run.metrics["coverage"] < 100


class Dither:
    """Up/down forever: photographs nothing new after a while. Counts the drones it was asked about."""

    name = "dither"

    def __init__(self) -> None:
        self.calls = 0

    def action_scores(self, world, drones):
        self.calls += len(drones)
        return np.array([[1.0 if world.t % 2 == 0 else 0.0, -1, 1.0 if world.t % 2 else 0.0, -1]] * len(drones))


def test_a_policy_that_stops_photographing_is_handed_to_the_path_finder():
    gmap = corridor_map(width=3)
    world = CoverageWorld(gmap, [(4, 2)])
    run = Planner(world, Dither()).run()
    assert run.success, run.failure
    assert run.pathfinder_decisions.sum() > 0


def test_patience_is_how_long_a_fruitless_policy_keeps_the_drone():
    gmap = corridor_map(width=3)
    runs = {}
    for patience in (1, 8):
        policy = Dither()
        run = Planner(CoverageWorld(gmap, [(4, 2)]), policy, patience=patience).run()
        assert run.success, run.failure
        runs[patience] = (policy.calls, run.metrics["MMN"])
    assert runs[1][0] < runs[8][0]  # a longer patience asks the dithering policy more often
    assert runs[1][1] < runs[8][1]  # and lets it waste moves


def test_plan_map_hands_its_patience_to_the_planner(monkeypatch):
    from missionplan.planning import pipeline
    from missionplan.maps.catalog import load_shipped

    seen = []
    original = planner_module.Planner.__init__

    def recording_init(self, *args, **kwargs):
        seen.append(kwargs.get("patience"))
        original(self, *args, **kwargs)

    monkeypatch.setattr(planner_module.Planner, "__init__", recording_init)
    pipeline.plan_map(load_shipped("leonardo"), 3, policy="expert")
    pipeline.plan_map(load_shipped("leonardo"), 3, policy="expert", patience=5)
    assert seen == [POLICY_PATIENCE, 5]


def test_expert_tables_cover_every_sequence_inside_the_view():
    tables = sequence_tables()
    assert tables.new_weights.shape == (4 ** 5, 361)
    assert tables.cells.min() >= 0 and tables.cells.max() < 361
    # Five straight moves into fresh ground reveal 5 new columns of 9 cells.
    centre = 9 * 19 + 9
    cells = np.concatenate([np.full((len(tables.cells), 1), centre), tables.cells], axis=1)
    straight = np.flatnonzero(np.all(np.diff(cells, axis=1) == 1, axis=1))
    assert len(straight) == 1
    assert (tables.new_weights[straight[0]] > 0).sum() == 45


def test_expert_runs_straight_down_a_street_and_never_into_a_wall():
    obstacle = np.ones((9, 60), dtype=bool)
    obstacle[2:7, :] = False  # a street 5 cells wide, nothing else
    gmap = GridMap("street", obstacle, ~obstacle, [])
    world = CoverageWorld(gmap, [(4, 8)])
    policy = ExpertPolicy()
    scores = policy.action_scores(world, [0])[0]
    assert np.argmax(scores) == RIGHT  # the only unexplored ground is down the street
    world_edge = CoverageWorld(gmap, [(2, 20)])
    assert not np.isfinite(policy.action_scores(world_edge, [0])[0][UP])  # (1, 20) is a wall
    moves = []
    for _ in range(10):
        action = int(np.argmax(policy.action_scores(world, [0])[0]))
        moves.append(action)
        world.step([action])
    assert moves.count(RIGHT) == 10
    assert HOVER not in moves and DOWN not in moves


def test_progress_bar_shows_coverage_and_time_left(capsys):
    gmap = corridor_map()
    world = CoverageWorld(gmap, [(4, 2)])
    run = Planner(world, ExpertPolicy(), progress=True).run()
    assert run.success
    shown = capsys.readouterr().err
    assert "% covered" in shown and "ETA" in shown and "cells" in shown


def test_expert_scores_a_batch_as_it_scores_each_drone_alone():
    """Batching the drones of a step must not mix their views, visits or memories."""
    obstacle = np.zeros((40, 50), dtype=bool)
    obstacle[10:14, 5:45] = True
    gmap = GridMap("batch", obstacle, ~obstacle, [])
    zone = np.where(np.arange(50)[None, :] < 25, 0, 1) * np.ones((40, 1), dtype=np.int64)
    zone[20:, :] += 2
    world = CoverageWorld(gmap, [(2, 2), (2, 47), (30, 3), (30, 46)], zone)
    expert = ExpertPolicy()
    rng = np.random.default_rng(0)
    for _ in range(30):
        world.step(rng.integers(-1, 4, size=4))
    together = expert.action_scores(world, [0, 1, 2, 3])
    alone = np.vstack([expert.action_scores(world, [k]) for k in range(4)])
    assert np.array_equal(together, alone)
    assert np.isfinite(together).any(axis=1).all()


def test_expert_distance_field_is_the_breadth_first_distance():
    # Checked against scipy's shortest paths on the grid graph of each view: exact everywhere
    # without `needed`, exact on the needed open cells with it; blocked or unreached cells read
    # the cap.
    from scipy.sparse.csgraph import shortest_path
    from distance_field import flight_distance_field  # tests/distance_field.py: the reference
    from missionplan.grid.zones import grid_graph

    rng = np.random.default_rng(7)
    blocked = rng.random((5, 19, 19)) < 0.3
    goals = rng.random((5, 19, 19)) < 0.02
    goals[4] = False  # a view with nothing to reach: every cell at the cap
    needed = np.zeros((19, 19), dtype=bool)
    needed[4:15, 4:15] = True
    limit = 38
    full = flight_distance_field(goals, blocked, limit)
    partial = flight_distance_field(goals, blocked, limit, needed=needed)
    for v in range(5):
        open_cells = ~blocked[v]
        sources = np.flatnonzero(goals[v] & open_cells)  # grid_graph numbers every cell row-major
        expected = np.full((19, 19), float(limit))
        if sources.size:
            hops = shortest_path(grid_graph(open_cells), unweighted=True, indices=sources).min(axis=0)
            expected[open_cells] = np.minimum(hops.reshape(19, 19), limit)[open_cells]
        assert np.array_equal(full[v], expected)
        assert np.array_equal(partial[v][needed & open_cells], expected[needed & open_cells])
        assert (partial[v][blocked[v]] == limit).all()
