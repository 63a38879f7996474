"""Code and docs describe the product; its history (issue numbers, what changed when) lives in the commits.

Every text file we write (sources, tests, benches, docs, the build files) is searched for a
reference to an issue: "issue 12", "issues 11 and 13", "issue #4", "the issue" and the like. Third-party
files kept for tests (tests/data) are left out: they are not ours to reword.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("missionplan", "geo", "bridge", "sitl_tests", "tests", "bench", "docs", ".ci", "examples")
FILES = ("README.md", "Makefile", "pyproject.toml")
SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".sh", ""}
SKIP = (ROOT / "tests" / "data",)
ISSUE_REFERENCE = re.compile(r"\bissues?\s*#?\d+|\b(?:the|this|that|an?)\s+issue(?:'s)?\b", re.IGNORECASE)


def _our_text_files() -> list[Path]:
    found = [ROOT / name for name in FILES if (ROOT / name).is_file()]
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*")):
            if (path.is_file() and path.suffix in SUFFIXES and "__pycache__" not in path.parts
                    and not any(path.is_relative_to(skip) for skip in SKIP)):
                found.append(path)
    return found


def issue_references(text: str) -> list[str]:
    """Each line of `text` that points at an issue, as 'line N: ...'."""
    return [f"line {number}: {line.strip()}" for number, line in enumerate(text.splitlines(), start=1)
            if ISSUE_REFERENCE.search(line)]


def test_no_issue_numbers_in_code_or_docs() -> None:
    this_file = Path(__file__).resolve()
    found = {str(path.relative_to(ROOT)): refs for path in _our_text_files() if path.resolve() != this_file
             and (refs := issue_references(path.read_text(encoding="utf-8", errors="replace")))}
    assert found == {}


def test_the_rule_finds_an_issue_reference() -> None:
    assert issue_references("x = 1\n# fixed in issue 16\n") == ["line 2: # fixed in issue 16"]
    assert issue_references("see Issue #4 and issues 11") == ["line 1: see Issue #4 and issues 11"]
    assert issue_references("TOLERANCE = 0.15  # the issue's goal") != []
    # MAVLink message ids and plain words are not issues.
    assert issue_references("ask with MISSION_REQUEST (#40)\nissued a command\ntissue 3\n") == []
