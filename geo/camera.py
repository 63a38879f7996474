"""Camera footprint <-> grid cell size (SPEC section 7): the one place that knows a photo is 9 cells a side.

A nadir camera at altitude H with field of view FOV sees a square of side
S = 2*H*tan(FOV/2) on flat ground; the grid cell is S / CELLS_PER_FOOTPRINT (9), so one photo covers
a 9x9 block of cells (the 3x3 "photo" of the planner with overlap). `cell_of_footprint` and
`footprint_of_cell` are that rule and its inverse; every other module asks them (or the constant).
`Camera` is that field of view, and what a capture plan needs beside it when known (a name, the sensor,
the image size, the focal length, the capture interval: geo/capture.py's rules read them).
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


# The optional fields a camera may carry beyond its field of view, in the order to_json writes them.
CAMERA_FIELDS = ("name", "sensor_width_mm", "sensor_height_mm", "image_width_px", "image_height_px",
                 "focal_length_mm", "capture_interval_s")


def _check_pixels(value: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= 1_000_000:
        raise GeoError(f"{what} {value!r} must be a whole number of pixels from 1 to 1,000,000")
    return value


@dataclass(frozen=True)
class Camera:
    """A nadir camera: its (square-footprint) field of view in degrees, and what a capture plan needs to
    know beside it when it is known (each None when not): a name (a catalogue id), the sensor's width and
    height (mm), the image's width and height (px), the focal length (mm) and the shortest time between two
    photos it can take (s). The field of view alone sizes the grid; the rest gives the ground sample distance
    (geo/capture.py) and the fastest speed."""

    fov_deg: float
    name: str | None = None
    sensor_width_mm: float | None = None
    sensor_height_mm: float | None = None
    image_width_px: int | None = None
    image_height_px: int | None = None
    focal_length_mm: float | None = None
    capture_interval_s: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "fov_deg", _check_fov(self.fov_deg))
        for key, what in (("sensor_width_mm", "sensor width (mm)"), ("sensor_height_mm", "sensor height (mm)"),
                          ("focal_length_mm", "focal length (mm)"), ("capture_interval_s", "capture interval (s)")):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, _check_positive(getattr(self, key), what))
        for key, what in (("image_width_px", "image width (px)"), ("image_height_px", "image height (px)")):
            if getattr(self, key) is not None:
                _check_pixels(getattr(self, key), what)

    @classmethod
    def from_fov(cls, fov_deg: float) -> "Camera":
        return cls(fov_deg)

    @classmethod
    def from_sensor(cls, sensor_width_mm: float, sensor_height_mm: float, focal_length_mm: float,
                    **known: Any) -> "Camera":
        """FOV of the narrower sensor side, fov = 2*atan(min(w, h) / (2 f)); the sensor and focal length kept,
        and `known`: the other optional fields (name, image size, capture interval).

        The narrower side is used so the square footprint lies wholly inside the photo.
        """
        w = _check_positive(sensor_width_mm, "sensor width (mm)")
        h = _check_positive(sensor_height_mm, "sensor height (mm)")
        f = _check_positive(focal_length_mm, "focal length (mm)")
        return cls(math.degrees(2.0 * math.atan(min(w, h) / (2.0 * f))), sensor_width_mm=w, sensor_height_mm=h,
                   focal_length_mm=f, **known)

    @property
    def label(self) -> str:
        """How a message names it: its name, else "the camera"."""
        return self.name if self.name is not None else "the camera"

    def footprint_side_m(self, altitude_m: float) -> float:
        return footprint_side_m(altitude_m, self.fov_deg)

    def cell_size_m(self, altitude_m: float) -> float:
        return cell_size_m(altitude_m, self.fov_deg)

    def to_json(self) -> dict[str, Any]:
        """fov_deg, then each optional field that is known (an fov-only camera is {"fov_deg": ...})."""
        doc: dict[str, Any] = {"fov_deg": self.fov_deg}
        doc |= {key: getattr(self, key) for key in CAMERA_FIELDS if getattr(self, key) is not None}
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> "Camera":
        return cls(doc["fov_deg"], **{key: doc[key] for key in CAMERA_FIELDS if doc.get(key) is not None})
