"""How a library error names a setting the user gave: by what it means, never by how a front end spells it.

The library knows quantities (the ceiling of the altitude layers, the output folder), not command lines: an
error about one names it by a `Setting`, whose key is the library's own name for it (`max_altitude`, the
keyword safety_settings takes). The front end says how its user gives that setting: the CLI spells
`max_altitude` as `--max-altitude` (missionplan/cli/errors.py), so its one-line messages read as before,
while a program calling the library reads `max_altitude 90: below the flight altitude 120 m`.

A `Named` message is a str.format template whose named fields are settings and whose positional fields are
the values it reports: `Named("{max_altitude} {0:g}: below the flight altitude {1:g} m", 90.0, 120.0)`.
The error carries it as its one argument (`MapError(Named(...))`), so str() of the error is the library's
wording and `err.args[0].values` the values; `spelled(spell)` words it as a front end does. A field may stand
for a setting of another name (`Named("{name} {0}: ...", value, name="sysid")`), for a function that checks
several settings alike.
"""

from __future__ import annotations

import string
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Setting:
    """A value the user gives, named by what it means; `key` is the library's name for it."""

    key: str

    def __str__(self) -> str:
        return self.key


class Named:
    """An error message that names settings: a template, the values it reports and the settings it names."""

    def __init__(self, template: str, *values: Any, **settings: Setting | str) -> None:
        named = [name for _, name, _, _ in string.Formatter().parse(template) if name and not name.isdigit()]
        self.template = template
        self.values = values
        self.settings = {name: _setting(settings.get(name, name)) for name in named}

    def spelled(self, spell: Callable[[Setting], str] = str) -> str:
        """The message with each setting spelled by `spell` (by default: its key)."""
        return self.template.format(*self.values, **{name: spell(s) for name, s in self.settings.items()})

    def __str__(self) -> str:
        return self.spelled()

    def __repr__(self) -> str:
        return f"Named({self.spelled()!r})"


def _setting(value: Setting | str) -> Setting:
    return value if isinstance(value, Setting) else Setting(value)
