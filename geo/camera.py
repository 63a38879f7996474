"""Camera footprint <-> grid cell size (SPEC section 7): the one place that knows a photo is 9 cells a side.

A nadir camera at altitude H with field of view FOV sees a square of side
S = 2*H*tan(FOV/2) on flat ground; the grid cell is S / CELLS_PER_FOOTPRINT (9), so one photo covers
a 9x9 block of cells (the 3x3 "photo" of the planner with overlap). `cell_of_footprint` and
`footprint_of_cell` are that rule and its inverse; every other module asks them (or the constant).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .errors import GeoError

CELLS_PER_FOOTPRINT = 9  # a photo's footprint is this many grid cells a side


def cell_of_footprint(footprint_m: float) -> float:
    """The grid cell side for a photo footprint of side `footprint_m`: footprint / 9."""
    return footprint_m / CELLS_PER_FOOTPRINT


def footprint_of_cell(cell_m: float) -> float:
    """The photo footprint side on a grid of `cell_m` cells: 9 cells (the inverse of cell_of_footprint)."""
    return cell_m * CELLS_PER_FOOTPRINT


def _check_positive(value: float, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise GeoError(f"{what} {value!r} is not a number") from None
    if not math.isfinite(v) or v <= 0:
        raise GeoError(f"{what} {value!r} must be a positive number")
    return v


def _check_fov(fov_deg: float) -> float:
    try:
        v = float(fov_deg)
    except (TypeError, ValueError):
        raise GeoError(f"camera field of view {fov_deg!r} is not a number") from None
    # 0 and 180 are excluded: the footprint would be a point or infinitely wide.
    if not math.isfinite(v) or not 0.0 < v < 180.0:
        raise GeoError(f"camera field of view {fov_deg!r} deg must be strictly between 0 and 180 degrees")
    return v


def footprint_side_m(altitude_m: float, fov_deg: float) -> float:
    """Side S = 2*H*tan(FOV/2) of the square ground footprint, in metres."""
    h = _check_positive(altitude_m, "altitude")
    fov = _check_fov(fov_deg)
    return 2.0 * h * math.tan(math.radians(fov) / 2.0)


def cell_size_m(altitude_m: float, fov_deg: float) -> float:
    """Grid cell side = footprint side / 9, in metres."""
    return cell_of_footprint(footprint_side_m(altitude_m, fov_deg))


@dataclass(frozen=True)
class Camera:
    """A nadir camera described by its (square-footprint) field of view in degrees.

    Room for what a capture plan needs next (the sensor, the ground sample distance, the capture
    interval): fields added here, each written by to_json and read by from_json."""

    fov_deg: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "fov_deg", _check_fov(self.fov_deg))

    @classmethod
    def from_fov(cls, fov_deg: float) -> "Camera":
        return cls(fov_deg)

    @classmethod
    def from_sensor(cls, sensor_width_mm: float, sensor_height_mm: float, focal_length_mm: float) -> "Camera":
        """FOV of the narrower sensor side, fov = 2*atan(min(w, h) / (2 f)).

        The narrower side is used so the square footprint lies wholly inside the photo.
        """
        w = _check_positive(sensor_width_mm, "sensor width (mm)")
        h = _check_positive(sensor_height_mm, "sensor height (mm)")
        f = _check_positive(focal_length_mm, "focal length (mm)")
        return cls(math.degrees(2.0 * math.atan(min(w, h) / (2.0 * f))))

    def footprint_side_m(self, altitude_m: float) -> float:
        return footprint_side_m(altitude_m, self.fov_deg)

    def cell_size_m(self, altitude_m: float) -> float:
        return cell_size_m(altitude_m, self.fov_deg)

    def to_json(self) -> dict[str, Any]:
        return {"fov_deg": self.fov_deg}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> "Camera":
        return cls(doc["fov_deg"])
