"""Reading a city-wide building file: wall and CPU seconds and peak memory, each reader side by side.

Two city-sized files are made in a temporary folder at bench time (nothing large is kept):
- a GeoJSON of buildings of about `--geojson-mb` MB (200 by default): the 134 Turin footprints of
  ../shared/maps/turin_cenisia_osm_buildings.geojson (OpenStreetMap data, © OpenStreetMap contributors,
  ODbL) copied over a 60-wide grid of shifted blocks, each with its own id; the same buildings are also
  written as a GeoPackage and a FlatGeobuf (pyogrio);
- an OpenStreetMap PBF of a whole city (synthetic, written with pyosmium: `--pbf-buildings` closed
  building ways on a 25 m lattice, a third with `height`, a third with `building:levels`, 2 % courtyard
  multipolygons, 40 multipolygons whose inner way is missing as at an extract's edge, and highways).

Each row reads one file in a fresh child process and prints the footprints it gave, the wall seconds,
the child's CPU seconds (user + system) and its peak resident memory (VmHWM: C++ allocations of GDAL
and libosmium included, which tracemalloc would miss). The readers:
- `missionplan`: what `plan --osm` uses (geo/readers.py: our GeoJSON parser, pyosmium for OSM, GDAL
  through pyogrio for GeoPackage and FlatGeobuf), heights and every check included;
- `GDAL`: GDAL's own driver for the same file through pyogrio (GeoJSON; OSM with an osmconf.ini that
  keeps height and building:levels), then the same checks and heights (geo/ogr_files.read_layer);
- `before`: the readers as they were at commit `--before` (the previous geo/readers.py, loaded from git),
  for the record; skipped when git or that commit is not at hand.

Run by hand (about 4 minutes, 2 GB of memory at most; the GeoJSON rows need ../shared/maps):

    .venv/bin/python bench/read_bench.py [--geojson-mb 200] [--pbf-buildings 400000] [--before e1c2679]
                                         [--write-doc docs/coverage-and-inputs.md]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path
from typing import Any

import doctable  # bench/doctable.py: --write-doc
from child_row import peak_rss_mb, run_child_row
from machine import machine_line

ROOT = Path(__file__).resolve().parent.parent


TURIN = ROOT.parent / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"
LAT0, LON0 = 45.0, 7.6
ROW_TIMEOUT_S = 900.0


# ---- the files -----------------------------------------------------------------------------------------------

def write_city_geojson(path: Path, megabytes: float) -> int:
    """The Turin footprints copied block by block until the file reaches `megabytes`; the count written."""
    source = json.loads(TURIN.read_text())["features"]
    count = 0
    with open(path, "w") as out:
        out.write('{"type": "FeatureCollection", "features": [\n')
        block = 0
        while out.tell() < megabytes * 1e6:
            dx, dy = (block % 60) * 0.008, (block // 60) * 0.006

            def shifted(ring: list[list[float]]) -> list[list[float]]:
                return [[round(x + dx, 7), round(y + dy, 7)] for x, y in ring]

            for feature in source:
                geom = feature["geometry"]
                coords = ([shifted(r) for r in geom["coordinates"]] if geom["type"] == "Polygon"
                          else [[shifted(r) for r in p] for p in geom["coordinates"]])
                props = {k: v for k, v in feature["properties"].items() if k in ("building", "height", "building:levels")}
                props["osmid"] = count
                out.write(("" if count == 0 else ",\n") + json.dumps(
                    {"type": "Feature", "properties": props, "geometry": {"type": geom["type"], "coordinates": coords}}))
                count += 1
            block += 1
        out.write("\n]}\n")
    return count


def write_gis_copies(geojson: Path, folder: Path) -> list[Path]:
    """The GeoJSON's buildings as a GeoPackage and a FlatGeobuf (pyogrio)."""
    import pyogrio.raw

    meta, _, geometry, fields = pyogrio.raw.read(str(geojson))
    out = []
    for name, driver in (("city.gpkg", "GPKG"), ("city.fgb", "FlatGeobuf")):
        path = folder / name
        pyogrio.raw.write(str(path), geometry, fields, meta["fields"], driver=driver, geometry_type="MultiPolygon",
                          crs="EPSG:4326", promote_to_multi=True)
        out.append(path)
    return out


def write_city_pbf(path: Path, buildings: int) -> int:
    """A synthetic city as an OSM PBF (see the module docstring); the number of footprints it should give."""
    import numpy as np
    import osmium

    mutable = osmium.osm.mutable
    rng = np.random.default_rng(0)
    side = int(buildings ** 0.5) + 1
    step_lat, step_lon = 25 / 111_320, 25 / (111_320 * 0.7071)  # 25 m at 45°
    size_lat, size_lon = 15 / 111_320, 15 / (111_320 * 0.7071)
    courtyards = {k for k in range(buildings) if k % 50 == 7}
    broken = set(sorted(courtyards)[:40])  # their inner way is not in the file
    nodes: list[tuple[int, float, float]] = []
    ways: list[tuple[int, list[int], dict[str, str]]] = []
    relations: list[tuple[int, list[tuple[str, int, str]], dict[str, str]]] = []
    node_id, way_id = 1, 1
    for k in range(buildings):
        lat, lon = LAT0 + (k // side) * step_lat, LON0 + (k % side) * step_lon
        tags = {"building": "yes"}
        if k % 3 == 0:
            tags["height"] = str(6 + k % 30)
        elif k % 3 == 1:
            tags["building:levels"] = str(2 + k % 8)
        ring = [(lat, lon), (lat, lon + size_lon), (lat + size_lat, lon + size_lon), (lat + size_lat, lon)]
        ids = list(range(node_id, node_id + 4))
        nodes += [(i, y, x) for i, (y, x) in zip(ids, ring)]
        node_id += 4
        if k not in courtyards:
            ways.append((way_id, ids + ids[:1], tags))
            way_id += 1
            continue
        inner = [(lat + size_lat * f, lon + size_lon * g) for f, g in ((0.3, 0.3), (0.3, 0.7), (0.7, 0.7), (0.7, 0.3))]
        inner_ids = list(range(node_id, node_id + 4))
        nodes += [(i, y, x) for i, (y, x) in zip(inner_ids, inner)]
        node_id += 4
        ways.append((way_id, ids + ids[:1], {}))
        if k not in broken:
            ways.append((way_id + 1, inner_ids + inner_ids[:1], {}))
        relations.append((k + 1, [("w", way_id, "outer"), ("w", way_id + 1, "inner")], {"type": "multipolygon", **tags}))
        way_id += 2
    for k in range(buildings // 4):  # streets between the blocks: ways the readers must skip
        lat = LAT0 + (k % side) * step_lat + size_lat * 1.5
        ids = list(range(node_id, node_id + 3))
        nodes += [(i, lat, LON0 + (k // side + j) * step_lon) for j, i in enumerate(ids)]
        node_id += 3
        ways.append((way_id, ids, {"highway": "residential"}))
        way_id += 1
    # Each node some decimetres off the lattice, as surveyed data is: a perfect lattice compresses so well that
    # GDAL's PBF reader refuses its blocks ("Excessive uncompressed vs compressed ratio").
    jitter = rng.normal(0.0, 0.3 / 111_320, size=(len(nodes), 2))
    with osmium.SimpleWriter(str(path), overwrite=True) as writer:
        for (i, lat, lon), (dy, dx) in zip(nodes, jitter):
            writer.add_node(mutable.Node(id=i, location=osmium.osm.Location(lon + dx, lat + dy), tags={}))
        for i, refs, tags in ways:
            writer.add_way(mutable.Way(id=i, nodes=refs, tags=tags))
        for i, members, tags in relations:
            writer.add_relation(mutable.Relation(id=i, members=members, tags=tags))
    return buildings - len(broken)


# ---- the readers (in a child) ------------------------------------------------------------------------------

def _osmconf(folder: Path) -> Path:
    """GDAL's osmconf.ini with height and building:levels kept as fields of the multipolygons layer."""
    import pyogrio

    source = Path(pyogrio.__file__).parent / "gdal_data" / "osmconf.ini"
    text = source.read_text()
    text = re.sub(r"(\[multipolygons\][^\[]*?attributes=)([^\n]*)", r"\1\2,height,building:levels", text, count=1)
    path = folder / "osmconf.ini"
    path.write_text(text)
    return path


def _gdal_osm(path: Path) -> int:
    import numpy as np
    import pyogrio.raw
    import shapely

    from missionplan.geo.heights import building_height
    from missionplan.geo.shapes import check_polygons

    with tempfile.TemporaryDirectory(prefix="read-bench-osmconf-") as folder:
        meta, fids, wkb, columns = pyogrio.raw.read(str(path), layer="multipolygons", return_fids=True,
                                                    where="building IS NOT NULL AND building != 'no'",
                                                    CONFIG_FILE=str(_osmconf(Path(folder))))
    geoms = shapely.from_wkb(wkb)
    invalid = ~shapely.is_valid(geoms)  # OSM footprints are repaired, as geo/osm.py does
    geoms[invalid] = shapely.make_valid(geoms[invalid])
    geoms, _ = check_polygons(list(geoms), lambda i: f"{path}: feature {i}")
    names = [str(f) for f in meta["fields"]]
    values = [c.tolist() for c in columns]
    heights = [building_height({n: v[i] for n, v in zip(names, values)}) for i in range(len(geoms))]
    return len(np.asarray(heights, dtype=object))


def _before(rev: str) -> types.ModuleType:
    """geo/readers.py as it was at `rev`, loaded as a module beside today's geo package."""
    text = subprocess.run(["git", "show", f"{rev}:geo/readers.py"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout
    text = text.replace("from .errors import", "from missionplan.geo.errors import").replace(
        "from .frame import", "from missionplan.geo.frame import")
    module = types.ModuleType(f"readers_at_{rev}")
    sys.modules[module.__name__] = module  # dataclasses look their module up there
    exec(compile(text, f"{rev}:geo/readers.py", "exec"), module.__dict__)
    return module


def read_row(reader: str, path: Path, before: str) -> dict[str, Any]:
    """Read `path` with `reader` and measure it (this process is the child)."""
    import osmium  # noqa: F401  (loaded before the clock starts, as plan loads them)
    import pyogrio  # noqa: F401

    from missionplan.geo import ogr_files
    from missionplan.geo.heights import building_height
    from missionplan.geo.readers import read_building_file

    old = _before(before) if reader == "before" else None
    start_wall, start = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
    if reader == "baseline":
        count = 0
    elif reader == "missionplan":
        count = len(read_building_file(path)[0])
    elif reader == "before":
        count = len(old.read_buildings(path))
    elif path.suffix == ".pbf":
        count = _gdal_osm(path)
    else:
        fmt = ogr_files.OgrFormat("GeoJSON", "GeoJSON", (b"{",))
        feats, _ = ogr_files.read_layer(path, str(path), fmt, None)
        count = len([building_height(f.properties) for f in feats])
    end = resource.getrusage(resource.RUSAGE_SELF)
    return {"buildings": count, "wall_s": time.perf_counter() - start_wall,
            "cpu_s": end.ru_utime + end.ru_stime - start.ru_utime - start.ru_stime, "peak_mb": peak_rss_mb()}


# ---- the table ---------------------------------------------------------------------------------------------------

def _size(path: Path) -> str:
    size = path.stat().st_size / 1e6
    return f"{size:,.0f} MB" if size >= 10 else f"{size:.1f} MB"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--geojson-mb", type=float, default=200.0, help="size of the city GeoJSON (default 200)")
    parser.add_argument("--pbf-buildings", type=int, default=400_000, help="buildings in the city PBF (default 400000)")
    parser.add_argument("--before", default="e1c2679", help="the commit whose readers the 'before' rows load")
    parser.add_argument("--timeout", type=float, default=ROW_TIMEOUT_S, help="seconds a row may take")
    parser.add_argument("--row", help=argparse.SUPPRESS)  # internal: READER,PATH in a child
    doctable.add_option(parser)
    args = parser.parse_args()
    if args.row:
        reader, path = args.row.split(",", 1)
        print(json.dumps(read_row(reader, Path(path), args.before)))
        return 0
    has_git = shutil.which("git") is not None and subprocess.run(
        ["git", "cat-file", "-e", f"{args.before}:geo/readers.py"], cwd=ROOT, capture_output=True).returncode == 0
    with doctable.Recorder(args.write_doc, __file__), tempfile.TemporaryDirectory(prefix="read-bench-") as tmp:
        folder = Path(tmp)
        files: list[tuple[Path, str, list[str]]] = []  # (file, what it holds, readers)
        if TURIN.is_file():
            geojson = folder / "city.geojson"
            count = write_city_geojson(geojson, args.geojson_mb)
            gpkg, fgb = write_gis_copies(geojson, folder)
            files += [(geojson, f"{count:,} footprints", ["missionplan", "GDAL"] + (["before"] if has_git else [])),
                      (gpkg, "the same", ["missionplan"]), (fgb, "the same", ["missionplan"])]
        pbf = folder / "city.osm.pbf"
        expected = write_city_pbf(pbf, args.pbf_buildings)
        files.append((pbf, f"{expected:,} footprints", ["missionplan", "GDAL"] + (["before"] if has_git else [])))
        print(f"{'file':<14} {'size':>7}  {'holds':<19} {'reader':<29} {'read':>8} {'wall s':>7} {'CPU s':>6} "
              f"{'peak MB':>8}")
        for path, holds, readers in files:
            for reader in readers:
                name = {"missionplan": "missionplan (plan)", "GDAL": "GDAL's own driver",
                        "before": f"before ({args.before})"}[reader]
                if reader == "missionplan":
                    name += {".geojson": ": own", ".pbf": ": pyosmium"}.get(path.suffix, ": GDAL")
                row = run_child_row([sys.executable, __file__, "--row", f"{reader},{path}", "--before", args.before],
                                    args.timeout)
                if isinstance(row, str):
                    print(f"{path.name:<14} {_size(path):>7}  {holds:<19} {name:<29} {row}")
                    continue
                print(f"{path.name:<14} {_size(path):>7}  {holds:<19} {name:<29} {row['buildings']:>8,} "
                      f"{row['wall_s']:>7.1f} {row['cpu_s']:>6.1f} {row['peak_mb']:>8,.0f}")
                holds = ""
        base = run_child_row([sys.executable, __file__, "--row", f"baseline,{pbf}"], args.timeout)
        if not isinstance(base, str):
            print(f"(a child that only loads the readers peaks at {base['peak_mb']:,.0f} MB)")
        print(machine_line())
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    raise SystemExit(main())
