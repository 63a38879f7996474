"""Imports run one way: cli -> verify -> planning -> flight -> mission -> learn -> grid -> maps -> geo -> bridge -> base, inside
bridge/ from the transfers down to the flight models, inside missionplan/flight/ from fly down to the records; geo,
maps, grid and learn import nothing from bridge (base has what they share with it); no module imports itself round a
circle (a -> b -> a), inside a layer or across the top; and argparse stays in the command line: no module below
missionplan/cli/ imports it or handles a Namespace. The test support, missionplan/testing/ (fixtures and the pytest
plugin), sits above them all: it may import the product, and nothing of the product imports it.

Every module is parsed with `ast` (imports inside functions included). A module's layer is the
subpackage it sits in (missionplan/grid/world.py: grid; geo/ and bridge/ install as missionplan.geo and
missionplan.bridge); missionplan/planning/ (plan_map, plan_field, the plan folder, replan, retask) may import
every layer below it; missionplan/verify/ (a plan flown many times on simulated fleets) sits above it, and only the
command line (missionplan/cli/, and __main__) imports those two; nothing imports the command line.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Lowest first: a module may import its own layer and the layers before it.
LAYERS = ("base", "bridge", "geo", "maps", "grid", "learn", "mission", "flight", "planning", "verify")
TOP = len(LAYERS)  # the modules directly in missionplan/
CLI = TOP + 1  # the command line: missionplan/cli/ and `python -m missionplan` (__main__)
SUPPORT = CLI + 1  # the test support, missionplan/testing/: drives the product as a user does, through the CLI too
# The source folders outside missionplan/ and the package each installs as (pyproject.toml's package-dir).
INSTALLED_AS = {"geo": "missionplan.geo", "bridge": "missionplan.bridge"}


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[0] in INSTALLED_AS:
        parts[:1] = INSTALLED_AS[parts[0]].split(".")
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.lru_cache(maxsize=None)
def code_nodes(source: str) -> tuple[ast.AST, ...]:
    """Every node of `source`, parsed once for all the rules below (a module's source is asked for by each).
    An annotation written as a string ("argparse.Namespace") is code too: it is parsed where it stands."""
    tree = ast.parse(source)
    annotations = [n.annotation for n in ast.walk(tree) if isinstance(n, (ast.arg, ast.AnnAssign))] + [
        n.returns for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
    quoted = [ast.fix_missing_locations(ast.copy_location(ast.parse(a.value, mode="eval").body, a))
              for a in annotations if isinstance(a, ast.Constant) and isinstance(a.value, str)]
    return tuple(node for root in [tree, *quoted] for node in ast.walk(root))


def imported_modules(source: str, name: str, is_package: bool = False) -> list[str]:
    """Absolute names of every module `source` (the module `name`) imports, at any depth."""
    package = name if is_package else name.rpartition(".")[0]
    found = []
    for node in code_nodes(source):
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
    """Rank of a missionplan module (TOP for the top-level ones, CLI for the command line, SUPPORT for the test
    support), None outside missionplan."""
    parts = module.split(".")
    if parts[0] != "missionplan":
        return None
    if len(parts) > 1 and parts[1] == "testing":
        return SUPPORT
    if len(parts) > 1 and parts[1] in ("cli", "__main__"):
        return CLI
    if len(parts) > 2 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])
    if len(parts) == 2 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])  # the subpackage itself
    return TOP


def wrong_way(source: str, name: str, is_package: bool = False) -> list[str]:
    """The imports of module `name` that point to a higher layer than its own."""
    own = layer(name)
    assert own is not None
    if own == SUPPORT:
        return []
    return sorted({m for m in imported_modules(source, name, is_package)
                   if (rank := layer(m)) is not None and rank > own and m != "missionplan"})


def sources(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


ALL_SOURCES = sources("missionplan") + sources("geo") + sources("bridge")


@pytest.mark.parametrize("path", ALL_SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_run_one_way(path: Path) -> None:
    name = module_name(path)
    assert wrong_way(path.read_text(encoding="utf-8"), name, path.name == "__init__.py") == []


def test_nothing_imports_geo_or_bridge_by_a_top_level_name() -> None:
    # `import bridge` works from the repository root by accident (the folder is there); installed, it does not exist.
    for path in ALL_SOURCES:
        imports = imported_modules(path.read_text(encoding="utf-8"), module_name(path), path.name == "__init__.py")
        assert [m for m in imports if m.split(".")[0] in INSTALLED_AS] == [], path


TESTING = "missionplan.testing"


def imports_test_support(source: str, name: str, is_package: bool = False) -> list[str]:
    """The imports of module `name` that reach the test support (missionplan.testing and its modules)."""
    return sorted({m for m in imported_modules(source, name, is_package)
                   if m == TESTING or m.startswith(TESTING + ".")})


def test_nothing_of_the_product_imports_the_test_support() -> None:
    product = [p for p in ALL_SOURCES if module_name(p).split(".")[:2] != TESTING.split(".")]
    assert len(product) > 100 and len(product) < len(ALL_SOURCES)  # missionplan/testing/ is left out, only it
    offenders = {str(p.relative_to(ROOT)): found for p in product
                 if (found := imports_test_support(p.read_text(encoding="utf-8"), module_name(p),
                                                   p.name == "__init__.py"))}
    assert offenders == {}


def test_an_import_of_the_test_support_is_found() -> None:
    assert imports_test_support("def f():\n    from missionplan.testing.loopback import wait_until\n",
                                "missionplan.cli") == ["missionplan.testing.loopback",
                                                       "missionplan.testing.loopback.wait_until"]
    assert imports_test_support("from ..testing import plans\n", "missionplan.flight.fly") == [
        "missionplan.testing", "missionplan.testing.plans"]
    assert imports_test_support("from missionplan import testing\n", "missionplan.demo") == ["missionplan.testing"]
    assert imports_test_support("from ..flight.fly import fly\nimport missionplan.testingx\n",
                                "missionplan.testing.sitl_fleet") == []


def test_a_wrong_way_import_is_found() -> None:
    # The checker itself: a lazy import up the layers, relative or absolute, is reported; down is fine.
    lazy = "def f():\n    from ..learn.net import Net\n    return Net\n"
    assert wrong_way(lazy, "missionplan.grid.pipe") == ["missionplan.learn.net", "missionplan.learn.net.Net"]
    assert wrong_way("from missionplan.flight import flyer\n", "missionplan.maps.x") == [
        "missionplan.flight", "missionplan.flight.flyer"]
    assert wrong_way("from ..cli import main\n", "missionplan.mission.x") == ["missionplan.cli", "missionplan.cli.main"]
    assert wrong_way("from ..maps.m import M\nfrom .w import W\nimport numpy\n", "missionplan.grid.x") == []
    assert wrong_way("from ..grid import w\n", "missionplan.geo.x") == ["missionplan.grid", "missionplan.grid.w"]
    assert wrong_way("from missionplan.base.atomic import a\n", "missionplan.geo.x") == []
    assert wrong_way("from missionplan.bridge import errors\n", "missionplan.base.x") == [
        "missionplan.bridge", "missionplan.bridge.errors"]
    assert wrong_way("from .grid.w import W\nfrom .flight import f\n", "missionplan.cli") == []
    assert wrong_way("from ..plan_folder import p\nfrom ..bridge import e\n", "missionplan.cli.plan") == []
    # Planning sits below the command line: it may not import it.
    assert wrong_way("from ..cli.errors import said\n", "missionplan.planning.replan") == [
        "missionplan.cli.errors", "missionplan.cli.errors.said"]
    assert wrong_way("from ..flight.fly import fly\n", "missionplan.planning.replan") == []
    # base is below every layer, bridge included.
    assert wrong_way("from missionplan.base.naming import Named\n", "missionplan.bridge.limits") == []
    assert wrong_way("from missionplan.bridge import BridgeError\n", "missionplan.base.naming") == [
        "missionplan.bridge", "missionplan.bridge.BridgeError"]
    assert imported_modules("from . import z\n", "missionplan.grid", is_package=True) == [
        "missionplan.grid", "missionplan.grid.z"]


# The layers between bridge and mission know grids and places, not autopilots: they import nothing from bridge,
# though it lies below them (what they share with it, atomic writes, is in base).
WITHOUT_BRIDGE = ("geo", "maps", "grid", "learn")


def bridge_imports(source: str, name: str, is_package: bool = False) -> list[str]:
    """The imports of missionplan.bridge (or anything in it) by module `name`."""
    return sorted({m for m in imported_modules(source, name, is_package)
                   if m == "missionplan.bridge" or m.startswith("missionplan.bridge.")})


@pytest.mark.parametrize("path", [p for p in ALL_SOURCES if layer(module_name(p)) in
                                  {LAYERS.index(name) for name in WITHOUT_BRIDGE}],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_geo_maps_grid_and_learn_import_nothing_from_bridge(path: Path) -> None:
    assert bridge_imports(path.read_text(encoding="utf-8"), module_name(path), path.name == "__init__.py") == []


def test_an_import_of_bridge_is_found() -> None:
    assert bridge_imports("from missionplan.bridge.atomic import atomic_path\n", "missionplan.geo.kml") == [
        "missionplan.bridge.atomic", "missionplan.bridge.atomic.atomic_path"]
    assert bridge_imports("def f():\n    from ..bridge import BridgeError\n", "missionplan.learn.x") == [
        "missionplan.bridge", "missionplan.bridge.BridgeError"]
    assert bridge_imports("from missionplan.base.atomic import atomic_path\nfrom ..maps import gridmap\n",
                          "missionplan.learn.x") == []


def argparse_uses(source: str) -> list[str]:
    """Where a module uses argparse: an import of it, or the name Namespace (argparse.Namespace, or imported
    bare), each as "line N: what"."""
    found = []
    for node in code_nodes(source):
        if isinstance(node, ast.Import):
            found += [f"line {node.lineno}: import {a.name}" for a in node.names if a.name.split(".")[0] == "argparse"]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "argparse":
            found.append(f"line {node.lineno}: from {node.module} import ...")
        elif isinstance(node, ast.Attribute) and node.attr == "Namespace":
            found.append(f"line {node.lineno}: .Namespace")
        elif isinstance(node, ast.Name) and node.id == "Namespace":
            found.append(f"line {node.lineno}: Namespace")
    return found


def below_the_command_line(path: Path) -> bool:
    return layer(module_name(path)) != CLI


@pytest.mark.parametrize("path", [p for p in ALL_SOURCES if below_the_command_line(p)],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_no_argparse_below_the_command_line(path: Path) -> None:
    # The command line parses into typed requests; the library takes those or plain parameters.
    assert argparse_uses(path.read_text(encoding="utf-8")) == []


def test_an_argparse_use_is_found() -> None:
    assert argparse_uses("import argparse\n") == ["line 1: import argparse"]
    assert argparse_uses("from argparse import Namespace\n\ndef f(args: Namespace) -> None:\n    pass\n") == [
        "line 1: from argparse import ...", "line 3: Namespace"]
    assert argparse_uses("def f(args: 'x') -> None:\n    pass\ndef g(args: argparse.Namespace) -> None:\n"
                         "    pass\n") == ["line 3: .Namespace"]
    assert argparse_uses("def g(args: 'argparse.Namespace') -> 'Namespace':\n    pass\n") == [
        "line 1: .Namespace", "line 1: Namespace"]
    assert argparse_uses("from types import SimpleNamespace\nx = SimpleNamespace(a=1)\n") == []
    assert below_the_command_line(ROOT / "missionplan" / "planning" / "replan.py")
    assert not below_the_command_line(ROOT / "missionplan" / "cli" / "plan.py")
    assert not below_the_command_line(ROOT / "missionplan" / "__main__.py")


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
    graph = import_graph(ALL_SOURCES)
    assert import_circles(graph) == []


def test_an_import_circle_is_found() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"d"}}
    assert import_circles(graph) == [["a", "b", "c"]]
    assert import_circles({"x": {"y"}, "y": set()}) == []


# Inside bridge/: the part a module belongs to (its subpackage, or its own name directly in bridge/) and the parts
# it may import besides its own; each subpackage's __init__ says the same in words. The package itself
# (missionplan.bridge: the two errors) may be imported from anywhere.
BRIDGE_MAY_IMPORT = {
    "errors": set(),
    "terminal_text": set(),
    "limits": {"errors"},
    "folder_lock": {"errors", "terminal_text"},
    "flight_models": set(),
    "formats": {"errors", "limits"},
    "link": {"errors", "formats"},
    "transfer": {"errors", "formats", "link"},
    "sim": {"errors", "formats", "link", "flight_models", "terminal_text"},
    "session": {"errors", "formats", "link", "transfer", "flight_models"},
}


def bridge_part(module: str) -> str | None:
    """The part of bridge/ a module is in ("link" for missionplan.bridge.link.params), None outside bridge/."""
    parts = module.split(".")
    if parts[:2] != ["missionplan", "bridge"] or len(parts) == 2:
        return None
    return parts[2]


def bridge_wrong_way(source: str, name: str, is_package: bool = False) -> list[str]:
    own = bridge_part(name)
    assert own in BRIDGE_MAY_IMPORT, f"{name}: a part of bridge/ that BRIDGE_MAY_IMPORT does not place"
    return sorted({m for m in imported_modules(source, name, is_package)
                   if (part := bridge_part(m)) in BRIDGE_MAY_IMPORT  # not a name from the package: BridgeError
                   and part != own and part not in BRIDGE_MAY_IMPORT[own]})


@pytest.mark.parametrize("path", [p for p in sources("bridge") if p != ROOT / "bridge" / "__init__.py"],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_bridge_imports_run_one_way(path: Path) -> None:
    assert bridge_wrong_way(path.read_text(encoding="utf-8"), module_name(path), path.name == "__init__.py") == []


def test_a_wrong_way_import_inside_bridge_is_found() -> None:
    assert bridge_wrong_way("from ..transfer.uploader import upload\n", "missionplan.bridge.sim.mock") == [
        "missionplan.bridge.transfer.uploader", "missionplan.bridge.transfer.uploader.upload"]
    assert bridge_wrong_way("from ..link import connection\nfrom .. import BridgeError\n",
                            "missionplan.bridge.transfer.protocol") == []
    with pytest.raises(AssertionError):
        bridge_wrong_way("", "missionplan.bridge.newpart.x")


# Inside missionplan/flight/: tiers, lowest first; a module imports only modules of lower tiers, and every module
# has a tier (a new one is placed here).
FLIGHT_TIERS = (
    ("record", "plan_report", "flight_layers", "flight_plot", "mock_fleet", "salvage",  # what was planned and recorded
     "journal_db",  # the journal's tables
     "events", "link_silence", "retask_planner",  # a follower's events, what a silence means, a re-task's contract
     "terrain_service",  # the plan's ground served to its ArduPilot vehicles
     "image_match"),  # a camera card's images paired with capture records
    ("journal_read", "journal_repair"),  # a journal read back; a damaged one repaired
    ("ledger", "phases", "journal", "photo_positions",  # the photos, the flight's phases, the journal on disk
     "above_ground"),  # heights above the ground of a flight over a DEM
    ("ledger_repair",),  # a ledger rebuilt from the journals
    ("geotag", "survey_status"),  # what the photos and the survey come to
    ("flight_report", "exif_geotag"),  # judging a flown fleet; a crew's camera cards geotagged
    ("event_journal", "telemetry_record", "fleet_start", "follower_mail"),  # events, messages and posts into records
    ("after_landing", "fleet_view", "retask_actions"),  # after landing; the fleet as events tell it; a re-task's part
    ("drone_flight", "display"),  # one drone's flight; what a crew sees
    ("live_replan", "disk_space"),  # taking over a lost drone's cells in flight; room for a flight's record
    ("fly",),  # the fleet's flight
)


def flight_tier(module: str) -> int | None:
    parts = module.split(".")
    if parts[:2] != ["missionplan", "flight"] or len(parts) < 3:
        return None
    tiers = [i for i, tier in enumerate(FLIGHT_TIERS) if parts[2] in tier]
    assert tiers, f"{module}: not in FLIGHT_TIERS"
    return tiers[0]


def flight_wrong_way(source: str, name: str) -> list[str]:
    own = flight_tier(name)
    return sorted({m for m in imported_modules(source, name)
                   if (tier := flight_tier(m)) is not None and m != name and tier >= own})


@pytest.mark.parametrize("path", [p for p in sources("missionplan/flight") if p.name != "__init__.py"],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_flight_imports_run_one_way(path: Path) -> None:
    assert flight_wrong_way(path.read_text(encoding="utf-8"), module_name(path)) == []


def test_a_wrong_way_import_inside_flight_is_found() -> None:
    assert flight_wrong_way("from .fly import fly\n", "missionplan.flight.record") == [
        "missionplan.flight.fly", "missionplan.flight.fly.fly"]
    assert flight_wrong_way("from .phases import p\n", "missionplan.flight.ledger") == [
        "missionplan.flight.phases", "missionplan.flight.phases.p"]
    assert flight_wrong_way("from .record import DroneRecord\n", "missionplan.flight.fly") == []


# The flight loop asks its vehicles through a VehicleSession (missionplan.bridge.session: action, mission, streams,
# parameters, log), where each MAVLink command is built once; flight/ sends no raw COMMAND_LONG / COMMAND_INT itself.
RAW_COMMAND = re.compile(r"\bcommand_(long|int)(_send)?\b")


def raw_commands(source: str) -> list[int]:
    """The lines of `source` that send (or name a sender of) a raw MAVLink command."""
    return [number for number, line in enumerate(source.splitlines(), 1) if RAW_COMMAND.search(line)]


def test_flight_sends_no_raw_mavlink_command() -> None:
    found = {str(p.relative_to(ROOT)): lines for p in sources("missionplan/flight")
             if (lines := raw_commands(p.read_text(encoding="utf-8")))}
    assert found == {}, "through the vehicle's session (missionplan.bridge.session), not command_long"


def test_a_raw_command_is_found() -> None:
    assert raw_commands("x = 1\nresult = link.command_long(1, 400, [1.0], deadline)\n") == [2]
    assert raw_commands("view.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)\n") == [1]
    assert raw_commands("view.mav.command_int_send(1, 1, 0, 192, 0, 0, 0, 0, 0, 0, 0, 0, 0)\n") == [1]
    assert raw_commands("session.action.arm(deadline)\ncommand_longer = 1\n") == []


# A module is one job a newcomer can read through: none of missionplan/, geo/ or bridge/ is longer than this.
MAX_MODULE_LINES = 600
# The modules allowed over it, each with its reason; an entry goes when its module is split (the test says so).
LONG_MODULES: dict[str, str] = {}


def long_modules(paths: list[Path], root: Path = ROOT, limit: int = MAX_MODULE_LINES) -> dict[str, int]:
    """Path (relative to root, with /) -> lines, of the modules in `paths` longer than `limit` lines."""
    lines = {p.relative_to(root).as_posix(): len(p.read_text(encoding="utf-8").splitlines()) for p in paths}
    return {path: count for path, count in sorted(lines.items()) if count > limit}


def test_no_module_is_over_600_lines() -> None:
    over = long_modules(ALL_SOURCES)
    assert set(over) - set(LONG_MODULES) == set(), f"over {MAX_MODULE_LINES} lines, split along its seams: {over}"
    assert set(LONG_MODULES) - set(over) == set(), "no longer over the limit: remove it from LONG_MODULES"


def test_a_long_module_is_found(tmp_path: Path) -> None:
    (tmp_path / "short.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    (tmp_path / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    assert long_modules(sorted(tmp_path.iterdir()), tmp_path) == {"long.py": MAX_MODULE_LINES + 1}


# report.json is read only through the plan record (missionplan/mission/plan_record.py: read_plan_record, listed_files):
# no other module opens it for reading or parses it, so every reader gets the typed record.
RECORD_MODULES = {"missionplan.mission.plan_record"}
READ_CALLS = {"read_text", "read_bytes", "open", "load", "loads"}
REPORT_NAMES = {"REPORT_NAME", "report_path"}  # plan_record's own name for the file and the path of a folder's


def report_json_reads(source: str) -> list[int]:
    """Lines where `source` opens or parses a report.json: a read (read_text, read_bytes, open, json.load / loads)
    of an expression that names the file ("report.json", REPORT_NAME, report_path(...)), directly or through a
    variable assigned from one."""
    tree = ast.parse(source)

    def names_the_file(node: ast.AST) -> bool:
        return any((isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value.endswith("report.json"))
                   or (isinstance(n, ast.Name) and n.id in REPORT_NAMES) for n in ast.walk(node))

    paths = {target.id for node in ast.walk(tree) if isinstance(node, (ast.Assign, ast.AnnAssign, ast.NamedExpr))
             and node.value is not None and names_the_file(node.value)
             for target in ([node.target] if not isinstance(node, ast.Assign) else node.targets)
             if isinstance(target, ast.Name)}

    def mentions(node: ast.AST) -> bool:
        return names_the_file(node) or any(isinstance(n, ast.Name) and n.id in paths for n in ast.walk(node))

    found = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else None
        if name not in READ_CALLS:
            continue
        read = [*node.args, *(k.value for k in node.keywords)]
        if isinstance(func, ast.Attribute) and name in ("read_text", "read_bytes", "open"):
            read.append(func.value)  # path.read_text(): the path is what is read
        if any(mentions(arg) for arg in read):
            found.add(node.lineno)
    return sorted(found)


@pytest.mark.parametrize("path", ALL_SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_report_json_is_read_only_through_the_plan_record(path: Path) -> None:
    if module_name(path) in RECORD_MODULES:
        return
    assert report_json_reads(path.read_text(encoding="utf-8")) == [], (
        f"{path.relative_to(ROOT)} reads report.json itself: read it with mission.plan_record.read_plan_record")


def test_a_report_json_read_is_found() -> None:
    # The checker itself: each way a module could read the file is found, and what only names it is not.
    assert report_json_reads('report = json.loads((plan_dir / "report.json").read_text())\n') == [1]
    assert report_json_reads('path = plan_dir / "report.json"\nwith open(path) as f:\n    doc = json.load(f)\n') == [2]
    assert report_json_reads('with (out / REPORT_NAME).open() as f:\n    pass\n') == [1]
    assert report_json_reads('doc = json.loads(report_path(out).read_bytes())\n') == [1]
    assert report_json_reads('text = Path(f"{folder}/report.json").read_text(encoding="utf-8")\n') == [1]
    assert report_json_reads('if not (d / "report.json").is_file():\n    raise E(f"{d}: no report.json")\n') == []
    assert report_json_reads('doc = json.loads((d / "flight.json").read_text())\n') == []
