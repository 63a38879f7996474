"""Every shipped map x 3-6 drones x both policies: full coverage, checked by replaying the paths.

The replay (tests/replay_check.py) does not import the planner: it re-derives moves,
collisions, swaps, obstacle entries and footprint coverage from report.json alone.
"""

import json

import pytest

from missionplan.maps.catalog import load_shipped, shipped_map_names
from missionplan.planning.pipeline import plan_map
from missionplan.mission.report import build_report
from replay_check import replay

SHIPPED = ["leonardo", "grid-city", "old-town", "river-city"]


def test_the_four_maps_ship():
    assert set(SHIPPED) <= set(shipped_map_names())


@pytest.mark.parametrize("uavs", [3, 4, 5, 6])
@pytest.mark.parametrize("name", SHIPPED)
@pytest.mark.parametrize("policy", ["nn", "expert"])
def test_full_coverage_and_legal_paths(policy, name, uavs):
    result = plan_map(load_shipped(name), uavs, policy=policy)
    report = json.loads(json.dumps(build_report(result, seed=0).to_json()))  # exactly what report.json holds
    assert report["success"], report["failure"]
    checked = replay(report)
    assert checked["problems"] == []
    assert checked["coverage"] == pytest.approx(100.0)
    assert checked["reachable"] == report["targets"]
    assert checked["unreachable"] == report["unreachable"]
    assert checked["mmn"] == pytest.approx(report["metrics"]["MMN"])
    assert checked["makespan"] == report["metrics"]["makespan"]
    assert report["metrics"]["MMN"] >= report["floor"]  # the hard floor U / (9A)


@pytest.mark.parametrize("policy", ["nn", "expert"])
def test_leonardo_five_drones_beats_the_thesis(policy):
    result = plan_map(load_shipped("leonardo"), 5, policy=policy)
    metrics = result.run.metrics
    assert result.world.unreachable_cells.size > 0  # the map's enclosed pockets are detected
    assert metrics["MMN"] < 133  # thesis Table 5.1, 5 UAVs
    assert metrics["TE"] > 32.4


def test_report_counts_network_and_path_finder_decisions():
    record = build_report(plan_map(load_shipped("leonardo"), 5, policy="nn"), seed=0)
    decisions = record.decisions
    assert record.policy == "nn"
    assert len(decisions.policy) == record.steps
    assert sum(decisions.policy) > 0 and sum(decisions.pathfinder) > 0
    for step in range(record.steps):
        assert decisions.policy[step] + decisions.pathfinder[step] + decisions.idle[step] == 5
