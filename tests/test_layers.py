"""Imports run one way: cli -> flight -> mission -> learn -> grid -> maps; geo and bridge stand alone;
and no module imports itself round a circle (a -> b -> a), inside a layer or across the top.

Every module is parsed with `ast` (imports inside functions included). A module's layer is the
subpackage it sits in (missionplan/grid/world.py: grid); the modules at the top of the package (the
CLI and the entry points plan_map / plan_field) may import anything, nothing below may import them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Lowest first: a module may import its own layer and the layers before it.
LAYERS = ("maps", "grid", "learn", "mission", "flight")
TOP = len(LAYERS)  # the modules directly in missionplan/


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(source: str, name: str, is_package: bool = False) -> list[str]:
    """Absolute names of every module `source` (the module `name`) imports, at any depth."""
    package = name if is_package else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            # `from pkg import mod` imports the module pkg.mod: count both names
            found += [module] + [f"{module}.{alias.name}" for alias in node.names]
    return found


def layer(module: str) -> int | None:
    """Rank of a missionplan module (TOP for the top-level ones), None outside missionplan."""
    parts = module.split(".")
    if parts[0] != "missionplan":
        return None
    if len(parts) > 2 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])
    if len(parts) == 2 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])  # the subpackage itself
    return TOP


def wrong_way(source: str, name: str, is_package: bool = False) -> list[str]:
    """The imports of module `name` that point to a higher layer than its own."""
    own = layer(name)
    assert own is not None
    if own == TOP:
        return []
    return sorted({m for m in imported_modules(source, name, is_package)
                   if (rank := layer(m)) is not None and rank > own and m != "missionplan"})


def sources(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("path", sources("missionplan"), ids=lambda p: str(p.relative_to(ROOT)))
def test_missionplan_imports_run_one_way(path: Path) -> None:
    name = module_name(path)
    assert wrong_way(path.read_text(encoding="utf-8"), name, path.name == "__init__.py") == []


@pytest.mark.parametrize("path", sources("geo") + sources("bridge"), ids=lambda p: str(p.relative_to(ROOT)))
def test_geo_and_bridge_import_nothing_from_missionplan(path: Path) -> None:
    name = module_name(path)
    imports = imported_modules(path.read_text(encoding="utf-8"), name, path.name == "__init__.py")
    assert [m for m in imports if m.split(".")[0] == "missionplan"] == []


def test_a_wrong_way_import_is_found() -> None:
    # The checker itself: a lazy import up the layers, relative or absolute, is reported; down is fine.
    lazy = "def f():\n    from ..learn.net import Net\n    return Net\n"
    assert wrong_way(lazy, "missionplan.grid.pipe") == ["missionplan.learn.net", "missionplan.learn.net.Net"]
    assert wrong_way("from missionplan.flight import flyer\n", "missionplan.maps.x") == [
        "missionplan.flight", "missionplan.flight.flyer"]
    assert wrong_way("from ..cli import main\n", "missionplan.mission.x") == ["missionplan.cli", "missionplan.cli.main"]
    assert wrong_way("from ..maps.m import M\nfrom .w import W\nimport numpy\n", "missionplan.grid.x") == []
    assert wrong_way("from .grid.w import W\nfrom .flight import f\n", "missionplan.cli") == []
    assert imported_modules("from . import z\n", "missionplan.grid", is_package=True) == [
        "missionplan.grid", "missionplan.grid.z"]


def import_graph(paths: list[Path], root: Path = ROOT) -> dict[str, set[str]]:
    """module -> the modules of `paths` it imports (at any depth in the file; a package counts as its __init__)."""
    names = {module_name(p, root): p for p in paths}
    graph = {}
    for name, path in names.items():
        imports = imported_modules(path.read_text(encoding="utf-8"), name, path.name == "__init__.py")
        graph[name] = {m for m in imports if m in names and m != name}
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every group of modules that import each other round a circle (strongly connected, 2 or more), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles = []

    def visit(module: str) -> None:  # Tarjan's algorithm; the graphs are a few hundred modules deep at most
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in sorted(graph[module]):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == module:
                    break
            if len(group) > 1:
                circles.append(sorted(group))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return sorted(circles)


def test_no_import_circles() -> None:
    # A package importing its own modules is fine; a module importing its package's __init__ that imports it back
    # is a circle like any other.
    graph = import_graph(sources("missionplan") + sources("geo") + sources("bridge"))
    assert import_circles(graph) == []


def test_an_import_circle_is_found() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"d"}}
    assert import_circles(graph) == [["a", "b", "c"]]
    assert import_circles({"x": {"y"}, "y": set()}) == []
