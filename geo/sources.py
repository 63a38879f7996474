"""What the readers return: the shapes of a file and the record of how the file was read.

* `Feature`: one polygonal shape, its properties and its name in the file (`ref`: "feature 3",
  "placemark 'yard'", "way 42"), with why its geometry was repaired when it was.
* `Building`: a footprint with its height (None: unknown).
* `Omission`: a feature left out of what was read, or repaired, with its name and the cause.
* `SourceFile`: one file read: its path, format, the reader and driver, the layer, the CRS it was in
  and whether it was reprojected, how many features it gave, and what was dropped or repaired.
  `plan` lists these in report.json (`inputs`) and names what was dropped in a warning.
* `feature_ref`: a feature's name for a crew: its place in the file, and the id its data gives
  (an OpenStreetMap way, a GeoJSON id) when it gives one.
* `choose_layer`: which layer of a file with several is read (`FILE:LAYER`), the one rule every
  layered format follows.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from shapely.geometry import MultiPolygon, Polygon

from .errors import GeoError

Polygonal = Polygon | MultiPolygon
WGS84 = "EPSG:4326 (WGS 84 lon/lat)"


@dataclass
class Feature:
    """One polygonal shape and the properties that came with it (may be empty)."""

    geometry: Polygonal
    properties: dict[str, Any] = field(default_factory=dict)
    ref: str = ""  # its name in the file, for messages: "feature 3", "placemark 'yard'", "way 42"
    repaired: str | None = None  # why make_valid repaired it (GEOS's explanation), None when it was valid


@dataclass
class Building:
    """A building footprint; `height_m` None when the data does not say."""

    geometry: Polygonal
    height_m: float | None
    properties: dict[str, Any] = field(default_factory=dict)
    ref: str = ""  # its name in the file: "way 42", "relation 7", "feature 3"
    repaired: str | None = None


@dataclass(frozen=True)
class Omission:
    """A feature dropped from what a file gave (or repaired), named as the file names it, and why."""

    ref: str
    cause: str

    def to_json(self) -> dict[str, str]:
        return {"id": self.ref, "cause": self.cause}

    @classmethod
    def from_json(cls, doc: Mapping[str, str]) -> "Omission":
        return cls(doc["id"], doc["cause"])


@dataclass
class SourceFile:
    """How one file was read (report.json `inputs`)."""

    path: str
    format: str  # "GeoJSON", "KML", "GeoPackage", "OpenStreetMap PBF", ...
    reader: str  # "missionplan" (own parser), "GDAL GPKG" (pyogrio), "pyosmium"
    layer: str | None = None
    crs: str = WGS84
    reprojected: bool = False
    features: int = 0  # polygonal features taken from the file (buildings: footprints read)
    dropped: list[Omission] = field(default_factory=list)
    repaired: list[Omission] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # e.g. "ids renumbered for reading: negative node ids"

    def to_json(self) -> dict[str, Any]:
        return {"path": self.path, "format": self.format, "reader": self.reader, "layer": self.layer,
                "crs": self.crs, "reprojected": self.reprojected, "features": self.features,
                "dropped": [o.to_json() for o in self.dropped], "repaired": [o.to_json() for o in self.repaired],
                "notes": list(self.notes)}


def choose_layer(label: str, names: list[str], polygon_layers: list[str], asked: str | None,
                 kind: str = "layers of polygons", listed_as: str = "layers") -> str | None:
    """The layer of a file to read: the one asked for (`FILE:LAYER`; it must be one of `names`), else its
    only layer of polygons (None when it has none); a file with several and none asked is refused in one
    line listing them. `kind` and `listed_as` name the layers in the messages ("Shapefiles" of a zip)."""
    if asked is not None:
        if asked not in names:
            raise GeoError(f"{label}: no layer {asked!r} (its {listed_as}: {', '.join(names) or 'none'})")
        return asked
    if len(polygon_layers) > 1:
        raise GeoError(f"{label} holds {len(polygon_layers)} {kind}: {', '.join(polygon_layers)}; "
                       f"name one as {label}:LAYER")
    return polygon_layers[0] if polygon_layers else None


MAX_ID_CHARS = 60  # an id is shown whole up to this; a longer one is no name a crew can search for


def _id_text(value: Any) -> str | None:
    if isinstance(value, bool) or not isinstance(value, (int, str)) or value == "":
        return None
    text = str(value)
    return text if len(text) <= MAX_ID_CHARS else text[:MAX_ID_CHARS] + "..."


def feature_ref(place: str, properties: Mapping[str, Any], own_id: Any = None) -> str:
    """`place` ("feature 3"), followed by the id the feature's data gives, so a crew can find it in the
    source they edit: the GeoJSON feature's own `id`, an Overpass export's `@id` ("way/42"), or an
    OpenStreetMap id (`osm_id` / `osmid`, with `osm_type` / `element_type` when given): "feature 3 [way 42]"."""
    shown = _id_text(own_id)
    if shown is not None:
        return f"{place} [id {shown}]"
    shown = _id_text(properties.get("@id"))
    if shown is not None:
        return f"{place} [{shown}]"
    osm = next((text for key in ("osm_id", "osmid") if (text := _id_text(properties.get(key))) is not None), None)
    if osm is not None:
        kind = next((v for key in ("osm_type", "element_type") if isinstance(v := properties.get(key), str) and v), None)
        return f"{place} [{kind[:20]} {osm}]" if kind else f"{place} [OSM id {osm}]"
    return place
