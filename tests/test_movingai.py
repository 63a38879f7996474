"""MovingAI octile maps read as missionplan maps, and the launch points spread over launchless grids.

A tiny hand-written map checks parsing, each terrain character and each refused header (a MapError
naming the file, one line); the four real street maps of ../shared/maps/movingai (skipped only when
that folder is absent) check shape, obstacle share and launches (distinct, free, open, in the largest
region, spread, and each the farthest-point choice by a geodesic distance computed here independently
with scipy.sparse.csgraph); one end-to-end `plan` of Berlin checks full coverage.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import sliding_window_view
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from missionplan.cli import main
from missionplan.maps.catalog import load_shipped
from missionplan.maps.gridmap import MapError, load_map, save_map
from missionplan.maps.launches import spread_launches
from missionplan.maps.movingai import CREDIT, LAUNCH_COUNT, SHORT_CREDIT, is_movingai, parse_movingai

MOVINGAI = Path(__file__).resolve().parents[1].parent / "shared" / "maps" / "movingai"
CITIES = ("Berlin_1_256", "Boston_0_256", "Milan_0_256", "Paris_1_256")
needs_maps = pytest.mark.skipif(not MOVINGAI.is_dir(), reason=f"no MovingAI maps at {MOVINGAI}")

# Every terrain character once: row 0 of the grid. The rest is open ground to launch from.
TINY = """type octile
height 8
width 9
map
.GS@OTW..
.........
.........
.........
.........
.........
.........
.........
"""


def _write(tmp_path: Path, text: str | bytes, name: str = "tiny.map") -> Path:
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


# ---- the reader -------------------------------------------------------------------------------

def test_tiny_map_parses_each_terrain_character(tmp_path):
    gmap = load_shipped(str(_write(tmp_path, TINY)))
    assert gmap.name == "tiny" and gmap.shape == (8, 9)
    # . G S: streets to photograph; @ O T W: obstacles
    assert gmap.target[0, :3].all() and not gmap.obstacle[0, :3].any()
    assert gmap.obstacle[0, 3:7].all() and not gmap.target[0, 3:7].any()
    assert gmap.target.sum() == 8 * 9 - 4 and (gmap.target == ~gmap.obstacle).all()
    assert gmap.meta["title"] == f"MovingAI street map tiny; {SHORT_CREDIT}"
    assert gmap.meta["credit"] == CREDIT and "OpenStreetMap contributors" in CREDIT and "Sturtevant" in CREDIT
    assert "origin_lat" not in gmap.meta  # no georeference: plan writes report.json and plan.png only
    assert len(gmap.launch) == len(set(gmap.launch)) == min(LAUNCH_COUNT, 8 * 9 - 4)
    assert all(gmap.free[cell] for cell in gmap.launch)
    # the first on an open cell (5x5 free) nearest the centroid: only (3..5, 2..6) are open
    assert gmap.launch[0] == (4, 4)


def test_header_order_and_line_endings_are_free(tmp_path):
    swapped = TINY.replace("height 8\nwidth 9", "width 9\nheight 8").replace("\n", "\r\n")
    assert (load_shipped(str(_write(tmp_path, swapped))).obstacle == parse_movingai(TINY, "tiny.map").obstacle).all()


def test_own_format_is_still_read_as_ours(tmp_path):
    ours = "name: x\nlaunch: 1,1\ngrid:\n###\n#.#\n###\n"
    gmap = load_shipped(str(_write(tmp_path, ours, "x.map")))
    assert gmap.launch == [(1, 1)] and gmap.target.sum() == 1 and not is_movingai(ours)
    assert is_movingai(TINY) and is_movingai("\ufefftype octile\r\n")


def test_round_trip_through_our_format(tmp_path):
    gmap = parse_movingai(TINY, "tiny.map")
    save_map(gmap, tmp_path / "ours.map")
    again = load_map(tmp_path / "ours.map")
    assert again.rows_text() == gmap.rows_text() and again.launch == gmap.launch and again.meta == gmap.meta


HEADER = "type octile\nheight 2\nwidth 3\nmap\n"


@pytest.mark.parametrize("bad, message", [
    ("type tile\nheight 2\nwidth 3\nmap\n...\n...\n", "map type 'tile' is not supported"),
    ("type octile\nwidth 3\nmap\n...\n...\n", "the header has no 'height' line"),
    ("type octile\nheight 2\nmap\n...\n...\n", "the header has no 'width' line"),
    ("type octile\nheight two\nwidth 3\nmap\n...\n...\n", "height 'two' is not a whole number"),
    ("type octile\nheight 2\nwidth 0\nmap\n...\n...\n", "width '0' is not a whole number of at least 1"),
    ("type octile\nheight 2\nwidth ³\nmap\n...\n...\n", "width '³' is not a whole number"),
    ("type octile\nheight 2\nheight 2\nwidth 3\nmap\n", ":3: 'height' given twice"),
    ("type octile\nheight 2\nwidth 3\nsize 6\nmap\n...\n...\n", ":4: expected 'height N', 'width N' or 'map'"),
    ("type octile\nheight 2\nwidth 3\n...\n...\n", "expected 'height N', 'width N' or 'map'"),
    ("type octile\nheight 2\nwidth 3\n", "no 'map' line after the header"),
    ("type octile\n", "no 'map' line after the header"),
    (HEADER + "...\n", "the header says height 2 but 1 rows follow 'map'"),
    (HEADER + "...\n...\n...\n", "the header says height 2 but 3 rows follow 'map'"),
    (HEADER + "...\n....\n", ":6: row 1 has 4 cells, the header says width 3"),
    (HEADER + "...\n.. \n", ":6: unknown cell character ' ' in row 1, column 2"),
    (HEADER + "...\n.x.\n", ":6: unknown cell character 'x' in row 1, column 1"),
    (HEADER + "@@T\nOW@\n", "no passable cell ('.', 'G' or 'S') in the 2x3 grid"),
    (b"type octile\nheight 1\nwidth 1\nmap\n\xff\n", "not a map file (not UTF-8 text: byte 33)"),
])
def test_bad_input_names_the_file_and_the_problem(tmp_path, bad, message):
    path = _write(tmp_path, bad, "broken.map")
    with pytest.raises(MapError) as err:
        load_shipped(str(path))
    text = str(err.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text, text


def test_cli_refuses_a_bad_movingai_map_in_one_line(tmp_path, capsys):
    path = _write(tmp_path, HEADER + "...\n", "broken.map")
    assert main(["plan", "--map", str(path), "--uavs", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"missionplan: {path}: the header says height 2 but 1 rows follow 'map'"
    assert not (tmp_path / "out").exists()


# Near-valid maps: a header of plausible and odd values, then rows drawn from the terrain characters
# and a few strangers; or a consistent grid. Whatever comes, the reader returns a usable map or one
# MapError line naming the file.
_header_value = st.one_of(st.integers(-1, 6).map(str), st.sampled_from(["", "x", "2.0", "٣", "1e3"]))
_odd_rows = st.lists(st.text(alphabet=".GS@OTW x\t\x00é", max_size=7), max_size=7)


@st.composite
def _octile_texts(draw: st.DrawFn) -> str:
    if draw(st.booleans()):
        height, width = draw(st.integers(1, 7)), draw(st.integers(1, 7))
        cell = st.sampled_from("...GS@OTW")
        rows = ["".join(draw(st.lists(cell, min_size=width, max_size=width))) for _ in range(height)]
        head, body = ["type octile", f"height {height}", f"width {width}", "map"], rows
    else:
        head = ["type octile", f"height {draw(_header_value)}", f"width {draw(_header_value)}",
                draw(st.sampled_from(["map", "", "mapp"]))]
        body = draw(_odd_rows)
    return "\n".join(head + body) + "\n"


@settings(max_examples=150, deadline=None, database=None)
@given(_octile_texts())
def test_the_reader_only_raises_map_error(text):
    try:
        gmap = parse_movingai(text, "fuzz.map")
    except MapError as err:
        assert "\n" not in str(err) and str(err).startswith("fuzz.map"), str(err)
        return
    height, width = (int(line.split()[1]) for line in text.split("\n")[1:3])
    assert gmap.shape == (height, width) and gmap.free.any()
    assert gmap.launch and all(gmap.free[cell] for cell in gmap.launch) and len(set(gmap.launch)) == len(gmap.launch)


# ---- spread_launches --------------------------------------------------------------------------

def _geodesic(free: np.ndarray, sources: list[tuple[int, int]]) -> np.ndarray:
    """BFS distance (4-connected, through free cells) to the nearest source; inf where unreachable."""
    index = np.full(free.shape, -1)
    index[free] = np.arange(int(free.sum()))
    right = free[:, :-1] & free[:, 1:]
    down = free[:-1, :] & free[1:, :]
    a = np.concatenate([index[:, :-1][right], index[:-1, :][down]])
    b = np.concatenate([index[:, 1:][right], index[1:, :][down]])
    n = int(free.sum())
    graph = sparse.coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)).tocsr()
    d = csgraph.dijkstra(graph, directed=False, unweighted=True, min_only=True,
                         indices=[index[s] for s in sources])
    out = np.full(free.shape, np.inf)
    out[free] = d
    return out


def _open5(free: np.ndarray) -> np.ndarray:
    """Cells whose whole 5x5 neighbourhood is free (the map's edge counts as closed)."""
    padded = np.pad(free, 2, constant_values=False)
    return sliding_window_view(padded, (5, 5)).all(axis=(2, 3))


def _largest(free: np.ndarray) -> np.ndarray:
    labels, _ = ndimage.label(free)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == sizes.argmax()


def _check_farthest_point(free: np.ndarray, launches: list[tuple[int, int]], upto: int) -> None:
    """Each of launches[1:upto] is the first (row-major) open cell farthest from the ones before it."""
    open_cells = _open5(free) & _largest(free)
    r, c = np.nonzero(_largest(free))
    rr, cc = np.nonzero(open_cells)
    nearest = np.argmin((rr - r.mean()) ** 2 + (cc - c.mean()) ** 2)
    assert launches[0] == (rr[nearest], cc[nearest])
    for k in range(1, upto):
        d = _geodesic(free, launches[:k])
        best = np.where(open_cells, d, -1.0)
        assert d[launches[k]] == best.max(), (k, launches[k], d[launches[k]], best.max())
        assert launches[k] == tuple(int(v) for v in np.argwhere(best == best.max())[0])


def test_launches_follow_geodesic_not_straight_distance():
    # Two 7-wide streets joined only at their right ends: their left ends are 11 cells apart in a
    # straight line, 73 along the streets.
    free = np.zeros((16, 40), bool)
    free[:7, :] = free[9:, :] = free[7:9, 33:] = True
    launches = spread_launches(free, 5)
    _check_farthest_point(free, launches, 5)
    assert launches[1] == (13, 2) and launches[3] == (2, 2)  # a straight-line measure would not pick (2, 2)
    assert _geodesic(free, [(13, 2)])[2, 2] == 73


def test_launches_avoid_alleys_small_regions_and_repeat_nothing():
    free = np.zeros((30, 30), bool)
    free[2:12, 2:12] = True           # a square with open cells
    free[6, 12:29] = True             # a 1-cell alley out of it, reaching far
    free[20:29, 20:29] = True         # joined by the alley: the same region
    free[20:29, 2:8] = True           # a separate, smaller region
    region = _largest(free)
    launches = spread_launches(free, 1000)
    assert len(launches) == len(set(launches)) == int(region.sum())  # every region cell, once
    assert all(region[cell] for cell in launches)
    opened = int((_open5(free) & region).sum())
    assert all(_open5(free)[cell] for cell in launches[:opened])  # open cells first, the alley last
    assert not any(cell[0] == 6 and 12 <= cell[1] < 20 for cell in launches[:opened + 9])
    assert launches[:7] == spread_launches(free, 7)  # the sequence does not depend on the count
    assert spread_launches(np.zeros((4, 4), bool), 3) == [] and spread_launches(free, 0) == []


def test_launches_fall_back_when_nothing_is_open():
    free = np.zeros((5, 9), bool)
    free[2, :] = True                 # one 1-cell street: no 3x3 or 5x5 open cell
    assert spread_launches(free, 3) == [(2, 4), (2, 0), (2, 8)]


# ---- the real street maps ---------------------------------------------------------------------

@needs_maps
@pytest.mark.parametrize("city", CITIES)
def test_real_street_maps(city):
    gmap = load_shipped(str(MOVINGAI / f"{city}.map"))
    assert gmap.name == city and gmap.shape == (256, 256)
    assert 0.2 < gmap.obstacle.mean() < 0.35  # street blocks of a city centre: about 28 %
    assert (gmap.target == gmap.free).all()
    launches = gmap.launch
    assert len(launches) == len(set(launches)) == LAUNCH_COUNT
    region = _largest(gmap.free)
    assert all(region[cell] and _open5(gmap.free)[cell] for cell in launches)
    first6 = np.array(launches[:6])
    spacing = min(np.hypot(*(a - b)) for a, b in itertools.combinations(first6, 2))
    assert spacing > 50, spacing  # six random cells are typically about 30 apart
    _check_farthest_point(gmap.free, launches, 6)


@needs_maps
def test_plan_berlin_end_to_end(tmp_path):
    berlin = MOVINGAI / "Berlin_1_256.map"
    out = tmp_path / "berlin"
    assert main(["plan", "--map", str(berlin), "--uavs", "6", "--out", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["plan.png", "report.json"]
    report = json.loads((out / "report.json").read_text())
    assert report["map"] == "Berlin_1_256" and report["uavs"] == 6
    assert report["coverage"]["reachable_pct"] == 100.0
    assert report["coverage"]["targets_reachable"] == report["coverage"]["targets_all"] == int(
        load_shipped(str(berlin)).target.sum())
