"""KML (`.kml`) and KMZ (`.kmz`) polygons, read by our own parser (ElementTree).

Placemark Polygons (outerBoundaryIs / innerBoundaryIs), also inside MultiGeometry. A placemark's
properties are its `name`, `description`, every `<ExtendedData><Data name=..><value>` and every
`<SchemaData><SimpleData name=..>` (what GDAL's KML and LIBKML drivers, QGIS and Google Earth's
schemas write). Rings must be closed (the KML LinearRing repeats its first point) with at least 4
points, every coordinate a finite number: GDAL's LIBKML driver reads a coordinate 'x,y' as 0,0 and an
unclosed ring as closed, which is why these files are not handed to it.

Layers, as GDAL and QGIS show them: below the document's root (a lone Document or Folder wrapping
everything is looked through), each Folder or Document is a layer named by its `<name>`; placemarks
directly in the root are the layer named after the root (or the file). A KMZ is a zip holding a KML
(doc.kml, else its first .kml); a NetworkLink in it to another KML of the same archive (how LIBKML
writes one file per layer) adds that file's layers. Links out of the archive are not followed.

Hostile input: a DTD is refused (guards.refuse_dtd), a KMZ member is read only up to its declared,
bounded size (guards.member_bytes).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from shapely.geometry import MultiPolygon, Polygon

from .errors import GeoError
from .guards import member_bytes, open_zip, refuse_dtd
from .shapes import checked_polygon
from .sources import Feature, Omission, SourceFile, choose_layer

CONTAINERS = ("Document", "Folder")
NON_POLYGONS = ("Point", "LineString", "LinearRing", "Model", "Track")
MAX_LINKED_FILES = 256  # KML files followed through NetworkLinks inside one KMZ


def _local(tag: Any) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""  # drop the XML namespace (comments have no str tag)


def _children(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el if _local(c.tag) == name]


def _descendants(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el.iter() if _local(c.tag) == name]


def _name(el: ET.Element) -> str | None:
    found = _children(el, "name")
    return found[0].text.strip() if found and found[0].text and found[0].text.strip() else None


def _kml_ring(boundary: ET.Element, where: str) -> list[tuple[float, float]]:
    coords = _descendants(boundary, "coordinates")
    if not coords or not (coords[0].text or "").strip():
        raise GeoError(f"{where}: polygon boundary without coordinates")
    pts = []
    for token in coords[0].text.split():
        try:
            vals = [float(v) for v in token.split(",")]
        except ValueError:
            raise GeoError(f"{where}: bad coordinate {token[:40]!r}") from None
        if len(vals) < 2:
            raise GeoError(f"{where}: bad coordinate {token[:40]!r}")
        if not all(math.isfinite(v) for v in vals):
            raise GeoError(f"{where}: coordinate {token[:40]!r} is not finite numbers")
        pts.append((vals[0], vals[1]))
    if pts[0] != pts[-1]:
        # KML's LinearRing repeats its first point at the end; an open ring usually lost a vertex.
        raise GeoError(f"{where}: polygon ring is not closed (its first and last points differ)")
    if len(pts) < 4:
        raise GeoError(f"{where}: polygon ring has {len(pts)} points; a closed ring needs at least 4")
    return pts


def _properties(pm: ET.Element) -> dict[str, Any]:
    props: dict[str, Any] = {}
    for key in ("name", "description"):
        found = _children(pm, key)
        if found and found[0].text:
            props[key] = found[0].text.strip()
    for data in _descendants(pm, "Data"):
        val = _children(data, "value")
        props[data.get("name", "")] = val[0].text if val else None
    for data in _descendants(pm, "SimpleData"):
        props[data.get("name", "")] = data.text
    return props


@dataclass
class _Placemark:
    element: ET.Element
    layer: str
    ref: str  # "placemark 'yard'", "placemark 3"
    where: str  # "FILE: placemark 'yard'" / "FILE (layers/b.kml): placemark 3"


@dataclass
class _Document:
    """The placemarks of a KML (and of the KMLs its in-archive NetworkLinks name), by layer."""

    placemarks: list[_Placemark] = field(default_factory=list)
    layers: list[str] = field(default_factory=list)  # in document order
    counter: int = 0  # placemarks numbered through the whole document, as the messages name them


def _parse(data: bytes, where: str) -> ET.Element:
    refuse_dtd(data, where, "KML")
    try:
        return ET.fromstring(data)
    except (ET.ParseError, ValueError) as err:
        raise GeoError(f"{where}: cannot read KML ({err})") from None


def _top(root: ET.Element) -> ET.Element:
    """The element whose containers are the layers: the root, looked through while it is a lone
    container holding nothing but one container (Google Earth wraps everything in a Document)."""
    top = root
    while True:
        containers = [c for c in top if _local(c.tag) in CONTAINERS]
        if len(containers) != 1 or _children(top, "Placemark") or _children(top, "NetworkLink"):
            return top
        top = containers[0]


class _Reader:
    """Walks a KML (and, in a KMZ, the KMLs it links to) collecting placemarks by layer."""

    def __init__(self, label: str, default_layer: str, archive: zipfile.ZipFile | None) -> None:
        self.label = label  # the file as messages name it
        self.default_layer = default_layer
        self.archive = archive
        self.doc = _Document()
        self.followed: set[str] = set()

    def read(self, root: ET.Element, member: str | None) -> None:
        top = _top(root)
        root_layer = _name(top) or self.default_layer
        self._walk(top, root_layer, member, at_top=True)

    def _walk(self, el: ET.Element, layer: str, member: str | None, at_top: bool) -> None:
        for child in el:
            tag = _local(child.tag)
            if tag == "Placemark":
                self._placemark(child, layer, member)
            elif tag in CONTAINERS:
                self._walk(child, (_name(child) or f"{tag.lower()} {len(self.doc.layers) + 1}") if at_top else layer,
                           member, at_top=False)
            elif tag == "NetworkLink":
                self._link(child, member)

    def _placemark(self, pm: ET.Element, layer: str, member: str | None) -> None:
        name = _name(pm)
        label = f"placemark {name!r}" if name is not None else f"placemark {self.doc.counter}"
        where = f"{self.label} ({member}): {label}" if member else f"{self.label}: {label}"
        self.doc.counter += 1
        if layer not in self.doc.layers:
            self.doc.layers.append(layer)
        self.doc.placemarks.append(_Placemark(pm, layer, label, where))

    def _link(self, link: ET.Element, member: str | None) -> None:
        """A NetworkLink to another KML in the same KMZ: read it in place. Others are not followed."""
        if self.archive is None:
            return
        hrefs = [h.text.strip() for h in _descendants(link, "href") if h.text and h.text.strip()]
        if not hrefs:
            return
        base = PurePosixPath(member).parent if member else PurePosixPath(".")
        target = (base / hrefs[0]).as_posix()
        if "://" in hrefs[0] or hrefs[0].startswith("/") or ".." in PurePosixPath(target).parts:
            return  # out of the archive
        target = target.removeprefix("./")
        try:
            info = self.archive.getinfo(target)
        except KeyError:
            return
        if target in self.followed or len(self.followed) >= MAX_LINKED_FILES:
            return
        self.followed.add(target)
        where = f"{self.label} ({target})"
        self.read(_parse(member_bytes(self.archive, info, self.label), where), target)


def _polygons(placemark: _Placemark) -> Polygon | MultiPolygon | None:
    where = placemark.where
    polys = []
    for pg in _descendants(placemark.element, "Polygon"):
        outer = _children(pg, "outerBoundaryIs")
        if not outer:
            raise GeoError(f"{where}: Polygon without outerBoundaryIs")
        holes = [_kml_ring(b, where) for b in _children(pg, "innerBoundaryIs")]
        polys.append(Polygon(_kml_ring(outer[0], where), holes))
    if not polys:
        return None
    return polys[0] if len(polys) == 1 else MultiPolygon(polys)


def _has_polygon(placemark: _Placemark) -> bool:
    return any(_local(c.tag) == "Polygon" for c in placemark.element.iter())


def _features(doc: _Document, label: str, layer: str | None, fmt: str) -> tuple[list[Feature], SourceFile]:
    polygon_layers = [name for name in doc.layers if any(p.layer == name and _has_polygon(p) for p in doc.placemarks)]
    chosen = choose_layer(label, doc.layers, polygon_layers, layer)
    out: list[Feature] = []
    for placemark in doc.placemarks:
        if chosen is not None and placemark.layer != chosen:
            continue
        geom = _polygons(placemark)
        if geom is None:
            others = {_local(c.tag) for c in placemark.element.iter()} & set(NON_POLYGONS)
            if others:
                raise GeoError(f"{placemark.where}: not a polygon ({sorted(others)[0]})")
            continue
        checked, repaired = checked_polygon(geom, placemark.where)
        out.append(Feature(checked, _properties(placemark.element), placemark.ref, repaired))
    if not out:
        raise GeoError(f"{label}: no polygon found")
    source = SourceFile(label, fmt, "missionplan", layer=chosen if len(doc.layers) > 1 or layer else None,
                        features=len(out))
    source.repaired = [Omission(f.ref, f.repaired) for f in out if f.repaired]
    return out, source


def read_kml(path: Path, layer: str | None = None) -> tuple[list[Feature], SourceFile]:
    """Every polygon of a KML file (of one layer), with its properties, and how the file was read."""
    try:
        data = path.read_bytes()
    except OSError as err:
        raise GeoError(f"{path}: cannot read KML ({err.strerror or err})") from None
    reader = _Reader(str(path), path.stem, None)
    reader.read(_parse(data, str(path)), None)
    return _features(reader.doc, str(path), layer, "KML")


def _main_document(archive: zipfile.ZipFile, path: Path) -> zipfile.ZipInfo:
    """doc.kml, else the first .kml in the archive (the KMZ convention)."""
    kml = [info for info in archive.infolist() if info.filename.lower().endswith(".kml") and not info.is_dir()]
    for info in kml:
        if info.filename == "doc.kml":
            return info
    if not kml:
        raise GeoError(f"{path}: a KMZ holds a .kml document, this archive holds none")
    return kml[0]


def read_kmz(path: Path, layer: str | None = None) -> tuple[list[Feature], SourceFile]:
    """Every polygon of a KMZ (of one layer), its in-archive linked KMLs included."""
    with open_zip(path, "KMZ") as archive:
        main = _main_document(archive, path)
        reader = _Reader(str(path), path.stem, archive)
        reader.followed.add(main.filename)
        member = main.filename if main.filename != "doc.kml" else None
        where = f"{path} ({main.filename})" if member else str(path)
        reader.read(_parse(member_bytes(archive, main, str(path)), where), member)
    return _features(reader.doc, str(path), layer, "KMZ")
