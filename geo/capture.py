"""The capture rules: from a camera, a flight height (or a ground sample distance) and front / side overlaps
to the numbers a survey is flown by, each with the rule that gives it. Pure: numbers in, numbers out.

With H the height above the ground, f the focal length, w x h the sensor (mm) and W x Hpx the image (px):
- GSD (cm/px) = 100 x w x H / (f x W), and likewise 100 x h x H / (f x Hpx); the worse (larger) of the two;
- H from a GSD: the inverse on that worse side, H = GSD x f x W / (100 x w);
- footprint side S on flat ground = H x min(w, h) / f, the narrower side's square (SPEC section 7: the
  camera's field of view, camera.Camera.from_sensor), = 2 H tan(FOV / 2) for a camera known by its FOV;
- grid cell = S / 9 (camera.cell_of_footprint);
- trigger distance = S x (1 - front overlap);
- lane spacing on open ground = S x (1 - side overlap), in whole cells floor(9 x (1 - side overlap)), at
  least 1; so the side overlap kept, 1 - cells / 9, is never less than the one asked;
- fastest speed = trigger distance / capture interval: faster, the camera would be asked for a photo
  sooner than it can take one;
- the speed: the one asked (never above the fastest), else min(cruise speed, fastest speed);
- the transit speed, the ways out to the survey and home from it with the camera off: the one asked, else the
  cruise speed when the survey is slower (choose_transit_speed); no limit from the camera there.

`CapturePlan` holds one survey's numbers and `rules()` the lines a report prints. The checks that refuse a
combination (a speed above the fastest, a GSD whose height is above the ceiling, a GSD from a camera that
lacks a sensor, image size or focal length) raise GeoError with one line naming the settings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from missionplan.base.naming import Named

from .camera import CELLS_PER_FOOTPRINT, Camera, cell_of_footprint
from .errors import GeoError

# The fastest waypoint speed either autopilot flies a multirotor at: ArduCopter's WPNAV_SPEED ranges 10 to
# 2000 cm/s (AC_WPNav) and PX4's MPC_XY_VEL_MAX 0 to 20 m/s (mc_pos_control parameters).
MAX_SPEED_M_S = 20.0
CRUISE_SPEED_M_S = 5.0  # plan's speed when none is asked (mission.drone_missions.DEFAULT_SPEED_M_S)
# A side overlap closer than this leaves lanes under one cell apart: the grid cannot fly them.
MAX_SIDE_OVERLAP = 1.0 - 1.0 / CELLS_PER_FOOTPRINT
# What a GSD needs of a camera, each with the setting that gives it.
GSD_NEEDS = (("sensor_width_mm", "sensor_width", "MM"), ("sensor_height_mm", "sensor_height", "MM"),
             ("image_width_px", "image_width", "PX"), ("image_height_px", "image_height", "PX"),
             ("focal_length_mm", "focal_length", "MM"))
# The camera straight down, in MAVLink's convention (bridge.formats.gimbal's NADIR_PITCH_DEG; geo imports no bridge).
NADIR_PITCH_DEG = -90.0
SPEED_SOURCES = ("asked", "limit", "cruise")  # the speed given, chosen from the camera's limit, or the cruise speed


def shown(value: float) -> str:
    """A number as a report prints it: three significant digits, no exponent, no trailing zeros (46.3, 1.67,
    0.367, 1, 120, 1230)."""
    if not math.isfinite(value):
        return f"{value:g}"
    text = f"{float(f'{value:.3g}'):f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def gsd_missing(camera: Camera) -> list[tuple[str, str]]:
    """The (setting, placeholder) pairs a GSD needs that `camera` lacks (empty: it has them all)."""
    return [(setting, unit) for key, setting, unit in GSD_NEEDS if getattr(camera, key) is None]


def _check_gsd_camera(camera: Camera) -> tuple[float, float, float, float, float]:
    missing = gsd_missing(camera)
    if missing:
        needs = " ".join(f"{{{setting}}} {unit}" for setting, unit in missing)
        raise GeoError(Named("{gsd} needs the camera's sensor, image size and focal length: give " + needs
                             + " (or {camera} NAME: `missionplan cameras` lists them)"))
    assert camera.sensor_width_mm is not None and camera.sensor_height_mm is not None
    assert camera.image_width_px is not None and camera.image_height_px is not None
    assert camera.focal_length_mm is not None
    return (camera.sensor_width_mm, camera.sensor_height_mm, camera.image_width_px, camera.image_height_px,
            camera.focal_length_mm)


def _worse_side(camera: Camera) -> tuple[str, float, int]:
    """The sensor side whose pixels are larger on the ground (width on a tie): its name, mm and px."""
    w, h, width_px, height_px, _ = _check_gsd_camera(camera)
    # Square pixels (13.2 mm / 5472 px = 8.8 mm / 3648 px) tie within rounding: the width then.
    return ("width", w, width_px) if w * height_px >= h * width_px * (1 - 1e-12) else ("height", h, height_px)


def gsd_cm(camera: Camera, height_m: float) -> float:
    """GSD in cm/px at `height_m`: 100 x sensor x H / (f x image), the worse of width and height."""
    _, side_mm, side_px = _worse_side(camera)
    assert camera.focal_length_mm is not None
    return 100.0 * side_mm * height_m / (camera.focal_length_mm * side_px)


def height_for_gsd(camera: Camera, gsd: float) -> float:
    """The height (m) at which `camera` has a GSD of `gsd` cm/px: GSD x f x image / (100 x sensor), worse side."""
    _, side_mm, side_px = _worse_side(camera)
    assert camera.focal_length_mm is not None
    return gsd * camera.focal_length_mm * side_px / (100.0 * side_mm)


def trigger_distance_m(footprint_m: float, front_overlap: float) -> float:
    """The distance between photos along a lane: S x (1 - front overlap)."""
    return footprint_m * (1.0 - front_overlap)


def lane_spacing_cells(side_overlap: float | None) -> int:
    """The cells between open-ground lanes for a side overlap (a fraction; None: lanes one footprint apart):
    floor(9 x (1 - side)), which must be at least 1 (GeoError otherwise)."""
    if side_overlap is None:
        return CELLS_PER_FOOTPRINT
    cells = math.floor(CELLS_PER_FOOTPRINT * (1.0 - side_overlap) + 1e-9)  # 2/3 gives 3 cells, not 2.999...
    if cells < 1:
        raise GeoError(Named("{side_overlap} {0} %: lanes {1} cells apart, and the grid's lanes are at least one "
                             "cell apart: at most {2} %", shown(100 * side_overlap),
                             shown(CELLS_PER_FOOTPRINT * (1.0 - side_overlap)), shown(100 * MAX_SIDE_OVERLAP)))
    return cells


def fastest_speed_m_s(trigger_m: float, capture_interval_s: float) -> float:
    """The fastest speed at which the camera keeps up: trigger distance / capture interval."""
    return trigger_m / capture_interval_s


def check_height(camera: Camera, gsd: float, height_m: float, ceiling_m: float) -> None:
    """GeoError when the height a GSD gives is above the ceiling (--max-altitude): the line names the height,
    the ceiling and the largest GSD flown at or under it."""
    if height_m > ceiling_m:
        raise GeoError(Named("{gsd} {0} cm/px puts {1} at {2} m, above {max_altitude} {3} m: the coarsest GSD "
                             "flown at or under it is {4} cm/px", shown(gsd), camera.label, shown(height_m),
                             shown(ceiling_m), shown(gsd_cm(camera, ceiling_m))))


def choose_transit_speed(speed_m_s: float, asked_m_s: float | None) -> float | None:
    """The speed of the ways out and home when it differs from the survey's `speed_m_s`: the one asked
    (`--transit-speed`), else the cruise speed when the survey is slower (a camera's capture interval slowed
    it: the camera is off on the way out and home); None: the survey's speed throughout."""
    transit = asked_m_s if asked_m_s is not None else max(CRUISE_SPEED_M_S, speed_m_s)
    return None if transit == speed_m_s else transit


def choose_speed(camera: Camera, trigger_m: float, asked_m_s: float | None) -> tuple[float, str]:
    """The speed flown and where it came from (SPEED_SOURCES): the one asked, refused in one line when it asks
    the camera for photos sooner than its capture interval; else min(cruise speed, fastest) with an interval,
    the cruise speed without one."""
    interval = camera.capture_interval_s
    if interval is None:
        return (asked_m_s, "asked") if asked_m_s is not None else (CRUISE_SPEED_M_S, "cruise")
    fastest = fastest_speed_m_s(trigger_m, interval)
    if asked_m_s is None:
        return min(CRUISE_SPEED_M_S, fastest), "limit"
    if asked_m_s > fastest:
        raise GeoError(Named("{speed} {0} m/s asks {1} (a photo every {2} s at most) for one every {3} s: the "
                             "fastest allowed is {4} m/s", shown(asked_m_s), camera.label, shown(interval),
                             shown(trigger_m / asked_m_s), shown(fastest)))
    return asked_m_s, "asked"


@dataclass(frozen=True)
class CapturePlan:
    """One survey's capture: the camera, the height above the ground, the footprint side the plan's grid was
    drawn for (9 cells), the overlaps (fractions; side None: not asked, lanes one footprint apart), the
    speed flown and where it came from, the GSD the height was asked by (None: the height was given) and the
    speed of the ways out and home (None: the survey's speed throughout; choose_transit_speed)."""

    camera: Camera
    height_m: float
    footprint_m: float
    front_overlap: float
    side_overlap: float | None
    speed_m_s: float
    speed_from: str = "asked"  # SPEED_SOURCES
    gsd_asked_cm: float | None = None
    transit_speed_m_s: float | None = None
    gimbal_pitch_deg: float = NADIR_PITCH_DEG  # where the mission points the camera (plan --gimbal-pitch)

    @property
    def tilt_deg(self) -> float:
        """How far the camera looks from straight down, degrees (0: nadir)."""
        return self.gimbal_pitch_deg - NADIR_PITCH_DEG

    @property
    def gsd_cm(self) -> float | None:
        """The GSD at the height (None: the camera's sensor, image size or focal length is not known)."""
        return None if gsd_missing(self.camera) else gsd_cm(self.camera, self.height_m)

    @property
    def cell_m(self) -> float:
        return cell_of_footprint(self.footprint_m)

    @property
    def trigger_m(self) -> float:
        return trigger_distance_m(self.footprint_m, self.front_overlap)

    @property
    def lane_spacing_cells(self) -> int:
        return lane_spacing_cells(self.side_overlap)

    @property
    def lane_spacing_m(self) -> float:
        return self.lane_spacing_cells * self.cell_m

    @property
    def fastest_speed_m_s(self) -> float | None:
        """Trigger distance / capture interval (None: no capture interval known)."""
        interval = self.camera.capture_interval_s
        return None if interval is None else fastest_speed_m_s(self.trigger_m, interval)

    def rules(self) -> list[tuple[str, float, str, str]]:
        """(quantity, value, unit, rule) for every number the capture gives, in the order they follow."""
        camera = self.camera
        lines: list[tuple[str, float, str, str]] = []
        gsd = self.gsd_cm
        if self.gsd_asked_cm is not None:
            side, _, _ = _worse_side(camera)
            lines.append(("height", self.height_m, "m", f"from GSD {shown(self.gsd_asked_cm)} cm/px: H = GSD x f x "
                          f"image {side} / (100 x sensor {side})"))
        else:
            lines.append(("height", self.height_m, "m", "as asked, above the ground"))
            if gsd is not None:
                side, _, _ = _worse_side(camera)
                lines.append(("GSD", gsd, "cm/px", f"GSD = 100 x sensor {side} x H / (f x image {side}), the "
                              "worse of width and height"))
        if camera.sensor_width_mm is not None and camera.sensor_height_mm is not None:
            footprint_rule = "S = H x min(sensor width, height) / f: the narrower side's square"
        else:
            footprint_rule = f"S = 2 H tan(FOV / 2), FOV {shown(camera.fov_deg)} deg"
        lines += [("footprint", self.footprint_m, "m", footprint_rule)]
        lines += self._oblique_rules(gsd)
        lines += [
                  ("grid cell", self.cell_m, "m", "S / 9"),
                  ("trigger distance", self.trigger_m, "m",
                   f"S x (1 - front overlap {shown(100 * self.front_overlap)} %)")]
        cells = self.lane_spacing_cells
        if self.side_overlap is None:
            lanes = f"{cells} cells: one footprint, no side overlap asked (on open ground)"
        else:
            kept = 100 * (1.0 - cells / CELLS_PER_FOOTPRINT)
            lanes = (f"{cells} cells = floor(9 x (1 - side overlap {shown(100 * self.side_overlap)} %)), on open "
                     f"ground: side overlap {shown(kept)} % kept")
        lines.append(("lane spacing", self.lane_spacing_m, "m", lanes))
        fastest = self.fastest_speed_m_s
        if fastest is not None:
            lines.append(("fastest speed", fastest, "m/s",
                          f"trigger distance / capture interval {shown(camera.capture_interval_s or 0)} s"))
        speed_rule = {"asked": "as asked", "cruise": "the cruise speed",
                      "limit": f"min({shown(CRUISE_SPEED_M_S)} m/s, fastest speed): none asked"}[self.speed_from]
        lines.append(("speed", self.speed_m_s, "m/s", speed_rule))
        if self.transit_speed_m_s is not None:
            source = "cruise" if self.transit_speed_m_s == CRUISE_SPEED_M_S else "as asked"
            lines.append(("transit speed", self.transit_speed_m_s, "m/s",
                          f"{source}: the camera is off on the way out and home"))
        return lines

    def _oblique_rules(self, gsd: float | None) -> list[tuple[str, float, str, str]]:
        """An oblique camera: the photo's centre lies ahead of the drone, and its pixels cover more ground there.
        The grid and the overlaps keep the nadir footprint: what the planner covers is what a nadir camera sees."""
        tilt = self.tilt_deg
        if tilt == 0.0:
            return []
        t = math.radians(tilt)
        lines = [("camera pitch", self.gimbal_pitch_deg, "deg", f"--gimbal-pitch: {shown(tilt)} deg from straight down"),
                 ("photo centre ahead", self.height_m * math.tan(t), "m",
                  f"H x tan({shown(tilt)} deg): the grid, overlaps and coverage stay the nadir footprint's")]
        if gsd is not None:
            lines.append(("GSD at the photo centre", gsd / math.cos(t) ** 2, "cm/px",
                          f"GSD / cos^2({shown(tilt)} deg) along the tilt (GSD / cos across)"))
        return lines

    def rule_lines(self) -> list[str]:
        """The rules as a report prints them, e.g. `height 46.3 m  from GSD 1.2 cm/px: H = ...`."""
        return [f"{quantity} {shown(value)} {unit}  {rule}" for quantity, value, unit, rule in self.rules()]

    # ---- report.json's georeference `camera` block ------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The camera's fields, then the capture's numbers and its rules (height and footprint are the
        georeference's own altitude_m and footprint_m); the transit speed and the gimbal pitch only where they
        differ from the survey's speed and straight down."""
        optional: dict[str, float] = {}
        if self.transit_speed_m_s is not None:
            optional["transit_speed_m_s"] = self.transit_speed_m_s
        if self.gimbal_pitch_deg != NADIR_PITCH_DEG:
            optional["gimbal_pitch_deg"] = self.gimbal_pitch_deg
        return {**self.camera.to_json(), "gsd_cm": self.gsd_cm, "gsd_asked_cm": self.gsd_asked_cm,
                "front_overlap": self.front_overlap, "side_overlap": self.side_overlap,
                "lane_spacing_m": self.lane_spacing_m, "lane_spacing_cells": self.lane_spacing_cells,
                "speed_m_s": self.speed_m_s, "speed_from": self.speed_from,
                "fastest_speed_m_s": self.fastest_speed_m_s, **optional,
                "rules": [{"quantity": q, "value": v, "unit": u, "rule": r} for q, v, u, r in self.rules()]}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any], height_m: float, footprint_m: float) -> "CapturePlan":
        """The block to_json writes, for a plan at `height_m` with footprint `footprint_m` (its georeference's);
        the derived numbers and the rules follow from the rest."""
        speed_from = doc.get("speed_from", "asked")
        if speed_from not in SPEED_SOURCES:
            raise GeoError(f"camera block: speed_from {speed_from!r} is not one of {', '.join(SPEED_SOURCES)}")
        return cls(Camera.from_json(doc), float(height_m), float(footprint_m), float(doc["front_overlap"]),
                   None if doc.get("side_overlap") is None else float(doc["side_overlap"]), float(doc["speed_m_s"]),
                   speed_from, None if doc.get("gsd_asked_cm") is None else float(doc["gsd_asked_cm"]),
                   None if doc.get("transit_speed_m_s") is None else float(doc["transit_speed_m_s"]),
                   float(doc.get("gimbal_pitch_deg", NADIR_PITCH_DEG)))
