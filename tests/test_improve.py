"""The anytime improvement (plan --improve, planning/improve.py): never a worse plan, the same plan for the same seed and
rounds, every promise kept, and the record of what it tried."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from missionplan.cli.app import main
from missionplan.maps.catalog import load_shipped
from missionplan.mission.plan_improvement import PlanImprovement
from missionplan.mission.plan_record import read_plan_record
from missionplan.planning.errors import PlanRequestError
from missionplan.planning.field_plan import plan_field
from missionplan.planning.improve import ZoneSearch, Trial, improve, zone_neighbours
from missionplan.planning.plan_folder import PlanOptions, shipped_ground, write_plan_folder

ROUNDS = 3  # every move of the cycle tried once, and one kept on this map (checked below)


@pytest.fixture(scope="module")
def improved(tmp_path_factory: pytest.TempPathFactory):
    """old-town with 4 drones, planned without and with ROUNDS rounds of improvement."""
    ground = shipped_ground("old-town", 4)
    plain = write_plan_folder(tmp_path_factory.mktemp("plain"), ground, PlanOptions())
    better = write_plan_folder(tmp_path_factory.mktemp("better"), shipped_ground("old-town", 4),
                               PlanOptions(improve_s=600.0, improve_rounds=ROUNDS))
    return plain, better


def busiest_s(record) -> float:
    return max(sum(s.flight_s for s in d.sorties) for d in record.drones)


def test_the_kept_plan_is_never_worse_and_is_what_the_record_says(improved) -> None:
    plain, better = improved
    block = better.record.improve
    assert block is not None and block.objective == "flight_s" and block.rounds == ROUNDS
    assert block.first == pytest.approx(busiest_s(plain.record), abs=0.1)  # the planner's plan came first
    assert block.kept == pytest.approx(busiest_s(better.record), abs=0.1)  # and the written plan is the kept one
    assert block.kept < block.first and block.kept_round > 0  # this map and seed: a shorter plan was found
    best = block.first
    for candidate in block.candidates:  # a candidate is kept exactly when it is shorter than all before it
        shorter = candidate.value is not None and candidate.value < best
        assert candidate.kept == shorter or (candidate.value == best and not candidate.kept)
        best = min(best, candidate.value) if candidate.kept else best
    assert best == block.kept
    times = [c.at_s for c in block.candidates]
    assert times == sorted(times) and times[-1] <= block.seconds


def test_every_promise_holds_in_the_improved_plan(improved) -> None:
    _, better = improved
    record = better.record
    assert record.success and record.metrics.coverage == 100.0
    separation, clearance = record.separation, record.clearance
    assert separation is not None and separation.guaranteed_m is not None
    assert separation.closest.d3 >= separation.required_m
    assert clearance is not None and clearance.kept


def test_the_record_reads_back(improved) -> None:
    _, better = improved
    read = read_plan_record(better.out)
    assert read.improve == better.record.improve
    assert PlanImprovement.from_json(read.improve.to_json()) == read.improve


def test_the_same_seed_and_rounds_give_the_same_plan(tmp_path: Path, improved) -> None:
    _, better = improved
    again = write_plan_folder(tmp_path / "again", shipped_ground("old-town", 4),
                              PlanOptions(improve_s=600.0, improve_rounds=ROUNDS))
    assert again.record.paths == better.record.paths
    assert [(c.move, c.value, c.kept) for c in again.record.improve.candidates] == \
           [(c.move, c.value, c.kept) for c in better.record.improve.candidates]


def test_no_time_is_the_planner_s_plan(tmp_path: Path, improved) -> None:
    plain, _ = improved
    none = write_plan_folder(tmp_path / "none", shipped_ground("old-town", 4), PlanOptions(improve_s=0.0))
    assert none.record.improve is not None and none.record.improve.rounds == 0
    assert none.record.paths == plain.record.paths


def test_a_grid_plan_is_improved_on_its_makespan() -> None:
    gmap = load_shipped("old-town")
    first = plan_field(gmap, 4, None, None, None, seed=3)
    field = plan_field(gmap, 4, None, None, None, seed=3, improve_s=600.0, improve_rounds=4)
    block = field.improvement
    assert block is not None and block.objective == "moves"
    assert block.first == first.result.run.metrics["makespan"]
    assert block.kept <= block.first and field.result.run.success
    assert block.kept == max(int(np.count_nonzero(np.any(np.diff(p, axis=0) != 0, axis=1))) for p in field.result.run.paths)


def test_a_failed_first_plan_is_left_as_it_is() -> None:
    class Failed:
        class result:
            class run:
                success = False

    calls: list[object] = []
    kept, record = improve(Failed, None, lambda shares, seed: calls.append(seed), 10.0, 0)
    assert kept is Failed and record is None and not calls


def test_a_worse_candidate_is_never_kept() -> None:
    """With every candidate longer than the first, the first is what comes back."""
    gmap = load_shipped("leonardo")
    first = plan_field(gmap, 3, None, None, None)
    worse = plan_field(gmap, 2, None, None, None)  # two drones: a longer makespan on the same map
    kept, record = improve(first, None, lambda shares, seed: worse, 600.0, 0, rounds=4)
    assert kept is first and record is not None
    assert record.kept == record.first and not any(c.kept for c in record.candidates)


def test_the_moves_cycle_and_shift_to_a_neighbour() -> None:
    zone = np.array([[0, 0, 1, 1], [0, 0, 1, 1], [2, 2, -1, -1]])
    assert zone_neighbours(zone) == [{1, 2}, {0}, {0}]
    gmap = load_shipped("leonardo")
    first = plan_field(gmap, 3, None, None, None)
    search = ZoneSearch(seed=0)
    moves = [search.propose(Trial(first, None, 0))[0] for _ in range(6)]
    assert moves == ["balance", "shift", "reseed"] * 2
    _, shares, seed = ZoneSearch(seed=0).propose(Trial(first, None, 0))
    assert shares is not None and shares.sum() == pytest.approx(1.0) and seed == 0


@pytest.mark.parametrize("budget", [-1.0, float("nan"), 1e9])
def test_a_budget_out_of_range_is_refused_naming_it(budget: float) -> None:
    with pytest.raises(PlanRequestError, match="improve"):
        plan_field(load_shipped("leonardo"), 2, None, None, None, improve_s=budget)


def test_the_command_line_refuses_bad_budgets_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "a"), "--improve", "-3"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--improve" in err[0]
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "b"), "--improve-rounds", "3"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--improve-rounds needs --improve" in err[0]
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_the_command_line_prints_what_improve_did(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "p"), "--quiet",
                 "--improve", "600", "--improve-rounds", "2"]) == 0
    line = [l for l in capsys.readouterr().out.splitlines() if l.strip().startswith("improve:")]
    assert len(line) == 1 and "2 plans" in line[0] and "busiest drone" in line[0]


def test_a_fleet_sweeping_open_ground_only_reseeds() -> None:
    """Zone shares would switch off the block-by-block redraw of a fleet sweeping in lanes: reseeds only."""
    from missionplan.maps.gridmap import GridMap

    free = np.ones((54, 54), dtype=bool)
    field_map = GridMap("open 54", ~free, free.copy(), [(0, 0), (53, 53), (0, 53)])
    field = plan_field(field_map, 3, None, None, None, improve_s=600.0, improve_rounds=3)
    block = field.improvement
    assert field.result.run.lane_drones == 3 and block is not None
    assert [c.move for c in block.candidates] == ["reseed"] * 3 and block.kept <= block.first
