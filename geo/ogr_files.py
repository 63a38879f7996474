"""GIS files read through GDAL (pyogrio): GeoPackage, Shapefile (or a .zip holding one), FlatGeobuf, GML.

`read_ogr(path, ext, layer)` gives every polygon of one layer with its fields as properties, in WGS84
lon/lat (reprojected with pyproj when the layer is in another CRS, crs.py), each checked like any
other polygon (shapes.py) and named by GDAL's feature id (FID), the id QGIS shows.

Layers: a file with one polygon layer reads it; a file with several takes `FILE:LAYER` and, without
one, is refused in one line listing them. Non-spatial tables and point or line layers are not
polygon layers; a layer of "Unknown" geometry type (GML without a schema) counts as one.

Before GDAL opens a file: its first bytes must be the format's (a GeoPackage is SQLite, a
FlatGeobuf starts "fgb", a Shapefile with the code 9994, a GML is XML), so GDAL never picks another
driver for a renamed file; a GML's DTD is refused (guards.py); a .zip is never handed to GDAL
(its /vsizip/ reads past a member's declared size): the Shapefile is extracted, bounded, into a
temporary folder. The GML driver is told not to write a .gfs file beside the input.
"""

from __future__ import annotations

import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from .crs import crs_label, source_crs, to_lonlat
from .errors import GeoError
from .guards import extract, open_zip, refuse_dtd_in_file
from .shapes import check_polygons, union
from .sources import Feature, Omission, SourceFile, choose_layer, feature_ref


@dataclass(frozen=True)
class OgrFormat:
    name: str  # as the report names it
    driver: str  # GDAL's driver
    magic: tuple[bytes, ...]  # what the file starts with (after XML's byte-order mark / whitespace)
    open_options: tuple[tuple[str, str], ...] = ()


SHAPEFILE = OgrFormat("Shapefile", "ESRI Shapefile", (b"\x00\x00\x27\x0a",))  # file code 9994, big-endian
FORMATS = {
    ".gpkg": OgrFormat("GeoPackage", "GPKG", (b"SQLite format 3\x00",)),
    ".shp": SHAPEFILE,
    ".fgb": OgrFormat("FlatGeobuf", "FlatGeobuf", (b"fgb",)),
    ".gml": OgrFormat("GML", "GML", (b"<",), (("WRITE_GFS", "NO"),)),
}
ZIP_EXT = ".zip"
SHAPEFILE_SIBLINGS = (".shp", ".shx", ".dbf", ".prj", ".cpg")
_POLYGON_WORDS = ("Polygon", "Surface")
_MAYBE_POLYGON = ("Unknown", "Geometry", "GeometryCollection")


def _first_bytes(path: Path, count: int) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(count)
    except OSError as err:
        raise GeoError(f"{path}: cannot read ({err.strerror or err})") from None


def _check_signature(path: Path, fmt: OgrFormat, label: str) -> None:
    head = _first_bytes(path, 64)
    if fmt.name == "GML":
        head = head.removeprefix(b"\xef\xbb\xbf").lstrip()
        if not (head.startswith(b"<") or head.startswith((b"\xff\xfe", b"\xfe\xff"))):
            raise GeoError(f"{label}: not GML (not XML)")
        refuse_dtd_in_file(path, label, "GML")
        return
    if not head.startswith(fmt.magic):
        raise GeoError(f"{label}: not a {fmt.name} (it does not start as a {fmt.name} does)")


def _gdal_errors(err: Exception) -> str:
    """GDAL's message, first line, at most 300 characters (it may quote a whole SQL statement)."""
    text = str(err).strip().splitlines()
    first = text[0] if text else type(err).__name__
    return first if len(first) <= 300 else first[:297] + "..."


def _polygon_layers(layers: np.ndarray) -> list[str]:
    return [str(name) for name, geom_type in layers
            if geom_type is not None and (any(word in str(geom_type) for word in _POLYGON_WORDS)
                                          or str(geom_type) in _MAYBE_POLYGON)]


def _choose_layer(path: Path, label: str, fmt: OgrFormat, layer: str | None) -> tuple[str, bool]:
    """The layer to read and whether the file has several."""
    import pyogrio

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            layers = pyogrio.list_layers(path)
    except (RuntimeError, OSError, ValueError) as err:
        raise GeoError(f"{label}: cannot read it as {fmt.name} ({_gdal_errors(err)})") from None
    names = [str(name) for name, _ in layers]
    polygons = _polygon_layers(layers)
    if layer is None and not polygons:
        listed = ", ".join(f"{name} ({geom_type or 'no geometry'})" for name, geom_type in layers) or "none"
        raise GeoError(f"{label}: no layer of polygons (its layers: {listed})")
    chosen = choose_layer(label, names, polygons, layer)
    assert chosen is not None  # a layer asked for is one of names; else polygons is not empty
    return chosen, len(names) > 1


def _properties(fields: list[str], columns: list[np.ndarray], count: int) -> list[dict[str, Any]]:
    """One dict per feature, values as Python scalars (numpy's NaN for a null float stays NaN: no height)."""
    values = [column.tolist() for column in columns]
    return [{name: col[i] for name, col in zip(fields, values)} for i in range(count)]


def _geometries(wkb: np.ndarray, refs: list[str], label: str) -> list[shapely.Geometry | None]:
    """shapely geometries of GDAL's WKB; a null geometry is dropped (named), a WKB shapely cannot read
    (an unclosed ring, a curve) is an error naming the feature."""
    with np.errstate(invalid="ignore"):  # a NaN coordinate: refused below, not warned about on stderr
        geoms = shapely.from_wkb(wkb, on_invalid="ignore")
    out: list[shapely.Geometry | None] = []
    for i, (raw, geom) in enumerate(zip(wkb, geoms)):
        if geom is None and raw is not None:
            try:
                shapely.from_wkb(raw)
            except Exception as err:  # shapely / GEOS: several types
                raise GeoError(f"{label}: {refs[i]}: malformed geometry ({_gdal_errors(err)})") from None
        if geom is not None and geom.geom_type == "GeometryCollection":
            parts = [p for p in geom.geoms if not p.is_empty]
            if parts and all(isinstance(p, (Polygon, MultiPolygon)) for p in parts):
                geom = union(parts, f"{label}: {refs[i]}")
        out.append(geom)
    return out


def read_layer(path: Path, label: str, fmt: OgrFormat, layer: str | None) -> tuple[list[Feature], SourceFile]:
    """Every polygon of one layer of `path` (`label` names it in messages), read through GDAL as `fmt`."""
    import pyogrio.raw

    if "!" in str(path):
        raise GeoError(f"{label}: a file name with '!' cannot go through GDAL (pyogrio reads '!' as an archive "
                       f"separator); rename the file")
    _check_signature(path, fmt, label)
    name, several = _choose_layer(path, label, fmt, layer)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # GDAL's warnings come as Python warnings: not printed, its errors raise
            meta, fids, wkb, columns = pyogrio.raw.read(path, layer=name, return_fids=True, force_2d=True,
                                                        **dict(fmt.open_options))
    except (RuntimeError, OSError, ValueError) as err:
        raise GeoError(f"{label}: cannot read it as {fmt.name} ({_gdal_errors(err)})") from None
    source = SourceFile(label, fmt.name, f"GDAL {fmt.driver}", layer=name if several or layer else None)
    where = f"{label}: layer {name}" if several else label
    if wkb is None or not len(wkb):
        raise GeoError(f"{where}: no polygon found")
    places = [f"feature {int(fid)}" for fid in fids] if fids is not None else [f"feature {i}" for i in range(len(wkb))]
    geoms = _geometries(wkb, places, where)
    properties = _properties([str(f) for f in meta["fields"]], columns, len(wkb))
    refs = [feature_ref(place, props) for place, props in zip(places, properties)]
    if meta.get("crs"):
        crs = source_crs(meta["crs"], where)
        if crs is not None:
            geoms, source.crs, source.reprojected = to_lonlat(geoms, crs, where), crs_label(crs), True
    else:
        source.crs = "none in the file: taken as WGS84 lon/lat"
    keep = [i for i, g in enumerate(geoms) if g is not None]
    source.dropped = [Omission(refs[i], "no geometry (null)") for i, g in enumerate(geoms) if g is None]
    checked, repaired = check_polygons([geoms[i] for i in keep], lambda j: f"{where}: {places[keep[j]]}")
    out = [Feature(g, properties[i], refs[i], repaired.get(j)) for j, (i, g) in enumerate(zip(keep, checked))]
    if not out:
        raise GeoError(f"{where}: no polygon found")
    source.repaired = [Omission(f.ref, f.repaired) for f in out if f.repaired]
    source.features = len(out)
    return out, source


def _read_zipped_shapefile(path: Path, layer: str | None) -> tuple[list[Feature], SourceFile]:
    """The Shapefile a .zip holds (one, or the one named LAYER), extracted bounded and read."""
    with open_zip(path, "zip") as archive:
        infos = [info for info in archive.infolist() if not info.is_dir()]
        shapefiles = {Path(info.filename).stem: info for info in infos if info.filename.lower().endswith(".shp")}
        if not shapefiles:
            raise GeoError(f"{path}: the zip holds no Shapefile (.shp)")
        chosen = choose_layer(str(path), list(shapefiles), list(shapefiles), layer, kind="Shapefiles",
                              listed_as="Shapefiles")
        assert chosen is not None  # the zip holds at least one
        shp = shapefiles[chosen]
        stem = shp.filename[:-4]
        members = [info for info in infos if info.filename[:-4] == stem and info.filename[-4:].lower() in SHAPEFILE_SIBLINGS]
        with tempfile.TemporaryDirectory(prefix="missionplan-zip-") as folder:
            extracted = extract(archive, members, Path(folder), str(path))
            shp_path = next(p for p in extracted if p.suffix.lower() == ".shp")
            features, source = read_layer(shp_path, f"{path} ({shp.filename})", SHAPEFILE, None)
    source.path, source.format = str(path), "Shapefile in a zip"
    source.layer = chosen if len(shapefiles) > 1 or layer else None
    return features, source


def read_ogr(path: Path, ext: str, layer: str | None = None) -> tuple[list[Feature], SourceFile]:
    """Every polygon of one layer of a GDAL-read file (`ext`: a key of FORMATS, or ".zip")."""
    if ext == ZIP_EXT:
        return _read_zipped_shapefile(path, layer)
    fmt = FORMATS[ext]
    if fmt is SHAPEFILE and layer is not None and layer != path.stem:
        raise GeoError(f"{path}: no layer {layer!r} (a Shapefile is one layer, {path.stem})")
    return read_layer(path, str(path), fmt, None if fmt is SHAPEFILE else layer)
