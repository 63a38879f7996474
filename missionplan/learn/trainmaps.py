"""Training maps: the varied cities on which the expert plays to make imitation-learning data.

This module owns the maps the policy is trained on and nothing else. The network sees a
19 x 19 window around one drone, so what matters is that those windows are varied: narrow
lanes and wide avenues, small and large blocks, L-shaped and merged blocks, dead-end
alleys, courtyards, open squares with a tower in them, parks, bent and diagonal streets,
rivers with bridges. Two sources give that:

* `random_city(rng, shape)` (random_cities.py) paints a fresh random city in one of four
  styles - a recursive subdivision of the map, an orthogonal grid of streets of varied
  widths, an organic lattice of bent lanes, or a street grid turned by any angle - then
  dresses the blocks and adds a few overlays (diagonal avenue, river, plaza, big park).
* crops of the shipped-map generators of `mapgen` run with seeds other than the
  shipped ones, and the Leonardo arena, each turned or mirrored at random.

`training_maps(seed, count)` mixes both, deterministically for a seed; `heldout_cities`
makes larger random cities, from another seed, on which a trained network is judged. Every map it
returns has one launch cell, on a street when possible and away from the edge; every
target is 4-connected to that cell through free cells; every free cell lies in an
all-free 3 x 3 square (streets at least `MIN_STREET_WIDTH` wide); there are at least
`MIN_TARGETS` targets (random_cities.finish keeps the first three for every map). Free cells
that are not targets are parks (reachable, flown over) or walled-in courtyards (unreachable
pockets).

`python -m missionplan.learn.trainmaps preview.png [seed] [count]` draws some of them.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from ..maps import mapgen
from ..maps.gridmap import GridMap
from ..maps.mapgen import FREE, OBSTACLE, TARGET, enforce_min_street_width, main_component
from .random_cities import CELL_M, finish, random_city

MIN_TARGETS = 200
MIN_TARGET_FRACTION = 0.15  # below this most of the painted city was cut off: paint another
SIZE_RANGE = (40, 110)  # sides of the random cities
CROP_RANGE = (60, 100)  # sides of the windows cut out of the shipped-map generators
CROP_FRACTION = 0.22  # share of crops in a training set; Leonardo ~3 %, the rest random cities
LEONARDO_FRACTION = 0.03
MAX_ATTEMPTS = 12
HELDOUT_SIDE = 160  # sides of the held-out cities a trained network is judged on
CROP_TRIES = 3

SHIPPED_SEEDS = {"grid-city": mapgen.GRID_CITY_SEED, "old-town": mapgen.OLD_TOWN_SEED,
                 "river-city": mapgen.RIVER_CITY_SEED}
CITY_GENERATORS: dict[str, Callable[[int], GridMap]] = {
    "grid-city": mapgen.grid_city, "old-town": mapgen.old_town, "river-city": mapgen.river_city}


# --------------------------------------------------------------------------- kind arrays

def kind_of(gmap: GridMap) -> np.ndarray:
    """The OBSTACLE / TARGET / FREE painting canvas of a map (mapgen's cell kinds)."""
    kind = np.full(gmap.shape, FREE, dtype=np.int8)
    kind[gmap.target] = TARGET
    kind[gmap.obstacle] = OBSTACLE
    return kind


# --------------------------------------------------------------------------- crops of the shipped generators

def turned(kind: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, str]:
    """The canvas under a random one of the 8 rotations / mirrorings, and its description."""
    quarter_turns, mirror = int(rng.integers(4)), bool(rng.random() < 0.5)
    kind = np.rot90(kind, quarter_turns)
    if mirror:
        kind = kind[:, ::-1]
    return np.ascontiguousarray(kind), f"rot{90 * quarter_turns}{'+mirror' if mirror else ''}"


def other_seed(rng: np.random.Generator, source: str) -> int:
    """A generator seed other than the one of the shipped map (the held-out test maps)."""
    while True:
        seed = int(rng.integers(100, 1_000_000))
        if seed != SHIPPED_SEEDS[source]:
            return seed


def city_crop(rng: np.random.Generator, source: str, *, name: str) -> GridMap:
    """A window of 60-100 cells a side cut out of a shipped-map generator run with another seed."""
    seed = other_seed(rng, source)
    full = kind_of(CITY_GENERATORS[source](seed))
    height, width = (min(int(v), side) for v, side in zip(rng.integers(CROP_RANGE[0], CROP_RANGE[1] + 1, size=2),
                                                          full.shape))
    best, best_targets, window = None, 0, ""
    for _ in range(CROP_TRIES):  # the window with the most reachable targets (not all river, not all sea)
        top = int(rng.integers(0, full.shape[0] - height + 1))
        left = int(rng.integers(0, full.shape[1] - width + 1))
        kind = full[top:top + height, left:left + width].copy()
        enforce_min_street_width(kind)  # the cut may leave a street only 1-2 cells wide along the edge
        targets = int(((kind == TARGET) & main_component(kind)).sum())
        if targets > best_targets:
            best, best_targets, window = kind, targets, f"{top},{left} {height}x{width}"
    if best is None or best_targets < MIN_TARGETS:
        raise ValueError(f"no window of {source} seed {seed} holds {MIN_TARGETS} reachable targets")
    kind, turn = turned(best, rng)
    meta = {"title": f"Crop of {source} (seed {seed})", "cell_m": CELL_M, "generator": "missionplan.maps.mapgen",
            "source": source, "seed": str(seed), "window": window, "turn": turn}
    return finish(name, kind, rng, meta)


def leonardo_variant(rng: np.random.Generator, *, name: str) -> GridMap:
    """The Leonardo arena turned or mirrored; its walled-in courtyards become buildings."""
    kind, turn = turned(kind_of(mapgen.leonardo()), rng)
    meta = {"title": "Leonardo arena", "cell_m": "0.238", "source": "leonardo", "turn": turn}
    return finish(name, kind, rng, meta)


# --------------------------------------------------------------------------- the training set

def random_shape(rng: np.random.Generator) -> tuple[int, int]:
    """Sides of 40-110 cells, most of them small to medium (quick to cover), not always square."""
    low, high = SIZE_RANGE
    side = low + (high - low) * rng.beta(1.3, 2.6)
    other = side * np.exp(rng.normal(0.0, 0.25))
    return int(round(side)), int(round(np.clip(other, low, high)))


def map_kinds(rng: np.random.Generator, count: int) -> list[str]:
    """Which source each of `count` maps comes from: mostly random cities, some crops, a Leonardo."""
    crops = max(1, round(CROP_FRACTION * count)) if count >= 4 else 0
    leonardos = max(1, round(LEONARDO_FRACTION * count)) if count >= 8 else 0
    sources = list(CITY_GENERATORS)
    kinds = ["random"] * (count - crops - leonardos) + ["leonardo"] * leonardos
    first = int(rng.integers(len(sources)))
    kinds += [sources[(first + k) % len(sources)] for k in range(crops)]
    return [kinds[k] for k in rng.permutation(count)]


def training_map(kind: str, rng: np.random.Generator, index: int) -> GridMap:
    """One training map from `kind`'s source, drawn again until it has enough targets.

    The redraws use the same rng, so the result stays deterministic.
    """
    for _ in range(MAX_ATTEMPTS):
        try:
            if kind == "random":
                gmap = random_city(rng, random_shape(rng), name=f"random-{index}")
            elif kind == "leonardo":
                gmap = leonardo_variant(rng, name=f"leonardo-{index}")
            else:
                gmap = city_crop(rng, kind, name=f"{kind}-crop-{index}")
        except ValueError:  # nothing usable was left of this draw
            continue
        if gmap.target.sum() >= MIN_TARGETS and gmap.target.mean() >= MIN_TARGET_FRACTION:
            return gmap
    raise ValueError(f"could not make training map {index} ({kind}) with {MIN_TARGETS} targets")


def training_maps(seed: int, count: int) -> list[GridMap]:
    """`count` training maps, the same for the same seed; map k depends only on (seed, k, count)."""
    rng = np.random.default_rng(seed)
    kinds = map_kinds(rng, count)
    children = np.random.SeedSequence(seed).spawn(count)
    return [training_map(kind, np.random.default_rng(child), index)
            for index, (kind, child) in enumerate(zip(kinds, children))]


def heldout_cities(seed: int, count: int, side: int = HELDOUT_SIDE) -> list[GridMap]:
    """`count` random cities of `side` x `side` cells for judging a trained network with a fleet:
    larger than the training maps, so long runs and zone borders show; the same for the same seed."""
    cities = []
    for index, child in enumerate(np.random.SeedSequence(seed).spawn(count)):
        rng = np.random.default_rng(child)
        for _ in range(MAX_ATTEMPTS):
            try:
                cities.append(random_city(rng, (side, side), name=f"heldout-{index}"))
                break
            except ValueError:
                continue
    return cities

# --------------------------------------------------------------------------- preview

def draw_preview(maps: list[GridMap], path: str) -> None:
    """Draw the maps side by side: buildings dark, targets white, parks green, courtyards brown, launch red."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(4, len(maps))
    lines = -(-len(maps) // columns)
    fig, axes = plt.subplots(lines, columns, figsize=(4.2 * columns, 4.4 * lines), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, gmap in zip(axes.ravel(), maps):
        picture = np.ones((*gmap.shape, 3))
        labels, _ = ndimage.label(gmap.free)
        reachable = labels == labels[gmap.launch[0]]
        picture[gmap.free & ~gmap.target & reachable] = (0.62, 0.85, 0.55)  # parks
        picture[gmap.free & ~reachable] = (0.55, 0.45, 0.38)  # walled-in courtyards
        picture[gmap.obstacle] = 0.2
        ax.imshow(picture, interpolation="nearest")
        for row, col in gmap.launch:
            ax.plot(col, row, "o", color="red", markersize=5)
        ax.set_title(f"{gmap.name} {gmap.shape[0]}x{gmap.shape[1]}\n"
                     f"{gmap.meta.get('style', gmap.meta.get('source', ''))} "
                     f"{gmap.meta.get('extras', gmap.meta.get('turn', ''))}, {int(gmap.target.sum())} targets",
                     fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: python -m missionplan.learn.trainmaps PREVIEW.png [SEED] [COUNT]")
    preview_seed = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    preview_count = int(sys.argv[3]) if len(sys.argv) > 3 else 12
    draw_preview(training_maps(preview_seed, preview_count), sys.argv[1])
