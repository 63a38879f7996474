"""Building heights from the attributes that come with a footprint (OSM tags, GIS fields).

The height is the first of these a feature carries, in metres:

* the field named with `plan --height-field NAME`, when given;
* `height`, then `building:height` (OSM's tags; also under the names GIS formats turn them into:
  `building_height` in GML, `building_h` in a Shapefile, whose field names stop at 10 characters);
* `building:levels` (`building_levels`, `building_l`) times `LEVEL_HEIGHT_M`.

Field names match whatever their case (Shapefiles often carry `HEIGHT`). A value is a number or
text such as '12', '12 m', '12,5', "40'" or '40 ft'; anything else (negative, NaN, 'tall') is no
height, so the building is of unknown height.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

LEVEL_HEIGHT_M = 3.0  # metres per storey when only the number of levels is known
HEIGHT_FIELDS = ("height", "building:height", "building_height", "building_h")
LEVEL_FIELDS = ("building:levels", "building_levels", "building_l")
_CACHED_NAME_SETS = 4096

_HEIGHT_TEXT = re.compile(r"\s*(\d+(?:[.,]\d+)?)\s*(m|meters?|metres?|ft|feet|')?\s*", re.IGNORECASE)


def parse_height(value: Any) -> float | None:
    """OSM-style height: '12', '12 m', '12.5m', '12,5', "40'" / '40 ft' -> metres; else None."""
    if value is None or isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        v = float(value)
        return v if math.isfinite(v) and v >= 0 else None
    m = _HEIGHT_TEXT.fullmatch(str(value))
    if not m:
        return None
    v = float(m.group(1).replace(",", "."))
    if m.group(2) and m.group(2).lower() in ("ft", "feet", "'"):
        v *= 0.3048
    return v


class HeightReader:
    """`building_height` for many footprints: which attribute names hold a height (or levels) is worked
    out once per set of names (a GIS layer's features all have the same fields), not per feature."""

    def __init__(self, height_field: str | None = None) -> None:
        self.height_names = ((height_field,) if height_field else ()) + HEIGHT_FIELDS
        self._resolved: dict[tuple[str, ...], tuple[list[str], list[str]]] = {}

    def _names(self, keys: tuple[str, ...]) -> tuple[list[str], list[str]]:
        """The keys (as the feature spells them) that hold a height, then those that hold levels, in order."""
        by_lower: dict[str, str] = {}
        for key in keys:
            by_lower.setdefault(str(key).lower(), key)
        heights = [by_lower[n.lower()] for n in self.height_names if n.lower() in by_lower]
        levels = [by_lower[n.lower()] for n in LEVEL_FIELDS if n.lower() in by_lower]
        return heights, levels

    def __call__(self, tags: Mapping[str, Any]) -> float | None:
        keys = tuple(tags)
        names = self._resolved.get(keys)
        if names is None:
            if len(self._resolved) >= _CACHED_NAME_SETS:  # OSM tags vary without end: keep the cache small
                self._resolved.clear()
            names = self._resolved[keys] = self._names(keys)
        for key in names[0]:
            h = parse_height(tags[key])
            if h is not None:
                return h
        for key in names[1]:
            levels = parse_height(tags[key])
            if levels is not None:
                return levels * LEVEL_HEIGHT_M
        return None


def building_height(tags: Mapping[str, Any], height_field: str | None = None) -> float | None:
    """The footprint's height in metres from its attributes (see the module docstring), else None."""
    return HeightReader(height_field)(tags)


def has_field(field_names: Iterable[str], name: str) -> bool:
    """Whether `name` is among `field_names`, whatever the case."""
    return name.lower() in {str(f).lower() for f in field_names}
