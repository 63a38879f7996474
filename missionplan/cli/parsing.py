"""How the command line reads its arguments: the parser class every subcommand's parser is made of (a bad
argument is one line and exit 2; no abbreviated option; `--launch -33.86,151.21` works), the installed
version `--version` prints, and the step from argparse's Namespace to a command's typed request (a frozen
dataclass whose fields are the command's argument names)."""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

from missionplan.bridge.terminal_text import printable

EXIT_USAGE = 2

Request = TypeVar("Request")

# A negative number or LAT,LON pair such as -33.86,151.21 (argparse would take it for an option).
_NEGATIVE_VALUE = re.compile(r"-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(,\s*-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)*")


def attach_negative_values(argv: Sequence[str]) -> list[str]:
    """`--launch -33.86,151.21` -> `--launch=-33.86,151.21`, so a southern or western
    coordinate works with a space like any other value. argparse only recognises plain
    negative numbers, not a comma pair; the `=` form is unambiguous."""
    out: list[str] = []
    for token in argv:
        if (out and _NEGATIVE_VALUE.fullmatch(token) and out[-1].startswith("--") and "=" not in out[-1]
                and out[-1] != "--"):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def package_version() -> str:
    """The installed package's version (importlib.metadata); in a source tree that was never installed,
    the version its pyproject.toml declares; failing both, the package's __version__."""
    from importlib import metadata

    try:
        return metadata.version("missionplan")
    except metadata.PackageNotFoundError:
        pass
    import tomllib

    try:
        pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"  # missionplan/cli/ -> the repository
        project = tomllib.loads(pyproject.read_text())["project"]
        if project.get("name") == "missionplan" and isinstance(project.get("version"), str):
            return project["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        pass
    from missionplan import __version__

    return __version__


class CommandParser(argparse.ArgumentParser):
    """argparse that reports a bad argument in one line with exit code 2, and takes no abbreviated
    option (argparse would read `--uav 3` as `--uavs 3`; a typo must fail, not guess)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"missionplan: {printable(message)}\n")
        raise SystemExit(EXIT_USAGE)

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        argv = sys.argv[1:] if args is None else args
        return super().parse_known_args(attach_negative_values(argv), namespace)


def request_of(kind: type[Request], args: argparse.Namespace) -> Request:
    """The typed request `kind` (a frozen dataclass) from the parsed arguments of the same names; a
    repeatable option's list becomes a tuple, so the request cannot change once made."""
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(kind)}  # type: ignore[arg-type]
    return kind(**{name: tuple(v) if isinstance(v, list) else v for name, v in values.items()})


def runs(kind: type[Request], command: Callable[[Request], int]) -> Callable[[argparse.Namespace], int]:
    """A subparser's handler (set_defaults(handler=...)): the arguments made into a `kind` request, run by
    `command`, which returns the exit code."""
    return lambda args: command(request_of(kind, args))
