"""Cities unlike the ones the planner was tuned and trained on, for bench/unseen_bench.py.

missionplan's own generators (maps/mapgen.py, learn/trainmaps.py) cut rectangles: orthogonal
streets, rectangular blocks. This one is built differently on purpose, so that a bench on it
says something about cities the planner never saw:

- blocks are the cells of a Voronoi diagram of random sites (irregular polygons, streets at
  every angle, three- to six-way junctions);
- every street (the border between two sites) has its own width, 3 to 10 cells, drawn per
  pair of sites: a cell is street where its distance to the bisector of its two nearest sites,
  (d2² - d1²) / (2 |s2 - s1|), is under half that width;
- a block is a park (open target cells) with PARK_P, else a building; a building becomes a
  closed courtyard block (a ring of building COURTYARD_WALL cells thick around open target
  cells: a pocket no drone outside can reach) with COURTYARD_P;
- every free cell is a target; launch cells are drawn uniformly from all free cells, courtyards
  and parks included, so a drone may start walled in.

Deterministic for a seed (numpy's default_rng). Pure numpy + scipy's cKDTree.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from missionplan.maps.gridmap import Cell, GridMap

MEAN_BLOCK_CELLS = 1000  # mean Voronoi cell area, streets included
STREET_WIDTHS = (3, 10)  # inclusive, per street
PARK_P = 0.08
COURTYARD_P = 0.2
COURTYARD_WALL = 3
MIN_COURTYARD_CELLS = 25


def voronoi_city(size: int, seed: int) -> GridMap:
    """A size x size city (see the module docstring), no launch cells yet."""
    rng = np.random.default_rng(seed)
    num_sites = max(4, size * size // MEAN_BLOCK_CELLS)
    sites = rng.uniform(0, size, size=(num_sites, 2))
    cells = np.indices((size, size)).reshape(2, -1).T + 0.5
    dist, nearest = cKDTree(sites).query(cells, k=2)
    low, high = np.minimum(nearest[:, 0], nearest[:, 1]), np.maximum(nearest[:, 0], nearest[:, 1])
    # One width per pair of neighbouring sites, drawn from a hash of the pair so it is the same all along.
    pair_rng = np.random.default_rng(seed + 1).integers(STREET_WIDTHS[0], STREET_WIDTHS[1] + 1, size=4096)
    width = pair_rng[(low * 7919 + high * 104729) % pair_rng.size]
    apart = np.linalg.norm(sites[nearest[:, 1]] - sites[nearest[:, 0]], axis=1)
    from_bisector = (dist[:, 1] ** 2 - dist[:, 0] ** 2) / (2 * apart)
    street = (from_bisector < width / 2).reshape(size, size)
    block_of = nearest[:, 0].reshape(size, size)

    obstacle = ~street
    use = rng.uniform(size=num_sites)
    parks = use < PARK_P
    obstacle &= ~parks[block_of]
    courtyards = (use >= PARK_P) & (use < PARK_P + COURTYARD_P)
    building = obstacle & courtyards[block_of]
    # Each courtyard block's interior (its building cells COURTYARD_WALL in from any edge) opens up.
    inner = ndimage.binary_erosion(building, structure=np.ones((3, 3), dtype=bool), iterations=COURTYARD_WALL,
                                   border_value=0)
    labels, count = ndimage.label(inner)
    if count:
        big = np.bincount(labels.ravel(), minlength=count + 1) >= MIN_COURTYARD_CELLS
        big[0] = False
        obstacle &= ~big[labels]
    return GridMap(name=f"voronoi{size}-{seed}", obstacle=obstacle, target=~obstacle, launch=[],
                   meta={"generator": "bench/unseen_cities.py", "seed": str(seed)})


def random_free_launches(gmap: GridMap, count: int, seed: int) -> list[Cell]:
    """`count` distinct free cells drawn uniformly (courtyards and parks included)."""
    free = np.argwhere(gmap.free)
    picks = np.random.default_rng(seed).choice(len(free), size=count, replace=False)
    return [(int(r), int(c)) for r, c in free[picks]]

