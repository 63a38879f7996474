"""docs/cli.md lists every option of every command exactly as the parser has them.

Walks the argparse tree of `missionplan.cli.build_parser()` (the top parser and each subcommand's)
and reads docs/cli.md's reference block, one section per command (a line `missionplan CMD ...` at
the left margin, then its synopsis, then lines indented four spaces: description and one entry per
option, `    --opt  text` or `    --a, --b: text`). Every option must appear in its command's
synopsis (one of its spellings: `-o` for `-o, --output`) and have an entry (every spelling); nothing may be documented for a command that lacks it; and no option
mentioned anywhere in the file may be one that no command has.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import pytest

from missionplan.cli.app import build_parser

CLI_MD = Path(__file__).resolve().parent.parent / "docs" / "cli.md"
HELP = {"-h", "--help"}  # argparse's own, on every parser
OPTION = re.compile(r"(?<![\w-])(--?[A-Za-z][\w-]*)")
ENTRY = re.compile(r"^ {4}(--?[A-Za-z][\w-]*(?:, --?[A-Za-z][\w-]*)*)(?=[\s:,]|$)")
NOT_OPTIONS = {"--uav"}  # the docs' example of an abbreviation that is refused


def parsers() -> dict[str, argparse.ArgumentParser]:
    """'' -> the top parser; each subcommand's name -> its parser."""
    top = build_parser()
    out = {"": top}
    for action in top._actions:
        if isinstance(action, argparse._SubParsersAction):
            out.update(action.choices)
    return out


def actions(parser: argparse.ArgumentParser) -> list[set[str]]:
    """Each option of the parser as the set of its spellings (-h / --help left out)."""
    return [set(a.option_strings) for a in parser._actions if a.option_strings and not set(a.option_strings) & HELP]


def options(parser: argparse.ArgumentParser) -> set[str]:
    return set().union(*actions(parser))


def reference_block() -> list[str]:
    text = CLI_MD.read_text()
    start = text.index("```text\nmissionplan ") + len("```text\n")
    return text[start:text.index("\n```", start)].splitlines()


def sections() -> dict[str, tuple[set[str], set[str], set[str]]]:
    """Command ('' for `missionplan --OPTION`) -> (options in its synopsis, options with an entry,
    every option token in its section)."""
    out: dict[str, tuple[set[str], set[str], set[str]]] = {}
    synopsis = entries = mentioned = set()
    in_synopsis = False
    for line in reference_block():
        if line.startswith("missionplan "):
            word = line.split()[1]
            name = "" if word.startswith("-") else word
            assert name not in out, f"docs/cli.md documents `missionplan {name}` twice"
            synopsis, entries, mentioned = set(), set(), set()
            out[name] = (synopsis, entries, mentioned)
            in_synopsis = True
        elif re.match(r"^ {4}\S", line):
            in_synopsis = False
        tokens = set(OPTION.findall(line))
        mentioned |= tokens
        if in_synopsis:
            synopsis |= tokens
        elif entry := ENTRY.match(line):
            entries |= set(entry.group(1).split(", "))
    return out


def test_every_command_has_a_section_and_every_section_a_command() -> None:
    assert set(sections()) == set(parsers())


@pytest.mark.parametrize("command", sorted(parsers()))
def test_every_option_is_documented_and_every_documented_option_exists(command: str) -> None:
    have = options(parsers()[command])
    synopsis, entries, _ = sections()[command]
    name = f"`missionplan {command}`" if command else "the top parser"
    unlisted = sorted(min(spellings) for spellings in actions(parsers()[command]) if not spellings & synopsis)
    assert not unlisted, f"{name}: options missing from the synopsis in docs/cli.md: {unlisted}"
    assert not have - entries, f"{name}: options without an entry in docs/cli.md: {sorted(have - entries)}"
    stale = (synopsis | entries) - have - HELP
    assert not stale, f"{name}: docs/cli.md documents options the parser does not have: {sorted(stale)}"


def test_no_option_mentioned_anywhere_is_unknown() -> None:
    known = set().union(*(options(p) for p in parsers().values())) | HELP
    unknown = sorted(set(OPTION.findall(CLI_MD.read_text())) - known - NOT_OPTIONS)
    assert not unknown, f"docs/cli.md mentions options no command has: {unknown}"


def test_the_check_fails_on_a_missing_or_invented_option(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The walk is not vacuous: drop one entry and invent another, and both are caught."""
    text = CLI_MD.read_text()
    broken = tmp_path / "cli.md"
    assert "    --ready-timeout " in text
    broken.write_text(text.replace("    --ready-timeout ", "    --ready-timeoutx ", 1))
    monkeypatch.setattr(sys.modules[__name__], "CLI_MD", broken)
    synopsis, entries, _ = sections()["fly"]
    assert "--ready-timeout" not in entries and "--ready-timeoutx" in entries
    with pytest.raises(AssertionError, match="ready-timeout"):
        test_every_option_is_documented_and_every_documented_option_exists("fly")
