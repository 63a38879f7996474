"""`missionplan verify`: the runs' conditions (the same for a seed and an index whoever flies them), bad input in one
line, the same rows from one worker and from two, resume, the fallback without Ray, and a lost drone re-tasked as
`fly --replan` re-tasks it (the engines under stress: test_verify_engines.py)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

from missionplan.cli import main
from missionplan.verify.conditions import (FAULT_KINDS, ConditionsError, draw_conditions, parse_faults, parse_wind,
                                           run_seed)
from missionplan.verify.engines import choose_engine
from missionplan.verify.verify import VerifySettings, verify_plan
from verify_runs import FLY_S, leonardo_3, verify_doc

ITEMS = {1: 40, 2: 38, 3: 43}
# The mock's clock follows the wall clock, so two flights of the same conditions differ by a few telemetry samples.
COVERAGE_SLACK_PCT, MAKESPAN_SLACK = 1.5, 0.05


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return leonardo_3(tmp_path_factory.mktemp("verify"))


def outcomes_agree(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert a["conditions"] == b["conditions"] and a["seed"] == b["seed"]
    assert abs(a["coverage"] - b["coverage"]) <= COVERAGE_SLACK_PCT, (a["coverage"], b["coverage"])
    makespans = (a["makespan_s"], b["makespan_s"])
    assert abs(makespans[0] - makespans[1]) <= MAKESPAN_SLACK * makespans[1], makespans
    assert a["drones_lost"] == b["drones_lost"]


# ------------------------------------------------------------------------------------------ conditions
def test_conditions_depend_on_the_seed_and_the_index_only() -> None:
    kinds = FAULT_KINDS
    a = [draw_conditions(i, 7, (2.0, 6.0), kinds, ITEMS) for i in range(50)]
    assert a == [draw_conditions(i, 7, (2.0, 6.0), kinds, ITEMS) for i in range(50)]
    assert a != [draw_conditions(i, 8, (2.0, 6.0), kinds, ITEMS) for i in range(50)]
    assert len({c.seed for c in a}) == 50 and a[3].seed == run_seed(7, 3)
    for c in a:
        assert 2.0 <= c.wind_mps <= 6.0 and 0.0 <= c.wind_from_deg < 360.0
        assert [f.kind for f in c.faults] == list(kinds)
        for f in c.faults:
            assert f.drone in ITEMS and 2 <= f.at_item < ITEMS[f.drone] - 1
        glitch = c.faults[3]
        assert 10.0 - 0.02 <= (glitch.north_m ** 2 + glitch.east_m ** 2) ** 0.5 <= 30.0 + 0.02
    assert {c.faults[0].drone for c in a} == set(ITEMS)  # every drone gets lost in some run


def test_bad_ranges_and_fault_names_are_one_line() -> None:
    assert parse_wind("2-6") == (2.0, 6.0) and parse_wind("4") == (4.0, 4.0)
    for text in ("6-2", "a-b", "-3", "1-2-3", "40"):
        with pytest.raises(ConditionsError, match="^wind "):
            parse_wind(text)
    assert parse_faults("lost-drone,link-gap,lost-drone") == ("lost-drone", "link-gap")
    assert parse_faults("none") == ()
    with pytest.raises(ConditionsError, match="'engine-fire'"):
        parse_faults("lost-drone,engine-fire")


def test_the_command_line_refuses_bad_input_in_one_line(plan: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    cases = [([str(plan), "--wind", "9-1"], "--wind '9-1'"),
             ([str(plan), "--faults", "fire"], "--faults 'fire'"),
             ([str(tmp_path), "--runs", "1"], "no report.json"),
             ([str(plan), "--runs", "0"], "--runs"),
             ([str(plan), "--sim", "sitl"], "--sitl-dir")]
    for args, said in cases:
        assert main(["verify", *args, "--out", str(tmp_path / "v"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and said in err, err
    assert not (tmp_path / "v" / "verify.json").exists()


def test_without_ray_auto_is_the_process_pool_and_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # an install without the cluster extra
    engine, line = choose_engine("auto", None)
    assert engine == "pool" and "Ray is not installed" in line and "missionplan[cluster]" in line
    with pytest.raises(RuntimeError, match="Ray is not installed"):
        choose_engine("ray", None)


# ------------------------------------------------------------------------------------------ flights
@pytest.mark.flight
def test_the_same_seed_gives_the_same_rows_in_one_worker_and_in_two(plan: Path, tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from missionplan.verify.verify import mission_items

    items = mission_items(plan)
    # A seed whose first run's battery reads low early in its drone's mission: long enough (BATT_LOW_TIMER) for the
    # failsafe to send it home before it ends.
    seed = next(s for s in range(1000) if (f := draw_conditions(0, s, (2.0, 6.0), ("battery-failsafe",),
                                                                items).faults[0]).at_item < items[f.drone] // 3)
    settings = VerifySettings(runs=2, seed=seed, wind=(2.0, 6.0), faults=("battery-failsafe",))
    said: list[str] = []
    monkeypatch.setitem(sys.modules, "ray", None)
    pool = verify_plan(plan, settings, out=tmp_path / "pool", engine="auto", workers=2, progress=False, say=said.append)
    assert any("local process pool" in s for s in said)
    inline = verify_plan(plan, settings, out=tmp_path / "inline", engine="inline", progress=False, say=said.append)
    assert pool.complete and inline.complete
    engine = verify_doc(tmp_path / "pool")["engine"]
    assert engine["engine"] == "pool" and engine["workers"] == 2
    assert [r["run"] for r in pool.rows] == [0, 1]
    for a, b in zip(pool.rows, inline.rows):
        outcomes_agree(a, b)
        assert not a.get("error") and a["struck"][0]["kind"] == "battery-failsafe"
        assert all(0.0 < v < 1.0 for v in a["battery_left"].values())
    # A battery that reads low long enough (BATT_LOW_TIMER) sends its drone home early.
    assert pool.rows[0]["ended_early"] and inline.rows[0]["ended_early"]
    for name in ("verify.json", "verify.png", "verify.html"):
        assert (tmp_path / "pool" / name).stat().st_size > 0
    assert (tmp_path / "pool" / "runs" / "0001" / "flight.json").is_file()
    assert "battery reserve" in pool.verdict and "coverage >= 99 %" in pool.verdict
    # --resume flies only what is missing, and the earlier rows stay as they were.
    more = VerifySettings(runs=3, seed=seed, wind=(2.0, 6.0), faults=("battery-failsafe",))
    resumed = verify_plan(plan, more, out=tmp_path / "inline", engine="inline", resume=True, progress=False,
                          say=said.append)
    assert "resuming: 2 of 3 runs already flown, 1 to fly" in said
    assert resumed.rows[:2] == inline.rows and resumed.rows[2]["run"] == 2 and resumed.complete


@pytest.mark.flight
def test_a_lost_drone_with_replan_reaches_what_fly_replan_reaches(plan: Path, tmp_path: Path) -> None:
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet
    from missionplan.planning.retask import retask_planner
    from missionplan.verify.flight_run import copy_plan

    from missionplan.verify.verify import mission_items

    items = mission_items(plan)
    # A drone lost early, while the others still survey (later, they are on their way home: nothing to re-task to).
    seed = next(s for s in range(1000) if (f := draw_conditions(0, s, (0.0, 0.0), ("lost-drone",),
                                                                items).faults[0]).at_item < items[f.drone] // 3)
    settings = VerifySettings(runs=1, seed=seed, faults=("lost-drone",), replan=True)
    verified = verify_plan(plan, settings, out=tmp_path / "v", engine="inline", progress=False, say=lambda s: None)
    row = verified.rows[0]
    lost = row["conditions"]["faults"][0]
    assert row["drones_lost"] == [lost["drone"]] and row["retask"] == ["re-tasked"]
    assert [(f["kind"], f["drone"], f["at_item"]) for f in row["struck"]] == [("lost-drone", lost["drone"],
                                                                                lost["at_item"])]
    # The same conditions flown by fly --replan directly.
    copy = copy_plan(plan, tmp_path / "direct")
    mock = start_mock_fleet(copy, settings.time_scale)
    mock.kill(lost["drone"], at_item=lost["at_item"])
    try:
        result = fly(copy, mock.client_url, timeout_s=FLY_S, progress=False, time_scale=settings.time_scale,
                     replan=retask_planner, silences_in_vehicle_time=True)
    finally:
        mock.stop()
    assert abs(result.coverage - row["coverage"]) <= COVERAGE_SLACK_PCT, (result.coverage, row["coverage"])
    assert row["coverage"] >= 99.0  # the survivors finished the lost drone's share
