"""The training maps: deterministic by seed, usable by the single-drone expert, and varied.

Usable means: one launch cell, inside and free; every target 4-connected to it through
free cells; at least 200 targets; obstacles and targets disjoint; every free cell in an
all-free 3 x 3 square (streets at least 3 cells wide).
"""

from functools import cache

import numpy as np
import pytest
from scipy import ndimage

from missionplan.maps.gridmap import GridMap
from missionplan.maps.mapgen import MIN_STREET_WIDTH
from missionplan.learn import random_cities
from missionplan.learn.trainmaps import MIN_TARGETS, SHIPPED_SEEDS, heldout_cities, random_city, training_maps

COUNT = 12


@cache
def maps(seed: int = 0, count: int = COUNT) -> tuple[GridMap, ...]:
    return tuple(training_maps(seed, count))


def same_maps(a: tuple[GridMap, ...], b: tuple[GridMap, ...]) -> bool:
    return len(a) == len(b) and all(
        x.name == y.name and x.launch == y.launch and np.array_equal(x.obstacle, y.obstacle)
        and np.array_equal(x.target, y.target) for x, y in zip(a, b))


def check_usable(gmap: GridMap, min_targets: int = MIN_TARGETS) -> None:
    assert len(gmap.launch) == 1, gmap.name
    launch = gmap.launch[0]
    assert gmap.inside(launch) and gmap.free[launch], f"{gmap.name}: launch {launch} not a free cell"
    assert not (gmap.obstacle & gmap.target).any(), gmap.name
    labels, _ = ndimage.label(gmap.free)  # 4-connected, as the drone moves
    assert np.all(labels[gmap.target] == labels[launch]), f"{gmap.name}: a target is unreachable"
    assert gmap.target.sum() >= min_targets, f"{gmap.name}: only {gmap.target.sum()} targets"
    square = np.ones((MIN_STREET_WIDTH, MIN_STREET_WIDTH), dtype=bool)
    roomy = ndimage.binary_opening(gmap.free, structure=square, border_value=0)
    assert np.array_equal(roomy, gmap.free), f"{gmap.name}: a free cell lies in no all-free 3x3 square"


def test_same_seed_gives_the_same_maps():
    assert same_maps(maps(), tuple(training_maps(0, COUNT)))


def test_different_seeds_give_different_maps():
    other = maps(1)
    assert not same_maps(maps(), other)
    assert not any(np.array_equal(a.obstacle, b.obstacle) for a, b in zip(maps(), other)
                   if a.shape == b.shape)


@pytest.mark.parametrize("index", range(COUNT))
def test_every_map_is_usable(index):
    check_usable(maps()[index])


def test_random_city_is_deterministic_and_keeps_its_guarantees():
    for seed in range(6):
        gmap = random_city(np.random.default_rng(seed), (44, 52), name=f"random-{seed}")
        again = random_city(np.random.default_rng(seed), (44, 52), name=f"random-{seed}")
        assert gmap.shape == (44, 52) and gmap.name == f"random-{seed}"
        assert np.array_equal(gmap.obstacle, again.obstacle) and np.array_equal(gmap.target, again.target)
        assert gmap.launch == again.launch
        check_usable(gmap, min_targets=1)


def test_the_mix_holds_random_cities_crops_and_leonardo():
    names = [gmap.name for gmap in maps()]
    assert sum(name.startswith("random-") for name in names) >= COUNT // 2
    assert any("-crop-" in name for name in names)
    assert any(name.startswith("leonardo-") for name in names)
    assert len(set(names)) == len(names)


def test_crops_come_from_other_seeds_than_the_shipped_maps():
    crops = [gmap for gmap in maps() if "-crop-" in gmap.name]
    assert crops
    for gmap in crops:
        assert int(gmap.meta["seed"]) != SHIPPED_SEEDS[gmap.meta["source"]]
        assert all(60 <= side <= 100 for side in gmap.shape), gmap.shape


def test_sizes_and_density_vary():
    shapes = {gmap.shape for gmap in maps()}
    free = [float(gmap.free.mean()) for gmap in maps()]
    assert len(shapes) >= COUNT - 2
    assert all(40 <= side <= 110 for shape in shapes for side in shape)
    assert max(free) - min(free) >= 0.15, free
    random_styles = {gmap.meta["style"] for gmap in maps() if gmap.name.startswith("random-")}
    assert len(random_styles) >= 2


def test_some_free_cells_are_not_targets():
    """Parks (reachable) or courtyards (unreachable pockets) appear somewhere in the set."""
    assert any((gmap.free & ~gmap.target).any() for gmap in maps())


def test_turned_street_grids_staircase_and_keep_the_guarantees(monkeypatch):
    """The turned style: blocks on a street grid at an angle, so block edges are staircases."""
    monkeypatch.setattr(random_cities, "STYLE_P", (0.0, 0.0, 0.0, 1.0))
    staircased = 0
    for seed in range(6):
        gmap = random_city(np.random.default_rng(seed), (70, 80), name=f"turned-{seed}")
        assert gmap.meta["style"] == "turned"
        check_usable(gmap, min_targets=1)
        # Corners pointing down-right (an obstacle cell with free cells below and to its right):
        # an axis-aligned block has one, a block turned by an angle one per step of its staircase.
        solid = gmap.obstacle
        corners = solid[:-1, :-1] & ~solid[1:, :-1] & ~solid[:-1, 1:]
        staircased += int(corners.sum() > 1.5 * ndimage.label(solid)[1])
    assert staircased >= 3


def test_heldout_cities_are_larger_deterministic_and_usable():
    cities = heldout_cities(1000, 2, side=120)
    again = heldout_cities(1000, 2, side=120)
    assert same_maps(tuple(cities), tuple(again))
    assert not same_maps(tuple(cities), tuple(heldout_cities(1001, 2, side=120)))
    for city in cities:
        assert city.shape == (120, 120)
        check_usable(city)
