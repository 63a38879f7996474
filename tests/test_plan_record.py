"""The plan record (missionplan/mission/plan_record.py, plan_blocks.py, geo/georeference.py): every block goes
through to_json / from_json and back unchanged, report.json files written before the record existed are read
and written again byte for byte, and a report.json of a schema version this missionplan does not know fails
in one line naming the file and the version."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from missionplan.cli import main
from missionplan.geo.camera import Camera
from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import Georeference, TerrainRecord
from missionplan.geo.sources import Omission
from missionplan.mission.drone_missions import MissionSettings
from missionplan.mission.plan_blocks import (BandCounts, BuildingsRead, ClearancePromise, Closest, CoverageSummary,
                                             Decisions, DronePlan, FencePlan, InputFile, PathShape, PlanMetrics,
                                             PlanSettings, SafetyPromise, SeparationPromise, SmallShare, SortiePlan,
                                             SurveyPointer, Timing)
from missionplan.mission.photo_overlap import OverlapMeasure, OverlapSpread
from missionplan.mission.plan_record import (SCHEMA_VERSION, PlanRecord, PlanRecordError, read_plan_record,
                                             write_plan_record)
from missionplan.mission.roof_targets import ClassCoverage, RoofTargets, VerticalClearance
from missionplan.mission.safety import SafetySettings

RECORDS = Path(__file__).resolve().parent / "data" / "plan_records"
EARLIER = sorted(p.parent.name for p in RECORDS.glob("*/report.json"))

# ------------------------------------------------------------------------------------------- strategies
numbers = st.floats(allow_nan=False, allow_infinity=False, width=64) | st.integers(-10**6, 10**6)
maybe_numbers = st.none() | numbers
counts = st.integers(0, 10**6)
texts = st.text(max_size=12)
cells = st.tuples(st.integers(0, 500), st.integers(0, 500))


def tuples(strategy: st.SearchStrategy[Any], max_size: int = 4) -> st.SearchStrategy[tuple[Any, ...]]:
    return st.lists(strategy, max_size=max_size).map(tuple)


frames = st.builds(GridFrame.at, st.floats(-60, 60), st.floats(-179, 179), st.floats(0.1, 50), st.integers(1, 40),
                   st.integers(1, 40), st.floats(-360, 360))
metrics = st.builds(PlanMetrics, numbers, numbers, numbers, maybe_numbers, maybe_numbers, numbers, counts, counts)
decisions = st.builds(Decisions, tuples(counts), tuples(counts), tuples(counts))
timings = st.builds(Timing, numbers, numbers)
shapes = st.builds(PathShape, counts, numbers, numbers)
sorties = st.builds(SortiePlan, texts, numbers, counts, counts)
fences = st.builds(FencePlan, counts, numbers, maybe_numbers)
drones = st.builds(DronePlan, counts, counts, counts, numbers, numbers, counts, numbers, shapes, shapes,
                   tuples(sorties), st.none() | fences, st.none() | st.tuples(numbers, numbers))
closest = st.builds(Closest, maybe_numbers, maybe_numbers, tuples(counts, 2), tuples(counts, 2), maybe_numbers)
separations = st.one_of(
    st.builds(SeparationPromise, closest, st.none() | counts, texts, tuples(closest)),
    st.builds(SeparationPromise, closest, st.none() | counts, texts, tuples(closest), maybe_numbers, texts,
              maybe_numbers, maybe_numbers))
bands = st.builds(BandCounts, counts, counts, counts, counts)
clearances = st.one_of(
    st.builds(ClearancePromise, maybe_numbers, maybe_numbers, tuples(maybe_numbers), st.booleans(),
              band_moves_added=st.none() | counts, band=st.none() | bands),
    st.builds(ClearancePromise, maybe_numbers, maybe_numbers, tuples(maybe_numbers), st.booleans(), counts,
              st.tuples(numbers, numbers), st.none() | counts, st.none() | bands))
promises = st.builds(SafetyPromise, separations, clearances)
small_shares = st.builds(SmallShare, counts, counts, numbers, counts)
spreads = st.builds(OverlapSpread, numbers, numbers, counts)
overlaps = st.builds(OverlapMeasure, numbers, counts, counts, st.none() | spreads, st.none() | spreads, maybe_numbers,
                     maybe_numbers, counts, numbers, counts, counts, maybe_numbers, st.none() | counts,
                     st.none() | counts, counts, st.none() | st.booleans())
coverages = st.builds(CoverageSummary, numbers, numbers, counts, counts, counts, counts, numbers, st.none() | counts,
                      maybe_numbers, st.none() | counts, st.none() | counts, tuples(small_shares), tuples(texts),
                      st.none() | overlaps)
omissions = st.builds(Omission, texts, texts)
inputs = st.builds(InputFile, texts, texts, texts, texts, st.none() | texts, texts, st.booleans(), counts,
                   tuples(omissions), tuples(omissions), tuples(texts),
                   st.none() | st.builds(BuildingsRead, counts, tuples(texts), maybe_numbers, st.none() | texts))
mission_settings = st.builds(MissionSettings, numbers, numbers, numbers, numbers, texts, numbers, texts)
safety_settings = st.builds(SafetySettings, numbers, numbers, numbers, maybe_numbers, numbers)
plan_settings = st.builds(PlanSettings, mission_settings, safety_settings, texts, texts, st.booleans(), texts)
pointers = st.builds(SurveyPointer, texts, st.none() | counts, st.none() | texts)
terrains = st.builds(TerrainRecord, tuples(texts), tuples(texts), tuples(texts), numbers, numbers, numbers,
                     st.none() | counts)
verticals = st.builds(VerticalClearance, numbers, maybe_numbers, tuples(maybe_numbers), counts)
roof_targets = st.builds(RoofTargets, st.sampled_from(["streets", "roofs", "all"]), numbers, maybe_numbers, texts,
                         maybe_numbers, maybe_numbers, maybe_numbers, maybe_numbers,
                         st.sampled_from([(), (ClassCoverage("roofs", 3, 2),),
                                          (ClassCoverage("streets", 10, 10), ClassCoverage("roofs", 0, 0))]),
                         st.none() | verticals)


@st.composite
def records(draw: st.DrawFn) -> PlanRecord:
    rows, cols = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    grid = tuple(draw(st.text(alphabet="#.or", min_size=cols, max_size=cols)) for _ in range(rows))
    georef = None
    if draw(st.booleans()):
        frame = draw(frames)
        frame = GridFrame(frame.utm_epsg, frame.origin_e, frame.origin_n, frame.cell_m, rows, cols, frame.rotation_deg)
        georef = Georeference(frame, draw(maybe_numbers), trigger_distance_m=draw(maybe_numbers),
                              terrain=draw(st.none() | terrains))
    return PlanRecord(
        draw(texts), draw(counts), draw(texts), draw(texts), draw(st.booleans()), draw(tuples(counts)), draw(counts),
        draw(st.booleans()), draw(st.none() | texts), draw(metrics), draw(counts), draw(counts), draw(tuples(cells)),
        draw(numbers), draw(counts), draw(counts), draw(counts), draw(decisions), draw(timings), draw(tuples(cells)),
        draw(tuples(tuples(cells), 3)), grid, draw(st.none() | tuples(numbers)), draw(st.none() | tuples(drones, 2)),
        draw(st.none() | promises), draw(st.none() | plan_settings), draw(st.none() | tuples(counts)),
        draw(st.none() | pointers), draw(st.none() | texts), draw(st.none() | texts), georef,
        draw(st.none() | coverages), draw(st.none() | tuples(inputs, 2)), draw(st.none() | tuples(texts)),
        draw(st.none() | st.dictionaries(texts, texts, max_size=3)), draw(st.none() | roof_targets))


def through_json(doc: dict[str, Any]) -> Any:
    """What report.json gives back of `doc`."""
    return json.loads(json.dumps(doc, indent=1))


# ------------------------------------------------------------------------------------------- round trips
BLOCKS = [(PlanMetrics, metrics), (Decisions, decisions), (Timing, timings), (PathShape, shapes),
          (SortiePlan, sorties), (FencePlan, fences), (DronePlan, drones), (Closest, closest),
          (SeparationPromise, separations), (BandCounts, bands), (ClearancePromise, clearances),
          (SmallShare, small_shares), (OverlapMeasure, overlaps), (CoverageSummary, coverages), (InputFile, inputs),
          (PlanSettings, plan_settings), (SurveyPointer, pointers), (Omission, omissions), (TerrainRecord, terrains),
          (VerticalClearance, verticals), (RoofTargets, roof_targets), (PlanRecord, records())]


@pytest.mark.parametrize("cls, strategy", BLOCKS, ids=[cls.__name__ for cls, _ in BLOCKS])
def test_every_block_goes_through_json_and_back(cls: Any, strategy: st.SearchStrategy[Any]) -> None:
    @settings(max_examples=40, deadline=None)
    @given(strategy)
    def round_trip(block: Any) -> None:
        assert cls.from_json(through_json(block.to_json())) == block

    round_trip()


@settings(max_examples=40, deadline=None)
@given(frames, maybe_numbers, maybe_numbers)
def test_a_georeference_goes_through_report_json_and_back(frame: GridFrame, altitude: float | None,
                                                           trigger: float | None) -> None:
    georef = Georeference(frame, altitude, trigger_distance_m=trigger)
    doc = through_json(georef.to_json())
    assert Georeference.from_json(doc, frame.rows, frame.cols) == georef
    assert doc["footprint_m"] == 9 * frame.cell_m  # written, never stored apart from the cell


@settings(max_examples=30, deadline=None)
@given(records())
def test_a_plan_is_written_in_the_oldest_version_that_holds_it(record: PlanRecord) -> None:
    """A missionplan that cannot fly terrain refuses a terrain plan (2), one that knows no capture a capture plan
    (3: a camera block, roof targets or a MAVLink camera's capture); a flat street plan stays version 1."""
    doc = through_json(record.to_json())
    georef = record.georeference
    terrain = georef is not None and georef.terrain is not None
    mission = record.settings.mission if record.settings is not None else None
    capture = (georef is not None and georef.capture is not None) or record.roofs is not None or (
        mission is not None and (mission.capture != "relay" or mission.gimbal_pitch_deg != -90.0))
    if capture:
        assert next(iter(doc)) == "schema_version" and doc["schema_version"] == 3
    elif terrain:
        assert next(iter(doc)) == "schema_version" and doc["schema_version"] == 2
    else:
        assert "schema_version" not in doc and "terrain" not in (doc.get("georeference") or {})
    if terrain:
        assert doc["georeference"]["terrain"]["files"] == list(georef.terrain.files)
    assert PlanRecord.from_json(doc) == record


@settings(max_examples=40, deadline=None)
@given(frames, st.none() | st.floats(0.5, 500), st.none() | st.floats(1, 179), st.none() | st.floats(0, 50))
def test_a_georeference_goes_through_map_header_lines_and_back(frame: GridFrame, altitude: float | None,
                                                               fov: float | None, margin: float | None) -> None:
    georef = Georeference(frame, altitude, Camera(fov) if fov is not None else None, margin)
    header = georef.to_header()
    assert all(isinstance(value, str) for value in header.values())
    assert Georeference.from_header(header, frame.rows, frame.cols) == georef


def test_a_camera_goes_through_json_and_back() -> None:
    camera = Camera.from_sensor(13.2, 8.8, 8.8)
    assert Camera.from_json(through_json(camera.to_json())) == camera


# ------------------------------------------------------------------------------------------- earlier report.json
@pytest.mark.parametrize("name", EARLIER)
def test_a_report_json_written_before_the_record_is_read_and_written_again_byte_for_byte(name: str,
                                                                                        tmp_path: Path) -> None:
    record = read_plan_record(RECORDS / name)
    assert record.targets > 0
    write_plan_record(record, tmp_path / "report.json")
    assert (tmp_path / "report.json").read_bytes() == (RECORDS / name / "report.json").read_bytes()


def test_the_earlier_reports_hold_every_block() -> None:
    # What the files in tests/data/plan_records are there for: each block read from a real report.json.
    read = {name: read_plan_record(RECORDS / name) for name in EARLIER}
    leonardo, rest, turin, yard = read["leonardo-3"], read["leonardo-3-rest"], read["turin-corner"], read["yard"]
    assert leonardo.basemap and leonardo.georeference is not None and leonardo.settings is not None
    assert leonardo.georeference.footprint_m == leonardo.settings.mission.footprint_m
    assert rest.survey == SurveyPointer("../leonardo-3", rest.survey.missing_cells, "../leonardo-3")
    assert rest.drone_ids == (1, 3) and [d.id for d in rest.drones or ()] == [1, 3]
    assert turin.inputs is not None and turin.inputs[1].buildings is not None and turin.inputs[1].buildings.in_area > 0
    assert turin.clearance is not None and turin.clearance.band is not None
    assert all(len(d.sorties) == 3 for d in turin.drones or ()) and turin.coverage and turin.coverage.warnings
    assert yard.georeference is None and yard.drones is None and yard.promise is None and yard.files == (
        "plan.png", "report.json")


def test_a_written_plan_reads_back_as_the_record_it_was_written_from(tmp_path: Path) -> None:
    from missionplan.planning.plan_folder import PlanOptions, shipped_ground, write_plan_folder

    folder = write_plan_folder(tmp_path / "leo", shipped_ground("leonardo", 3), PlanOptions())
    assert read_plan_record(tmp_path / "leo") == folder.record


# ------------------------------------------------------------------------------------------- what cannot be read
def _with(tmp_path: Path, **changes: Any) -> Path:
    folder = tmp_path / "plan"
    shutil.copytree(RECORDS / "leonardo-3", folder)
    doc = json.loads((folder / "report.json").read_text())
    doc.update(changes)
    (folder / "report.json").write_text(json.dumps(doc))
    return folder


@pytest.mark.parametrize("version", [SCHEMA_VERSION + 1, "2", 0, None, True])
def test_a_report_json_of_an_unknown_schema_version_fails_in_one_line(tmp_path: Path, version: Any) -> None:
    folder = _with(tmp_path, schema_version=version)
    with pytest.raises(PlanRecordError) as caught:
        read_plan_record(folder)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"{folder / 'report.json'}: schema version {version!r}")
    assert f"reads up to version {SCHEMA_VERSION}" in message


def test_the_cli_says_which_file_and_version_it_cannot_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _with(tmp_path, schema_version=7)
    assert main(["status", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"missionplan: {folder / 'report.json'}: schema version 7, and this missionplan reads up to "
                   f"version {SCHEMA_VERSION}: a newer missionplan wrote it (update missionplan to read it)"]


def test_what_is_no_plan_report_fails_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(PlanRecordError, match=r": no report.json \(not a plan folder"):
        read_plan_record(tmp_path)
    (tmp_path / "report.json").write_text("{not json")
    with pytest.raises(PlanRecordError, match=r"report.json: cannot be read \("):
        read_plan_record(tmp_path)
    (tmp_path / "report.json").write_text(json.dumps({"grid": ["..."]}))
    with pytest.raises(PlanRecordError, match=r"report.json: not a missionplan plan report \(no 'map'\)$"):
        read_plan_record(tmp_path)
    folder = _with(tmp_path, drones=[{"id": 1}])
    with pytest.raises(PlanRecordError, match=r"report.json: not a missionplan plan report \(no 'smoothing'\)$"):
        read_plan_record(folder)
