"""Building footprints from OpenStreetMap data (`.osm` XML, `.osm.pbf`), read with pyosmium.

Closed ways and multipolygon relations tagged building=* (not building=no), assembled by libosmium
into areas; a footprint's properties are its tags plus `osm_id` and `osm_type`. Why pyosmium and not
GDAL's OSM driver, about twice as fast on a city (bench/read_bench.py): GDAL builds a building whose
node the file lacks from the nodes it has (a square read as a triangle) without a word, and cannot
name what it left out; here each is named.

Nothing is left out without a name. Each of these is listed (`SourceFile.dropped`, by OSM id, with
its cause) and the rest of the file is read:

* a building way that references a node the file does not hold (an extract clipped at its edge);
* a building way that is not closed and belongs to no building multipolygon;
* a building multipolygon whose member ways are missing or do not close into rings;
* a footprint of zero area.

An invalid footprint (a ring touching itself, a self-crossing) is repaired with make_valid instead
of refusing a whole extract for one roof drawn by someone else; it is listed as repaired. libosmium
assembles no area of a self-crossing way or of a broken multipolygon: when there is one, one more
pass over the file (`_second_look`, with node locations, for those ways only) repairs the way, or
names the multipolygon's missing member way or node. A node
outside WGS84 range is bad data and an error naming the way and node.

OSM ids are any signed 64-bit integer, but libosmium stores node locations for ids from 0 up only,
an area's id (twice the way's id, plus one for a relation) overflows from |id| = 2^62, its area
assembly wants the ways sorted by id, and it marks a relation member it is done with by the id 0 (a
member way of id 0 crashed the process). So a file with negative ids (JOSM gives new objects negative
ids), such large way / relation ids, ways out of order or a member way of id 0 would lose buildings:
when one is seen, the file is copied with those ids renumbered into free positive ones and sorted (a
temporary .osm.pbf), and read again; every message names the original ids. libosmium itself refuses
the two extreme ids, 2^63 - 1 and -2^63.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from .errors import GeoError
from .shapes import MAX_LON_SPAN_DEG, check_lonlat, polygonal_part
from .sources import Omission, SourceFile

_UNDEFINED_COORDINATE = 2**31 - 1  # osmium's x / y of a node the file does not hold
AREA_ID_LIMIT = 2**62  # from here on libosmium's area id (2 |id| + 1) overflows
MAX_NODE_ID = 2**63 - 2  # libosmium refuses 2^63 - 1
MAX_NAMED = 3  # missing nodes / members named in one cause
AREA_CHUNK = 20_000  # footprints checked at a time
# osmium's IdFilter takes ids from 0 up, its table grows with the largest id (an id of 2^46 ran out of
# memory; 2^40 costs nothing): above this limit Python picks the ways itself. OSM's ids are below 2^34.
ID_FILTER_LIMIT = 2**36


@dataclass
class _Names:
    """Original ids of renumbered objects, by type ('n', 'w', 'r'): new id -> the file's id."""

    original: dict[str, dict[int, int]] = field(default_factory=lambda: {"n": {}, "w": {}, "r": {}})

    def __call__(self, kind: str, new_id: int) -> int:
        return self.original[kind].get(new_id, new_id)


@dataclass
class OsmBuilding:
    """One footprint as read: geometry, tags (with osm_id, osm_type), its name, why it was repaired."""

    geometry: Any
    tags: dict[str, Any]
    ref: str
    repaired: str | None


@dataclass
class _Scan:
    buildings: list[OsmBuilding] = field(default_factory=list)
    dropped: list[Omission] = field(default_factory=list)
    renumber: str | None = None  # why the ids must be renumbered, when they must


def _error_text(err: Exception) -> str:
    return str(err).splitlines()[0] if str(err) else type(err).__name__


def _listed(ids: list[Any], what: str) -> str:
    """'node 5', 'nodes 5, 6, 7 and 2 more'."""
    shown = ", ".join(str(i) for i in ids[:MAX_NAMED])
    more = f" and {len(ids) - MAX_NAMED} more" if len(ids) > MAX_NAMED else ""
    return f"{what}{'s' if len(ids) > 1 else ''} {shown}{more}"


def _building_relations(path: Path, names: _Names) -> tuple[dict[int, list[tuple[int, str]]], str | None]:
    """Multipolygon relations tagged building: id -> its member ways (id, role); and why to renumber."""
    import osmium

    relations: dict[int, list[tuple[int, str]]] = {}
    renumber = None
    for rel in osmium.FileProcessor(str(path), osmium.osm.RELATION).with_filter(osmium.filter.KeyFilter("building")):
        if rel.tags.get("building", "no") == "no" or rel.tags.get("type") != "multipolygon":
            continue
        members = [(m.ref, m.role) for m in rel.members if m.type == "w"]
        relations[rel.id] = members
        if abs(rel.id) >= AREA_ID_LIMIT or any(abs(ref) >= AREA_ID_LIMIT for ref, _ in members):
            renumber = f"relation {names('r', rel.id)}: an id of 2^62 or more"
        elif any(ref == 0 for ref, _ in members):  # libosmium marks a member it is done with by id 0: it crashed
            renumber = f"relation {names('r', rel.id)}: a member way of id 0"
    return relations, renumber


def _way_nodes(label: str, way: Any, names: _Names) -> tuple[list[int], bool]:
    """The way's nodes the file lacks (original ids), and whether one of them has a negative id.

    A node whose location is out of WGS84 range is bad data, not a skip: an error.
    """
    missing: list[int] = []
    negative = False
    for node in way.nodes:
        loc = node.location
        if loc.valid():
            continue
        if loc.x != _UNDEFINED_COORDINATE and loc.y != _UNDEFINED_COORDINATE:
            raise GeoError(f"{label}: way {names('w', way.id)}, node {names('n', node.ref)}: location "
                           f"(lat {loc.y / 1e7}, lon {loc.x / 1e7}) is out of range "
                           f"(latitude in [-90, 90], longitude in [-180, 180])")
        if names("n", node.ref) not in missing:  # a closed way names its first node twice
            missing.append(names("n", node.ref))
        negative |= node.ref < 0
    return missing, negative


@dataclass
class _WayLook:
    """A way as the second look saw it: its tags, (lon, lat) points, the nodes the file lacks."""

    tags: dict[str, str]
    points: list[tuple[float, float]]
    missing: list[int]


@dataclass
class _Areas:
    """Footprints gathered during a pass, made into checked geometries a chunk at a time (vectorised in
    shapely; the chunks keep libosmium's WKB text from piling up), in file order."""

    label: str
    names: _Names
    failed: str | None = None  # libosmium did not assemble these: their rings are repaired if they can be
    geometries: list[Any] = field(default_factory=list)  # WKB hex text or shapely geometries, not yet checked
    tags: list[dict[str, Any]] = field(default_factory=list)
    kinds: list[str] = field(default_factory=list)  # "way" / "relation"
    ids: list[int] = field(default_factory=list)  # the id in the file read (renumbered ones too)
    buildings: list[OsmBuilding] = field(default_factory=list)
    dropped: list[Omission] = field(default_factory=list)

    def add(self, geometry: Any, tags: dict[str, Any], kind: str, osm_id: int) -> None:
        self.geometries.append(geometry)
        self.tags.append(tags)
        self.kinds.append(kind)
        self.ids.append(osm_id)
        if len(self.ids) >= AREA_CHUNK:
            self._check()

    def footprints(self) -> tuple[list[OsmBuilding], list[Omission]]:
        """The buildings (each checked in WGS84 range, repaired when invalid) and those dropped (zero area)."""
        self._check()
        return self.buildings, self.dropped

    def _check(self) -> None:
        if not self.ids:
            return
        buildings, dropped = self._checked(self.label, self.names, self.failed)
        self.buildings += buildings
        self.dropped += dropped
        self.geometries, self.tags, self.kinds, self.ids = [], [], [], []

    def _checked(self, label: str, names: _Names, failed: str | None) -> tuple[list[OsmBuilding], list[Omission]]:
        if isinstance(self.geometries[0], shapely.Geometry):
            geoms = np.empty(len(self.geometries), dtype=object)
            geoms[:] = self.geometries
        else:  # libosmium's WKB (hex text)
            geoms = shapely.from_wkb(np.asarray(self.geometries, dtype=object))
        refs = [f"{kind} {names(kind[0], osm_id)}" for kind, osm_id in zip(self.kinds, self.ids)]
        coords, owner = shapely.get_coordinates(geoms, return_index=True)
        with np.errstate(invalid="ignore"):
            bad = ~np.isfinite(coords).all(axis=1) | (np.abs(coords[:, 0]) > 180) | (np.abs(coords[:, 1]) > 90)
            bounds = shapely.bounds(geoms)
        wide = np.flatnonzero(bounds[:, 2] - bounds[:, 0] > MAX_LON_SPAN_DEG)
        first = min([int(owner[bad][0])] if bad.any() else [], default=len(geoms))
        first = min(first, int(wide[0]) if len(wide) else len(geoms))
        if first < len(geoms):
            check_lonlat(geoms[first], f"{label}: {refs[first]}")  # raises, naming it
        repaired: list[str | None] = [failed] * len(geoms)
        for i in np.flatnonzero(~shapely.is_valid(geoms)):
            reason = shapely.is_valid_reason(geoms[i])
            repaired[i] = f"{failed}: {reason}" if failed else reason
            geoms[i] = polygonal_part(shapely.make_valid(geoms[i]))
        single = shapely.get_num_geometries(geoms) == 1
        multi = shapely.get_type_id(geoms) == 6
        geoms[single & multi] = shapely.get_geometry(geoms[single & multi], 0)  # MultiPolygon of one: its Polygon
        zero = shapely.is_empty(geoms) | (shapely.area(geoms) == 0)
        buildings, dropped = [], []
        for i, (geom, tags) in enumerate(zip(geoms, self.tags)):
            if zero[i]:
                dropped.append(Omission(refs[i], "zero area (its nodes lie on a line)"))
                continue
            tags["osm_id"] = names(self.kinds[i][0], self.ids[i])
            tags["osm_type"] = self.kinds[i]
            buildings.append(OsmBuilding(geom, tags, refs[i], repaired[i]))
        return buildings, dropped


def _scan(path: Path, label: str, names: _Names) -> _Scan:
    """One read of the file: the footprints, what was dropped, or why the ids must be renumbered first."""
    import osmium  # imported here so the rest of geo works without the C++ extension loaded

    out = _Scan()
    relations, out.renumber = _building_relations(path, names)
    if out.renumber:
        return out
    in_relation = {ref for members in relations.values() for ref, _ in members}
    wkb = osmium.geom.WKBFactory()
    closed_ways: set[int] = set()  # closed building ways with every node: each should give an area
    assembled: set[tuple[str, int]] = set()
    areas = _Areas(label, names)
    fp = (osmium.FileProcessor(str(path)).with_areas()
          .with_filter(osmium.filter.EntityFilter(osmium.osm.AREA | osmium.osm.WAY))
          .with_filter(osmium.filter.KeyFilter("building")))  # in C++: Python sees buildings only
    for obj in fp:
        if obj.is_way():
            if obj.tags.get("building", "no") == "no":
                continue
            if abs(obj.id) >= AREA_ID_LIMIT:
                out.renumber = f"way {names('w', obj.id)}: an id of 2^62 or more"
                return out
            try:
                wkb.create_linestring(obj)  # C++: fails only when a node location is not valid
            except (RuntimeError, osmium.InvalidLocationError):
                missing, negative = _way_nodes(label, obj, names)  # the slow look, only then
                if negative:
                    out.renumber = f"way {names('w', obj.id)}: negative node ids"
                    return out
                out.dropped.append(Omission(f"way {names('w', obj.id)}",
                                            f"{_listed(missing, 'node')} missing from the file"))
                continue
            if obj.is_closed():
                closed_ways.add(obj.id)
            elif obj.id not in in_relation:
                out.dropped.append(Omission(f"way {names('w', obj.id)}", "not closed (its first and last nodes "
                                                                        "differ) and in no building multipolygon"))
            continue
        tags = dict(obj.tags)
        if tags.get("building", "no") == "no":
            continue
        try:
            geometry = wkb.create_multipolygon(obj)
        except (RuntimeError, osmium.InvalidLocationError):
            continue  # libosmium could not assemble it: looked at below, with the others it did not give
        kind = "way" if obj.from_way() else "relation"
        assembled.add((kind, obj.orig_id()))
        areas.add(geometry, tags, kind, obj.orig_id())
    out.buildings, dropped = areas.footprints()
    out.dropped += dropped
    unassembled = sorted(closed_ways - {i for k, i in assembled if k == "way"})
    broken = {rel: members for rel, members in relations.items() if ("relation", rel) not in assembled}
    if unassembled or broken:
        looks = _second_look(path, label, set(unassembled) | {ref for m in broken.values() for ref, _ in m}, names)
        if any(ref < 0 for look in looks.values() for ref in look.missing):
            out.renumber = "negative node ids in a multipolygon's member way"
            return out
        rings = _Areas(label, names, "libosmium could not assemble its ring")
        for way in unassembled:
            look = looks[way]
            rings.add(shapely.Polygon(look.points) if len(look.points) >= 4 else shapely.Polygon(), dict(look.tags),
                      "way", way)
        repaired, dropped = rings.footprints()
        out.buildings += repaired
        out.dropped += dropped
        out.dropped += [Omission(f"relation {names('r', rel)}", _why_broken(broken[rel], looks, names))
                        for rel in sorted(broken)]
    return out


def _second_look(path: Path, label: str, wanted: set[int], names: _Names) -> dict[int, _WayLook]:
    """The ways `wanted` as the file holds them (one more pass, with node locations): those libosmium
    did not make areas of, and the member ways of the multipolygons it did not assemble."""
    import osmium

    fp = (osmium.FileProcessor(str(path), osmium.osm.NODE | osmium.osm.WAY).with_locations()
          .with_filter(osmium.filter.EntityFilter(osmium.osm.WAY)))
    if 0 <= min(wanted, default=0) and max(wanted, default=0) < ID_FILTER_LIMIT:  # else Python picks the ways
        fp = fp.with_filter(osmium.filter.IdFilter(wanted))
    looks: dict[int, _WayLook] = {}
    for way in fp:
        if way.id not in wanted:
            continue
        missing, _ = _way_nodes(label, way, names)
        points = [] if missing else [(n.location.lon, n.location.lat) for n in way.nodes]
        looks[way.id] = _WayLook(dict(way.tags), points, list(dict.fromkeys(
            n.ref for n in way.nodes if not n.location.valid())))
    return looks


def _why_broken(members: list[tuple[int, str]], looks: dict[int, _WayLook], names: _Names) -> str:
    """Why libosmium did not assemble a building multipolygon: its missing member ways, their missing
    nodes, or rings that do not close."""
    absent = [(role, names("w", ref)) for ref, role in members if ref not in looks]
    lacking = [(ref, looks[ref].missing) for ref, _ in members if ref in looks and looks[ref].missing]
    if not members:
        return "broken multipolygon: no member ways"
    if absent:
        roles = dict.fromkeys(role for role, _ in absent)  # in member order
        return "broken multipolygon: " + " and ".join(
            f"{role + ' ' if role else ''}member {_listed([ref for r, ref in absent if r == role], 'way')}"
            for role in roles) + " missing from the file"
    if lacking:
        ref, nodes = lacking[0]
        return (f"broken multipolygon: member way {names('w', ref)} lacks "
                f"{_listed([names('n', n) for n in nodes], 'node')} (missing from the file)")
    return "broken multipolygon: its member ways do not close into rings"


def _renumbered(path: Path, folder: Path, label: str) -> tuple[Path, _Names]:
    """A copy of the OSM file with negative ids, and way / relation ids of 2^62 or more, renumbered into
    free positive ids (after the largest one in use), sorted as libosmium wants them (by type, then id),
    and the map back to the original ids. Held in memory while sorting: such files are edits, small."""
    import osmium

    # Plain copies (id, what it holds, tags): the file's objects live only while their buffer does.
    objects: dict[str, list[tuple[int, Any, dict[str, str]]]] = {"n": [], "w": [], "r": []}
    used: dict[str, set[int]] = {"n": set(), "w": set(), "r": set()}  # ids held or referenced (a missing node too)
    for obj in osmium.FileProcessor(str(path)):
        kind = obj.type_str()
        if kind == "n":  # x, y: 1e-7 degrees, kept as read even when out of range (checked when read back)
            loc = obj.location
            content: Any = (loc.x, loc.y) if _UNDEFINED_COORDINATE not in (loc.x, loc.y) else None
        elif kind == "w":
            content = [n.ref for n in obj.nodes]
            used["n"].update(content)
        elif kind == "r":
            content = [(m.type, m.ref, m.role) for m in obj.members]
            for member_kind, ref, _ in content:
                used.setdefault(member_kind, set()).add(ref)
        else:
            continue
        objects[kind].append((obj.id, content, dict(obj.tags)))
        used[kind].add(obj.id)
    limit = {"n": MAX_NODE_ID, "w": AREA_ID_LIMIT - 1, "r": AREA_ID_LIMIT - 1}
    lowest = {"n": 0, "w": 1, "r": 0}  # a way of id 0 is renumbered too (see _building_relations)
    new_ids: dict[str, dict[int, int]] = {}
    names = _Names()
    for kind in objects:
        safe = [i for i in used[kind] if lowest[kind] <= i <= limit[kind]]
        unsafe = sorted((i for i in used[kind] if not lowest[kind] <= i <= limit[kind]), key=abs)
        largest = max(safe, default=0)  # new ids go above every id in use, referenced or held
        if largest + len(unsafe) > limit[kind]:
            raise GeoError(f"{label}: its ids leave no room to renumber the {len(unsafe)} that libosmium cannot "
                           f"read (negative ids, way or relation ids of 2^62 or more)")
        new_ids[kind] = {old: largest + 1 + k for k, old in enumerate(unsafe)}
        names.original[kind] = {new: old for old, new in new_ids[kind].items()}

    def renamed(kind: str, osm_id: int) -> int:
        return new_ids[kind].get(osm_id, osm_id)

    mutable = osmium.osm.mutable
    copy = folder / "renumbered.osm.pbf"
    with osmium.SimpleWriter(str(copy), overwrite=True) as writer:
        for osm_id, xy, tags in sorted(objects["n"], key=lambda o: renamed("n", o[0])):
            location = osmium.osm.Location(xy[0] / 1e7, xy[1] / 1e7) if xy is not None else osmium.osm.Location()
            writer.add_node(mutable.Node(id=renamed("n", osm_id), location=location, tags=tags))
        for osm_id, refs, tags in sorted(objects["w"], key=lambda o: renamed("w", o[0])):
            writer.add_way(mutable.Way(id=renamed("w", osm_id), nodes=[renamed("n", r) for r in refs], tags=tags))
        for osm_id, members, tags in sorted(objects["r"], key=lambda o: renamed("r", o[0])):
            writer.add_relation(mutable.Relation(id=renamed("r", osm_id), tags=tags, members=[
                (kind, renamed(kind, ref) if kind in new_ids else ref, role) for kind, ref, role in members]))
    return copy, names


def read_osm(path: Path) -> tuple[list[OsmBuilding], SourceFile]:
    """The building footprints of an OSM file and how it was read (see the module docstring)."""
    import osmium

    label = str(path)
    fmt = "OpenStreetMap PBF" if path.name.lower().endswith(".pbf") else "OpenStreetMap XML"
    source = SourceFile(label, fmt, "pyosmium")
    try:
        try:
            scan = _scan(path, label, _Names())
        except RuntimeError as err:
            if "out of order" not in str(err):  # libosmium's areas need the file sorted by type and id
                raise
            scan = _Scan(renumber=_error_text(err))
        if scan.renumber:
            with tempfile.TemporaryDirectory(prefix="missionplan-osm-") as folder:
                copy, names = _renumbered(path, Path(folder), label)
                scan = _scan(copy, label, names)
            source.notes.append(f"ids renumbered for libosmium, named here as in the file ({_why(names)})")
    except GeoError:
        raise
    except (RuntimeError, OSError, ValueError, osmium.InvalidLocationError) as err:
        # libosmium reports a malformed file as RuntimeError (XML / PBF errors), a bad
        # coordinate text as InvalidLocationError, undecodable tag text or an illegal id as ValueError.
        raise GeoError(f"{label}: cannot read OSM data ({_error_text(err)})") from None
    if not scan.buildings:
        dropped = f" ({len(scan.dropped)} dropped: {scan.dropped[0].ref}: {scan.dropped[0].cause})" if scan.dropped else ""
        raise GeoError(f"{label}: no building polygon found{dropped}")
    source.features = len(scan.buildings)
    source.dropped = scan.dropped
    source.repaired = [Omission(b.ref, b.repaired) for b in scan.buildings if b.repaired]
    return scan.buildings, source


def _why(names: _Names) -> str:
    counts: Iterable[tuple[str, int]] = ((word, len(names.original[kind])) for kind, word in
                                         (("n", "node"), ("w", "way"), ("r", "relation")))
    return ", ".join(f"{count} {word}{'s' if count > 1 else ''}" for word, count in counts if count)
