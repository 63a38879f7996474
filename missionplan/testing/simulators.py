"""Where the simulators the real-autopilot tests start live: ArduCopter SITL and PX4 SIH.

One folder holds both, laid out as the development machine's `shared` folder is:

    sitl/arducopter, sitl/copter.parm        ArduCopter SITL and the defaults it starts with
    px4/bin/px4, px4/run-sih.sh, px4/etc/    PX4 SIH, built as its README there says

The folder is, first found:
- the environment variable MISSIONPLAN_SIMULATORS (pytest's `--simulators DIR`, an option of the
  missionplan plugin, sets it for the run, so the benches and child processes it starts see the same);
- in a checkout of missionplan (an editable install), the folder `shared` beside the repository:
  `../shared`.
An installed missionplan has no checkout to look beside: without the variable or the option no folder
is known, and a test that needs a simulator skips, saying how to give one.

Read at each call, not at import: the plugin sets the variable after this module may have been imported.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV = "MISSIONPLAN_SIMULATORS"
OPTION = "--simulators"


def checkout() -> Path | None:
    """The repository this module runs from, None when it runs from an installed package."""
    root = Path(__file__).resolve().parents[2]
    if (root / "pyproject.toml").is_file() and (root / "missionplan").is_dir() and (root / "bridge").is_dir():
        return root
    return None


def simulators_dir() -> Path | None:
    """The folder that holds sitl/ and px4/ (see the module doc), None when none is known."""
    given = os.environ.get(ENV, "").strip()
    if given:
        return Path(given).expanduser().resolve()
    root = checkout()
    return None if root is None else root.parent / "shared"


def sitl_dir() -> Path | None:
    """ArduCopter SITL's folder (sitl/arducopter, sitl/copter.parm), None when no folder is known."""
    found = simulators_dir()
    return None if found is None else found / "sitl"


def px4_dir() -> Path | None:
    """PX4 SIH's folder (px4/bin/px4, px4/run-sih.sh, px4/etc/), None when no folder is known."""
    found = simulators_dir()
    return None if found is None else found / "px4"


def how_to_give() -> str:
    """The end of a skip reason: how to say where the simulators are."""
    return f"{OPTION} DIR or {ENV}=DIR names a folder holding sitl/ and px4/"


def missing(what: str, path: Path | None, readme: Path | None) -> str:
    """A skip reason: `what` is not at `path` (or no folder is known)."""
    if path is None:
        return f"{what}: no simulators folder known ({how_to_give()})"
    see = f"see {readme}; " if readme is not None else ""
    return f"{what} not found at {path} ({see}{how_to_give()})"
