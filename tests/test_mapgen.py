"""The shipped maps: in step with their generators, the right size, and plannable.

Plannable means: six usable launch cells, every street at least 3 cells wide, every
target reachable (except Leonardo's deliberate walled-in courtyards), and the river map
crossed by exactly one bridge.
"""

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from missionplan.maps.gridmap import GridMap, format_map, load_map, save_map
from missionplan.maps.mapgen import LAUNCH_COUNT, SHIPPED, SHIPPED_COMMENT, georeference, parse_rect

MAPS_DIR = Path(__file__).resolve().parent.parent / "maps"

EXPECTED_SHAPE = {"leonardo": (42, 84), "grid-city": (195, 247), "old-town": (104, 161), "river-city": (133, 199)}
TARGET_FRACTION = {"leonardo": (0.45, 0.60), "grid-city": (0.30, 0.40), "old-town": (0.30, 0.45),
                   "river-city": (0.30, 0.45)}
NAMES = list(SHIPPED)


@cache
def generated(name: str) -> GridMap:
    return SHIPPED[name]()


def free_components(free: np.ndarray) -> np.ndarray:
    labels, _ = ndimage.label(free)  # default structure: 4-connected, as drones move
    return labels


def test_every_expected_map_has_a_generator():
    assert set(SHIPPED) == set(EXPECTED_SHAPE)


@pytest.mark.parametrize("name", NAMES)
def test_shipped_file_matches_its_generator(name):
    path = MAPS_DIR / f"{name}.map"
    assert path.is_file(), f"{path} is missing: run `python -m missionplan.maps.mapgen`"
    assert format_map(load_map(path)) == format_map(georeference(generated(name))), \
        f"{path} is stale: run `python -m missionplan.maps.mapgen`"
    assert "python -m missionplan.maps.mapgen" in path.read_text(encoding="utf-8").splitlines()[0]


@pytest.mark.parametrize("name", NAMES)
def test_a_shipped_map_reads_and_writes_back_byte_for_byte_with_its_georeference(name, tmp_path):
    # Its georeference read once into GridMap.georef; the header lines as the file spells them.
    path = MAPS_DIR / f"{name}.map"
    gmap = load_map(path)
    assert gmap.georef is not None and gmap.georef.altitude_m and gmap.georef.camera is not None
    assert gmap.georef.cell_m == float(gmap.meta["cell_m"]) and gmap.georef.footprint_m == 9 * gmap.georef.cell_m
    save_map(georeference(generated(name)), tmp_path / "again.map", comment=SHIPPED_COMMENT)
    assert (tmp_path / "again.map").read_bytes() == path.read_bytes()


@pytest.mark.parametrize("name", NAMES)
def test_generators_are_deterministic(name):
    assert format_map(SHIPPED[name]()) == format_map(generated(name))


@pytest.mark.parametrize("name", NAMES)
def test_shape_and_metadata(name):
    gmap = generated(name)
    assert gmap.name == name
    assert gmap.shape == EXPECTED_SHAPE[name]
    assert gmap.meta["title"]
    assert float(gmap.meta["cell_m"]) > 0


@pytest.mark.parametrize("name", NAMES)
def test_target_fraction(name):
    low, high = TARGET_FRACTION[name]
    assert low <= generated(name).target.mean() <= high


@pytest.mark.parametrize("name", NAMES)
def test_six_launch_cells_on_distinct_separate_targets(name):
    gmap = generated(name)
    launch = gmap.launch
    assert len(launch) == LAUNCH_COUNT
    assert len(set(launch)) == LAUNCH_COUNT
    labels = free_components(gmap.free)
    for cell in launch:
        assert gmap.inside(cell) and gmap.target[cell]
        assert labels[cell] == labels[launch[0]]  # all in the one big region
    for i, a in enumerate(launch):
        for b in launch[i + 1:]:
            assert max(abs(a[0] - b[0]), abs(a[1] - b[1])) >= 2, f"launch cells {a} and {b} touch"


@pytest.mark.parametrize("name", NAMES)
def test_first_three_launch_cells_are_spread(name):
    gmap = generated(name)
    first = np.array(gmap.launch[:3], dtype=float)
    gaps = [np.linalg.norm(first[i] - first[j]) for i in range(3) for j in range(i + 1, 3)]
    assert min(gaps) >= 0.25 * min(gmap.shape)


@pytest.mark.parametrize("name", NAMES)
def test_streets_are_at_least_three_cells_wide(name):
    # Every free cell lies in some all-free 3x3 square (the free space equals its opening).
    free = generated(name).free
    opened = ndimage.binary_opening(free, structure=np.ones((3, 3), dtype=bool), border_value=0)
    narrow = np.argwhere(free & ~opened)
    assert narrow.size == 0, f"cells in passages narrower than 3: {narrow[:5].tolist()}"


@pytest.mark.parametrize("name", [n for n in NAMES if n != "leonardo"])
def test_every_target_is_reachable(name):
    gmap = generated(name)
    labels = free_components(gmap.free)
    assert np.all(labels[gmap.target] == labels[gmap.launch[0]])


def test_leonardo_has_walled_in_target_pockets():
    gmap = generated("leonardo")
    labels = free_components(gmap.free)
    pocket_labels = set(np.unique(labels[gmap.target])) - {labels[gmap.launch[0]]}
    assert len(pocket_labels) >= 2
    unreachable = gmap.target & (labels != labels[gmap.launch[0]])
    assert 0 < unreachable.sum() < 0.05 * gmap.target.sum()  # small pockets, not a lost district


def test_river_city_is_crossed_by_exactly_one_bridge():
    gmap = generated("river-city")
    rows, cols = parse_rect(gmap.meta["bridge"])
    assert 4 <= cols.stop - cols.start <= 6
    assert gmap.target[rows, cols].all()
    without_bridge = gmap.free.copy()
    without_bridge[rows, cols] = False
    labels = free_components(without_bridge)
    banks = set(np.unique(labels[gmap.target & without_bridge]))
    assert banks.isdisjoint({0}) and len(banks) == 2, "the bridge must be the only way across"
    bank_of = [labels[cell] for cell in gmap.launch]
    assert bank_of[0] != bank_of[1]  # drones 1 and 2 start on opposite banks
    for bank in banks:
        assert (labels[gmap.target] == bank).sum() > 0.2 * gmap.target.sum()
