"""Behaviour unchanged, byte for byte: every golden case (tests/golden_cases.py: `plan` on every shipped
map, the real Turin area, a QGroundControl survey as the area, open ground in lanes, and a `demo`
flight on in-process mock autopilots) is run through the public command line and what it wrote is
compared with its manifest in tests/golden/, recorded from the code before a refactor. What is
normalised (wall times, clock times, what a flight's thread timing moves) and why: golden_cases.py.

A failure names the case, the file and, for report.json and flight.json, the first differing keys
with their golden and new values; for any other file, the first differing line as it is now. When a
behaviour change is intended: `.venv/bin/python tests/golden_cases.py --write` (docs/testing.md).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

import golden_cases as gc

_RUNS: dict[str, tuple[Path, dict[str, Any]]] = {}  # one run of each case per session, shared by the tests


def _run(case: gc.Case, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    if case.name not in _RUNS:
        out = tmp_path_factory.mktemp(case.name) / "out"
        _RUNS[case.name] = out, gc.run_case(case, out)
    return _RUNS[case.name]


# The demo case flies mock autopilots: it carries the `flight` marker as every mock flight does.
@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=[pytest.mark.flight] if case.is_flight else [])
                                  for case in gc.CASES])
def test_the_case_writes_what_it_wrote_before(case: gc.Case, tmp_path_factory: pytest.TempPathFactory) -> None:
    if case.needs is not None and not case.needs.exists():
        pytest.skip(f"{case.needs} is absent")
    assert gc.golden_path(case).exists(), f"no tests/golden/{case.name}.json: tests/golden_cases.py --write {case.name}"
    _, found = _run(case, tmp_path_factory)
    problems = gc.compare(gc.load_golden(case), found)
    if problems:
        pytest.fail(f"`{case.command}` differs from tests/golden/{case.name}.json:\n" + "\n".join(problems),
                    pytrace=False)


def test_every_manifest_belongs_to_a_case() -> None:
    assert sorted(p.stem for p in gc.GOLDEN.glob("*.json")) == sorted(gc.BY_NAME)


def test_a_change_is_named_by_case_file_key_and_line(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The comparison itself, against this run's own manifest: one value changed in report.json and one
    field of a .waypoints line are reported with the key and its two values, and the line as it is now."""
    case = gc.BY_NAME["leonardo-5"]
    out, fresh = _run(case, tmp_path_factory)
    golden = gc.public_manifest(fresh)
    changed = tmp_path_factory.mktemp("changed")
    for name in ("report.json", "uav1.waypoints"):
        shutil.copy(out / name, changed / name)
    report = json.loads((changed / "report.json").read_text())
    photos = report["drones"][1]["photos"]
    report["drones"][1]["photos"] = photos + 1
    (changed / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    lines = (changed / "uav1.waypoints").read_text().splitlines(keepends=True)
    fields = lines[4].split("\t")
    fields[4] = "9.99999999"  # the fifth line's first parameter
    lines[4] = "\t".join(fields)
    (changed / "uav1.waypoints").write_text("".join(lines))
    found = {**golden, "files": {**golden["files"], **{name: gc.file_entry(changed / name, changed)
                                                       for name in ("report.json", "uav1.waypoints")}}}
    problems = "\n".join(gc.compare(golden, found))
    assert "leonardo-5: report.json" in problems and f".drones[1].photos: golden {photos}, now {photos + 1}" in problems
    assert "leonardo-5: uav1.waypoints" in problems and "first differs at line 5 of" in problems
    assert "9.99999999" in problems
