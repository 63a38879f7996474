"""The field-safety settings of a georeferenced plan, from the command line and the map: one checked value object.

Each protects one thing (docs/field-safety.md):
- min_separation_m: two drones never closer than this, 3-D, over the whole flight (separation.py);
  default 5 m, or the map's own `min_separation_m` (the tiny shipped arena flies small drones);
- max_altitude_m: no altitude layer above it (and the geofence's ceiling is kept under it);
- clearance_m: horizontal margin of every track from obstacles; default max(5 m, one cell);
- endurance_s and reserve: each sortie's whole flight within endurance x (1 - reserve) (sorties.py);
- fence_margin_m: how far the geofence lies outside the drone's whole flight (geofence.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from missionplan.base.naming import Named, Setting

from ..maps.gridmap import GridMap, MapError
from .separation import DEFAULT_MAX_ALTITUDE_M, DEFAULT_MIN_SEPARATION_M
from .sorties import DEFAULT_ENDURANCE_MIN, DEFAULT_RESERVE

DEFAULT_CLEARANCE_M = 5.0


@dataclass(frozen=True)
class SafetySettings:
    min_separation_m: float = DEFAULT_MIN_SEPARATION_M
    max_altitude_m: float = DEFAULT_MAX_ALTITUDE_M
    clearance_m: float = DEFAULT_CLEARANCE_M
    endurance_s: float | None = DEFAULT_ENDURANCE_MIN * 60.0  # None: no limit (one sortie per drone)
    reserve: float = DEFAULT_RESERVE

    @property
    def budget_s(self) -> float | None:
        """Planned flight time one sortie may take: the endurance less the reserve."""
        return None if self.endurance_s is None else self.endurance_s * (1.0 - self.reserve)

    @property
    def fence_margin_m(self) -> float:
        """The geofence lies this far outside everything the drone flies over: room for the acceptance
        radius, wind and GPS error before the autopilot's breach action, but never less than the
        separation and the clearance."""
        return max(self.min_separation_m, self.clearance_m)


def _positive(name: str | Setting, value: float) -> float:
    if not value > 0:
        raise MapError(Named("{name} {0:g}: must be above 0", value, name=name) if isinstance(name, Setting)
                       else f"{name} {value:g}: must be above 0")
    return float(value)


def _declared(gmap: GridMap, key: str) -> float:
    """A positive number of metres the map file declares under `key`."""
    text = gmap.meta[key]
    try:
        value = float(text)
    except ValueError:
        raise MapError(f"map {gmap.name}: {key} {text!r} is not a number of metres") from None
    return _positive(f"map {gmap.name}: {key}", value)


def safety_settings(gmap: GridMap, altitude_m: float, *, min_separation: float | None = None,
                    max_altitude: float = DEFAULT_MAX_ALTITUDE_M, clearance: float | None = None,
                    endurance: float = DEFAULT_ENDURANCE_MIN, reserve: float = DEFAULT_RESERVE) -> SafetySettings:
    """The checked settings for a plan, as `plan` takes them (its defaults; endurance in minutes, 0: no limit);
    the map may declare its own min_separation_m and clearance_m, used where none is given."""
    if min_separation is not None:
        min_sep = _positive(Setting("min_separation"), min_separation)
    elif "min_separation_m" in gmap.meta:
        min_sep = _declared(gmap, "min_separation_m")
    else:
        min_sep = DEFAULT_MIN_SEPARATION_M
    max_alt = _positive(Setting("max_altitude"), max_altitude)
    if altitude_m > max_alt:
        raise MapError(Named("{max_altitude} {0:g}: below the flight altitude {1:g} m", max_alt, altitude_m))
    cell_m = gmap.cell_m or 0.0
    if clearance is not None:
        if clearance < 0:
            raise MapError(Named("{clearance} {0:g}: a margin cannot be negative", clearance))
        clearance = float(clearance)
    elif "clearance_m" in gmap.meta:
        clearance = _declared(gmap, "clearance_m")
    else:
        clearance = max(DEFAULT_CLEARANCE_M, cell_m)
    endurance_s = None if endurance == 0 else _positive(Setting("endurance"), endurance) * 60.0
    if not 0 <= reserve < 1:
        raise MapError(Named("{reserve} {0:g}: must be a fraction in [0, 1)", reserve))
    return SafetySettings(min_separation_m=min_sep, max_altitude_m=max_alt, clearance_m=clearance,
                          endurance_s=endurance_s, reserve=float(reserve))
