"""Write a bench's printed table into the docs, so no measured table there is edited by hand.

A doc holds a bench's table between two marker lines that name the command that prints it:

    <!-- table: python bench/fly_bench.py --streets '' -->
    ```text
    ... what the command printed ...
    ```
    <!-- end table -->

`--write-doc FILE` (repeatable) on a bench script replaces, in FILE, the text between every such pair
whose command is the one being run (the same script and the same arguments, `--write-doc` aside) by
what it printed. A FILE with no such pair is refused before anything is measured. tests/test_docs_commands.py
checks that every measured table of the docs sits between markers naming a bench script and its options.
"""

from __future__ import annotations

import argparse
import io
import re
import shlex
import sys
from pathlib import Path
from typing import TextIO

ROOT = Path(__file__).resolve().parent.parent
BEGIN = re.compile(r"^<!-- table: (.+?) -->\s*$")
END = re.compile(r"^<!-- end table -->\s*$")
INTERPRETERS = {"python", "python3", ".venv/bin/python", ".venv/bin/python3"}


def add_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--write-doc", action="append", default=[], metavar="FILE",
                        help="also write the printed table into FILE, between its <!-- table: COMMAND --> and "
                             "<!-- end table --> lines for this very command (repeatable)")


def command_tokens(script: str, argv: list[str]) -> list[str]:
    """`python bench/NAME.py ARGS` as tokens, the --write-doc options left out."""
    args: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--write-doc":
            skip = True
        elif not arg.startswith("--write-doc="):
            args.append(arg)
    return ["python", f"bench/{Path(script).name}", *args]


def _marker_tokens(text: str) -> list[str] | None:
    try:
        tokens = shlex.split(text)
    except ValueError:
        return None
    if tokens and tokens[0] in INTERPRETERS:
        tokens[0] = "python"
    return tokens


def _spans(lines: list[str], tokens: list[str]) -> list[tuple[int, int]]:
    """(begin, end) line indexes of every marker pair for this command."""
    spans = []
    begin: int | None = None
    for i, line in enumerate(lines):
        if (m := BEGIN.match(line)) and _marker_tokens(m.group(1)) == tokens:
            begin = i
        elif END.match(line) and begin is not None:
            spans.append((begin, i))
            begin = None
    return spans


def check_docs(files: list[str], tokens: list[str]) -> None:
    """Refuse (one line, exit 2) a doc that has nowhere to put this command's table."""
    for name in files:
        path = Path(name)
        if not path.is_file():
            _refuse(f"--write-doc {name}: no such file")
        if not _spans(path.read_text().splitlines(), tokens):
            _refuse(f"--write-doc {name}: no <!-- table: {shlex.join(tokens)} --> ... <!-- end table --> "
                    f"lines to write between")


def _refuse(line: str) -> None:
    print(f"{Path(sys.argv[0]).name}: {line}", file=sys.stderr)
    raise SystemExit(2)


def write_docs(files: list[str], tokens: list[str], text: str) -> None:
    for name in files:
        path = Path(name)
        lines = path.read_text().splitlines()
        for begin, end in reversed(_spans(lines, tokens)):
            lines[begin + 1:end] = ["```text", *text.rstrip("\n").splitlines(), "```"]
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_text("\n".join(lines) + "\n")
        tmp.replace(path)
        print(f"wrote the table into {name}", file=sys.stderr)


class Tee(io.TextIOBase):
    """stdout that also keeps what was printed."""

    def __init__(self, out: TextIO) -> None:
        self.out = out
        self.kept = io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


class Recorder:
    """`with Recorder(args.write_doc, __file__):` around a bench's printing: checks the docs first,
    then writes what was printed into them (only when the bench finished)."""

    def __init__(self, files: list[str], script: str, argv: list[str] | None = None) -> None:
        self.files = files
        self.tokens = command_tokens(script, sys.argv[1:] if argv is None else argv)
        self.tee: Tee | None = None

    def __enter__(self) -> Recorder:
        if self.files:
            check_docs(self.files, self.tokens)
            self.tee = Tee(sys.stdout)
            sys.stdout = self.tee  # type: ignore[assignment]
        return self

    def __exit__(self, kind: object, value: object, traceback: object) -> None:
        if self.tee is None:
            return
        sys.stdout = self.tee.out  # type: ignore[assignment]
        if kind is None:
            write_docs(self.files, self.tokens, self.tee.kept.getvalue())
