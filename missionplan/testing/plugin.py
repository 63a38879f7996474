"""missionplan's pytest plugin: installing missionplan gives a test suite these fixtures, markers and option
(registered under the `pytest11` entry point in pyproject.toml, so pytest loads it by itself; `-p
no:missionplan` leaves it out).

Fixtures (each a factory; whatever it started is stopped at teardown, even when the test fails):
- `arducopter(sysid=, home=, speedup=, serial0=, wait=)`: a real ArduCopter SITL vehicle (arducopter.py);
- `px4(instance=, home=, params=, sysid=, gcs_port=)`: a real PX4 SIH vehicle (px4_sih.py);
- `arducopter_fleet(plan_dir, sysids=None, speedup=5)`: one SITL vehicle per drone of a plan folder behind
  a loopback relay (sitl_fleet.py; `configure(fleet)` sets the cameras up before flying);
- `fly_runs(plan_dir, url, *args)`: `missionplan fly` as a child process, its output kept line by line
  (sitl_fleet.FlyRun);
- `mock_fleet(plan_dir, speedup, **options)`: in-process mock autopilots, one per drone of a plan folder at
  its launch point (missionplan.flight.mock_fleet); fly against `.client_url`.
The SITL and PX4 fixtures skip the test, saying why, when the simulator is not there.

Markers: `sitl` (starts a real autopilot) and `flight` (flies mock autopilots): `-m "not sitl and not
flight"` is the quick subset. Option: `--simulators DIR`, the folder holding sitl/ and px4/
(simulators.py; the environment variable MISSIONPLAN_SIMULATORS says the same).

Loading it is cheap, as pytest loads it in every run of an environment where missionplan is installed:
nothing but pytest and the standard library at import; each fixture imports what it starts.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from missionplan.testing import simulators

MARKERS = {
    "sitl": "starts a real autopilot (ArduCopter SITL or PX4 SIH); `pytest -m \"not sitl\"` leaves those out",
    "flight": "flies mock autopilots (a mock fleet flown by fly / demo / a survey, a MockAutopilot flying a "
              "mission); `pytest -m \"not sitl and not flight\"` is the quick subset",
}
_PREVIOUS = pytest.StashKey[str | None]()  # MISSIONPLAN_SIMULATORS before --simulators set it, put back at the end


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.getgroup("missionplan").addoption(
        simulators.OPTION, metavar="DIR", default=None,
        help=f"the folder holding ArduCopter SITL (sitl/) and PX4 SIH (px4/) for the real-autopilot tests "
             f"(default: ${simulators.ENV}, else ../shared beside a missionplan checkout)")


def pytest_configure(config: pytest.Config) -> None:
    registered = {line.split(":")[0].split("(")[0].strip() for line in config.getini("markers")}
    for name, meaning in MARKERS.items():
        if name not in registered:
            config.addinivalue_line("markers", f"{name}: {meaning}")
    given = config.getoption("simulators")
    if given:  # the environment, so that benches and child processes the tests start see it too
        config.stash[_PREVIOUS] = os.environ.get(simulators.ENV)
        os.environ[simulators.ENV] = str(Path(given).expanduser().resolve())


def pytest_unconfigure(config: pytest.Config) -> None:
    if _PREVIOUS in config.stash:
        previous = config.stash[_PREVIOUS]
        if previous is None:
            os.environ.pop(simulators.ENV, None)
        else:
            os.environ[simulators.ENV] = previous


def _vehicles(make: Callable[..., Any], start_options: tuple[str, ...] = ()) -> Iterator[Callable[..., Any]]:
    """A fixture's factory of simulated vehicles: each call makes one (`make(**options)`, the options named
    in start_options going to its start() instead) and starts it; every vehicle made is stopped after the
    test, even when it fails."""
    made: list[Any] = []

    def start(**options: Any) -> Any:
        at_start = {name: options.pop(name) for name in start_options if name in options}
        vehicle = make(**options)
        made.append(vehicle)
        return vehicle.start(**at_start)

    try:
        yield start
    finally:
        for vehicle in made:
            vehicle.stop()


@pytest.fixture()
def arducopter() -> Iterator[Callable[..., Any]]:
    """A factory: arducopter(sysid=..., home=..., serial0=..., wait=...) starts an instance (ready for
    missions unless wait=False), stopped at teardown, even when the test fails."""
    from missionplan.testing.arducopter import ArduCopter, sitl_or_skip

    sitl_or_skip()
    yield from _vehicles(ArduCopter, start_options=("wait",))


@pytest.fixture()
def px4() -> Iterator[Callable[..., Any]]:
    """A factory: px4(instance=..., home=..., params=...) starts a vehicle (its start-up script done),
    stopped and its folder removed at teardown, even when the test fails."""
    from missionplan.testing.px4_sih import PX4, px4_or_skip

    px4_or_skip()
    yield from _vehicles(PX4)


@pytest.fixture()
def arducopter_fleet() -> Iterator[Callable[..., Any]]:
    """A factory: arducopter_fleet(plan_dir, sysids=None, speedup=5) starts one SITL vehicle per drone of
    plan_dir behind a relay (sitl_fleet.Fleet; not configured yet), stopped at teardown."""
    from missionplan.testing.arducopter import sitl_or_skip
    from missionplan.testing.sitl_fleet import SPEEDUP, Fleet, sitl_fleet

    def start(plan_dir: Path, sysids: tuple[int, ...] | None = None, speedup: float = SPEEDUP) -> Fleet:
        return fleets.enter_context(sitl_fleet(plan_dir, sysids, speedup))

    sitl_or_skip()
    with contextlib.ExitStack() as fleets:
        yield start


@pytest.fixture()
def fly_runs() -> Iterator[Callable[..., Any]]:
    """A factory: fly_runs(plan_dir, url, *args, time_scale=5, timeout_s=300) starts `missionplan fly` as a
    child process (sitl_fleet.FlyRun); any still running at teardown is killed."""
    from missionplan.testing.sitl_fleet import FlyRun

    started: list[FlyRun] = []

    def start(plan_dir: Path, url: str, *extra: str, **options: Any) -> FlyRun:
        started.append(FlyRun(plan_dir, url, *extra, **options))
        return started[-1]

    try:
        yield start
    finally:
        for run in started:
            run.kill()


@pytest.fixture()
def mock_fleet() -> Iterator[Callable[..., Any]]:
    """A factory: mock_fleet(plan_dir, speedup, **options) starts in-process mock autopilots, one per drone of
    plan_dir at its launch point (missionplan.flight.mock_fleet.start_mock_fleet: SITL-like, cameras
    configured, unless options say otherwise); stopped at teardown."""
    from missionplan.flight.mock_fleet import start_mock_fleet

    started: list[Any] = []

    def start(plan_dir: Path, speedup: float, **options: Any) -> Any:
        started.append(start_mock_fleet(plan_dir, speedup, **options))
        return started[-1]

    try:
        yield start
    finally:
        for mock in started:
            mock.stop()
