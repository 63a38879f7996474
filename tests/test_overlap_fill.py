"""The overlap fill (missionplan/mission/overlap_fill.py, plan --overlap-fill): stubs and runs on small grids, the
corrector keeping their ends, and whole plans of a shipped map whose reachable points all see the implied photos."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from missionplan.cli import main
from missionplan.maps.gridmap import GridMap, save_map
from missionplan.mission.corrector import correct_path
from missionplan.mission.overlap_fill import choose_runs, choose_stubs, fill_paths
from missionplan.mission.clearance import steps_toward
from missionplan.mission.plan_blocks import OverlapFill, PlanSettings
from missionplan.mission.plan_record import CAPTURE_VERSION, read_plan_record
from missionplan.planning.plan_folder import PlanOptions, shipped_ground, write_plan_folder

HALF = 4  # the planner's footprint: 9 cells, 4 each way


def _street(length: int = 40) -> np.ndarray:
    """A one-cell street along row 5 of an 11-row map, walls all round it."""
    open_cells = np.zeros((11, length), dtype=bool)
    open_cells[5, :] = True
    return open_cells


def _is_grid_path(path: np.ndarray, open_cells: np.ndarray) -> bool:
    """Every step a move to a side neighbour (or a hover), every cell open."""
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    return bool((steps <= 1).all() and open_cells[path[:, 0], path[:, 1]].all())


def _is_subsequence(short: list[tuple[int, int]], long: list[tuple[int, int]]) -> bool:
    it = iter(long)
    return all(cell in it for cell in short)


def test_a_stub_carries_a_street_on_past_where_the_path_turned_back() -> None:
    """The path flies the street's cells 0..20 and stops; the point at 20 sees photos from 16..20 only (5 of 9).
    One stub out of the path along the street gives it the 4 it lacks: out and back over two cells."""
    open_cells = _street()
    on_path = np.zeros_like(open_cells)
    on_path[5, :21] = True
    stubs, left = choose_stubs(np.array([[5, 20]]), np.array([4]), on_path, open_cells, HALF, turn_cells=4.0)
    assert left.tolist() == [0] and len(stubs) == 1
    stub = stubs[0]
    assert stub.start == (5, 20) and stub.cells == ((5, 21), (5, 22), (5, 21), (5, 20)) and stub.ends == ((5, 22),)


def test_one_stub_serves_the_short_points_around_it() -> None:
    """Points 17..20 lack 1..4 photos: the stub the largest deficit asks for gives every one of them enough."""
    open_cells = _street()
    on_path = np.zeros_like(open_cells)
    on_path[5, :21] = True
    points = np.array([[5, 17], [5, 18], [5, 19], [5, 20]])
    stubs, left = choose_stubs(points, np.array([1, 2, 3, 4]), on_path, open_cells, HALF, turn_cells=4.0)
    assert len(stubs) == 1 and left.tolist() == [0, 0, 0, 0]


def test_a_stub_never_leaves_the_open_cells() -> None:
    """The street ends two cells past the path: the stub stops there, and what two new cells cannot give is left
    (a second stub over the same cells would add no new view)."""
    open_cells = _street(23)
    on_path = np.zeros_like(open_cells)
    on_path[5, :21] = True
    stubs, left = choose_stubs(np.array([[5, 20]]), np.array([8]), on_path, open_cells, HALF, turn_cells=4.0)
    assert all(open_cells[cell] for stub in stubs for cell in stub.cells)
    assert max(c for stub in stubs for _, c in stub.cells) == 22
    assert len(stubs) == 1 and left.tolist() == [4]  # out and back over two new cells: 4 of the 8


def test_a_point_whose_window_no_path_enters_gets_a_run_reached_from_the_path() -> None:
    """An open field with the path along its top row: a point 10 rows down is out of every stub's reach, and is
    served by a run of 9 open cells across its window, flown out of the path and back."""
    open_cells = np.ones((30, 30), dtype=bool)
    on_path = np.zeros_like(open_cells)
    on_path[0, :] = True
    point = np.array([[15, 15]])
    stubs, left = choose_stubs(point, np.array([9]), on_path, open_cells, HALF, turn_cells=4.0)
    assert not stubs and left.tolist() == [9]
    dist, nxt = steps_toward(open_cells, on_path)
    runs, unserved = choose_runs(point, dist, nxt, HALF)
    assert unserved == 0 and len(runs) == 1
    run = runs[0]
    assert run.start[0] == 0 and run.cells[-1] == run.start
    flown = set(run.cells)
    lines = ([[(r, c) for c in range(11, 20)] for r in range(11, 20)]
             + [[(r, c) for r in range(11, 20)] for c in range(11, 20)])
    crossing = [cells for cells in lines if set(cells) <= flown]
    assert crossing, "the run crosses the point's window end to end"


def test_filled_paths_keep_the_plan_and_fly_only_open_cells() -> None:
    """Two drones; the fill inserts detours that leave from a path cell and come back to it: each drone's old path
    is a subsequence of its new one, with the same start and end, and every step is a grid move."""
    open_cells = np.ones((24, 40), dtype=bool)
    open_cells[10:14, 10:30] = False  # a block in the middle
    a = [(2, c) for c in range(0, 30)]
    b = [(20, c) for c in range(39, 15, -1)]
    length = max(len(a), len(b))
    paths = np.array([a + [a[-1]] * (length - len(a)), b + [b[-1]] * (length - len(b))])
    points = np.array([[2, 30], [2, 31], [20, 12], [6, 20]])
    filled = fill_paths(paths, open_cells, points, np.array([5, 4, 6, 9]), HALF, turn_cells=4.0)
    assert filled.moves_added > 0 and filled.stubs + filled.runs >= 2 and filled.unserved == 0
    for old, new in zip(paths, filled.paths):
        assert _is_grid_path(new, open_cells)
        assert tuple(new[0]) == tuple(old[0]) and tuple(new[-1]) == tuple(old[-1])
        assert _is_subsequence([tuple(c) for c in old.tolist()], [tuple(c) for c in new.tolist()])
    keep = np.zeros(open_cells.shape, dtype=bool)
    filled.anchor(keep, starts=False)
    assert keep.sum() >= filled.stubs + filled.runs
    filled.anchor(keep, starts=True)
    assert keep[tuple(np.array(filled.starts).T)].all()


def test_the_corrector_keeps_a_detours_far_end_it_would_otherwise_cut() -> None:
    """A street flown 0..30 with a stub at 20 out to 24 and back: the rest of the street keeps every target's
    photo, so the corrector's shortcut drops the stub; with the stub's end kept it stays a waypoint."""
    open_cells = _street()
    obstacle = ~open_cells
    targets = open_cells.copy()
    path = np.array([(5, c) for c in range(0, 25)] + [(5, c) for c in range(23, 19, -1)]
                    + [(5, c) for c in range(21, 31)])
    cut = correct_path(path, obstacle, targets)
    assert cut.waypoints.tolist() == [[5.0, 0.0], [5.0, 30.0]]
    keep = np.zeros_like(open_cells)
    keep[5, 24] = True
    kept = correct_path(path, obstacle, targets, keep=keep)
    assert [5.0, 24.0] in kept.waypoints.tolist()


def test_the_fill_record_goes_through_json_and_back() -> None:
    fill = OverlapFill(3, 20, 1, 210, 285, 0, 0, 55.1, 64.8)
    assert OverlapFill.from_json(json.loads(json.dumps(fill.to_json()))) == fill
    assert fill.summary() == ("overlap fill: 20 stubs, 1 runs (210 grid moves) in 3 rounds; reachable points short "
                              "285 -> 0; busiest drone 55 s -> 65 s (+18 %)")


# ------------------------------------------------------------------------------------------- whole plans
def test_a_filled_plan_of_a_shipped_map_leaves_no_reachable_point_short(tmp_path: Path) -> None:
    """leonardo, 5 drones: without the fill 285 reachable points see fewer than the 9 photos the default front
    overlap implies (bench/reach_bench.py); with it none does, as measured from where the missions take their
    photos, and the clearance and separation promises still hold."""
    ground = shipped_ground("leonardo", 5)
    plain = write_plan_folder(tmp_path / "plain", ground)
    filled = write_plan_folder(tmp_path / "filled", ground, PlanOptions(overlap_fill=True))
    assert plain.overlap is not None and plain.overlap.reach is not None and plain.overlap.reach.reachable.short > 0
    assert filled.overlap is not None and filled.overlap.reach is not None
    assert filled.overlap.reach.reachable.short == 0 and filled.overlap.reach.reachable.least >= 9
    record = filled.record
    assert record.overlap_fill is not None and record.overlap_fill.short_after == 0
    assert record.overlap_fill.short_before == plain.overlap.reach.reachable.short
    assert record.overlap_fill.makespan_s >= record.overlap_fill.makespan_before_s
    assert record.promise is not None and record.promise.clearance.kept
    separation = record.promise.separation
    assert separation.required_m is not None and separation.closest.d3 >= separation.required_m - 1e-6
    assert record.metrics.coverage == plain.record.metrics.coverage == 100.0
    assert record.version == CAPTURE_VERSION and record.settings is not None and record.settings.overlap_fill
    assert read_plan_record(tmp_path / "filled") == record
    assert plain.record.overlap_fill is None and plain.record.version == 1


def test_open_ground_with_a_side_overlap_meets_it_at_the_zones_edges_too(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A 40 x 40 open field swept in lanes 2 cells apart (--side-overlap 70): inside, 4 or 5 lanes see each point;
    at the field's first and last lanes fewer neighbour, and the fill (on: an overlap was asked) gives those
    points the 27 photos implied where strips neighbour (9 along x 3 across)."""
    blocked = np.zeros((40, 40), dtype=bool)
    meta = {"origin_lat": "45.066000", "origin_lon": "7.670000", "cell_m": "2.0", "altitude_m": "10",
            "fov_deg": "83.9744"}
    save_map(GridMap("field", blocked, ~blocked, [(0, 0)], meta), tmp_path / "open.map")
    assert main(["plan", "--map", str(tmp_path / "open.map"), "--uavs", "1", "--side-overlap", "70", "--out",
                 str(tmp_path / "plan"), "--quiet"]) == 0
    assert "reachable points short " in capsys.readouterr().out
    overlap = read_plan_record(tmp_path / "plan").coverage.overlap  # type: ignore[union-attr]
    assert overlap is not None and overlap.reach is not None and overlap.implied_neighbouring == 27
    # the lanes keep the side overlap asked; a stub's few photos may lie farther from their side neighbours
    assert overlap.reach.reachable.short == 0 and overlap.side is not None and overlap.side.median >= 0.7


def test_the_fill_is_on_for_a_plan_asked_by_overlaps_and_can_be_turned_off(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    base = ["plan", "--map", "leonardo", "--uavs", "3", "--quiet", "--front-overlap", "80"]
    assert main(base + ["--out", str(tmp_path / "on")]) == 0
    out = capsys.readouterr().out
    assert "  overlap fill: " in out and "reachable points short " in out
    doc = json.loads((tmp_path / "on" / "report.json").read_text())
    assert doc["overlap_fill"]["short_after"] == 0 and doc["settings"]["overlap_fill"] is True
    assert main(base + ["--out", str(tmp_path / "off"), "--no-overlap-fill"]) == 0
    assert "overlap fill" not in capsys.readouterr().out
    doc = json.loads((tmp_path / "off" / "report.json").read_text())
    assert "overlap_fill" not in doc and "overlap_fill" not in doc["settings"]


def test_plan_settings_carry_the_fill_to_a_replan() -> None:
    ground = shipped_ground("leonardo", 2)
    assert ground.settings is not None and ground.safety is not None
    stored = PlanSettings(ground.settings, ground.safety, "expert", "geodesic", True, "lanes")
    assert "overlap_fill" not in stored.to_json()
    on = replace(stored, overlap_fill=True)
    assert PlanSettings.from_json(json.loads(json.dumps(on.to_json()))).overlap_fill is True


@pytest.mark.flight
def test_a_filled_plan_flown_on_the_mock_fleet_gives_its_points_the_photos(tmp_path: Path, mock_fleet) -> None:
    """The detours are flown, not only planned: the mock fleet follows the filled missions and triggers by
    distance along its track, and the judge, measuring where the vehicles reported their photos, finds the
    reachable points seen by the implied photos as the plan did."""
    from missionplan.flight.fly import fly

    plan_dir = tmp_path / "plan"
    planned = write_plan_folder(plan_dir, shipped_ground("leonardo", 3), PlanOptions(overlap_fill=True)).overlap
    assert planned is not None and planned.reach is not None and planned.reach.reachable.short == 0
    mock = mock_fleet(plan_dir, 10.0)
    result = fly(plan_dir, mock.client_url, timeout_s=120.0, progress=False, time_scale=10.0)
    flown = result.overlap
    assert flown is not None and flown.reach is not None
    assert flown.reach.reachable.points == planned.reach.reachable.points
    # a reported photo lies within a few centimetres of the planned one: at most a point or two on a window's edge
    assert flown.reach.reachable.short <= 0.01 * flown.reach.reachable.points
    assert flown.reach.reachable.p5 >= 9
