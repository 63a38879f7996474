"""Roof targets (`plan --targets streets|roofs|all`): the roofs low enough to overfly become targets, the
cell is sized at the highest of them, the clearance over every roof holds along the legs, buildings taller
than the flight stay obstacles, and the plan and the flight judge give coverage per class.

The real-city cases read ../shared/maps/ in place (OpenStreetMap data, © OpenStreetMap contributors, ODbL)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely

from missionplan.cli import main
from missionplan.geo.readers import read_building_file
from missionplan.geo.roofs import footprint_at, gsd_at, roof_cell_m
from missionplan.mission.plan_record import read_plan_record

TURIN_OSM = Path(__file__).resolve().parents[2] / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"
needs_osm = pytest.mark.skipif(not TURIN_OSM.is_file(), reason=f"{TURIN_OSM} is absent (../shared/maps)")
# A Turin block: courtyard buildings of 3 to 14 m, overflown at 20 m, and 17.5 to 21 m ones that are not.
BLOCK = [[7.6530, 45.0688], [7.6550, 45.0688], [7.6550, 45.0700], [7.6530, 45.0700], [7.6530, 45.0688]]
LAUNCH = "45.06885,7.65305"
ALTITUDE, FOV, MARGIN = 20.0, 84.0, 5.0  # MARGIN: the georeference's safety margin under the flight height


def _area(folder: Path, ring: list[list[float]] = BLOCK) -> Path:
    path = folder / "block.geojson"
    path.write_text(json.dumps({"type": "Feature", "properties": {"name": "block"},
                                "geometry": {"type": "Polygon", "coordinates": [ring]}}))
    return path


def _plan(folder: Path, targets: str | None, *more: str) -> tuple[int, Path]:
    out = folder / f"plan-{targets or 'default'}"
    args = ["plan", "--area", str(_area(folder)), "--osm", str(TURIN_OSM), "--launch", LAUNCH,
            "--altitude", f"{ALTITUDE:g}", "--fov", f"{FOV:g}", "--out", str(out), "--quiet", *more]
    return main(args + (["--targets", targets] if targets else [])), out


def _grid(out: Path) -> np.ndarray:
    return np.array([list(row) for row in read_plan_record(out).grid])


def _buildings_in_block() -> list:
    buildings, _ = read_building_file(TURIN_OSM, None)
    area = shapely.Polygon(BLOCK)
    return [b for b in buildings if b.geometry.intersects(area)]


@pytest.fixture(scope="module")
def all_targets(tmp_path_factory):
    folder = tmp_path_factory.mktemp("roofs-all")
    code, out = _plan(folder, "all")
    assert code == 0
    return out


# ------------------------------------------------------------------------------------------- the rules
def test_the_footprint_and_the_gsd_shrink_with_the_roof_height() -> None:
    assert footprint_at(36.0, 20.0, 0.0) == 36.0
    assert footprint_at(36.0, 20.0, 14.0) == pytest.approx(10.8)
    assert gsd_at(2.0, 30.0, 18.0) == pytest.approx(0.8)  # 12 m from the camera instead of 30
    # the cell at an 18 m roof from 30 m with a 84 degree camera: 2 * 12 * tan(42) / 9
    assert roof_cell_m(30.0, 84.0, 18.0) == pytest.approx(2 * 12 * math.tan(math.radians(42)) / 9)


@needs_osm
def test_the_cell_is_the_footprint_at_the_highest_roof_target_over_nine(all_targets: Path) -> None:
    record = read_plan_record(all_targets)
    low = [b.height_m for b in _buildings_in_block() if b.height_m is not None and b.height_m < ALTITUDE - MARGIN]
    highest = max(low)
    assert highest == 14.0  # the block's highest roof under 15 m
    ground = 2 * ALTITUDE * math.tan(math.radians(FOV / 2))
    assert record.georeference is not None
    assert record.georeference.cell_m == pytest.approx(ground * (ALTITUDE - highest) / ALTITUDE / 9)
    roofs = record.roofs
    assert roofs is not None and roofs.highest_roof_m == highest
    assert roofs.rule == f"cell {record.georeference.cell_m:.2f} m: the footprint at the highest roof (14 m) / 9"
    assert roofs.footprint_at_ground_m == pytest.approx(ground, abs=0.01)
    assert roofs.footprint_at_highest_roof_m == pytest.approx(ground * 6 / 20, abs=0.01)


@needs_osm
def test_all_targets_cover_every_reachable_roof_and_street(all_targets: Path) -> None:
    record = read_plan_record(all_targets)
    grid = _grid(all_targets)
    assert (grid == "r").sum() > 500 and (grid == ".").sum() > 5000
    assert record.roofs is not None
    roofs, streets = record.roofs.coverage_of("roofs"), record.roofs.coverage_of("streets")
    assert roofs is not None and streets is not None
    unreachable = {tuple(c) for c in record.unreachable_cells}
    reachable_roofs = sum(1 for r, c in zip(*np.nonzero(grid == "r")) if (r, c) not in unreachable)
    assert roofs.targets == reachable_roofs and roofs.covered == roofs.targets and roofs.pct == 100.0
    assert streets.pct == 100.0 and roofs.targets + streets.targets == record.targets


@needs_osm
def test_the_clearance_over_every_roof_holds_along_every_leg(all_targets: Path) -> None:
    """From the written paths (tracks.geojson, lon / lat / metres up) and the buildings themselves: wherever
    a leg passes over a roof, it is at least the margin above it; and the report says the smallest."""
    layers = json.loads((all_targets / "tracks.geojson").read_text())
    legs = [f for f in layers["features"] if f["properties"]["layer"] == "paths"]
    buildings = _buildings_in_block()
    smallest = math.inf
    crossed = 0
    for leg in legs:
        points = np.asarray(leg["geometry"]["coordinates"], dtype=float)
        cruise = points[points[:, 2] > 0]
        for a, b in zip(cruise[:-1], cruise[1:]):
            segment = shapely.LineString([a[:2], b[:2]])
            for building in buildings:
                if building.geometry.intersects(segment):
                    assert building.height_m is not None, "a building of unknown height is an obstacle"
                    crossed += 1
                    smallest = min(smallest, min(a[2], b[2]) - building.height_m)
    assert crossed > 0 and smallest >= MARGIN
    vertical = read_plan_record(all_targets).roofs.vertical
    assert vertical is not None and vertical.kept and vertical.required_m == MARGIN
    assert vertical.kept_m == pytest.approx(smallest, abs=0.01)


@needs_osm
def test_a_building_taller_than_the_flight_stays_an_obstacle(all_targets: Path) -> None:
    record = read_plan_record(all_targets)
    frame = record.georeference.frame
    grid = _grid(all_targets)
    tall = [b for b in _buildings_in_block() if b.height_m is not None and b.height_m > ALTITUDE]
    assert tall, "the block has a building taller than the flight"
    for building in tall:
        centre = building.geometry.representative_point()
        row, col = (int(v) for v in frame.latlon_to_cell(centre.y, centre.x))
        if frame.contains_cell(row, col):
            assert grid[row, col] == "#"


@needs_osm
def test_roofs_alone_leave_the_street_cells_untargeted(tmp_path: Path, all_targets: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    code, out = _plan(tmp_path, "roofs")
    assert code == 0
    grid, with_all = _grid(out), _grid(all_targets)
    assert (grid == ".").sum() == 0
    assert np.array_equal(grid == "r", with_all == "r")  # the same roofs, the same grid
    assert np.all(grid[with_all == "."] == "o")  # every street cell flown over, never a target
    record = read_plan_record(out)
    assert [c.name for c in record.roofs.by_class] == ["roofs"] and record.roofs.by_class[0].pct == 100.0
    printed = capsys.readouterr().out
    assert "targets: the roofs low enough to overfly (--targets roofs); cell 1.20 m: the footprint at the " \
           "highest roof (14 m) / 9" in printed
    assert "coverage roofs    100.0 %" in printed and "clearance over roofs: 6 m vertical at the least" in printed
    layers = json.loads((out / "tracks.geojson").read_text())
    assert [f["properties"]["cells"] for f in layers["features"] if f["properties"]["layer"] == "roofs"] == \
        [int((grid == "r").sum())]


@needs_osm
def test_the_default_plans_the_streets_as_before(tmp_path: Path) -> None:
    code, out = _plan(tmp_path, None)
    assert code == 0
    doc = json.loads((out / "report.json").read_text())
    assert "roofs" not in doc and not any("r" in row for row in doc["grid"])
    footprint = 2 * ALTITUDE * math.tan(math.radians(FOV / 2))
    assert float(doc["georeference"]["cell_m"]) == pytest.approx(footprint / 9)


# ------------------------------------------------------------------------------------------- --map
def test_roof_targets_on_a_map_without_a_roof_layer_are_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["plan", "--map", "leonardo", "--uavs", "1", "--targets", "all", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("missionplan: --targets all: map leonardo has no roof layer")
    assert not (tmp_path / "x").exists()


def test_a_map_with_a_roof_layer_plans_the_classes_asked(tmp_path: Path) -> None:
    from missionplan.maps.catalog import load_shipped
    from missionplan.maps.gridmap import GridMap, save_map

    base = load_shipped("leonardo")
    roof = np.zeros(base.shape, dtype=bool)
    rows, cols = np.nonzero(base.target)
    roof[rows[: len(rows) // 3], cols[: len(cols) // 3]] = True  # a third of the targets are roofs
    path = tmp_path / "roofed.map"
    save_map(GridMap(base.name, base.obstacle, base.target, base.launch, dict(base.meta), roof=roof), path)
    for targets, classes in (("roofs", ["roofs"]), ("all", ["streets", "roofs"]), ("streets", None)):
        out = tmp_path / targets
        assert main(["plan", "--map", str(path), "--uavs", "2", "--targets", targets, "--out", str(out),
                     "--quiet"]) == 0
        record = read_plan_record(out)
        grid = _grid(out)
        if classes is None:  # streets: the roofs are flown over, as before roofs could be targets
            assert record.roofs is None and (grid == "r").sum() == 0
            continue
        assert [c.name for c in record.roofs.by_class] == classes and record.roofs.vertical is None
        assert record.roofs.rule.endswith("as the map gives it (its roofs have no heights)")
        assert ((grid == ".").sum() == 0) == (targets == "roofs")
        assert (grid == "r").sum() == int(roof.sum())


# ------------------------------------------------------------------------------------------- the judge
@needs_osm
@pytest.mark.flight
def test_the_judge_of_a_mock_flight_gives_coverage_per_class(tmp_path: Path) -> None:
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet

    small = [[7.6530, 45.0688], [7.6541, 45.0688], [7.6541, 45.0696], [7.6530, 45.0696], [7.6530, 45.0688]]
    out = tmp_path / "flown"
    assert main(["plan", "--area", str(_area(tmp_path, small)), "--osm", str(TURIN_OSM), "--launch", LAUNCH,
                 "--altitude", "20", "--fov", "84", "--targets", "all", "--speed", "10", "--out", str(out),
                 "--quiet"]) == 0
    planned = read_plan_record(out).roofs
    mock = start_mock_fleet(out, speedup=20.0)
    try:
        result = fly(out, mock.client_url, timeout_s=120, progress=False, time_scale=20.0, telemetry_hz=50.0)
    finally:
        mock.stop()
    assert result.ok, result.problems
    by_class = json.loads((out / "flight.json").read_text())["coverage_by_class"]
    assert list(by_class) == ["streets", "roofs"]
    assert {name: block["targets"] for name, block in by_class.items()} == \
        {c.name: c.targets for c in planned.by_class}
    assert by_class["roofs"]["targets"] > 0 and by_class["roofs"]["coverage_pct"] >= 99.0
    assert sum(b["targets"] for b in by_class.values()) == result.targets
