"""The plan as data type-checks: mypy --strict over the plan record (mission/plan_record.py, plan_blocks.py,
geo/georeference.py, geo/camera.py) and the modules that build or read it and pass cleanly, so a block
that changes shape fails here, where it is read, before a report.json is ever written (py.typed ships).

geo/ and bridge/ install as missionplan.geo and missionplan.bridge (pyproject.toml's package-dir), which mypy
cannot follow through the editable install: it checks a tree of links laid out as the package installs.
Imported modules are read for their types, not checked themselves (--follow-imports=silent).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Strict, and to stay so: the record first, then what builds and reads it.
STRICT = (
    "missionplan.mission.plan_record", "missionplan.mission.plan_blocks", "missionplan.geo.georeference",
    "missionplan.geo.camera", "missionplan.geo.errors", "missionplan.mission.report", "missionplan.maps.gridmap",
    "missionplan.mission.drone_missions", "missionplan.mission.safety", "missionplan.mission.outputs",
    "missionplan.flight.plan_report", "missionplan.flight.disk_space", "missionplan.cli.plan_display",
    # the flight's events, its silence rule, the re-tasker's view of the fleet and the re-task planner's contract
    "missionplan.flight.events", "missionplan.flight.link_silence", "missionplan.flight.fleet_view",
    "missionplan.flight.retask_planner", "missionplan.flight.follower_mail",
    # overlaps as measured: report.json's coverage block holds its measure
    "missionplan.mission.photo_overlap",
    # the overlap fill's detours: report.json's overlap_fill block counts them
    "missionplan.mission.overlap_fill",
)


def installed_tree(where: Path) -> Path:
    """A folder holding `missionplan` as it installs: the package's own entries, with geo/ and bridge/ in it."""
    package = where / "missionplan"
    package.mkdir()
    for entry in (ROOT / "missionplan").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    for folder in ("geo", "bridge"):
        (package / folder).symlink_to(ROOT / folder)
    return where


def mypy(where: Path, modules: tuple[str, ...]) -> subprocess.CompletedProcess[str]:
    args = [arg for module in modules for arg in ("-m", module)]
    return subprocess.run([sys.executable, "-m", "mypy", "--strict", "--follow-imports=silent", "--no-color-output",
                           "--cache-dir", str(where / ".mypy_cache"), *args],
                          cwd=where, capture_output=True, text=True, timeout=600)


def test_the_plan_record_type_checks_strictly(tmp_path: Path) -> None:
    checked = mypy(installed_tree(tmp_path), STRICT)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert f"no issues found in {len(STRICT)} source files" in checked.stdout


def test_a_type_error_in_a_record_block_fails(tmp_path: Path) -> None:
    # The check itself: a block whose from_json gives the wrong type is an error mypy names.
    tree = installed_tree(tmp_path)
    wrong = tree / "wrong_block.py"
    wrong.write_text("from missionplan.mission.plan_blocks import SortiePlan\n\n\n"
                     "def planned_seconds(sortie: SortiePlan) -> str:\n    return sortie.flight_s\n")
    checked = mypy(tree, ("wrong_block",))
    assert checked.returncode == 1
    assert 'wrong_block.py:5: error: Incompatible return value type (got "float", expected "str")' in checked.stdout

