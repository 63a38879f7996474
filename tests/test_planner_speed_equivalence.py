"""The planner's fast paths give what the plain ways give, to the bit: the expert's scores (float32 sums
taken in the same order), the bitboard distances and goal search, Explorative A* reading a lookup, the
rival filter, the views the world keeps for a step and the steady-state distances read with kept arrays.
Plans must not change when the code gets faster, so each is checked against the way it replaced."""

from __future__ import annotations

import numpy as np
import pytest

from missionplan.grid import metrics, pathfinding
from missionplan.grid.expert import (DISTANCE_WEIGHT, GAMMA, LOOKAHEAD, REVISIT_WEIGHT, TURN_WEIGHT, ExpertPolicy,
                                     end_distances, sequence_tables)
from missionplan.grid.metrics import DistanceScratch, mean_distance_to_nearest
from missionplan.grid.pathfinding import FlightSearch, SeenLookup, SortedCells, find_goal
from missionplan.grid.world import CoverageWorld
from missionplan.maps.gridmap import GridMap

from distance_field import flight_distance_field  # tests/distance_field.py: the reference

VIEW = 19


def reference_scores(world: CoverageWorld, drones: list[int]) -> np.ndarray:
    """The expert's scores as first written: a full distance field, float32 counts, np.where on validity."""
    tables = sequence_tables()
    n = len(drones)
    index = np.asarray(drones)
    unexplored, blocked = world.views(index)
    flat = unexplored.reshape(n, -1).astype(np.float32)
    gain = np.empty((n, 4 ** LOOKAHEAD), dtype=np.float32)
    for i in range(n):
        np.matmul(tables.new_weights, flat[i], out=gain[i])
    gain /= 9.0
    score = gain - TURN_WEIGHT * tables.turn_cost[world.last_actions[index, 0] + 1]
    eight = np.float32(8.0)
    counts = world.flown_views(index).reshape(n, -1).astype(np.float32) + eight * blocked.reshape(n, -1)
    along = np.take(counts, tables.cells, axis=1).sum(axis=2)
    blocked_along = np.floor(along / eight)
    score -= REVISIT_WEIGHT * ((along - eight * blocked_along) + tables.self_revisits)
    ends = np.zeros(VIEW * VIEW, dtype=bool)
    ends[tables.cells[:, -1]] = True
    distance = flight_distance_field(unexplored, blocked, 2 * VIEW, needed=ends.reshape(VIEW, VIEW)).reshape(n, -1)
    score -= DISTANCE_WEIGHT * GAMMA ** LOOKAHEAD * np.take(distance, tables.cells[:, -1], axis=1)
    return np.where(blocked_along == 0, score, -np.inf).reshape(n, 4, -1).max(axis=2).astype(np.float64)


def city(rng: np.random.Generator, rows: int, cols: int, drones: int) -> CoverageWorld:
    obstacle = rng.random((rows, cols)) < 0.3
    free = np.argwhere(~obstacle)
    starts = [tuple(int(v) for v in free[i]) for i in rng.choice(len(free), drones, replace=False)]
    zone = rng.integers(0, drones, size=(rows, cols))
    return CoverageWorld(GridMap("city", obstacle, ~obstacle, []), starts, zone)


def test_expert_scores_are_the_reference_scores_to_the_bit() -> None:
    rng = np.random.default_rng(1)
    expert = ExpertPolicy()
    for trial in range(4):
        world = city(rng, 50, 60, 5)
        for _ in range(40):
            world.step(rng.integers(-1, 4, size=5))
            asked = sorted(rng.choice(5, int(rng.integers(1, 6)), replace=False).tolist())
            world.sees_unexplored()  # the planner asks first: the views of the step are then kept
            assert np.array_equal(expert.action_scores(world, asked), reference_scores(world, asked))


def test_end_distances_are_the_distance_field_on_the_ends() -> None:
    rng = np.random.default_rng(2)
    ends = np.unique(sequence_tables().cells[:, -1])
    needed = np.zeros(VIEW * VIEW, dtype=bool)
    needed[ends] = True
    for n in (1, 3, 6):
        for density in (0.001, 0.02, 0.3):
            blocked = rng.random((n, VIEW, VIEW)) < 0.35
            goals = rng.random((n, VIEW, VIEW)) < density
            field = flight_distance_field(goals, blocked, 2 * VIEW, needed=needed.reshape(VIEW, VIEW))
            assert np.array_equal(end_distances(goals, blocked, ends, 2 * VIEW), field.reshape(n, -1)[:, ends])


def test_world_keeps_each_drones_own_views_for_the_step() -> None:
    rng = np.random.default_rng(3)
    world = city(rng, 40, 45, 6)
    for _ in range(30):
        world.step(rng.integers(-1, 4, size=6))
        sees = world.sees_unexplored()
        unexplored, blocked = world.views(np.arange(6))
        for k in range(6):
            assert np.array_equal(unexplored[k], world.view_unexplored(k))
            assert np.array_equal(blocked[k], world.view_blocked(k))
            assert sees[k] == world.view_unexplored(k).any()


def random_search(rng: np.random.Generator) -> tuple[FlightSearch, np.ndarray, tuple[int, int]]:
    rows, cols = (int(v) for v in rng.integers(3, 150, size=2))
    free = rng.random((rows, cols)) > rng.uniform(0.0, 0.45)
    search = FlightSearch(free, pad=int(rng.choice([1, 32])))
    seen = (rng.random((rows, cols)) < rng.choice([0.001, 0.01, 0.05, 0.3])) & free
    return search, seen, (int(rng.integers(0, rows)), int(rng.integers(0, cols)))


@pytest.mark.parametrize("radii", [pathfinding.WINDOW_RADII, (3, 9), (0,)])
def test_find_goal_in_boxes_finds_the_ring_searchs_goal(monkeypatch: pytest.MonkeyPatch, radii: tuple[int, ...]) -> None:
    """The bitboard boxes (whatever their size, and however often the goal lies beyond them) against the
    plain ring search, with every form of `seen_unexplored`, goals taken, goals excluded and rivals."""
    rng = np.random.default_rng(sum(radii))
    for _ in range(250):
        search, seen, start = random_search(rng)
        cells = np.argwhere(seen)
        taken = [tuple(int(v) for v in t) for t in rng.integers(0, 150, size=(int(rng.integers(0, 4)), 2))]
        excluded = {tuple(int(v) for v in c) for c in cells[:int(rng.integers(0, 3))]} if rng.random() < 0.3 else None
        options: dict[str, object] = {}
        if rng.random() < 0.4:
            m = int(rng.integers(1, 5))
            options["rivals"] = np.column_stack([rng.integers(0, seen.shape[0], m), rng.integers(0, seen.shape[1], m)])
            options["rival_backlog"] = rng.uniform(0, 30, m)
        home = search.region(search.flat_index(start))[0]
        in_home = int((search.region(search.flat_index(cells)) == home).sum()) if home else len(cells)
        padded = np.zeros(search._free.size, dtype=np.int32) - 2  # -2: seen by nobody
        padded[search.flat_index(cells)] = 0
        forms = [(seen, {}), (lambda flat: padded[flat] == 0, {"seen_count": in_home}),
                 (SeenLookup(padded, [True, False, False]), {"seen_count": in_home})]
        for form, extra in forms:
            if "rivals" in options and extra:
                extra = {**extra, "seen_cells": cells if rng.random() < 0.5 else SortedCells(search.flat_index(cells))}
            monkeypatch.setattr(pathfinding, "WINDOW_RADII", radii)
            fast = find_goal(search, start, form, taken, excluded, **options, **extra)
            monkeypatch.setattr(pathfinding, "WINDOW_RADII", ())
            assert fast == find_goal(search, start, form, taken, excluded, **options, **extra)


@pytest.mark.parametrize("at_once", [0, 10 ** 9])
def test_rival_filter_is_the_distance_rule(monkeypatch: pytest.MonkeyPatch, at_once: int) -> None:
    monkeypatch.setattr(pathfinding, "_ALL_RIVALS_AT_ONCE", at_once)
    rng = np.random.default_rng(5)
    for _ in range(100):
        search, seen, start = random_search(rng)
        flat = np.sort(search.flat_index(np.argwhere(seen)))
        m = int(rng.integers(1, 6))
        rivals = np.column_stack([rng.integers(0, seen.shape[0], m), rng.integers(0, seen.shape[1], m)])
        backlog = rng.uniform(0, 20, m) if rng.random() < 0.8 else np.array([np.nan] + [1.0] * (m - 1))
        cells = search.cells(flat)
        mine = np.abs(cells - np.array(start)).sum(axis=1)
        theirs = np.abs(cells[:, None, :] - rivals[None, :, :]).sum(axis=2)
        expected = flat[(mine[:, None] <= theirs + backlog[None, :]).all(axis=1)]
        assert np.array_equal(pathfinding._first_to_reach(search, start, rivals, backlog, flat), expected)


def test_explorative_astar_reads_a_lookup_as_it_asks_a_predicate() -> None:
    rng = np.random.default_rng(6)
    for _ in range(60):
        search, seen, start = random_search(rng)
        goal = tuple(int(v) for v in np.argwhere(search._free.reshape(-1, search.width))[-1] - search.pad)
        padded = np.zeros(search._free.size, dtype=bool)
        padded[search.flat_index(np.argwhere(seen))] = True
        by_lookup = search.path(start, goal, SeenLookup(padded, (False, True)))
        assert by_lookup == search.path(start, goal, lambda flat: bool(padded[flat]))


def test_steady_state_distances_with_kept_arrays_are_the_fresh_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(7)
    scratch = DistanceScratch()
    for size in (5000, 200, 30000, 1200):  # growing and shrinking kept arrays
        unexplored = rng.random((180, 200)) < size / 36000
        positions = rng.integers(-5, 200, size=(int(rng.integers(1, 9)), 2))
        fresh = mean_distance_to_nearest(unexplored, positions)
        assert mean_distance_to_nearest(unexplored, positions, scratch) == fresh
        monkeypatch.setattr(metrics, "DIRECT_PAIRS_PER_BOX_CELL", 0)  # the distance transform's way
        assert mean_distance_to_nearest(unexplored, positions) == fresh
        monkeypatch.undo()
