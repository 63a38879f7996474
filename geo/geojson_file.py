"""GeoJSON (`.geojson`, `.json`) polygons, read by our own parser.

A FeatureCollection, a Feature or a bare geometry; Polygon and MultiPolygon (holes kept), or a
GeometryCollection of them; feature properties come with each shape. The file is checked as RFC 7946
writes it, each fault named by feature index and cause: `features` not a list, a feature, `geometry` or
`properties` that is not an object (`null` geometry is allowed: that feature is listed as dropped, it has
no shape), coordinates that are not nested lists of [lon, lat(, alt)] numbers, rings not closed or of
fewer than 4 positions, NaN or infinite numbers. A legacy (2008) `crs` member other than WGS84 is
honoured: the coordinates are reprojected (crs.py).

Why not GDAL's GeoJSON driver: it skips a malformed feature without a word (a feature that is not an
object, a `type` that is not "Feature", coordinates it cannot read), and "nothing dropped without a
name" is the rule here. It is faster and leaner on a city-wide file (bench/read_bench.py), so this reader
does its work in bulk: one json.loads, cheap per-ring checks in C-level loops, the geometries built and
checked as arrays (shapes.check_polygons).
"""

from __future__ import annotations

import json
import math
from itertools import chain
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon, shape

from .crs import crs_label, source_crs, to_lonlat
from .errors import GeoError
from .shapes import check_lonlat, check_polygons, union
from .sources import Feature, Omission, SourceFile, feature_ref


def load_json(path: Path) -> Any:
    """The JSON document of `path`; GeoError for a file that is not UTF-8 JSON."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise GeoError(f"{path}: cannot read JSON ({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None


def kind(value: Any) -> str:
    """A JSON value's type as a user reads it, for 'is not a list (it is a string)'-style messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "an object"


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite(value: int | float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # a JSON integer too large for a float
        return False


def check_positions(points: Any, not_numbers: str, position: str) -> None:
    """GeoError unless `points` is a list of 2- or 3-number lists, all finite (GeoJSON rings and
    .plan polygons alike): `not_numbers` is the message for the shape, `position` prefixes a bad one.

    The common case runs in C-level loops (map, set, sum); only a ring that fails them is looked at
    position by position, for the message."""
    if not isinstance(points, list):
        raise GeoError(not_numbers)
    if points:
        if set(map(type, points)) != {list} or not set(map(len, points)) <= {2, 3}:
            raise GeoError(not_numbers)
        values = list(chain.from_iterable(points))
        if not set(map(type, values)) <= {int, float}:
            raise GeoError(not_numbers)
        try:
            all_finite = math.isfinite(sum(values))  # inf or nan anywhere makes the sum so (or a large sum: looked at below)
        except OverflowError:
            all_finite = False
        if all_finite:
            return
    for p in points:
        if not all(_finite(v) for v in p):
            raise GeoError(f"{position} {p} is not finite numbers")


_CHUNK_POSITIONS = 1 << 18  # positions made into one numpy array at a time: the JSON's lists are freed as it goes
_EMPTY = {False: Polygon(), True: MultiPolygon()}


def _ring_messages(where: str, geom_type: str, k: int) -> tuple[str, str]:
    label = "outer ring" if k == 0 else f"hole {k}"
    return (f"{where}: {geom_type} {label}: positions are not [lon, lat] number pairs",
            f"{where}: {geom_type} {label}: position")


def _rings(geom: dict[str, Any], where: str) -> list[list[list[Any]]]:
    """The rings of each polygon of a Polygon / MultiPolygon geometry object, their shape checked here
    and their numbers by the builder, in bulk (`check_positions` looks at a ring alone only to name a fault).

    RFC 7946 polygon rings: lists of [lon, lat(, alt)] numbers, closed, at least 4 positions.
    shapely would close an open ring silently, so a 3-point sketch would pass as a triangle; the
    format says a ring is closed, and an open one usually means a vertex was lost.
    """
    geom_type = geom["type"]
    coords = geom.get("coordinates")
    polygons = [coords] if geom_type == "Polygon" else coords
    if not isinstance(polygons, list) or not all(isinstance(rings, list) for rings in polygons):
        raise GeoError(f"{where}: {geom_type} coordinates are not nested lists of [lon, lat] positions")
    for rings in polygons:
        for k, ring in enumerate(rings):
            closed = isinstance(ring, list) and (not ring or ring[0] == ring[-1])
            if not closed or len(ring) < 4:
                check_positions(ring, *_ring_messages(where, geom_type, k))  # a bad number is named first
                label = "outer ring" if k == 0 else f"hole {k}"
                if not closed:
                    raise GeoError(f"{where}: {geom_type} {label} is not closed (its first and last positions "
                                   f"differ); GeoJSON rings repeat the first position at the end")
                raise GeoError(f"{where}: {geom_type} {label} has {len(ring)} positions; a closed ring needs at least 4")
    return polygons


def _check_collection_rings(geom: dict[str, Any], where: str) -> None:
    """The polygon members of a GeometryCollection, checked as `_rings` and the builder check a polygon."""
    parts = geom.get("geometries")
    if not isinstance(parts, list):
        raise GeoError(f"{where}: GeometryCollection 'geometries' is not a list (it is {kind(parts)})")
    for part in parts:
        if not isinstance(part, dict):
            raise GeoError(f"{where}: a GeometryCollection member is not an object (it is {kind(part)})")
        if part.get("type") == "GeometryCollection":
            _check_collection_rings(part, where)
        elif part.get("type") in ("Polygon", "MultiPolygon"):
            for rings in _rings(part, where):
                for k, ring in enumerate(rings):
                    check_positions(ring, *_ring_messages(where, part["type"], k))


class _Builder:
    """Polygon rings gathered feature by feature, their numbers checked and turned into numpy arrays a
    chunk at a time (C-level passes: map, set, numpy), then made into shapely geometries in one go."""

    def __init__(self) -> None:
        self.pending: list[Any] = []  # positions of the rings not yet checked
        self.pending_rings: list[tuple[Any, str, str, int]] = []  # (ring, where, geometry type, ring index)
        self.arrays: list[np.ndarray] = []
        self.ring_sizes: list[int] = []  # positions in each ring
        self.polygon_rings: list[int] = []  # rings in each polygon (its first ring is the shell)
        self.slot_polygons: list[int] = []  # polygons in each slot (feature)
        self.multi: list[bool] = []  # per slot: a MultiPolygon

    def add(self, polygons: list[list[list[Any]]], multi: bool, where: str) -> None:
        self.multi.append(multi)
        geom_type = "MultiPolygon" if multi else "Polygon"
        count = 0
        for rings in polygons:
            if not rings:
                continue  # a polygon without rings is empty: nothing to add
            count += 1
            self.polygon_rings.append(len(rings))
            for k, ring in enumerate(rings):
                self.pending.extend(ring)
                self.pending_rings.append((ring, where, geom_type, k))
                self.ring_sizes.append(len(ring))
        self.slot_polygons.append(count)
        if len(self.pending) >= _CHUNK_POSITIONS:
            self.flush()

    def add_other(self) -> None:
        """A slot for a geometry made elsewhere (shapely's `shape`)."""
        self.multi.append(False)
        self.slot_polygons.append(0)

    def _name_fault(self) -> None:
        """Raise the message of the first pending ring whose numbers are wrong (as `check_positions` says)."""
        for ring, where, geom_type, k in self.pending_rings:
            check_positions(ring, *_ring_messages(where, geom_type, k))

    def flush(self) -> None:
        """Check the pending positions (lists of 2 or 3 numbers, all finite) and keep them as one array."""
        pending = self.pending
        if not pending:
            return
        if set(map(type, pending)) != {list}:
            self._name_fault()
        lengths = set(map(len, pending))
        if not lengths <= {2, 3} or not set(map(type, chain.from_iterable(pending))) <= {int, float}:
            self._name_fault()
        try:
            if lengths == {2}:
                coords = np.asarray(pending, dtype=np.float64)
            elif lengths == {3}:  # an altitude is dropped: the grid is flat
                coords = np.asarray(pending, dtype=np.float64)[:, :2]
            else:
                coords = np.asarray([p[:2] for p in pending], dtype=np.float64)
        except OverflowError:  # a JSON integer too large for a float: check_positions names it
            self._name_fault()
            raise GeoError(f"{self.pending_rings[0][1]}: a coordinate is too large a number") from None
        if not np.isfinite(coords).all():
            self._name_fault()
        self.arrays.append(coords)
        self.pending, self.pending_rings = [], []

    def build(self) -> list[shapely.Geometry]:
        """One geometry per slot: Polygon or MultiPolygon (empty when it had no rings), made from the
        flat coordinates and offsets in one call (shapely's ragged-array layout, as GeoArrow's)."""
        self.flush()
        if not self.ring_sizes:
            return [_EMPTY[m] for m in self.multi]
        coords = np.concatenate(self.arrays)
        self.arrays = []

        def offsets(counts: list[int]) -> np.ndarray:
            return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])

        geoms = shapely.from_ragged_array(shapely.GeometryType.MULTIPOLYGON, coords, (
            offsets(self.ring_sizes), offsets(self.polygon_rings), offsets(self.slot_polygons)))
        del coords
        single = ~np.asarray(self.multi, dtype=bool)
        parts = np.asarray(self.slot_polygons)
        geoms[single & (parts == 1)] = shapely.get_geometry(geoms[single & (parts == 1)], 0)
        geoms[single & (parts == 0)] = _EMPTY[False]
        return list(geoms)


def _legacy_crs(data: dict[str, Any], path: Path) -> str | None:
    """The CRS a GeoJSON 2008 `crs` member names ({"type": "name", "properties": {"name": ...}}), if any."""
    member = data.get("crs")
    if member is None:
        return None
    name = member.get("properties", {}).get("name") if isinstance(member, dict) and isinstance(
        member.get("properties"), dict) else None
    if not isinstance(name, str):
        raise GeoError(f"{path}: 'crs' member without a name (RFC 7946 GeoJSON is WGS84 lon/lat and has no 'crs'; "
                       f"a 2008 'crs' is {{\"type\": \"name\", \"properties\": {{\"name\": \"EPSG:...\"}}}})")
    return name


def _read_feature(feature: dict[str, Any], k: int, path: Path, builder: _Builder,
                  slots: list[tuple[int, dict[str, Any], shapely.Geometry | None, Any]], source: SourceFile) -> None:
    """One feature of the file: its properties and polygons into the builder (others made by shapely)."""
    where = f"{path}: feature {k}"
    geom, props = feature.get("geometry"), feature.get("properties")
    if props is not None and not isinstance(props, dict):
        raise GeoError(f"{where}: 'properties' is not an object (it is {kind(props)})")
    if geom is None:  # GeoJSON allows features without geometry; they carry no polygon
        source.dropped.append(Omission(feature_ref(f"feature {k}", props or {}, feature.get("id")), "no geometry (null)"))
        return
    if not isinstance(geom, dict):
        raise GeoError(f"{where}: 'geometry' is not an object (it is {kind(geom)})")
    geom_type = geom.get("type")
    if geom_type in ("Polygon", "MultiPolygon"):
        builder.add(_rings(geom, where), geom_type == "MultiPolygon", where)
        slots.append((k, dict(props or {}), None, feature.get("id")))
        return
    if geom_type == "GeometryCollection":
        _check_collection_rings(geom, where)
    try:
        other = shape(geom)
    except Exception as err:  # shapely raises several types for malformed geometry
        raise GeoError(f"{where}: malformed geometry "
                       f"({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None
    if other.geom_type == "GeometryCollection":
        check_lonlat(other, where)
        parts = [p for p in other.geoms if not p.is_empty]
        if parts and all(isinstance(p, (Polygon, MultiPolygon)) for p in parts):
            other = union(parts, where)
    builder.add_other()
    slots.append((k, dict(props or {}), other, feature.get("id")))


def read_geojson(path: Path) -> tuple[list[Feature], SourceFile]:
    """Every polygon of a GeoJSON file, with its properties, and how the file was read."""
    data = load_json(path)
    if not isinstance(data, dict) or "type" not in data:
        raise GeoError(f"{path}: not GeoJSON (no 'type' member)")
    crs_name = _legacy_crs(data, path)
    source = SourceFile(str(path), "GeoJSON", "missionplan")
    if data["type"] == "FeatureCollection":
        features = data.get("features")
        if not isinstance(features, list):
            raise GeoError(f"{path}: 'features' is not a list (it is {kind(features)})")
        for k, f in enumerate(features):
            if not isinstance(f, dict):
                raise GeoError(f"{path}: feature {k} is not an object (it is {kind(f)})")
    elif data["type"] == "Feature":
        features = [data]
    else:
        features = [{"geometry": data, "properties": {}}]
    del data  # each feature is let go once read, so the parsed file shrinks as it is read
    builder = _Builder()
    slots: list[tuple[int, dict[str, Any], shapely.Geometry | None, Any]] = []  # (feature index, properties, other geometry)
    try:
        for k in range(len(features)):
            feature, features[k] = features[k], None
            _read_feature(feature, k, path, builder, slots, source)
    except GeoError:
        builder.flush()  # a bad number in an earlier ring comes first, as the file reads
        raise
    built = builder.build()
    geoms = [other if other is not None else built[i] for i, (_, _, other, _) in enumerate(slots)]
    crs = source_crs(crs_name, f"{path}: 'crs' member") if crs_name is not None else None
    if crs is not None:  # not WGS84 lon/lat: reprojected before any check of the coordinates
        geoms, source.crs, source.reprojected = to_lonlat(geoms, crs, f"{path}: 'crs' member"), crs_label(crs), True
    checked, repaired = check_polygons(geoms, lambda i: f"{path}: feature {slots[i][0]}")
    out = [Feature(g, props, feature_ref(f"feature {k}", props, own_id), repaired.get(i))
           for i, ((k, props, _, own_id), g) in enumerate(zip(slots, checked))]
    source.repaired = [Omission(f.ref, f.repaired) for f in out if f.repaired]
    if not out:
        raise GeoError(f"{path}: no polygon found")
    source.features = len(out)
    return out, source
