"""bench/gap_bench.py's statistics: the gap of two policies' mean makespans and its bootstrap interval.

The bench itself plans for minutes and is run by hand; what it concludes from the plans (the gap, the
95 % interval over seeds, the verdict against the 3 % goal) is checked here on made-up makespans.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest


@pytest.fixture
def gap_bench() -> ModuleType:
    import gap_bench  # bench/ is on the tests' path (pyproject.toml's pytest pythonpath), as when run by hand

    return gap_bench


def test_equal_plans_have_no_gap_and_meet_the_goal(gap_bench: ModuleType) -> None:
    expert = np.array([2200, 2300, 2250, 2400, 2100])
    resamples = gap_bench.resampled_gaps(expert, expert.copy(), np.random.default_rng(0))
    assert gap_bench.gap_percent(expert, expert) == 0
    assert gap_bench.interval(resamples) == (0.0, 0.0)
    assert gap_bench.verdict(0.0, 0.0).startswith("met")


def test_a_steady_gap_gives_a_narrow_interval_that_decides(gap_bench: ModuleType) -> None:
    expert = np.array([2000, 2100, 2200, 2300, 2400])
    network = expert * 1.10  # 10 % longer on every seed
    low, high = gap_bench.interval(gap_bench.resampled_gaps(expert, network, np.random.default_rng(0)))
    assert low == pytest.approx(10.0) and high == pytest.approx(10.0)
    assert gap_bench.verdict(low, high).startswith("not met")


def test_a_noisy_gap_gives_an_interval_round_it_that_may_span_the_goal(gap_bench: ModuleType) -> None:
    expert = np.array([2214, 2163, 2262, 2230, 2202])
    network = np.array([2254, 2311, 2280, 2209, 2180])  # -1 % .. +7 % per seed
    gap = float(gap_bench.gap_percent(expert, network))
    low, high = gap_bench.interval(gap_bench.resampled_gaps(expert, network, np.random.default_rng(0)))
    assert low < gap < high
    assert low < gap_bench.GAP_GOAL_PERCENT < high
    assert gap_bench.verdict(low, high).startswith("undecided")


def test_the_interval_repeats_run_to_run(gap_bench: ModuleType) -> None:
    expert, network = np.array([700, 680, 720]), np.array([740, 690, 780])
    first = gap_bench.resampled_gaps(expert, network, np.random.default_rng(gap_bench.BOOTSTRAP_SEED))
    again = gap_bench.resampled_gaps(expert, network, np.random.default_rng(gap_bench.BOOTSTRAP_SEED))
    assert np.array_equal(first, again) and len(first) == gap_bench.BOOTSTRAP_RESAMPLES
