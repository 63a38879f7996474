"""The shipped maps: the `*.map` files in the repository's top-level `maps/` folder.

A built wheel carries the same files as package data, `missionplan/maps/shipped/` (pyproject.toml
maps that package to the `maps/` folder), so an installed missionplan finds them too.
"""

from __future__ import annotations

from pathlib import Path

from .gridmap import GridMap, MapError, load_map
from .movingai import load_any_map

_INSTALLED_DIR = Path(__file__).resolve().parent / "shipped"
# The repository root: one folder up per dot in this module's name, so the line holds wherever it sits.
_SOURCE_DIR = Path(__file__).resolve().parents[__name__.count(".")] / "maps"
# The installed package's copy when there is one (a wheel install); else the source tree's maps/
# (a checkout, or an editable install: setuptools' editable mode does not resolve the nested mapping).
MAPS_DIR = _INSTALLED_DIR if _INSTALLED_DIR.is_dir() else _SOURCE_DIR


def shipped_map_names() -> list[str]:
    return sorted(p.stem for p in MAPS_DIR.glob("*.map"))


def load_shipped(name: str) -> GridMap:
    """A shipped map by name, or a map file by path (anything ending in .map: ours or MovingAI's, by content)."""
    if name.endswith(".map"):
        return load_any_map(name)
    path = MAPS_DIR / f"{name}.map"
    if not path.is_file():
        names = ", ".join(shipped_map_names()) or "none"
        raise MapError(f"unknown map {name!r} (shipped maps: {names})")
    return load_map(path)
