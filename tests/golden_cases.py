"""The golden comparison's cases, how each output file is normalised, and the manifests in tests/golden/.

tests/test_golden.py runs every case below through the public command line (the function the
`missionplan` console script calls, in this process, from the repository's root) and compares what
it wrote with tests/golden/CASE.json, written from the code as it was before a refactor: the same
plans, missions, maps and flight records, byte for byte where the bytes are reproducible. When a
behaviour change is intended, rewrite the manifests by hand:

    .venv/bin/python tests/golden_cases.py --write            # every case, each run 3 times first
    .venv/bin/python tests/golden_cases.py --write turin-4    # one case
    .venv/bin/python tests/golden_cases.py                    # compare only, as the test does

`--write` runs each case `--runs` times (default 3) and writes nothing for a case whose normalised
output differs between runs: a golden file that flakes is worse than none.

A manifest holds, for every file the command wrote and for what it printed (`stdout`, `stderr`): how
it is compared, the sha256 and size of its normalised bytes, and hashes of its lines (8 hex digits
each, one per line, or per block of lines in a long file), so that a failure names the first
differing line without the manifest holding the text. A JSON file's lines are `path = value`, one per
leaf or short container, so that line names the key. report.json and flight.json are stored whole
(normalised), so a failure shows the golden and the new value of the first differing keys.

Normalised, and why (everything else is compared as written):
- report.json: `timing.zones_s` and `timing.plan_s` (wall seconds of the planning), `tours.cpu_s` (CPU seconds), and
  `files_sha256["plan.gpkg"]` (the hash of a file whose bytes hold clock times, below).
- plan.gpkg: compared as its SQLite content (application id, version, every schema entry, every
  table's rows in rowid order) with `gpkg_contents.last_change` blanked: GDAL writes the wall-clock
  time of each layer there, so the bytes differ from run to run while every row is the same.
- What the command printed: the output folder's path, the `plan s` figure (wall seconds).
- plan.png, plan.kmz, plan.html and the mission files are compared byte for byte: repeated runs
  gave the same bytes (matplotlib writes no date into a PNG; the KMZ's members carry a fixed date).
- The flight (`missionplan demo` at a 10x speed-up: in-process mock autopilots, threads, a clock)
  compares what repeated runs gave alike and only checks that the rest was written:
  - flight.json without when things happened (flown and phase seconds, the events' times, the wall
    seconds, the last position's clock time), the telemetry sample count and the measured closest
    approach (distance, pair, time, start spread): those follow the telemetry samples, which the
    threads' timing places. Compared: coverage and its other rules, missed cells, per drone finished /
    ended early / photos (from the camera, from the log, placed on the track) / planned photos and
    seconds / the vehicle's parameters / uploaded / held after the flight / items reached / the events
    in order / notes / where it landed, the separation verdict and the plan's promise, problems, the
    survey's figures.
  - photos.csv, geo.txt, photos.geojson, ledger.sqlite: every photo's name, vehicle, index and
    position (the mock triggers by distance along its simulated track, whatever its ticks' lengths)
    and the cells each covered, without the photo's clock time and yaw (a photo at a corner gets the
    yaw of the moment the turn was sampled) and the ledger's recording time.
  - demo's lines after its `== 2/2 fly:` heading (flown seconds, measured closest approach: what they
    say is compared in flight.json).
  - Only their presence: flight.png, flight.html, flight.gpkg, flight.kmz (they draw the flown
    tracks, from the telemetry samples), journal.sqlite and journal.commits (every message heard,
    with its arrival time).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import importlib.metadata
import io
import json
import math
import os
import re
import sqlite3
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
GOLDEN = Path(__file__).resolve().parent / "golden"
SHARED_MAPS = REPO.parent / "shared" / "maps"
OUT = "{out}"  # the output folder in a case's arguments
NORMALISED = "<normalised>"  # what a value that varies from run to run is replaced with


@dataclass(frozen=True)
class Case:
    name: str
    argv: tuple[str, ...]  # missionplan's arguments, run from the repository's root; OUT: the output folder
    what: str  # what this case covers
    needs: Path | None = None  # an input outside the repository: the case is skipped without it

    @property
    def command(self) -> str:
        return "missionplan " + " ".join(self.argv)

    @property
    def is_flight(self) -> bool:
        return self.argv[0] == "demo"


TURIN_LAUNCH = ("--launch", "45.069450,7.652588", "--launch", "45.069513,7.657924",
                "--launch", "45.066065,7.652668", "--launch", "45.066127,7.658004")
CASES = (
    Case("leonardo-5", ("plan", "--map", "leonardo", "--uavs", "5", "--out", OUT, "--quiet"),
         "the Leonardo arena with the defaults (the expert policy)"),
    Case("grid-city-2", ("plan", "--map", "grid-city", "--uavs", "2", "--out", OUT, "--quiet"),
         "grid-city with the defaults: routes longer than the battery, so sorties (uavK-sJ.plan)"),
    Case("old-town-4", ("plan", "--map", "old-town", "--uavs", "4", "--out", OUT, "--quiet"),
         "old-town with the defaults"),
    Case("river-city-3", ("plan", "--map", "river-city", "--uavs", "3", "--out", OUT, "--quiet"),
         "river-city with the defaults"),
    Case("river-city-4-nn", ("plan", "--map", "river-city", "--uavs", "4", "--policy", "nn", "--out", OUT,
                             "--quiet"),
         "river-city with the shipped network"),
    Case("turin-4", ("plan", "--area", "examples/turin-cenisia-area.geojson",
                     "--osm", "../shared/maps/turin_cenisia_osm_buildings.geojson", *TURIN_LAUNCH,
                     "--altitude", "20", "--fov", "84", "--out", OUT, "--quiet"),
         "the README's real area: OSM buildings with and without heights, the clearance, the warnings",
         needs=SHARED_MAPS / "turin_cenisia_osm_buildings.geojson"),
    Case("qgc-survey-px4", ("plan", "--area", "tests/data/qgc/qgroundcontrol_sample_with_survey.plan",
                            "--launch", "47.39790,8.54580", "--launch", "47.39750,8.54615",
                            "--altitude", "10", "--fov", "84", "--autopilot", "px4", "--out", OUT, "--quiet"),
         "a QGroundControl survey's polygon as the area, for PX4 (no .waypoints), altitude layers"),
    Case("open-field-3", ("plan", "--map", "tests/golden/open-field.map", "--uavs", "3", "--out", OUT, "--quiet"),
         "open ground: every drone sweeps its zone in footprint-wide lanes"),
    Case("demo-5", ("demo", "--uavs", "5", "--speedup", "10", "--out", OUT, "--quiet"),
         "plan Leonardo for 5 drones with the network, fly it on 5 in-process mock autopilots, judge it"),
)
BY_NAME = {case.name: case for case in CASES}

# report.json: the planning's wall seconds, and the hash of plan.gpkg (its bytes hold clock times).
REPORT_TIMING = re.compile(r'("(?:zones_s|plan_s|cpu_s)": )-?[0-9.eE+-]+')
REPORT_GPKG_HASH = re.compile(r'("plan\.gpkg": )"[0-9a-f]{64}"')
PRINTED_PLAN_S = re.compile(r"^(\s*plan s\s+)\d+\.\d+", re.MULTILINE)  # what plan prints: its wall seconds
FLIGHT_HEADING = "== 2/2 fly:"  # demo's line before the flight's, whose figures are timed
# SQLite columns holding a clock time (or, in the ledger, a photo's yaw: see the docstring).
SQLITE_TIMING = {("gpkg_contents", "last_change"), ("flights", "recorded"), ("photos", "time"), ("photos", "yaw")}
# flight.json: what follows the threads' timing (see the docstring).
FLIGHT_TIMING = {"wall_s"}
SEPARATION_MEASURED = {"horizontal", "3d", "pair_horizontal", "pair_3d", "at_s", "start_spread_s"}
DRONE_TIMING = {"flight_s", "samples"}
PHOTO_TIMING = {"time_utc", "yaw_deg"}  # photos.csv columns, photos.geojson properties
NOT_COMPARED = {
    "flight.png": "draws the flown tracks, from telemetry samples placed by the threads' timing",
    "flight.html": "draws the flown tracks, from telemetry samples placed by the threads' timing",
    "flight.gpkg": "holds the flown tracks, from telemetry samples placed by the threads' timing",
    "flight.kmz": "holds the flown tracks, from telemetry samples placed by the threads' timing",
    "journal.sqlite": "every message heard, with its arrival time",
    "journal.commits": "the journal's commit count, which follows the messages' timing",
}
PRINTED = ("stdout", "stderr")  # what the command printed, compared as two more files
LINE_HASH_HEX = 8
MAX_LINE_HASHES = 400  # a longer file is hashed in blocks of lines, to keep the manifests small
SHORT_JSON = 100  # a JSON container whose compact form is at most this long is one line


# ------------------------------------------------------------------ running a case
@contextlib.contextmanager
def _in_repository() -> Iterator[None]:
    """Run from the repository's root, as the docs do: report.json names its inputs as given."""
    before = Path.cwd()
    os.chdir(REPO)
    try:
        yield
    finally:
        os.chdir(before)


def console_script() -> Callable[[list[str]], int]:
    """The function the `missionplan` console script calls, looked up as pip installed it, so the
    cases keep running wherever the command line's code moves."""
    (script,) = importlib.metadata.entry_points(group="console_scripts", name="missionplan")
    return script.load()


def run_case(case: Case, out: Path) -> dict[str, Any]:
    """Run `case` into the folder `out` (which must not exist yet) and return its manifest. The
    manifest's keys starting with `_` (the lines themselves) are not written to the golden file."""
    main = console_script()
    argv = [str(out) if arg == OUT else arg for arg in case.argv]
    printed_out, printed_err = io.StringIO(), io.StringIO()
    with _in_repository(), contextlib.redirect_stdout(printed_out), contextlib.redirect_stderr(printed_err):
        status = main(argv)
    if status != 0:
        raise RuntimeError(f"{case.name}: `{case.command}` exited {status}: {printed_err.getvalue().strip()}")
    files = {name: _text_entry(printed_text(case, text.getvalue(), out), "text")
             for name, text in zip(PRINTED, (printed_out, printed_err))}
    for path in sorted(out.iterdir(), key=lambda p: p.name):
        files[path.name] = file_entry(path, out)
    return {"case": case.name, "command": case.command, "what": case.what, "files": files}


def printed_text(case: Case, text: str, out: Path) -> str:
    text = PRINTED_PLAN_S.sub(r"\g<1>" + NORMALISED, text.replace(str(out), "OUT"))
    if case.is_flight and FLIGHT_HEADING in text:
        text = text[:text.index(FLIGHT_HEADING)] + FLIGHT_HEADING + " " + NORMALISED + "\n"
    return text


# ------------------------------------------------------------------ normalising one file
def file_entry(path: Path, out: Path) -> dict[str, Any]:
    """How one output file is compared, its normalised sha256 and size, and its line hashes (and, for
    report.json and flight.json, the normalised JSON itself)."""
    name = path.name
    if path.is_dir():
        raise RuntimeError(f"{name}/ is a folder: no command here writes one")
    if name in NOT_COMPARED:
        return {"how": "not compared: " + NOT_COMPARED[name]}
    data = path.read_bytes()
    if name == "report.json":
        text = REPORT_TIMING.sub(r'\g<1>"' + NORMALISED + '"', data.decode())
        text = REPORT_GPKG_HASH.sub(r'\g<1>"' + NORMALISED + '"', text)
        return _json_entry(json.loads(text), text, "json, timing normalised", store=True)
    if name == "flight.json":
        record = flight_record(json.loads(data), out)
        return _json_entry(record, json.dumps(record, indent=1) + "\n", "json, timing left out", store=True)
    if name == "photos.geojson":
        doc = json.loads(data)
        for feature in doc["features"]:
            feature["properties"].update(dict.fromkeys(PHOTO_TIMING & feature["properties"].keys(), NORMALISED))
        return _json_entry(doc, json.dumps(doc, indent=1) + "\n", "json, time and yaw normalised")
    if name.endswith((".json", ".geojson", ".plan")):
        return _json_entry(json.loads(data), data.decode(), "json")
    if name.endswith((".gpkg", ".sqlite")):
        return _text_entry(sqlite_rows(path), "sqlite rows, clock times normalised")
    if name == "photos.csv":
        return _text_entry(photos_csv(data.decode()), "csv, time and yaw normalised")
    if name == "geo.txt":
        return _text_entry(geo_txt(data.decode()), "text, yaw normalised")
    if name.endswith(".kmz"):
        return {"how": "bytes", **_digest(data), **_line_hashes(_zip_lines(data))}
    if name.endswith(".png"):
        return {"how": "bytes", **_digest(data)}
    return _text_entry(data.decode(), "text")


def flight_record(doc: dict[str, Any], out: Path) -> dict[str, Any]:
    """flight.json with what follows the threads' timing replaced by NORMALISED (see the docstring)."""
    doc.update(dict.fromkeys(FLIGHT_TIMING & doc.keys(), NORMALISED))
    separation = doc.get("min_separation_m") or {}
    separation.update(dict.fromkeys(SEPARATION_MEASURED & separation.keys(), NORMALISED))
    for drone in doc.get("drones", []):
        drone.update(dict.fromkeys(DRONE_TIMING & drone.keys(), NORMALISED))
        for phase in drone.get("phases", []):
            phase["flown_s"] = NORMALISED
        drone["events"] = [[NORMALISED, what] for _, what in drone.get("events", [])]
        if isinstance(drone.get("last_position"), dict):
            drone["last_position"]["time_utc"] = NORMALISED
    if isinstance(doc.get("survey"), dict) and "root" in doc["survey"]:
        doc["survey"]["root"] = doc["survey"]["root"].replace(str(out), "OUT")
    return doc


def photos_csv(text: str) -> str:
    reader = csv.DictReader(io.StringIO(text))
    target = io.StringIO()
    writer = csv.DictWriter(target, list(reader.fieldnames or []), lineterminator="\n")
    writer.writeheader()
    for row in reader:
        writer.writerow({**row, **dict.fromkeys(PHOTO_TIMING & row.keys(), NORMALISED)})
    return target.getvalue()


def geo_txt(text: str) -> str:
    """OpenDroneMap's geo.txt: a CRS line, then `image x y z yaw pitch roll`; the yaw blanked."""
    lines = text.splitlines()
    photos = [" ".join(parts[:4] + [NORMALISED] + parts[5:]) for parts in (line.split(" ") for line in lines[1:])]
    return "\n".join(lines[:1] + photos) + "\n"


def sqlite_rows(path: Path) -> str:
    """A SQLite file's content as text: application id, version, schema, every table's rows in rowid
    order, SQLITE_TIMING columns blanked. Read from a copy: nothing is added beside the output."""
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / path.name
        copy.write_bytes(path.read_bytes())
        with contextlib.closing(sqlite3.connect(copy)) as db:
            lines = [f"application_id {db.execute('PRAGMA application_id').fetchone()[0]}",
                     f"user_version {db.execute('PRAGMA user_version').fetchone()[0]}"]
            schema = db.execute("SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY type, name").fetchall()
            lines += [f"{kind} {name} on {table}: {sql}" for kind, name, table, sql in schema]
            for kind, table, _, _ in schema:
                if kind != "table":
                    continue
                cursor = db.execute(f'SELECT * FROM "{table}" ORDER BY rowid')
                columns = [column[0] for column in cursor.description]
                blank = {i for i, column in enumerate(columns) if (table, column) in SQLITE_TIMING}
                lines.append(f"rows of {table}: {', '.join(columns)}")
                lines += [repr(tuple(NORMALISED if i in blank else value for i, value in enumerate(row)))
                          for row in cursor]
    return "\n".join(lines) + "\n"


def _zip_lines(data: bytes) -> list[str]:
    """A KMZ's members as lines, each after a header line naming it."""
    lines: list[str] = []
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        for info in archive.infolist():
            lines.append(f"== {info.filename} {info.date_time}")
            lines += archive.read(info).decode("utf-8", "replace").splitlines()
    return lines


def json_lines(value: Any, path: str = "") -> list[str]:
    """`path = value` for every leaf and every container short enough, in document order."""
    compact = json.dumps(value, separators=(",", ":"))
    if not isinstance(value, (dict, list)) or not value or len(compact) <= SHORT_JSON:
        return [f"{path or '.'} = {compact}"]
    if isinstance(value, list):
        return [line for i, item in enumerate(value) for line in json_lines(item, f"{path}[{i}]")]
    return [f"{path or '.'} keys {json.dumps(list(value))}",
            *(line for key, item in value.items() for line in json_lines(item, f"{path}.{key}"))]


# ------------------------------------------------------------------ digests and line hashes
def _digest(data: bytes) -> dict[str, Any]:
    return {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}


def _block_size(count: int) -> int:
    return max(1, math.ceil(count / MAX_LINE_HASHES))


def _line_hashes(lines: list[str]) -> dict[str, Any]:
    """Hashes of the lines (of blocks of `lines_per_hash` lines in a long file), and the lines
    themselves under `_lines`, kept in memory to show a differing one."""
    block = _block_size(len(lines))
    hashes = "".join(hashlib.sha256("\n".join(lines[i:i + block]).encode()).hexdigest()[:LINE_HASH_HEX]
                     for i in range(0, len(lines), block))
    return {"lines": len(lines), "lines_per_hash": block, "line_hashes": hashes, "_lines": lines}


def _text_entry(text: str, how: str) -> dict[str, Any]:
    return {"how": how, **_digest(text.encode()), **_line_hashes(text.splitlines())}


def _json_entry(doc: Any, text: str, how: str, store: bool = False) -> dict[str, Any]:
    return {"how": how, **_digest(text.encode()), **_line_hashes(json_lines(doc)), **({"json": doc} if store else {})}


# ------------------------------------------------------------------ comparing
def _show(value: Any, width: int = 120) -> str:
    text = json.dumps(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def json_differences(golden: Any, now: Any, shown: int = 5) -> list[str]:
    """The first `shown` differences between two JSON values, each `path: golden X, now Y`, in document
    order, and how many more there are."""
    found: list[str] = []

    def walk(a: Any, b: Any, where: str) -> None:
        if isinstance(a, dict) and isinstance(b, dict):
            for key in [*a, *(k for k in b if k not in a)]:
                if key not in b:
                    found.append(f"{where}.{key}: golden {_show(a[key])}, now missing")
                elif key not in a:
                    found.append(f"{where}.{key}: new, {_show(b[key])}")
                else:
                    walk(a[key], b[key], f"{where}.{key}")
            if list(a) != list(b) and set(a) == set(b):
                found.append(f"{where or '.'}: the keys in another order: golden {list(a)}, now {list(b)}")
        elif isinstance(a, list) and isinstance(b, list):
            for i, (x, y) in enumerate(zip(a, b)):
                walk(x, y, f"{where}[{i}]")
            if len(a) != len(b):
                found.append(f"{where}: golden {len(a)} items, now {len(b)}")
        elif a != b or type(a) is not type(b):
            found.append(f"{where or '.'}: golden {_show(a)}, now {_show(b)}")

    walk(golden, now, "")
    more = [f"... and {len(found) - shown} more"] if len(found) > shown else []
    return found[:shown] + more


def first_differing_line(golden: dict[str, Any], now: dict[str, Any]) -> str:
    """Where the lines first differ, with the new line (the golden file has only their hashes)."""
    lines, block = now["_lines"], golden["lines_per_hash"]
    again = "".join(hashlib.sha256("\n".join(lines[i:i + block]).encode()).hexdigest()[:LINE_HASH_HEX]
                    for i in range(0, len(lines), block))
    want = golden["line_hashes"]
    for start in range(0, min(len(want), len(again)), LINE_HASH_HEX):
        if want[start:start + LINE_HASH_HEX] != again[start:start + LINE_HASH_HEX]:
            first = start // LINE_HASH_HEX * block
            shown = "\n      ".join(line if len(line) <= 200 else line[:197] + "..."
                                     for line in lines[first:first + min(block, 3)])
            where = f"line {first + 1}" if block == 1 else f"lines {first + 1}-{first + block} (hashed as one block)"
            return f"first differs at {where} of {golden['lines']} golden, {len(lines)} now; now:\n      {shown}"
    if golden["lines"] != len(lines):
        return f"{golden['lines']} lines golden, {len(lines)} now; the common ones are the same"
    return "the same lines: the line endings, the final newline or the bytes outside the lines differ"


def compare(golden: dict[str, Any], now: dict[str, Any]) -> list[str]:
    """What differs between a golden manifest and a fresh one, a readable paragraph each ([] when equal)."""
    case = golden["case"]
    problems: list[str] = []
    missing = sorted(set(golden["files"]) - set(now["files"]))
    new = sorted(set(now["files"]) - set(golden["files"]))
    if missing or new:
        problems.append(f"{case}: the files written differ: missing {missing or 'none'}, new {new or 'none'}")
    for name, want in golden["files"].items():
        got = now["files"].get(name)
        if got is None or "sha256" not in want or _public(got) == want:
            continue
        where = (f"{case}: {name} ({want['how']}): sha256 {got.get('sha256', '-')[:12]} "
                 f"(golden {want['sha256'][:12]}), size {got.get('size')} (golden {want['size']})")
        if "json" in want and "json" in got:
            details = json_differences(want["json"], got["json"]) or [first_differing_line(want, got)]
            problems.append(f"{where}\n    " + "\n    ".join(details))
        elif "line_hashes" in want and "_lines" in got:
            problems.append(f"{where}\n    {first_differing_line(want, got)}")
        else:
            problems.append(where)
    return problems


# ------------------------------------------------------------------ the golden files
def _public(entry: dict[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in entry.items() if not key.startswith("_")}


def golden_path(case: Case) -> Path:
    return GOLDEN / f"{case.name}.json"


def load_golden(case: Case) -> dict[str, Any]:
    return json.loads(golden_path(case).read_text())


def write_golden(found: dict[str, Any]) -> None:
    """One line per file, so that a rewritten manifest's diff says which files changed."""
    head = [f" {json.dumps(key)}: {json.dumps(found[key])}," for key in ("case", "command", "what")]
    files = [f"  {json.dumps(name)}: {json.dumps(_public(entry), separators=(',', ':'))}"
             for name, entry in found["files"].items()]
    text = "{\n" + "\n".join(head) + '\n "files": {\n' + ",\n".join(files) + "\n }\n}\n"
    golden_path(BY_NAME[found["case"]]).write_text(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Compare the golden cases with tests/golden/, or rewrite it.")
    parser.add_argument("cases", nargs="*", help=f"case names (default: all): {', '.join(BY_NAME)}")
    parser.add_argument("--write", action="store_true", help="rewrite the manifests, after --runs equal runs")
    parser.add_argument("--runs", type=int, default=3, help="runs of each case that must agree (default 3)")
    args = parser.parse_args(argv)
    unknown = [name for name in args.cases if name not in BY_NAME]
    if unknown:
        parser.error(f"no case {', '.join(unknown)}; the cases: {', '.join(BY_NAME)}")
    failed = 0
    for case in [BY_NAME[name] for name in args.cases] or list(CASES):
        if case.needs is not None and not case.needs.exists():
            print(f"{case.name}: skipped, {case.needs} is absent")
            continue
        with tempfile.TemporaryDirectory(prefix=f"golden-{case.name}-") as tmp:
            started = time.perf_counter()
            runs = [run_case(case, Path(tmp) / f"run{i}") for i in range(1, max(args.runs, 1) + 1)]
            each = f"{(time.perf_counter() - started) / len(runs):.1f} s each"
        unstable = [problem for found in runs[1:] for problem in compare(public_manifest(runs[0]), found)]
        if unstable:
            failed += 1
            print(f"{case.name}: NOT THE SAME over {len(runs)} runs ({each}), nothing written:\n  "
                  + "\n  ".join(unstable))
        elif args.write:
            write_golden(runs[0])
            print(f"{case.name}: {len(runs)} equal runs ({each}), wrote {golden_path(case).relative_to(REPO)}")
        elif not golden_path(case).exists():
            failed += 1
            print(f"{case.name}: {len(runs)} equal runs ({each}); no golden file yet (--write writes it)")
        else:
            problems = compare(load_golden(case), runs[0])
            failed += bool(problems)
            print(f"{case.name}: {len(runs)} equal runs ({each}), "
                  + ("the same as golden" if not problems else "DIFFERS from golden:\n  " + "\n  ".join(problems)))
    return 1 if failed else 0


def public_manifest(found: dict[str, Any]) -> dict[str, Any]:
    return {**found, "files": {name: _public(entry) for name, entry in found["files"].items()}}


if __name__ == "__main__":
    sys.exit(main())
