"""The test suite's own rules, checked on its source (ast), so a new test cannot quietly break them:

- no test synchronises by sleeping: it waits for the event with a bound (a message on the link, a
  thread's join, a port bound). The one sleep allowed is between the polls of `wait_until`
  (sitl_tests/loopback.py), for events that come with nothing to block on (a simulator's log line);
- a module that starts a real autopilot (it imports sitl_tests/arducopter.py or px4_sih.py) is marked
  `sitl`, so that `pytest -m "not sitl"` is a quick subset without them, while `make test` runs all.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SUITES = (ROOT / "tests", ROOT / "sitl_tests")
ALLOWED_SLEEPS = {("loopback.py", "wait_until")}  # (file, enclosing function)
REAL_AUTOPILOT_HELPERS = {"arducopter", "px4_sih"}


def _modules() -> list[Path]:
    return sorted(p for suite in SUITES for p in suite.glob("*.py"))


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
                 for path in _modules() for function, line in _sleeps(ast.parse(path.read_text()))
                 if (path.name, function) not in ALLOWED_SLEEPS]
    assert offenders == [], "wait for the event with a bound instead (loopback.wait_until for a poll): " + \
        ", ".join(offenders)


def test_the_rule_finds_a_sleep() -> None:
    tree = ast.parse("import time\n\ndef test_x():\n    time.sleep(0.3)\n")
    assert _sleeps(tree) == [("test_x", 4)]


def _imports(tree: ast.Module) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def _marked_sitl(tree: ast.Module) -> bool:
    for node in tree.body:
        if (isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "pytestmark" for t in node.targets)
                and "sitl" in ast.unparse(node.value)):
            return True
    return False


def test_modules_that_start_a_real_autopilot_are_marked_sitl() -> None:
    tests = [p for p in _modules() if p.name.startswith("test_")]
    starting = [p for p in tests if _imports(ast.parse(p.read_text())) & REAL_AUTOPILOT_HELPERS]
    assert len(starting) >= 9  # ArduCopter SITL and PX4 SIH: fleets, missions, fences, the mock compared
    unmarked = [p.name for p in starting if not _marked_sitl(ast.parse(p.read_text()))]
    assert unmarked == [], f"add `pytestmark = pytest.mark.sitl` to {unmarked}"
