"""`Georeference`: where a planning grid lies on the Earth and how it is photographed, as one typed value.

It holds the grid's frame (GridFrame: UTM zone, origin, cell, rotation, size), the flight altitude, the
camera the cell was sized for, the margin under the altitude that an area's buildings were overflown
with and, in a plan, the distance flown between photos. The footprint is never stored apart from the
cell: it is camera.footprint_of_cell(cell), the one rule.

It has two spellings on disk, both written and read here and nowhere else:
* a .map file's header lines (`to_header` / `from_header`): the frame as GridFrame.to_meta spells it
  (a shipped or hand-written map may give only origin_lat / origin_lon, cell_m and rotation_deg), then
  altitude_m, fov_deg and safety_margin_m; a map without origin_lat / origin_lon has no georeference;
* report.json's `georeference` block (`to_json` / `from_json`): the frame's strings, then altitude_m,
  footprint_m and trigger_distance_m as numbers.

A plan made over a DEM (`plan --dem`) carries `terrain` (TerrainRecord): the ground under the plan as the
plan folder keeps it (a GeoTIFF of heights above sea level beside report.json, which fly, the mock and the
judge read) and where it came from. Its altitude is then a height above the ground under the drone, not
above the launch point. It is written in report.json only (a .map file has no ground), and only when
there is one, so a plan over flat ground is written as before.

A plan made from a camera, a GSD or overlaps (`plan --camera`, `--gsd`, `--front-overlap`, ...) carries
`capture` (geo.capture.CapturePlan): report.json's `camera` block holds the camera's fields, the GSD, the
overlaps, the lane spacing, the speeds and the rules that gave them; written only when there is one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .camera import Camera, footprint_of_cell
from .capture import CapturePlan
from .frame import GridFrame, header_float

# The .map header keys a georeference is written to and read from (GridFrame.to_meta's, then the flight's).
FRAME_KEYS = ("utm_epsg", "origin_e", "origin_n", "cell_m", "rotation_deg", "grid_rows", "grid_cols",
              "origin_lat", "origin_lon")
HEADER_KEYS = (*FRAME_KEYS, "altitude_m", "fov_deg", "safety_margin_m")


@dataclass(frozen=True)
class TerrainRecord:
    """The ground a plan was made over: the plan folder's copies of it, the DEM files it was read from, their
    CRSs and coarsest pixel, and the range of its heights under the area (metres above sea level, as the
    DEM gives them)."""

    files: tuple[str, ...]  # in the plan folder: the ground the plan used (dem_copy), served by fly, judged against
    sources: tuple[str, ...]
    crs: tuple[str, ...]
    resolution_m: float
    lowest_m: float
    highest_m: float
    # ArduPilot's TERRAIN_SPACING (m) at which its terrain following was checked to hold the plan's heights; upload
    # and fly set it (None: a PX4 plan, whose altitudes are above sea level).
    spacing_m: int | None = None

    def to_json(self) -> dict[str, Any]:
        return {"files": list(self.files), "sources": list(self.sources), "crs": list(self.crs),
                "resolution_m": self.resolution_m, "lowest_m": self.lowest_m, "highest_m": self.highest_m,
                "spacing_m": self.spacing_m}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> "TerrainRecord":
        return cls(tuple(doc["files"]), tuple(doc["sources"]), tuple(doc["crs"]), float(doc["resolution_m"]),
                   float(doc["lowest_m"]), float(doc["highest_m"]), doc.get("spacing_m"))


@dataclass(frozen=True)
class Georeference:
    """A grid on the Earth: its frame, and the altitude and camera it is photographed from."""

    frame: GridFrame
    # flight altitude above the launch points, or above the ground under the drone with `terrain` (None: the
    # map leaves it to the crew)
    altitude_m: float | None = None
    camera: Camera | None = None  # the camera the cell was sized for (None: not recorded, e.g. in a plan report)
    safety_margin_m: float | None = None  # an area's buildings this far under the altitude are obstacles
    trigger_distance_m: float | None = None  # a plan's distance between photos along a track (None: no plan yet)
    terrain: TerrainRecord | None = None  # the ground a plan was made over (None: taken as flat)
    capture: CapturePlan | None = None  # the camera, GSD and overlaps a plan was asked for (None: not asked)

    @property
    def cell_m(self) -> float:
        return self.frame.cell_m

    @property
    def footprint_m(self) -> float:
        """The photo footprint's side on the ground: 9 cells (camera.footprint_of_cell)."""
        return footprint_of_cell(self.frame.cell_m)

    # ---- a .map file's header lines -----------------------------------------------------
    def to_header(self) -> dict[str, str]:
        """The header lines of a map with this georeference (repr keeps floats exact through a .map file)."""
        lines = self.frame.to_meta()
        if self.altitude_m is not None:
            lines["altitude_m"] = repr(float(self.altitude_m))
        if self.camera is not None:
            lines["fov_deg"] = repr(float(self.camera.fov_deg))
        if self.safety_margin_m is not None:
            lines["safety_margin_m"] = repr(float(self.safety_margin_m))
        return lines

    @classmethod
    def from_header(cls, header: Mapping[str, str], rows: int, cols: int) -> "Georeference | None":
        """The georeference a map's header lines give for its rows x cols grid; None without an origin
        (origin_lat and origin_lon). GeoError naming the key when a value is not a number."""
        if "origin_lat" not in header or "origin_lon" not in header:
            return None
        frame = GridFrame.from_meta(header, rows, cols)
        altitude = header_float(header, "altitude_m") if "altitude_m" in header else None
        camera = Camera(header_float(header, "fov_deg")) if "fov_deg" in header else None
        margin = header_float(header, "safety_margin_m") if "safety_margin_m" in header else None
        return cls(frame, altitude, camera, margin)

    # ---- report.json's `georeference` block ---------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """report.json's `georeference`: the frame's strings, the altitude, footprint and trigger distance, and
        the terrain and the camera block when there are."""
        doc: dict[str, Any] = {**self.frame.to_meta(), "altitude_m": self.altitude_m, "footprint_m": self.footprint_m,
                               "trigger_distance_m": self.trigger_distance_m}
        if self.terrain is not None:
            doc["terrain"] = self.terrain.to_json()
        if self.capture is not None:
            doc["camera"] = self.capture.to_json()
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any], rows: int, cols: int) -> "Georeference":
        """The block to_json writes, on a rows x cols grid (the plan's grid gives the size)."""
        frame = GridFrame.from_meta({key: str(value) for key, value in doc.items() if key not in ("terrain", "camera")},
                                    rows, cols)
        terrain = TerrainRecord.from_json(doc["terrain"]) if doc.get("terrain") is not None else None
        capture = None
        if doc.get("camera") is not None:
            capture = CapturePlan.from_json(doc["camera"], doc["altitude_m"], footprint_of_cell(frame.cell_m))
        return cls(frame, altitude_m=doc.get("altitude_m"), trigger_distance_m=doc.get("trigger_distance_m"),
                   terrain=terrain, capture=capture)
