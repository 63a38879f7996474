"""The shipped maps: the `*.map` files in the repository's top-level `maps/` folder."""

from __future__ import annotations

from pathlib import Path

from .gridmap import GridMap, MapError, load_map

# The repository root: one folder up per dot in this module's name, so the line holds wherever it sits.
MAPS_DIR = Path(__file__).resolve().parents[__name__.count(".")] / "maps"


def shipped_map_names() -> list[str]:
    return sorted(p.stem for p in MAPS_DIR.glob("*.map"))


def load_shipped(name: str) -> GridMap:
    """A shipped map by name, or a map file by path (anything ending in .map)."""
    if name.endswith(".map"):
        return load_map(name)
    path = MAPS_DIR / f"{name}.map"
    if not path.is_file():
        names = ", ".join(shipped_map_names()) or "none"
        raise MapError(f"unknown map {name!r} (shipped maps: {names})")
    return load_map(path)
