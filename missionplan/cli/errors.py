"""How the command line says a library error: one line, each setting it names spelled as the option that
gives it. The library names a setting by what it means, the name of the option's value (its argparse dest,
missionplan.base.naming: `max_altitude`); the command line spells it as the option, so a message reads
`--max-altitude 90: below the flight altitude 120 m` whichever layer found the fault."""

from __future__ import annotations

from missionplan.base.naming import Named, Setting


def option(setting: Setting) -> str:
    """The option that gives `setting`: its key as argparse spells a dest as an option, `max_altitude` ->
    `--max-altitude` (tests/test_cli_errors.py checks that every setting the library names is an option)."""
    return "--" + setting.key.replace("_", "-")


def said(err: BaseException) -> str:
    """The error's one line as the command line says it."""
    message = err.args[0] if len(err.args) == 1 else None
    if isinstance(message, Named):
        return message.spelled(option)
    return str(err)
