"""Overlaps as measured (missionplan/mission/photo_overlap.py): front and side overlap and photos per target
point from photo positions, on hand-made lane patterns whose answers are known; then in the plan report of a
shipped map and in the judge of a mock flight."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.mission.drone_missions import DEFAULT_OVERLAP
from missionplan.mission.photo_overlap import (BOUNDED_BY, OverlapMeasure, classify_points, implied_photos,
                                               measure_overlap, photos_per_point, reachable_windows, strips_of,
                                               window_half_cells)
from missionplan.mission.plan_record import read_plan_record
from missionplan.planning.plan_folder import shipped_ground, write_plan_folder

S = 90.0  # footprint side, m
NO_CELLS = np.zeros((0, 2), dtype=np.int64)


def lanes(count: int, spacing_m: float, trigger_m: float, length_m: float = 300.0) -> tuple[np.ndarray, np.ndarray]:
    """`count` parallel lanes along the column axis, `spacing_m` apart, a photo every `trigger_m`; each
    lane its own drone, flown back and forth as a fleet's lanes are: (centres, runs)."""
    centres, runs = [], []
    along = np.arange(0.0, length_m + 1e-9, trigger_m)
    for k in range(count):
        cols = along if k % 2 == 0 else along[::-1]
        centres.append(np.column_stack([np.full(len(cols), k * spacing_m), cols]))
        runs.append(np.full(len(cols), k))
    return np.vstack(centres), np.concatenate(runs)


def test_front_and_side_overlap_of_parallel_lanes_are_exact() -> None:
    centres, runs = lanes(4, spacing_m=36.0, trigger_m=10.0)
    m = measure_overlap(centres, runs, S, NO_CELLS, 1.0, asked_front=1 - 10 / S, asked_side=1 - 36 / S)
    assert m.strips == 4
    assert m.front is not None and m.side is not None
    assert abs(m.front.median - (1 - 10 / S)) < 1e-9 and abs(m.front.p5 - (1 - 10 / S)) < 1e-9
    assert m.front.pairs == 4 * 30
    assert abs(m.side.median - (1 - 36 / S)) < 1e-9 and abs(m.side.p5 - (1 - 36 / S)) < 1e-9
    assert m.side.pairs == len(centres)  # every photo has a lane beside it


def test_one_drone_flying_the_lanes_back_and_forth_gives_the_same_overlaps() -> None:
    """Strips derived from headings: the turn between two lanes starts a new strip, and the photos of the
    short connecting leg are no side neighbours of the lanes (they cross them)."""
    centres, _ = lanes(3, spacing_m=45.0, trigger_m=15.0)
    m = measure_overlap(centres, np.zeros(len(centres)), S, NO_CELLS, 1.0)
    assert m.front is not None and m.side is not None
    assert abs(m.front.median - (1 - 15 / S)) < 1e-9
    assert abs(m.side.median - 0.5) < 1e-9 and abs(m.side.p5 - 0.5) < 1e-9


def test_leg_ids_given_by_the_caller_are_used() -> None:
    centres, runs = lanes(2, spacing_m=45.0, trigger_m=15.0)
    legs = (np.arange(len(centres)) // 7)  # made-up legs of 7 photos: consecutive pairs across them do not count
    m = measure_overlap(centres, np.zeros(len(centres)), S, NO_CELLS, 1.0, strips=legs)
    assert m.strips == int(np.ceil(len(centres) / 7))
    assert m.front is not None and m.front.pairs == len(centres) - m.strips


def test_a_single_strip_has_no_side_overlap_and_every_point_is_seen_by_one_strip() -> None:
    centres, runs = lanes(1, spacing_m=0.0, trigger_m=10.0, length_m=200.0)
    cells = np.array([[0, c] for c in range(0, 201, 10)])
    m = measure_overlap(centres, runs, S, cells, 1.0, asked_front=1 - 10 / S, asked_side=0.6)
    assert m.strips == 1 and m.side is None
    assert m.single_strip_share == 1.0
    # on one strip the side overlap implies nothing more: 9 photos a point, not 9 x 2
    assert (m.implied_one_strip, m.implied_neighbouring) == (9, 18)
    assert "side overlap not measured (one strip) (asked 60 %)" in m.summary()


def test_photos_per_point_on_a_grid_of_photos() -> None:
    """Photos every 10 m on a 0..100 m square, footprint 30 m (15 m each side of the photo, edge included);
    the points are centres of 5 m cells."""
    axis = np.arange(0.0, 101.0, 10.0)
    rows, cols = np.meshgrid(axis, axis, indexing="ij")
    centres = np.column_stack([rows.ravel(), cols.ravel()])
    runs = np.repeat(np.arange(len(axis)), len(axis))  # one drone per row of photos: each row a strip
    points_m = np.array([[50, 50], [45, 45], [0, 0], [105, 50], [50, 115], [50, 120], [200, 200]])
    counts, single = photos_per_point(centres, strips_of(centres, runs), points_m // 5, 5.0, 30.0)
    # 3 x 3; 4 x 4 (30 and 60 lie on the edge); 2 x 2 at the corner; 2 x 3 past the side; 3 x 1 (100 on the
    # edge); 3 x 0; none
    assert counts.tolist() == [9, 16, 4, 6, 3, 0, 0]
    assert single.tolist() == [False, False, False, False, False, False, False]
    one_row = photos_per_point(centres[:11], np.zeros(11, dtype=np.int64), points_m // 5, 5.0, 30.0)
    assert one_row[0].tolist() == [0, 0, 2, 0, 0, 0, 0] and one_row[1].tolist() == [False, False, True] + [False] * 4


def test_what_the_asked_overlaps_imply() -> None:
    assert implied_photos(DEFAULT_OVERLAP, None) == (9, 9)  # 1 / (1 - 8/9) is 9, not 8.999...
    assert implied_photos(0.8, 0.6) == (5, 10)
    assert implied_photos(0.75, 0.42) == (4, 4)
    assert implied_photos(None, 0.6) == (None, None)


def test_a_measure_goes_through_json_and_back() -> None:
    centres, runs = lanes(3, spacing_m=40.0, trigger_m=10.0)
    m = measure_overlap(centres, runs, S, np.rint(centres[::3] / 5).astype(int), 5.0, asked_front=0.8, asked_side=None)
    assert OverlapMeasure.from_json(json.loads(json.dumps(m.to_json()))) == m
    assert m.to_json()["asked_side"] is None


# ------------------------------------------------------------------------------------------- reachable or bounded
def dead_end_street() -> np.ndarray:
    """A 20 x 30 map of buildings with one street 3 cells wide (rows 8..10) from the map's west edge to a
    dead end at column 20."""
    flyable = np.zeros((20, 30), dtype=bool)
    flyable[8:11, :21] = True
    return flyable


def test_the_photo_window_is_half_a_footprint_each_way() -> None:
    assert window_half_cells(9 * 2.0, 2.0) == 4  # the planner's 9-cell footprint: 4 cells each way
    assert window_half_cells(30.0, 5.0) == 3


def test_a_street_is_reachable_between_its_dead_end_and_the_map_edge() -> None:
    flyable = dead_end_street()
    cells = np.array([[9, c] for c in range(21)])
    reachable, edge = classify_points(flyable, cells, 4)
    # a row run of 9 flyable cells crosses the window of columns 4..16; nearer the dead end the buildings
    # close it, nearer column 0 the map's edge does
    assert np.flatnonzero(reachable).tolist() == list(range(4, 17))
    assert np.flatnonzero(edge).tolist() == [0, 1, 2, 3]
    # the street's side rows alike: a run in row 9 crosses the window of a point in row 8 or 10
    assert classify_points(flyable, np.array([[8, 10], [10, 10], [10, 17]]), 4)[0].tolist() == [True, True, False]


def test_an_open_field_is_reachable_but_at_its_corners() -> None:
    flyable = np.ones((12, 12), dtype=bool)
    windows = reachable_windows(flyable, 4)
    # a point near one edge is crossed by a run along that edge; at a corner both ways leave the map
    expected = np.ones((12, 12), dtype=bool)
    for rows in (slice(0, 4), slice(8, 12)):
        for cols in (slice(0, 4), slice(8, 12)):
            expected[rows, cols] = False
    assert (windows == expected).all()
    # a building in the middle: the points beside it are crossed by a run beside it
    flyable[5:7, 5:7] = False
    assert reachable_windows(flyable, 4)[4:8, 4:8].all()


def test_a_1024_city_is_classified_in_one_pass() -> None:
    """The classification is over the whole grid at once: a city's mask of streets every 20 cells has its
    street crossings reachable and its dead ends (cut by a wall) bounded."""
    flyable = np.zeros((1024, 1024), dtype=bool)
    flyable[::20, :] = flyable[:, ::20] = True
    flyable[:, 500] = False  # a wall: every row street ends at it from both sides
    windows = reachable_windows(flyable, 4)
    assert windows[100, 100] and windows[100, 300]
    assert not windows[100, 497] and not windows[100, 503]  # between the wall and the crossing street 3 cells away
    assert windows[100, 495]  # the row run 491..499 still fits short of the wall


def test_met_is_judged_on_the_reachable_points_every_one() -> None:
    """One street flown down its middle, a photo every 2 m cell, the footprint 9 cells: the points near the dead
    end and the map edge see fewer than 9 photos but are bounded, so the plan meets the implied count; a
    photo missing in the middle leaves reachable points short, and `met` fails though the 5th percentile
    of all points would not notice it."""
    flyable = dead_end_street()
    cells = np.argwhere(flyable)
    cell_m = 2.0
    centres = np.column_stack([np.full(21, 9.0), np.arange(21.0)]) * cell_m
    m = measure_overlap(centres, np.zeros(21), 9 * cell_m, cells, cell_m, asked_front=8 / 9, flyable=flyable)
    assert m.reach is not None
    assert m.reach.reachable.points == 3 * 13 and m.reach.reachable.least == 9 and m.reach.reachable.short == 0
    assert m.reach.bounded.points == 3 * 8 and m.reach.bounded.least == 5  # the last photo is the dead end's
    assert dict(zip(BOUNDED_BY, m.reach.bounded_by)) == {"obstacles": 12, "map edge": 12}
    assert m.short == m.reach.bounded.short == 3 * 8  # each sees 5 .. 8 photos where 9 are implied
    assert m.met is True
    assert "reachable points 9 median, 9 p5, 9 least (0 of 39 fewer); bounded points" in m.summary()
    assert "(24: 12 obstacles, 12 map edge)" in m.summary()

    gap = np.delete(centres, 10, axis=0)  # one photo left out in the middle: 9 reachable points see 8
    m = measure_overlap(gap, np.zeros(20), 9 * cell_m, cells, cell_m, asked_front=8 / 9, flyable=flyable)
    assert m.reach is not None and m.reach.reachable.short == 3 * 9 and m.reach.reachable.least == 8
    assert m.met is False
    unsplit = measure_overlap(gap, np.zeros(20), 9 * cell_m, cells, cell_m, asked_front=8 / 9)
    assert unsplit.reach is None and unsplit.met is False  # the old rule: the 5th percentile, here 5


def test_a_measure_with_its_reach_goes_through_json_and_back() -> None:
    flyable = dead_end_street()
    centres = np.column_stack([np.full(21, 9.0), np.arange(21.0)]) * 2.0
    m = measure_overlap(centres, np.zeros(21), 18.0, np.argwhere(flyable), 2.0, asked_front=8 / 9, flyable=flyable)
    doc = json.loads(json.dumps(m.to_json()))
    assert doc["reach"]["bounded"]["by"] == {"obstacles": 12, "map edge": 12}
    assert OverlapMeasure.from_json(doc) == m


# ------------------------------------------------------------------------------------------- the plan report
def test_the_plan_report_of_a_shipped_map_meets_the_front_overlap_it_asked(tmp_path: Path,
                                                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--map", "old-town", "--uavs", "3", "--out", str(tmp_path / "plan"), "--quiet"]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if "overlaps as planned:" in line)
    assert "front overlap 89 % median, 89 % p5 (asked 89 %)" in line
    assert "(not asked)" in line and "photos per target point" in line and "9 implied" in line
    assert "; reachable points " in line and "; bounded points " in line and "map edge)" in line
    # report.json as before: a plan that asks no side overlap records no overlap block
    assert "overlap" not in json.loads((tmp_path / "plan" / "report.json").read_text())["coverage"]


def test_a_plan_that_asks_a_side_overlap_records_the_measure(tmp_path: Path) -> None:
    ground = replace(shipped_ground("old-town", 3), side_overlap=0.3)
    folder = write_plan_folder(tmp_path / "plan", ground)
    assert folder.overlap is not None and folder.overlap.front is not None
    assert folder.overlap.front.median >= DEFAULT_OVERLAP - 1e-9
    assert folder.overlap.front.p5 >= DEFAULT_OVERLAP - 1e-9  # no photo of a leg farther than the trigger distance
    recorded = read_plan_record(tmp_path / "plan").coverage
    assert recorded is not None and recorded.overlap == folder.overlap
    assert recorded.overlap.asked_side == 0.3 and recorded.overlap.points == folder.record.targets


# ------------------------------------------------------------------------------------------- the judge
@pytest.mark.flight
def test_the_judge_measures_the_overlaps_of_the_photos_flown(tmp_path: Path, mock_fleet,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    from missionplan.flight.display import print_flight

    plan_dir = tmp_path / "plan"
    planned = write_plan_folder(plan_dir, replace(shipped_ground("leonardo", 3), side_overlap=0.3)).overlap
    mock = mock_fleet(plan_dir, 10.0)
    result = fly(plan_dir, mock.client_url, timeout_s=120.0, progress=False, time_scale=10.0)
    flown = result.overlap
    assert planned is not None and flown is not None and flown.front is not None
    assert flown.photos == sum(d["photos"] for d in result.drones)
    assert flown.asked_front == pytest.approx(DEFAULT_OVERLAP) and flown.asked_side == 0.3
    # the mock triggers by distance along its track: its spacing is the plan's, to a few centimetres
    assert flown.front.median == pytest.approx(planned.front.median, abs=0.02)
    assert flown.per_point_median >= planned.per_point_median - 2
    # judged as the plan is: on the points a strip can reach, the bounded ones apart
    assert flown.reach is not None and planned.reach is not None
    assert (flown.reach.reachable.points, flown.reach.bounded.points) == (planned.reach.reachable.points,
                                                                        planned.reach.bounded.points)
    doc = json.loads((plan_dir / "flight.json").read_text())
    assert OverlapMeasure.from_json(doc["overlap"]) == flown
    print_flight(result)
    assert "overlaps as flown: front overlap" in capsys.readouterr().out


def test_a_street_crossing_is_not_where_strips_neighbour_side_by_side() -> None:
    """One east-west and one north-south strip crossing at (100, 100): the crossing is seen by both, yet no side
    overlap was asked of them, so it wants the one-strip count; two parallel strips 10 m apart want the product."""
    along = np.arange(0.0, 201.0, 10.0)
    east_west = np.column_stack([np.full_like(along, 100.0), along])  # (row metres, column metres)
    north_south = np.column_stack([along, np.full_like(along, 100.0)])
    crossing = np.vstack([east_west, north_south])
    runs = np.repeat([0, 1], len(along))
    cells = np.array([[100, 100]])
    m = measure_overlap(crossing, runs, S, cells, 1.0, asked_front=1 - 10 / S, asked_side=0.6)
    assert m.implied_one_strip == 9 and m.short == 0 and m.single_strip_share == 1.0
    side_by_side = np.vstack([east_west, east_west + [10.0, 0.0]])
    m2 = measure_overlap(side_by_side, runs, S, cells + [5, 0], 1.0, asked_front=1 - 10 / S, asked_side=0.6)
    assert m2.single_strip_share == 0.0 and m2.implied_neighbouring == 18
