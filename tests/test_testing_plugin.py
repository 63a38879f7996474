"""missionplan's pytest plugin (missionplan/testing/plugin.py) as a field team's CI gets it: installed with
missionplan, it gives a suite outside this repository the fixtures, the `sitl` / `flight` markers and
`--simulators DIR`; loading it is cheap; and the simulators' folder is found as documented
(missionplan/testing/simulators.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from missionplan.testing import simulators
from missionplan.testing.arducopter import sitl_or_skip
from missionplan.testing.px4_sih import px4_or_skip

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "numpy", "pymavlink", "matplotlib", "missionplan.bridge", "missionplan.flight")

FIELD_SUITE = '''
from pathlib import Path

import pytest


@pytest.fixture
def plan_dir():
    return Path(__file__).parent / "plan"


def test_the_markers_are_registered(request):
    assert {"sitl", "flight"} <= {line.split(":")[0] for line in request.config.getini("markers")}


def test_a_mock_fleet_from_a_plan_folder(mock_fleet, plan_dir):
    mock = mock_fleet(plan_dir, 10.0)
    assert sorted(mock.vehicles) == [1, 2] and mock.client_url.startswith("udp")


@pytest.mark.sitl
def test_arducopter_skips_without_it(fly_runs, arducopter_fleet, arducopter):
    arducopter()


@pytest.mark.sitl
def test_px4_skips_without_it(px4):
    px4()
'''


def _field_run(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """pytest in a folder of its own (no pyproject.toml, no conftest.py: the plugin comes from the entry
    point), MISSIONPLAN_SIMULATORS unset."""
    env = {k: v for k, v in os.environ.items() if k not in (simulators.ENV, "PYTEST_ADDOPTS", "PYTEST_PLUGINS")}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", *args],
                          cwd=tmp_path, capture_output=True, text=True, timeout=240, env=env)


def test_a_suite_outside_the_repository_gets_the_fixtures_markers_and_option(tmp_path: Path) -> None:
    from missionplan.cli import main

    suite = tmp_path / "field"
    suite.mkdir()
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(suite / "plan"), "--quiet"]) == 0
    (suite / "test_field.py").write_text(FIELD_SUITE)
    empty = tmp_path / "no-simulators"
    empty.mkdir()
    done = _field_run(suite, "--strict-markers", "--simulators", str(empty), "test_field.py")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 passed, 2 skipped" in done.stdout, done.stdout
    assert f"ArduCopter SITL not found at {empty / 'sitl' / 'arducopter'}" in done.stdout, done.stdout
    assert f"PX4 SIH not found at {empty / 'px4' / 'bin' / 'px4'}" in done.stdout, done.stdout


def test_loading_the_plugin_imports_nothing_heavy(tmp_path: Path) -> None:
    code = ("import sys, missionplan.testing.plugin\n"
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r} or m.startswith({HEAVY!r})))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]", done.stdout


def test_the_simulators_are_beside_the_checkout_unless_told(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(simulators.ENV, raising=False)
    assert simulators.checkout() == ROOT
    assert simulators.sitl_dir() == ROOT.parent / "shared" / "sitl"
    assert simulators.px4_dir() == ROOT.parent / "shared" / "px4"
    monkeypatch.setenv(simulators.ENV, str(tmp_path))
    assert simulators.sitl_dir() == tmp_path / "sitl" and simulators.px4_dir() == tmp_path / "px4"


def test_an_absent_simulator_skips_with_where_it_was_looked_for(monkeypatch: pytest.MonkeyPatch,
                                                                tmp_path: Path) -> None:
    monkeypatch.setenv(simulators.ENV, str(tmp_path))
    with pytest.raises(pytest.skip.Exception) as sitl:
        sitl_or_skip()
    with pytest.raises(pytest.skip.Exception) as px4:
        px4_or_skip()
    assert str(sitl.value).startswith(f"ArduCopter SITL not found at {tmp_path / 'sitl' / 'arducopter'}")
    assert str(px4.value).startswith(f"PX4 SIH not found at {tmp_path / 'px4' / 'bin' / 'px4'}")
    assert "--simulators DIR or MISSIONPLAN_SIMULATORS=DIR" in str(sitl.value)
    monkeypatch.delenv(simulators.ENV)
    monkeypatch.setattr(simulators, "checkout", lambda: None)  # an installed missionplan: nowhere to look
    with pytest.raises(pytest.skip.Exception) as installed:
        sitl_or_skip()
    assert str(installed.value).startswith("ArduCopter SITL: no simulators folder known (--simulators DIR")
