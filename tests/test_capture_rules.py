"""The capture rules (geo/capture.py) against hand-computed numbers, the camera catalogue, and `plan`'s capture
options: the height a GSD gives, the trigger distance and lane spacing the overlaps give, the speed the camera's
capture interval allows, each refusal in one line, the camera block of report.json (schema version 3) read back,
and open-ground lanes as close as the side overlap asks."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from missionplan.cli import main
from missionplan.geo.camera import Camera
from missionplan.geo.camera_catalogue import CATALOGUE, camera, find
from missionplan.geo.capture import (CapturePlan, choose_speed, gsd_cm, height_for_gsd, lane_spacing_cells, shown,
                                     trigger_distance_m)
from missionplan.geo.errors import GeoError
from missionplan.maps.gridmap import GridMap, save_map
from missionplan.mission.plan_record import CAPTURE_VERSION, read_plan_record, report_path, write_plan_record
from missionplan.planning.pipeline import plan_map

AREA = Path(__file__).resolve().parents[1] / "examples" / "turin-cenisia-area.geojson"
LAUNCH = "45.069450,7.652588"


# ------------------------------------------------------------------------------------------- the rules by hand
@pytest.mark.parametrize("name, gsd, height", [
    # 1-inch 20 MP, 8.8 mm: 13.2 mm / 5472 px = 8.8 mm / 3648 px; H = 0.010 m x 8.8 mm x 5472 / 13.2 mm = 36.48 m.
    ("dji-phantom4pro", 1.0, 0.010 * 8.8 * 5472 / 13.2),
    # APS-C 16 mm: the width's pixels are larger (23.5 / 6000 > 15.6 / 4000): H = 0.02 x 16 x 6000 / 23.5.
    ("sony-a6000-16mm", 2.0, 0.02 * 16 * 6000 / 23.5),
    # Full frame 35 mm: the height's pixels are larger (24 / 5460 > 35.9 / 8192): H = 0.01 x 35 x 5460 / 24.
    ("dji-zenmuse-p1-35mm", 1.0, 0.01 * 35 * 5460 / 24.0),
    # RedEdge-MX: 8 cm/px at 115.2 m (its sheet: 8 cm per pixel at 120 m, rounded).
    ("micasense-rededge-mx", 8.0, 0.08 * 5.4 * 1280 / 4.8),
])
def test_height_from_gsd_for_catalogue_cameras(name: str, gsd: float, height: float) -> None:
    cam = camera(name)
    assert height_for_gsd(cam, gsd) == pytest.approx(height, rel=1e-12)
    assert gsd_cm(cam, height) == pytest.approx(gsd, rel=1e-12)  # the inverse


def test_the_worked_one_inch_example() -> None:
    cam = camera("dji-phantom4pro")
    height = height_for_gsd(cam, 1.0)
    assert height == pytest.approx(36.48)
    footprint = cam.footprint_side_m(height)
    assert footprint == pytest.approx(36.48 * 8.8 / 8.8)  # S = H x min(w, h) / f
    plan = CapturePlan(cam, height, footprint, 0.80, 0.70, *choose_speed(cam, trigger_distance_m(footprint, 0.8), None),
                       gsd_asked_cm=1.0)
    assert plan.trigger_m == pytest.approx(36.48 * 0.2)  # 7.296 m
    assert plan.lane_spacing_cells == 2 and plan.lane_spacing_m == pytest.approx(2 * 36.48 / 9)
    assert plan.fastest_speed_m_s == pytest.approx(7.296 / 2.0)
    assert (plan.speed_m_s, plan.speed_from) == (pytest.approx(3.648), "limit")
    assert plan.rule_lines()[0] == ("height 36.5 m  from GSD 1 cm/px: H = GSD x f x image width / "
                                    "(100 x sensor width)")


@pytest.mark.parametrize("side, cells", [(None, 9), (0.0, 9), (0.05, 8), (0.5, 4), (2 / 3, 3), (0.7, 2),
                                         (0.8, 1), (0.888, 1)])
def test_lane_spacing_from_the_side_overlap(side: float | None, cells: int) -> None:
    assert lane_spacing_cells(side) == cells


def test_a_side_overlap_leaving_lanes_under_a_cell_apart_is_refused() -> None:
    with pytest.raises(GeoError, match=r"side_overlap 95 %: lanes 0.45 cells apart.*at most 88.9 %"):
        lane_spacing_cells(0.95)


@pytest.mark.parametrize("front, trigger", [(8 / 9, 4.0), (0.75, 9.0), (0.0, 36.0)])
def test_trigger_distance_from_the_front_overlap(front: float, trigger: float) -> None:
    assert trigger_distance_m(36.0, front) == pytest.approx(trigger)


def test_the_speed_never_asks_for_photos_faster_than_the_capture_interval() -> None:
    cam = camera("dji-phantom4pro")  # a photo every 2 s at most
    assert choose_speed(cam, 10.0, None) == (5.0, "limit")  # fastest 5 m/s: the cruise speed fits
    assert choose_speed(cam, 4.0, None) == (2.0, "limit")
    assert choose_speed(cam, 4.0, 1.5) == (1.5, "asked")
    with pytest.raises(GeoError) as caught:
        choose_speed(cam, 4.0, 12.0)
    assert str(caught.value) == ("speed 12 m/s asks dji-phantom4pro (a photo every 2 s at most) for one every "
                                 "0.333 s: the fastest allowed is 2 m/s")
    assert choose_speed(Camera(84.0), 4.0, None) == (5.0, "cruise")  # no interval known: nothing to keep up with


def test_a_camera_without_sensor_fields_keeps_its_json() -> None:
    assert Camera(84.0).to_json() == {"fov_deg": 84.0}
    assert Camera.from_json({"fov_deg": 84.0}) == Camera(84.0)
    cam = camera("sony-a6000-20mm")
    assert Camera.from_json(json.loads(json.dumps(cam.to_json()))) == cam


def test_the_catalogue_rows_are_whole_and_their_field_of_view_is_the_narrower_side() -> None:
    assert 10 <= len(CATALOGUE) <= 15 and len({row.id for row in CATALOGUE}) == len(CATALOGUE)
    for row in CATALOGUE:
        cam = row.camera()
        narrow = min(row.sensor_width_mm, row.sensor_height_mm)
        assert cam.footprint_side_m(100.0) == pytest.approx(100.0 * narrow / row.focal_length_mm)
    one_inch = find("DJI-Phantom4Pro")  # any case
    assert (one_inch.sensor_width_mm, one_inch.sensor_height_mm, one_inch.focal_length_mm) == (13.2, 8.8, 8.8)


def test_an_unknown_camera_names_the_nearest() -> None:
    with pytest.raises(GeoError) as caught:
        find("sony-a6000")
    assert str(caught.value).startswith("camera sony-a6000: no such camera in the catalogue; nearest: "
                                        "sony-a6000-16mm, sony-a6000-20mm")


def test_shown_numbers() -> None:
    assert [shown(v) for v in (46.28, 1.6667, 0.36666, 1.0, 120.0, 1234.0)] == ["46.3", "1.67", "0.367", "1", "120",
                                                                                 "1230"]


# ------------------------------------------------------------------------------------------- plan's options
def _plan(tmp_path: Path, capsys: pytest.CaptureFixture[str], *options: str) -> tuple[int, str, str]:
    code = main(["plan", "--area", str(AREA), "--launch", LAUNCH, "--out", str(tmp_path / "plan"), "--quiet",
                 *options])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("options, line", [
    (("--camera", "dji-phantom4pro", "--altitude", "30", "--speed", "12"),
     "missionplan: --speed 12 m/s asks dji-phantom4pro (a photo every 2 s at most) for one every 0.278 s: the "
     "fastest allowed is 1.67 m/s"),
    (("--fov", "84", "--altitude", "30", "--speed", "25"),
     "missionplan: --speed 25: must be a waypoint speed ArduCopter and PX4 fly, above 0 and at most 20 m/s"),
    (("--camera", "dji-phantom4pro", "--gsd", "5"),
     "missionplan: --gsd 5 cm/px puts dji-phantom4pro at 182 m, above --max-altitude 120 m: the coarsest GSD flown "
     "at or under it is 3.29 cm/px"),
    (("--fov", "84", "--gsd", "1", "--image-width", "5472"),
     "missionplan: --gsd needs the camera's sensor, image size and focal length: give --sensor-width MM "
     "--sensor-height MM --image-height PX --focal-length MM (or --camera NAME: `missionplan cameras` lists them)"),
    (("--camera", "sony-a600", "--altitude", "30"),
     "missionplan: --camera sony-a600: no such camera in the catalogue; nearest: sony-a6000-16mm, sony-a6000-20mm, "
     "sony-a6300-21mm (`missionplan cameras` lists all 14)"),
    (("--camera", "dji-phantom4pro", "--fov", "84", "--altitude", "30"),
     "missionplan: --camera dji-phantom4pro describes the camera already: give --camera or --fov, not both "
     "(--capture-interval may replace its interval)"),
    (("--fov", "84", "--altitude", "30", "--side-overlap", "95"),
     "missionplan: --side-overlap 95 %: lanes 0.45 cells apart, and the grid's lanes are at least one cell apart: "
     "at most 88.9 %"),
    (("--fov", "84", "--altitude", "30", "--overlap", "0.5", "--front-overlap", "60"),
     "missionplan: argument --front-overlap: not allowed with argument --overlap"),
    (("--camera", "dji-phantom4pro", "--altitude", "30", "--gsd", "1"),
     "missionplan: argument --gsd: not allowed with argument --altitude"),
    (("--fov", "84", "--altitude", "30", "--front-overlap", "100"),
     "missionplan: --front-overlap 100: must be a percentage, at least 0 and below 100 %"),
])
def test_bad_capture_options_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          options: tuple[str, ...], line: str) -> None:
    try:
        code, out, err = _plan(tmp_path, capsys, *options)
    except SystemExit as stop:  # argparse's own refusals
        code, err = int(stop.code or 0), capsys.readouterr().err
    assert code == 2 and err == line + "\n"
    assert not (tmp_path / "plan").exists()


def test_gsd_and_overlaps_plan_and_read_back_as_schema_version_3(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _plan(tmp_path, capsys, "--camera", "dji-phantom4pro", "--gsd", "1", "--front-overlap", "80",
                           "--side-overlap", "70")
    assert code == 0, err
    assert "    height 36.5 m  from GSD 1 cm/px: H = GSD x f x image width / (100 x sensor width)" in out
    assert "    speed 3.65 m/s  min(5 m/s, fastest speed): none asked" in out
    folder = tmp_path / "plan"
    doc = json.loads(report_path(folder).read_text())
    assert next(iter(doc)) == "schema_version" and doc["schema_version"] == CAPTURE_VERSION == 3
    block = doc["georeference"]["camera"]
    assert block["name"] == "dji-phantom4pro" and block["gsd_cm"] == pytest.approx(1.0)
    assert (block["front_overlap"], block["side_overlap"], block["lane_spacing_cells"]) == (0.8, 0.7, 2)
    assert block["speed_m_s"] == pytest.approx(3.648) and block["fastest_speed_m_s"] == pytest.approx(3.648)
    assert doc["georeference"]["altitude_m"] == pytest.approx(36.48)
    assert doc["georeference"]["trigger_distance_m"] == pytest.approx(7.296)
    assert doc["settings"]["mission"]["speed_m_s"] == pytest.approx(3.648)
    assert doc["settings"]["lane_spacing_cells"] == 2
    assert [rule["quantity"] for rule in block["rules"]][:2] == ["height", "footprint"]
    record = read_plan_record(folder)
    assert record.version == 3 and record.georeference is not None
    capture = record.georeference.capture
    assert capture is not None and capture.camera == camera("dji-phantom4pro") and capture.gsd_asked_cm == 1.0
    write_plan_record(record, tmp_path / "again.json")
    assert (tmp_path / "again.json").read_bytes() == report_path(folder).read_bytes()


def test_a_plan_without_capture_options_has_no_camera_block(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _plan(tmp_path, capsys, "--fov", "84", "--altitude", "30")
    assert code == 0, err
    doc = json.loads(report_path(tmp_path / "plan").read_text())
    assert "schema_version" not in doc and "camera" not in doc["georeference"]
    assert "lane_spacing_cells" not in doc["settings"] and doc["settings"]["mission"]["speed_m_s"] == 5.0
    assert "capture with" not in out


def test_without_speed_the_cruise_speed_fits_a_slow_enough_trigger(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # Sony a6000 16 mm at 60 m: S = 60 x 15.6 / 16 = 58.5 m, trigger S / 9 = 6.5 m, a photo a second: 6.5 m/s.
    code, out, err = _plan(tmp_path, capsys, "--camera", "sony-a6000-16mm", "--altitude", "60")
    assert code == 0, err
    assert "    fastest speed 6.5 m/s  trigger distance / capture interval 1 s" in out
    assert "    speed 5 m/s  min(5 m/s, fastest speed): none asked" in out


# ------------------------------------------------------------------------------------------- lanes
def _open_field(rows: int, cols: int, launches: list[tuple[int, int]], georeferenced: bool = False) -> GridMap:
    blocked = np.zeros((rows, cols), dtype=bool)
    meta = ({"origin_lat": "45.066000", "origin_lon": "7.670000", "cell_m": "2.0", "altitude_m": "10",
             "fov_deg": "83.9744"} if georeferenced else {})
    return GridMap("field", blocked, ~blocked, launches, meta)


def _lane_lines(path: np.ndarray) -> tuple[list[int], int]:
    """The rows or columns a drone flew lanes along (more than 8 steps in a row on one), and the axis of their
    number (0: lanes along rows)."""
    best: tuple[list[int], int] = ([], 0)
    for axis in (0, 1):
        values, run, lines = path[:, axis].tolist(), 1, set()
        for before, value in zip(values, values[1:]):
            run = run + 1 if value == before else 1
            if run > 8:
                lines.add(value)
        if len(lines) > len(best[0]):
            best = (sorted(lines), axis)
    return best


@pytest.mark.parametrize("spacing", [9, 4, 2, 1])
def test_open_ground_lanes_lie_the_spacing_apart_and_see_each_cell_that_often(spacing: int) -> None:
    gmap = _open_field(45, 60, [(0, 0)])
    run = plan_map(gmap, 1, policy="expert", lanes=True, lane_spacing=spacing).run
    assert run.success and run.lane_drones == 1
    lines, axis = _lane_lines(run.paths[0])
    inner = [v for v in lines if 0 < v < gmap.shape[axis] - 1]  # a lane clipped at the map's edge aside
    assert set(np.diff(inner)) == {spacing}
    # Every cell at least a footprint's half from the edges is under floor(9 / spacing) lanes or more.
    for cell in range(4, gmap.shape[axis] - 4):
        assert sum(abs(v - cell) <= 4 for v in lines) >= 9 // spacing


def test_side_overlap_puts_plan_lanes_that_many_cells_apart(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "open.map"
    save_map(_open_field(40, 40, [(0, 0)], georeferenced=True), path)
    for side, cells in (("70", 2), ("60", 3)):
        out = tmp_path / f"side-{side}"
        # the lanes as planned, without the overlap fill's detours (tests/test_overlap_fill.py)
        assert main(["plan", "--map", str(path), "--uavs", "1", "--side-overlap", side, "--out", str(out),
                     "--quiet", "--no-overlap-fill"]) == 0
        assert f"open ground: 1 of 1 drones sweep their zone in lanes {cells} cells apart" in capsys.readouterr().out
        doc = json.loads(report_path(out).read_text())
        assert doc["georeference"]["camera"]["lane_spacing_cells"] == cells and doc["lane_drones"] == 1
        assert doc["metrics"]["coverage"] == 100.0
        lines, axis = _lane_lines(np.array(doc["paths"][0]))
        inner = [v for v in lines if 0 < v < 39]  # a lane clipped at the map's edge aside
        assert len(inner) >= 40 // cells - 2 and set(np.diff(inner)) == {cells}, lines
        # and as the missions fly them: the corrector keeps every lane, so the side overlap measured from the
        # photos is the one asked, at the 5th percentile too
        measured = doc["coverage"]["overlap"]["side"]
        assert measured["p5"] >= int(side) / 100, measured


def test_an_oblique_pitch_moves_the_photo_centre_ahead_and_coarsens_its_gsd() -> None:
    """--gimbal-pitch -60 on the 1-inch camera at 1 cm/px: tilted 30 deg, the photo's centre lies
    36.48 x tan 30 = 21.06 m ahead, and its GSD there is 1 / cos^2 30 = 1.333 cm/px along the tilt."""
    cam = camera("dji-phantom4pro")
    height = height_for_gsd(cam, 1.0)
    nadir = CapturePlan(cam, height, cam.footprint_side_m(height), 0.8, None, 3.0, gsd_asked_cm=1.0)
    oblique = replace(nadir, gimbal_pitch_deg=-60.0)
    assert oblique.tilt_deg == pytest.approx(30.0) and nadir.tilt_deg == 0.0
    rules = {quantity: value for quantity, value, _, _ in oblique.rules()}
    assert rules["camera pitch"] == -60.0
    assert rules["photo centre ahead"] == pytest.approx(36.48 / 3 ** 0.5, rel=1e-9)  # 21.06 m
    assert rules["GSD at the photo centre"] == pytest.approx(4.0 / 3.0, rel=1e-9)
    assert "camera pitch" not in {quantity for quantity, *_ in nadir.rules()}
    # the trigger, lanes and cell keep the nadir footprint's: the planner covers what a nadir camera sees
    assert (oblique.trigger_m, oblique.cell_m) == (nadir.trigger_m, nadir.cell_m)
    doc = oblique.to_json()
    assert doc["gimbal_pitch_deg"] == -60.0 and "gimbal_pitch_deg" not in nadir.to_json()
    assert CapturePlan.from_json(doc, height, oblique.footprint_m) == oblique
