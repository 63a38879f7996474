"""KMZ for Google Earth of GeoJSON layers: a zip holding one doc.kml (KML 2.2).

One folder per layer, named by it, in the layers' order; one Placemark per feature, its properties
in ExtendedData/SchemaData typed by the layer's <Schema> (int / double / bool / string). The folder
is a nested <Document> rather than a <Folder>: Google Earth shows both alike in its Places tree, but
only a Document may hold a Schema, and GDAL's LIBKML driver (QGIS, ogr2ogr) finds a layer's schema
inside a .kmz only there; with Folders it reads the KMZ's properties as nothing. A feature with a
"uav" property takes that drone's colour (`colours`, else matplotlib's tab10 in uav order, as
plan.png draws the tracks); the others take their layer's colour. Points with a "label" property
show it on the map, other points only in the Places tree (thousands of photo labels hide the map).

Heights: positions with an altitude are drawn at it with altitudeMode relativeToGround (lines
and points: the flight paths, photo positions). The layers' altitudes are metres above the home /
launch point, the autopilots' relative frame; relativeToGround measures from the terrain under each
point instead. The two are equal on flat ground; where the ground under a point lies higher (lower)
than at the launch point, Google Earth draws the point that much higher (lower) than flown. A plan over a
DEM (`plan --dem`) gives heights above the ground under each point, which is what relativeToGround means. 2-D
shapes lie clampToGround (polygons filled, outlined); a polygon feature with a finite, positive
"height_m" (and no "known_height": false) is extruded from the ground to that height (buildings).

Same layers, same bytes: fixed zip timestamps and attributes, numbers written by repr. The file
is written beside the target and renamed over it only when complete.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import re
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Mapping, Sequence
from typing import Any

from missionplan.base.atomic import atomic_path

from .geojson_layers import geometry_positions, layer_schema

KML_NS = "http://www.opengis.net/kml/2.2"
TAB10 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
         "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
# Layers without a drone: matplotlib's Dark2, reordered to start apart from tab10's first colours
LAYER_COLOURS = ("#e6ab02", "#666666", "#a6761d", "#e7298a", "#1b9e77", "#7570b3", "#66a61e", "#d95f02")
SCHEMA_TYPES = {"bool": "bool", "int": "int", "float": "double", "str": "string"}
ICON = "http://maps.google.com/mapfiles/kml/shapes/shaded_dot.png"
FILL_ALPHA = "55"  # polygon fill, about a third opaque, so the map shows through
ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # the earliest a zip can hold: fixed, so output is reproducible


def write_kmz(path: str | os.PathLike[str], layers: Mapping[str, dict[str, Any]], title: str,
              colours: Mapping[int, str] | None = None) -> None:
    """Write `layers` (name -> GeoJSON FeatureCollection, EPSG:4326) as the KMZ `path`.

    `colours`: uav id -> "#rrggbb"; drones not named there take tab10's colour for their id
    (uav 1 blue, 2 orange, ...). ValueError for a colour not "#rrggbb", a geometry type other
    than (Multi)Point / LineString / Polygon or a non-finite coordinate.
    """
    document = _document(layers, title, colours or {})
    with atomic_path(path) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as kmz:
            entry = zipfile.ZipInfo("doc.kml", date_time=ZIP_TIME)
            entry.compress_type = zipfile.ZIP_DEFLATED
            entry.create_system = 3  # Unix, on every platform (the default depends on the one writing)
            entry.external_attr = 0o644 << 16
            kmz.writestr(entry, document)


def kml_colour(rgb: str, alpha: str = "ff") -> str:
    """KML's aabbggrr of "#rrggbb"."""
    if not re.fullmatch(r"#[0-9a-fA-F]{6}", rgb):
        raise ValueError(f"colour {rgb!r} is not #rrggbb")
    return (alpha + rgb[5:7] + rgb[3:5] + rgb[1:3]).lower()


def _document(layers: Mapping[str, dict[str, Any]], title: str, colours: Mapping[int, str]) -> bytes:
    root = ET.Element("kml", xmlns=KML_NS)
    doc = ET.SubElement(root, "Document")
    ET.SubElement(doc, "name").text = title
    styles: dict[str, str] = {}  # style id -> "#rrggbb", filled while the placemarks name them
    containers = []
    for index, (name, collection) in enumerate(layers.items()):
        schema_id = f"schema{index}"
        fields = layer_schema(collection).fields
        container = ET.Element("Document")
        ET.SubElement(container, "name").text = name
        if fields:
            schema = ET.SubElement(container, "Schema", name=name, id=schema_id)
            for key, kind in fields.items():
                ET.SubElement(schema, "SimpleField", name=key, type=SCHEMA_TYPES[kind])
        for number, feature in enumerate(collection.get("features") or [], start=1):
            props = feature.get("properties") or {}
            geometry = feature.get("geometry")
            placemark = ET.SubElement(container, "Placemark")
            ET.SubElement(placemark, "name").text = _placemark_name(name, number, props)
            ET.SubElement(placemark, "styleUrl").text = "#" + _style_id(index, geometry, props, colours, styles)
            if fields:
                data = ET.SubElement(ET.SubElement(placemark, "ExtendedData"), "SchemaData", schemaUrl="#" + schema_id)
                for key, kind in fields.items():
                    if props.get(key) is not None:  # null: no SimpleData, read back as null
                        ET.SubElement(data, "SimpleData", name=key).text = _text(props[key], kind)
            if geometry_positions(geometry):
                _geometry(placemark, geometry["type"], geometry["coordinates"], _extrusion(props))
        containers.append(container)
    for style_id, rgb in styles.items():
        _style(doc, style_id, rgb)
    doc.extend(containers)  # after the shared styles, as KML orders a Document's children
    ET.indent(root, space=" ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _placemark_name(layer: str, number: int, props: Mapping[str, Any]) -> str:
    """The feature's own label or name if it has one, else the layer, its drone and sortie / index."""
    for key in ("label", "name", "image"):
        if isinstance(props.get(key), str) and props[key]:
            return props[key]
    ids = [f"{key} {props[key]}" for key in ("uav", "sortie", "index")
           if isinstance(props.get(key), int) and not isinstance(props[key], bool)]
    return " ".join([layer] + ids) if ids else f"{layer} {number}"


def _style_id(layer_index: int, geometry: dict[str, Any] | None, props: Mapping[str, Any],
              colours: Mapping[int, str], styles: dict[str, str]) -> str:
    """The shared style of a placemark (registered in `styles`): its drone's or its layer's colour,
    with "-label" when it is a point showing its label on the map."""
    uav = props.get("uav")
    if isinstance(uav, int) and not isinstance(uav, bool):
        base, rgb = f"uav{uav}", colours.get(uav) or TAB10[(uav - 1) % len(TAB10)]
    else:
        base, rgb = f"layer{layer_index}", LAYER_COLOURS[layer_index % len(LAYER_COLOURS)]
    labelled = bool(geometry) and geometry.get("type") in ("Point", "MultiPoint") and bool(props.get("label"))
    style_id = base + ("-label" if labelled else "")
    kml_colour(rgb)  # a wrong colour fails here, before anything is written
    styles[style_id] = rgb
    return style_id


def _style(doc: ET.Element, style_id: str, rgb: str) -> None:
    style = ET.SubElement(doc, "Style", id=style_id)
    icon = ET.SubElement(style, "IconStyle")
    ET.SubElement(icon, "color").text = kml_colour(rgb)
    ET.SubElement(icon, "scale").text = "0.7"
    ET.SubElement(ET.SubElement(icon, "Icon"), "href").text = ICON
    ET.SubElement(ET.SubElement(style, "LabelStyle"), "scale").text = "1" if style_id.endswith("-label") else "0"
    line = ET.SubElement(style, "LineStyle")
    ET.SubElement(line, "color").text = kml_colour(rgb)
    ET.SubElement(line, "width").text = "2"
    poly = ET.SubElement(style, "PolyStyle")
    ET.SubElement(poly, "color").text = kml_colour(rgb, FILL_ALPHA)
    ET.SubElement(poly, "outline").text = "1"


def _text(value: Any, kind: str) -> str:
    if kind == "bool":
        return "1" if value else "0"
    if kind in ("int", "float"):
        return repr(int(value) if kind == "int" else float(value))
    return value if isinstance(value, str) else json.dumps(value)  # as missionplan.geo.gpkg writes it


def _extrusion(props: Mapping[str, Any]) -> float | None:
    """The height a polygon is extruded to: a finite, positive height_m not marked unknown."""
    height = props.get("height_m")
    if (isinstance(height, numbers.Real) and not isinstance(height, bool) and math.isfinite(height)
            and height > 0 and props.get("known_height") is not False):
        return float(height)
    return None


def _coordinates(positions: Sequence[Sequence[float]], altitude: float | None = None) -> str:
    """lon,lat[,alt] tuples; `altitude` replaces the positions' own (an extruded roof)."""
    out = []
    for p in positions:
        values = [float(v) for v in p[:3]] if altitude is None else [float(p[0]), float(p[1]), altitude]
        if not all(map(math.isfinite, values)):
            raise ValueError(f"non-finite coordinate {list(p)}")
        out.append(",".join(map(repr, values)))
    return " ".join(out)


def _geometry(parent: ET.Element, kind: str, coords: Any, extrude_to: float | None) -> None:
    if kind.startswith("Multi"):
        multi = ET.SubElement(parent, "MultiGeometry")
        for part in coords:
            _geometry(multi, kind.removeprefix("Multi"), part, extrude_to)
        return
    element = ET.SubElement(parent, kind)
    rings = coords if kind == "Polygon" else [[coords]] if kind == "Point" else [coords]
    has_z = any(len(p) >= 3 for ring in rings for p in ring)
    if kind == "Polygon" and extrude_to is not None:
        ET.SubElement(element, "extrude").text = "1"
        has_z = True
    elif kind != "Point" and not has_z:
        ET.SubElement(element, "tessellate").text = "1"  # follow the terrain between vertices
    ET.SubElement(element, "altitudeMode").text = "relativeToGround" if has_z else "clampToGround"
    if kind != "Polygon":
        ET.SubElement(element, "coordinates").text = _coordinates(rings[0])
        return
    for number, ring in enumerate(rings):
        boundary = ET.SubElement(element, "outerBoundaryIs" if number == 0 else "innerBoundaryIs")
        ET.SubElement(ET.SubElement(boundary, "LinearRing"), "coordinates").text = _coordinates(ring, extrude_to)
