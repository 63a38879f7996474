"""The test suite's own rules, checked on its source (ast), so a new test cannot quietly break them:

- no test synchronises by sleeping: it waits for the event with a bound (a message on the link, a
  thread's join, a port bound). The one sleep allowed is between the polls of `wait_until`
  (missionplan/testing/loopback.py), for events that come with nothing to block on (a simulator's log line);
- a test that starts a real autopilot is marked `sitl`, and a test that flies mock autopilots is marked
  `flight`, so that `pytest -m "not sitl and not flight"` is a quick subset without them, while `make
  test` runs all. What a test reaches is read from its body, the fixtures it asks for and the functions
  of its module (and of its folder's conftest.py) it calls, followed through: it starts a real autopilot
  when it reaches the plugin's `arducopter`, `px4` or `arducopter_fleet` fixture or starts a vehicle
  itself (missionplan.testing's ArduCopter, PX4 or sitl_fleet); it flies mock autopilots
  when it reaches a mock fleet (missionplan.flight.mock_fleet.start_mock_fleet, the plugin's `mock_fleet`,
  tests/lost_drone.py, `missionplan demo`, `missionplan verify`), or a MockAutopilot together with something that flies it (`fly`,
  the re-task harness, the wind flight of missionplan/testing/wind_flight.py, or arming and MISSION_START). The
  marker is the module's `pytestmark` or the test's own decorator.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SUITES = (ROOT / "tests", ROOT / "sitl_tests")
SUPPORT = ROOT / "missionplan" / "testing"  # the test support: its waits are held to the same rule
ALLOWED_SLEEPS = {("loopback.py", "wait_until")}  # (file, enclosing function)
# What a test reaches, as _names() spells it: NAME (a name it uses), attr:NAME (an attribute), arg:NAME (a
# fixture it asks for), cli:COMMAND (a command line it builds).
# The fixtures of missionplan/testing/plugin.py that start real autopilots, and what starts one directly.
REAL_AUTOPILOTS = {"arg:arducopter", "arg:px4", "arg:arducopter_fleet", "ArduCopter", "PX4", "sitl_fleet"}
# Reached, these fly mock autopilots whatever else the test does (names or attributes alike).
MOCK_FLEET_FLIGHTS = {"start_mock_fleet", "arg:mock_fleet", "fly_with_a_lost_drone", "cli:demo", "cli:verify",
                      "verify_plan"}
# Reached together with a MockAutopilot, these fly it.
MOCK_FLYERS = {"fly", "cli:fly", "retask_and_follow", "start_flying", "fly_wind_mission"}
MISSION_START, ARMING = "MAV_CMD_MISSION_START", {"MAV_CMD_COMPONENT_ARM_DISARM", "arm"}


def _modules() -> list[Path]:
    return sorted(p for suite in SUITES for p in suite.glob("*.py"))


def _waiting_modules() -> list[Path]:
    """Every module whose waits the sleep rule holds: the suites and the test support."""
    return _modules() + sorted(SUPPORT.glob("*.py"))


def _sleeps(tree: ast.Module) -> list[tuple[str, int]]:
    """(enclosing function, line) of every call of time.sleep / sleep in a module."""
    found: list[tuple[str, int]] = []

    def visit(node: ast.AST, function: str) -> None:
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Call):
                func = child.func
                called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
                if called == "sleep":
                    found.append((function, child.lineno))
            visit(child, name)

    visit(tree, "<module>")
    return found


def test_no_test_waits_by_sleeping() -> None:
    offenders = [f"{path.relative_to(ROOT)}:{line} in {function}()"
                 for path in _waiting_modules() for function, line in _sleeps(ast.parse(path.read_text()))
                 if (path.name, function) not in ALLOWED_SLEEPS]
    assert offenders == [], "wait for the event with a bound instead (missionplan.testing.loopback.wait_until " \
                            "for a poll): " + \
        ", ".join(offenders)


def test_the_rule_finds_a_sleep() -> None:
    tree = ast.parse("import time\n\ndef test_x():\n    time.sleep(0.3)\n")
    assert _sleeps(tree) == [("test_x", 4)]


def _walk_own(node: ast.AST) -> list[ast.AST]:
    """The nodes of a function's arguments and body, or a class's body (decorators left out: a
    parametrize list is data, not something the test does)."""
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        parts: list[ast.AST] = [node.args, *node.body]
    elif isinstance(node, ast.ClassDef):
        parts = list(node.body)
    else:
        parts = [node]
    return [n for part in parts for n in ast.walk(part)]


def _names(node: ast.AST) -> set[str]:
    """What a function (or class) names: `arg:NAME` for its arguments (the fixtures it asks for), every name
    and `attr:NAME` for every attribute it uses, and `cli:COMMAND` for a command line it builds (a list of
    strings starting with `fly` or `demo`, or with `missionplan fly` / `missionplan demo` in it)."""
    found: set[str] = set()
    for n in _walk_own(node):
        if isinstance(n, ast.arg):
            found.add(f"arg:{n.arg}")
        elif isinstance(n, ast.Name):
            found.add(n.id)
        elif isinstance(n, ast.Attribute):
            found.add(f"attr:{n.attr}")
        elif isinstance(n, (ast.List, ast.Tuple)):
            words = [e.value if isinstance(e, ast.Constant) and isinstance(e.value, str) else None for e in n.elts]
            for k, word in enumerate(words):
                if word in ("fly", "demo") and (k == 0 or words[k - 1] == "missionplan"):
                    found.add(f"cli:{word}")
    return found


def _definitions(tree: ast.Module) -> dict[str, ast.AST]:
    return {node.name: node for node in tree.body
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}


def _tests(tree: ast.Module) -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef, list[ast.expr]]]:
    """(name, function, the decorators that apply to it: its own and its class's) of every test."""
    found = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith("test_"):
            found.append((node.name, node, list(node.decorator_list)))
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            found += [(f"{node.name}.{sub.name}", sub, [*node.decorator_list, *sub.decorator_list])
                      for sub in node.body
                      if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)) and sub.name.startswith("test_")]
    return found


def _reach(test: ast.AST, definitions: dict[str, ast.AST]) -> set[str]:
    """Every name the test uses, following the module's (and conftest's) functions, classes and fixtures
    it names or asks for, and those they name, to the end."""
    names: set[str] = set()
    followed: set[str] = set()
    todo = [test]
    while todo:
        own = _names(todo.pop())
        names |= own
        for name in sorted({n.removeprefix("arg:") for n in own} & definitions.keys() - followed):
            followed.add(name)
            todo.append(definitions[name])
    return names


def starts_a_real_autopilot(names: set[str]) -> bool:
    return bool(names & REAL_AUTOPILOTS)  # names, not attributes: Flavour.PX4 is no vehicle


def flies_mock_autopilots(names: set[str]) -> bool:
    used = {n.removeprefix("attr:") for n in names}  # mavlink.MAV_CMD_MISSION_START, vehicle.arm(), fly_module.fly
    if used & MOCK_FLEET_FLIGHTS:
        return True
    return "MockAutopilot" in used and bool(used & MOCK_FLYERS or (MISSION_START in used and used & ARMING))


def _module_marks(tree: ast.Module) -> str:
    return " ".join(ast.unparse(node.value) for node in tree.body if isinstance(node, ast.Assign)
                    and any(getattr(t, "id", "") == "pytestmark" for t in node.targets))


def unmarked(source: str, conftest: str = "") -> dict[str, list[str]]:
    """marker -> the tests of a module (`source`; `conftest`: its folder's conftest.py) that need it and lack it."""
    tree = ast.parse(source)
    definitions = {**_definitions(ast.parse(conftest)), **_definitions(tree)}
    module_marks = _module_marks(tree)
    missing: dict[str, list[str]] = {"sitl": [], "flight": []}
    for name, test, decorators in _tests(tree):
        names = _reach(test, definitions)
        marks = module_marks + " " + " ".join(ast.unparse(d) for d in decorators)
        needs = {"sitl": starts_a_real_autopilot(names), "flight": flies_mock_autopilots(names)}
        for marker, needed in needs.items():
            if needed and f"mark.{marker}" not in marks:
                missing[marker].append(name)
    return missing


def _suite_modules() -> list[tuple[Path, str, str]]:
    """(path, source, its folder's conftest.py source) of every test module."""
    return [(p, p.read_text(), (p.parent / "conftest.py").read_text() if (p.parent / "conftest.py").exists() else "")
            for p in _modules() if p.name.startswith("test_")]


def _needing(marker: str) -> list[str]:
    """The test modules with at least one test that needs `marker`, marked or not."""
    return [p.name for p, source, conftest in _suite_modules()
            if unmarked(source.replace(f"mark.{marker}", "mark.unmarked"), conftest)[marker]]


def test_tests_that_start_a_real_autopilot_are_marked_sitl() -> None:
    assert len(_needing("sitl")) >= 15  # ArduCopter SITL and PX4 SIH: fleets, missions, fences, the mock compared
    found = {p.name: missing for p, source, conftest in _suite_modules()
             if (missing := unmarked(source, conftest)["sitl"])}
    assert found == {}, f"add `pytestmark = pytest.mark.sitl` to {sorted(found)}: {found}"


def test_tests_that_fly_mock_autopilots_are_marked_flight() -> None:
    assert len(_needing("flight")) >= 15  # fly, demo, surveys, faults and re-tasking against the mock
    found = {p.name: missing for p, source, conftest in _suite_modules()
             if (missing := unmarked(source, conftest)["flight"])}
    assert found == {}, f"mark them `@pytest.mark.flight` (or the module's pytestmark): {found}"


def test_the_rules_find_an_unmarked_flight_and_an_unmarked_autopilot() -> None:
    fleet = ("from missionplan.flight.mock_fleet import start_mock_fleet\n\n"
             "def _fly(plan):\n    mock = start_mock_fleet(plan, 10.0)\n    return fly(plan, mock.client_url)\n\n"
             "def test_a(tmp_path):\n    _fly(tmp_path)\n\n"
             "@pytest.mark.flight\ndef test_b(tmp_path):\n    _fly(tmp_path)\n\n"
             "def test_c(tmp_path):\n    assert tmp_path\n")
    assert unmarked(fleet) == {"sitl": [], "flight": ["test_a"]}
    assert unmarked("pytestmark = pytest.mark.flight\n" + fleet)["flight"] == []
    started = ("def _start_and_arm(link):\n    command(link, mavlink.MAV_CMD_COMPONENT_ARM_DISARM)\n"
               "    command(link, mavlink.MAV_CMD_MISSION_START)\n\n"
               "def test_flies():\n    with MockAutopilot() as mock:\n        _start_and_arm(mock.link)\n\n"
               "def test_refused():\n    with MockAutopilot() as mock:\n        command(mock.link, mavlink.MAV_CMD_MISSION_START)\n")
    assert unmarked(started)["flight"] == ["test_flies"]
    assert unmarked("def test_v():\n    with ArduCopter(sysid=1) as v:\n        assert v\n\n"
                    "def test_flavour():\n    assert Flavour.PX4\n")["sitl"] == ["test_v"]
    through_a_fixture = ("@pytest.fixture\ndef fleet(arducopter_fleet, tmp_path):\n    return arducopter_fleet(tmp_path)\n")
    assert unmarked("def test_x(fleet):\n    pass\n", through_a_fixture) == {"sitl": ["test_x"], "flight": []}
    assert unmarked("@pytest.mark.parametrize('argv', [['demo', '--uav', '2']])\ndef test_usage(argv):\n"
                    "    assert main(argv) == 2\n") == {"sitl": [], "flight": []}  # a parametrize list is data
    assert unmarked("def test_demo(tmp_path):\n    main(['demo', '--out', str(tmp_path)])\n")["flight"] == ["test_demo"]
