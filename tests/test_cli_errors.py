"""A library error names the setting the user gave by what it means; the command line says it as the option.

Below missionplan/cli/ an error about a value names its setting (`max_altitude`, missionplan.base.naming)
and carries the values; missionplan/cli/errors.py spells each setting as the option that gives it, so the
crew reads the same one line as ever (`--max-altitude 100: ...`). Checked here: the two wordings of one
error, that no library error spells an option itself (parsed with `ast`, a few recorded texts excepted),
that every setting the library names has its option, and the command line's exact lines for the errors
that moved out of it.
"""

from __future__ import annotations

import ast
import re
import string
from pathlib import Path

import pytest

from missionplan.base.naming import Named, Setting
from missionplan.cli import main
from missionplan.cli.errors import option, said
from missionplan.maps.catalog import load_shipped
from missionplan.maps.gridmap import MapError
from missionplan.mission.safety import safety_settings
from test_cli_docs import options, parsers  # tests/: pyproject.toml's pytest pythonpath

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = sorted(p for folder in ("missionplan", "geo", "bridge") for p in (ROOT / folder).rglob("*.py")
                 if "__pycache__" not in p.parts and (ROOT / "missionplan" / "cli") not in p.parents)
COMMAND_LINE = sorted((ROOT / "missionplan" / "cli").glob("*.py"))
AREA = ROOT / "examples" / "turin-cenisia-area.geojson"
ON_THE_AREA = ["plan", "--area", str(AREA), "--quiet"]

# An option outside a `quoted command` (a hint such as "`missionplan plan --out` makes one" names a command
# to run, not a value the user gave).
OPTION_NAMED = re.compile(r"(?<![\w-])--[a-z]")
QUOTED = re.compile(r"`[^`]*`")
# Errors that still spell an option, each said as it happens in a flight and recorded in its journal
# (flight.json): their words are the flight record's, which stays as it was.
RECORDED = {
    ("bridge/link/shared_link.py", "vehicle"): "a drone's thread finds no link for it: its problem in flight.json",
    ("bridge/transfer/protocol.py", "upload"): "MAV_MISSION_DENIED by another ground station, in fly's record",
    ("bridge/transfer/mavsdk_backend.py", "_import_mavsdk"): "fly --upload-with mavsdk without mavsdk, recorded",
}
# The library functions that take the setting they check (its key), and where: (position, keyword).
TAKES_A_SETTING = {"parse_url": 1, "parse_sysid": 1, "parse_compid": 1, "parse_sysids": 1, "parse_gcs_sysid": 2,
                   "check_gcs_identity": 3, "parse_connects": 1}


def test_a_library_error_names_the_setting_and_carries_its_values() -> None:
    with pytest.raises(MapError) as err:
        safety_settings(load_shipped("leonardo"), 120.0, max_altitude=100.0)
    assert str(err.value) == "max_altitude 100: below the flight altitude 120 m"
    message = err.value.args[0]
    assert isinstance(message, Named) and message.values == (100.0, 120.0)
    assert list(message.settings.values()) == [Setting("max_altitude")]
    assert said(err.value) == "--max-altitude 100: below the flight altitude 120 m"


def test_a_field_may_stand_for_another_setting_and_plain_errors_are_said_as_they_are() -> None:
    named = Named("{name} {0!r}: not a system id; give {sysid}", "x", name="gcs_sysid")
    assert str(named) == "gcs_sysid 'x': not a system id; give sysid"
    assert said(ValueError(named)) == "--gcs-sysid 'x': not a system id; give --sysid"
    assert said(ValueError("--out x: as written")) == "--out x: as written"
    assert said(ValueError("two", "args")) == "('two', 'args')"
    assert option(Setting("unheard_of")) == "--unheard-of"  # its key as an option


def _texts(node: ast.AST) -> list[str]:
    """Each string written in `node`: an f-string whole (its values as {}), so a `quoted command` is one span."""
    inside = {id(part) for n in ast.walk(node) if isinstance(n, ast.JoinedStr) for part in n.values}
    return ["".join(part.value if isinstance(part, ast.Constant) else "{}" for part in n.values)
            if isinstance(n, ast.JoinedStr) else n.value for n in ast.walk(node)
            if isinstance(n, ast.JoinedStr) or (isinstance(n, ast.Constant) and isinstance(n.value, str)
                                                and id(n) not in inside)]


def options_in_errors(source: str) -> list[tuple[str, int]]:
    """(function, line) of each error made with an option spelled in its words: a raise, an ...Error(...) call
    or an error's .args set."""
    tree = ast.parse(source)
    where = {id(sub): node.name for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
             for sub in ast.walk(node)}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise):
            made = node.exc
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id.endswith("Error"):
            made = node
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Attribute) and t.attr == "args"
                                                  for t in node.targets):
            made = node.value
        else:
            made = None
        if made is not None and any(OPTION_NAMED.search(QUOTED.sub("", text)) for text in _texts(made)):
            found.append((where.get(id(node), ""), node.lineno))
    return sorted(set(found))


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_library_error_spells_an_option(path: Path) -> None:
    relative = str(path.relative_to(ROOT))
    found = [(function, line) for function, line in options_in_errors(path.read_text(encoding="utf-8"))
             if (relative, function) not in RECORDED]
    assert found == [], f"{relative}: name the setting (missionplan.base.naming), the CLI spells the option"


def test_an_option_in_an_error_is_found() -> None:
    assert options_in_errors('def f(x):\n    raise MapError(f"--out {x}: no")\n') == [("f", 2)]
    assert options_in_errors('def f(e):\n    e.args = ("raise --endurance",)\n') == [("f", 2)]
    assert options_in_errors('def f(x):\n    raise MapError(Named("{out} {0}: no", x))\n') == []
    hint = 'def f():\n    raise LedgerError("no report.json (`missionplan plan --out` makes one)")\n'
    assert options_in_errors(hint) == []
    assert options_in_errors('def f(a):\n    raise MapError(f"plan it with `missionplan plan "\n'
                             '                   f"--autopilot {a}` (docs)")\n') == []


def settings_named(source: str) -> set[str]:
    """Every setting key a module names: a Named template's fields (or what they stand for), a Setting(...), a
    `setting` parameter's default, and the key handed to a function that takes a setting."""
    keys: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            name, args = node.func.id, node.args
            if name == "Named" and args and isinstance(args[0], ast.Constant):
                bound = {k.arg: k.value for k in node.keywords}
                for _, field, _, _ in string.Formatter().parse(args[0].value):
                    if field and not field.isdigit():
                        stands_for = bound.get(field)
                        if stands_for is None:
                            keys.add(field)
                        elif isinstance(stands_for, ast.Constant):
                            keys.add(stands_for.value)
            elif name == "Setting" and args and isinstance(args[0], ast.Constant):
                keys.add(args[0].value)
            elif name in TAKES_A_SETTING:
                given = [k.value for k in node.keywords if k.arg == "setting"]
                given += args[TAKES_A_SETTING[name]:TAKES_A_SETTING[name] + 1]
                keys |= {g.value for g in given if isinstance(g, ast.Constant) and isinstance(g.value, str)}
        elif isinstance(node, ast.FunctionDef):
            params = node.args.args[len(node.args.args) - len(node.args.defaults):]
            keys |= {d.value for p, d in zip(params, node.args.defaults)
                     if p.arg == "setting" and isinstance(d, ast.Constant)}
    return keys


def test_every_setting_the_library_names_has_its_option() -> None:
    named = set().union(*(settings_named(p.read_text(encoding="utf-8")) for p in LIBRARY + COMMAND_LINE))
    assert {"max_altitude", "out", "launch", "sysid", "connect", "gcs_compid", "home", "upload_with"} <= named
    defined = set().union(*(options(parser) for parser in parsers().values()))
    assert sorted(key for key in named if option(Setting(key)) not in defined) == []
    assert settings_named('Named("{name} {0}", v, name="drones")\nparse_sysid(w, "home")\n'
                          'def f(u, setting="listen"):\n    pass\n') == {"drones", "home", "listen"}


@pytest.fixture(scope="module")
def survey(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("survey") / "leo"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(folder), "--quiet"]) == 0
    return folder


FLY = "FLY"  # a folder with a report.json, which fly checks before it reads any option of a vehicle
SURVEY = "SURVEY"  # the module's survey: a plan of leonardo for 3 drones
MIN_SEPARATION_LINE = (
    "--min-separation 20 m cannot be guaranteed: uav2 and uav4 come within 0.405 m of each other near "
    "45.478345,9.226955, 1.2 m up, 23.12 s into sortie 1 (one altitude, horizontal spacing); layers 20 m apart "
    "would put uav5 at 81.2 m, above --max-altitude 30 m. Lower --min-separation, raise --max-altitude or move "
    "the launch points apart")


@pytest.mark.parametrize("argv, line", [
    (ON_THE_AREA, "--altitude is required with --area"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84"], "--area needs at least one --launch LAT,LON (one per drone)"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--launch", "45.06945,7.652588", "--unknown-building-height",
                    "3"], "--unknown-building-height needs --osm (the buildings it applies to)"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--launch", "45.06945,7.652588", "--height-field", "h"],
     "--height-field needs --osm (the buildings whose height it holds)"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--sensor-width", "6", "--launch", "45.06945,7.652588"],
     "give either --fov or --sensor-width/--sensor-height/--focal-length, not both"),
    (ON_THE_AREA + ["--altitude", "20", "--launch", "45.06945,7.652588"],
     "the camera is needed: --fov DEG, or --sensor-width MM --sensor-height MM --focal-length MM"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--launch", "abc"],
     "--launch abc: expected LAT,LON in degrees, e.g. 45.0701,7.6573"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--launch", "95,7"],
     "--launch 95,7: latitude must be in [-90, 90] and longitude in [-180, 180]"),
    (ON_THE_AREA + ["--altitude", "20", "--fov", "84", "--launch", "45.0,7.0"],
     f"--launch 45.0,7.0 is outside the area {AREA}"),
    (ON_THE_AREA + ["--altitude", "120", "--fov", "84", "--launch", "45.06945,7.652588", "--max-altitude", "100"],
     "--max-altitude 100: below the flight altitude 120 m"),
    (["plan", "--map", "leonardo", "--uavs", "2", "--clearance", "5", "--quiet"],
     "map leonardo: the launch point of drone 1 (cell 21,42) is closer than --clearance 5 m to an obstacle: move "
     "it into the open or lower --clearance"),
    (["plan", "--map", "leonardo", "--uavs", "5", "--min-separation", "20", "--max-altitude", "30", "--quiet"],
     MIN_SEPARATION_LINE),
    (["plan", "--map", "leonardo", "--uavs", "2", "--basemap", "ftp://x", "--quiet"],
     "--basemap ftp://x: must be a tile URL template with {z}, {x} and {y}"),
    (["fly", FLY, "--upload-with", "mavsdk", "--gcs-sysid", "9"],
     "--upload-with mavsdk: MAVSDK sends as its own ground station (system 245), so --gcs-sysid 9 / --gcs-compid "
     "190 cannot apply; leave them at their defaults or use missionplan's own uploader"),
    (["upload", "m.plan", "--sysid", "0"], "--sysid 0: system ids run from 1 to 254"),
    (["upload", "m.plan", "--sysid", "1", "--compid", "x"], "--compid 'x': not a component id (an integer 1..255)"),
    (["upload", "m.plan", "--sysid", "1", "--gcs-sysid", "1"],
     "--gcs-sysid 1: that is a vehicle's system id; the ground station needs its own (default 255)"),
    (["upload", "m.plan", "--sysid", "1", "--connect", "tcp:h:99999"],
     "--connect tcp:h:99999: port 99999 out of range"),
    (["upload", "m.plan", "--sysid", "1", "--backend", "mavsdk", "--gcs-sysid", "7"],
     "--backend mavsdk: MAVSDK sends as its own ground station (system 245), so --gcs-sysid 7 / --gcs-compid 190 "
     "cannot apply; leave them at their defaults or use missionplan's own uploader"),
    (["mock", "--listen", "tcp:127.0.0.1:5", "--duration", "0.1"],
     "--listen tcp:127.0.0.1:5: the mock serves udpin:, udpout: or tcpin: URLs, a serial device (/dev/ttyUSB1,57600) "
     "or pty"),
    (["mock", "--listen", "udpin:127.0.0.1:0", "--home", "x=45,7"], "--home 'x': not a system id (an integer 1..254)"),
    (["replan", SURVEY, "--drones", "9"], "--drones 9: the survey's plan has no drone 9 (it has 1, 2, 3); give new "
                                          "launch points with --launch and --sysid"),
    (["replan", SURVEY, "--drones", "x"], "--drones 'x': not a system id (an integer 1..254)"),
    (["replan", SURVEY, "--launch", "45,7"], "--sysid: say which vehicle flies each --launch point: no --sysid for "
                                             "drone 1"),
    (["replan", SURVEY, "--launch", "45,7", "--sysid", "1=3", "--sysid", "2=3"],
     "--sysid: one system id for two drones (1=3, 2=3)"),
    (["replan", SURVEY, "--launch", "45,7", "--sysid", "1=3"], "--launch 45,7: outside the survey's grid"),
], ids=lambda value: " ".join(value)[:60] if isinstance(value, list) else None)
def test_the_command_line_says_a_library_error_as_it_always_did(argv: list[str], line: str, survey: Path,
                                                                tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "flown").mkdir()
    (tmp_path / "flown" / "report.json").write_text("{}")
    argv = [{FLY: str(tmp_path / "flown"), SURVEY: str(survey)}.get(a, a) for a in argv]
    if argv[0] in ("plan", "replan"):
        argv += ["--out", str(tmp_path / "out")]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err.splitlines() == [f"missionplan: {line}"]
    assert not (tmp_path / "out").exists()
