"""The survey across flights, against in-process mock autopilots: the ledger, `status`, `replan` and the
geotagged photo files (the fast suite's share of sitl_tests/test_survey_sitl.py).

A drone lost half-way leaves part of the survey unphotographed; `status` says what and where, `replan`
plans only that for the vehicles named, a second `fly` of the re-plan adds to the same ledger, and
`status` shows the survey whole. Every coverage figure checked here is recomputed independently from
the photo files (photos.csv) with the judge's rule, not read back from the ledger alone."""

from __future__ import annotations

import csv
import json
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.cli import main
from missionplan.flight.plan_report import SLACK_CELLS, frame_of, target_cells, to_grid_m
from missionplan.flight.ledger import LEDGER_NAME, Ledger
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.mission.plan_record import read_plan_record
from lost_drone import fly_with_a_lost_drone

FAST = 10.0


@pytest.fixture(scope="module")
def lost_drone_survey(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Leonardo for 3 drones, flown with drone 2 killed at item 8: the survey's first flight."""
    root = tmp_path_factory.mktemp("survey") / "day1"
    assert fly_with_a_lost_drone(root) == 1  # a drone lost is a problem of the flight
    return root


def _covered_from_csv(root: Path, *folders: Path) -> tuple[int, int]:
    """(covered, targets) of the root plan's reachable targets, from the photos.csv files alone."""
    record = read_plan_record(root)
    frame, targets = frame_of(record), target_cells(record)
    footprint = record.georeference.footprint_m
    rows = [row for folder in folders for row in csv.DictReader((folder / "photos.csv").open())]
    photos = to_grid_m(frame, [float(r["lat"]) for r in rows], [float(r["lon"]) for r in rows])
    reach = footprint / 2 - frame.cell_m / 2 + SLACK_CELLS * frame.cell_m + 1e-6
    centres = targets.astype(float) * frame.cell_m
    gap = np.min(np.max(np.abs(centres[:, None, :] - photos[None, :, :]), axis=2), axis=1)
    return int((gap <= reach).sum()), len(targets)


@pytest.mark.flight
def test_the_first_flight_is_in_the_ledger_and_the_photo_files(lost_drone_survey: Path) -> None:
    root = lost_drone_survey
    flight = json.loads((root / "flight.json").read_text())
    rows = list(csv.DictReader((root / "photos.csv").open()))
    assert len(rows) == sum(d["photos"] for d in flight["drones"]) > 100
    assert {r["vehicle"] for r in rows} == {"1", "2", "3"}  # drone 2's photos before it was lost count too
    first = rows[0]
    assert first["image"] == f"f1-uav{first['vehicle']}-{int(first['img_idx']):05d}.jpg"
    assert first["alt_amsl_m"] and first["alt_rel_m"] and first["source"] == "camera"
    # geo.txt: ODM's projection line, then one line per photo, lon before lat.
    lines = (root / "geo.txt").read_text().splitlines()
    assert lines[0] == "EPSG:4326" and len(lines) == len(rows) + 1
    name, lon, lat, alt, *_angles = lines[1].split()
    assert (name, float(lon), float(lat)) == (first["image"], float(first["lon"]), float(first["lat"]))
    points = json.loads((root / "photos.geojson").read_text())["features"]
    assert len(points) == len(rows) and points[0]["geometry"]["coordinates"][:2] == [float(first["lon"]),
                                                                                       float(first["lat"])]
    # flight.json's figure is the ledger's, and both are what the photos themselves say.
    covered, targets = _covered_from_csv(root, root)
    assert flight["coverage"] == pytest.approx(100.0 * covered / targets, abs=0.01)
    assert flight["survey"]["covered"] == covered and flight["survey"]["flights"] == 1
    assert flight["coverage"] < 95.0  # a third of the survey was lost with drone 2


@pytest.mark.flight
def test_status_says_what_is_left_and_writes_it(lost_drone_survey: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = lost_drone_survey
    assert main(["status", str(root)]) == 0
    out = capsys.readouterr().out
    covered, targets = _covered_from_csv(root, root)
    assert f"covered {covered} of {targets} target cells" in out
    assert f"left: {targets - covered} cells" in out
    missing = json.loads((root / "missing.geojson").read_text())["features"][0]
    assert missing["properties"]["cells"] == targets - covered and missing["geometry"]["type"] == "MultiPolygon"
    assert (root / "status.png").stat().st_size > 10_000


@pytest.mark.flight
def test_replan_plans_only_the_missing_cells_for_the_vehicles_named_and_the_survey_ends_whole(
        lost_drone_survey: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = lost_drone_survey
    rest = root.parent / "day2"
    with Ledger.of(root) as ledger:
        missing = ledger.missing_cells()
    assert main(["replan", str(root), "--out", str(rest), "--drones", "1,3", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "drone 1: system id 1" in out and "drone 2: system id 3" in out
    report = json.loads((rest / "report.json").read_text())
    # Only the missing targets are the re-plan's, files named by system id, the survey pointer kept.
    grid_targets = np.argwhere(np.array([list(row) for row in report["grid"]]) == ".")
    assert sorted(map(tuple, grid_targets.tolist())) == sorted(map(tuple, missing.tolist()))
    assert sorted(d["id"] for d in report["drones"]) == [1, 3] and (rest / "uav3.plan").exists()
    assert not (rest / "uav2.plan").exists() and report["drone_ids"] == [1, 3]
    assert report["survey"]["root"] == "../day1" and report["separation"]["3d"] is not None
    mock = start_mock_fleet(rest, FAST)
    try:
        code = main(["fly", str(rest), "--connect", mock.client_url, "--time-scale", str(FAST), "--timeout", "60",
                     "--quiet"])
    finally:
        mock.stop()
    out = capsys.readouterr().out
    assert code == 0, out
    assert "over 2 flights" in out
    flight = json.loads((rest / "flight.json").read_text())
    assert flight["survey"]["flights"] == 2 and flight["survey"]["coverage"] >= 99.0
    # The whole survey from both folders' photos, recomputed from the files: what status says.
    covered, targets = _covered_from_csv(root, root, rest)
    assert 100.0 * covered / targets >= 99.0
    assert main(["status", str(rest)]) == 0
    out = capsys.readouterr().out
    assert f"covered {covered} of {targets} target cells" in out and "2 flights recorded" in out
    assert "../day2" in out


@pytest.mark.flight
def test_a_flight_judged_again_replaces_its_rows(lost_drone_survey: Path, tmp_path: Path) -> None:
    """fly --resume judges a flight again: the ledger keeps one copy of its photos."""
    from missionplan.flight.flight_report import judge
    from missionplan.flight.journal_read import read_flight

    copy = tmp_path / "copy"
    copy.mkdir()
    for path in lost_drone_survey.iterdir():
        if path.is_file() and not path.name.startswith(LEDGER_NAME):
            (copy / path.name).write_bytes(path.read_bytes())
    flight, sortie, records = read_flight(copy)
    record = read_plan_record(copy)
    for _ in range(2):
        judge(copy, record, records, FAST, wall_s=1.0, telemetry_hz=25.0, flight=flight, sortie=sortie)
    db = sqlite3.connect(copy / LEDGER_NAME)
    assert db.execute("SELECT COUNT(*) FROM flights").fetchone()[0] == 1
    photos = db.execute("SELECT COUNT(*) FROM photos").fetchone()[0]
    assert photos == sum(len(rec.camera) for rec in records)


@pytest.mark.flight
@pytest.mark.parametrize("argv, message", [
    (["--drones", "1,7"], "has no drone 7"),
    ([], "say who flies the re-plan"),
    (["--launch", "45.4784,9.2270"], "no --sysid for drone 1"),
    (["--launch", "45.4784,9.2270", "--sysid", "1=2", "--sysid", "2=3"], "drone 2 has no --launch point"),
    (["--drones", "1", "--launch", "45.4784,9.2270"], "either --drones"),
])
def test_replan_refuses_an_unsaid_assignment(lost_drone_survey: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    out = tmp_path / "new"
    assert main(["replan", str(lost_drone_survey), "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (out / "report.json").exists()


@pytest.mark.flight
def test_replan_will_not_write_over_the_survey(lost_drone_survey: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replan", str(lost_drone_survey), "--out", str(lost_drone_survey), "--drones", "1"]) == 2
    assert "not over the survey's own plan" in capsys.readouterr().err


def test_status_of_a_plan_never_flown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(plan), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["status", str(plan)]) == 0
    out = capsys.readouterr().out
    targets = len(target_cells(read_plan_record(plan)))
    assert "0 flights recorded" in out and f"covered 0 of {targets} target cells: 0.00 %" in out


def test_status_of_a_folder_that_is_no_plan(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["status", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no report.json" in err and str(tmp_path) in err


# ------------------------------------------------------------------------------- a ledger lost, damaged, read-only
def _survey_copy(root: Path, to: Path, ledger: bool) -> Path:
    """The survey's first folder (files only), with its ledger holding that folder's flights alone (a
    re-plan flown in the module's survey is not copied), or without a ledger."""
    to.mkdir(parents=True)
    for path in root.iterdir():
        if path.is_file() and not path.name.startswith(LEDGER_NAME):
            (to / path.name).write_bytes(path.read_bytes())
    if ledger:
        source = sqlite3.connect(root / LEDGER_NAME)
        copy = sqlite3.connect(to / LEDGER_NAME)
        source.backup(copy)
        source.close()
        with copy:
            copy.execute("DELETE FROM covered WHERE photo IN (SELECT p.id FROM photos p JOIN flights f ON "
                         "f.id = p.flight_id WHERE f.plan != '.')")
            copy.execute("DELETE FROM photos WHERE flight_id IN (SELECT id FROM flights WHERE plan != '.')")
            copy.execute("DELETE FROM flights WHERE plan != '.'")
        copy.execute("VACUUM")
        copy.close()
    return to


def _ledger_rows(folder: Path) -> tuple[list[tuple], list[tuple]]:
    """The ledger's photos (without their ids) and covered cells (by the photo's vehicle and index)."""
    db = sqlite3.connect(folder / LEDGER_NAME)
    photos = sorted(db.execute("SELECT f.plan, f.flight, f.sortie, p.vehicle, p.img_idx, p.time, p.lat, p.lon, "
                               "p.alt_amsl, p.alt_rel, p.roll, p.pitch, p.yaw, p.source FROM photos p JOIN flights f "
                               "ON f.id = p.flight_id").fetchall())
    covered = sorted(db.execute("SELECT p.vehicle, p.img_idx, c.row, c.col FROM covered c JOIN photos p ON "
                                "p.id = c.photo").fetchall())
    db.close()
    return photos, covered


def _status(folder: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["status", str(folder)])
    out = capsys.readouterr()
    return code, out.out.replace(str(folder), "DIR"), out.err


@pytest.mark.flight
def test_a_deleted_ledger_is_rebuilt_from_the_journal_with_the_rows_the_judge_wrote(
        lost_drone_survey: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    whole = _survey_copy(lost_drone_survey, tmp_path / "whole", ledger=True)
    expected = _status(whole, capsys)
    lost = _survey_copy(lost_drone_survey, tmp_path / "lost", ledger=False)
    code, out, err = _status(lost, capsys)
    assert (code, out) == expected[:2] and "1 flight recorded" in out, out
    photos = len(_ledger_rows(whole)[0])
    assert err == (f"missionplan status: {lost / LEDGER_NAME}: missing; rebuilt from the journal.sqlite of {lost}: "
                   f"1 flight, {photos} photos\n"), err
    rebuilt, original = _ledger_rows(lost), _ledger_rows(whole)
    assert rebuilt == original and len(rebuilt[1]) > 1000
    assert _status(lost, capsys) == expected  # rebuilt once: the next status is as ever


@pytest.mark.flight
def test_a_deleted_ledger_of_a_survey_flown_twice_is_rebuilt_from_both_folders(
        lost_drone_survey: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The journals of the first plan and of the re-plan beside it (`replan --out ../day2`) hold both flights."""
    day1 = _survey_copy(lost_drone_survey, tmp_path / "survey" / "day1", ledger=True)
    day2 = tmp_path / "survey" / "day2"
    assert main(["replan", str(day1), "--out", str(day2), "--drones", "1,3", "--quiet"]) == 0
    mock = start_mock_fleet(day2, FAST)
    try:
        assert main(["fly", str(day2), "--connect", mock.client_url, "--time-scale", str(FAST), "--timeout", "60",
                     "--quiet"]) == 0
    finally:
        mock.stop()
    capsys.readouterr()
    whole = _ledger_rows(day1)
    expected = _status(day1, capsys)
    assert "2 flights recorded" in expected[1]
    (day1 / LEDGER_NAME).unlink()
    code, out, err = _status(day1, capsys)
    assert (code, out) == expected[:2], out
    assert err == (f"missionplan status: {day1 / LEDGER_NAME}: missing; rebuilt from the journal.sqlite of {day1}, "
                   f"{day2}: 2 flights, {len(whole[0])} photos\n"), err
    assert _ledger_rows(day1) == whole


def _page_of_a_photo(path: Path) -> int:
    """The offset of a page of ledger.sqlite holding photo rows (found by a latitude, a float SQLite stores
    big-endian)."""
    import struct

    db = sqlite3.connect(path)
    count = db.execute("SELECT COUNT(*) FROM photos").fetchone()[0]
    lat = db.execute("SELECT lat FROM photos ORDER BY id LIMIT 1 OFFSET ?", (count // 2,)).fetchone()[0]
    db.close()
    at = path.read_bytes().index(struct.pack(">d", lat))
    return at - at % 4096


@pytest.mark.flight
@pytest.mark.parametrize("command", ["status", "replan"])
def test_a_damaged_ledger_is_rebuilt_in_one_line(lost_drone_survey: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str], command: str) -> None:
    whole = _survey_copy(lost_drone_survey, tmp_path / "whole", ledger=True)
    expected = _status(whole, capsys)
    damaged = _survey_copy(lost_drone_survey, tmp_path / "damaged", ledger=True)
    path = damaged / LEDGER_NAME
    with open(path, "r+b") as f:
        f.seek(_page_of_a_photo(path))
        f.write(b"\xa5" * 4096)
    if command == "status":
        code, out, err = _status(damaged, capsys)
        assert (code, out) == expected[:2], out
    else:
        code = main(["replan", str(damaged), "--out", str(tmp_path / "rest"), "--drones", "1,3", "--quiet"])
        out, err = capsys.readouterr()
        assert code == 0 and "1 flight recorded" in out, out
    assert re.fullmatch(rf"missionplan {command}: {re.escape(str(path))}: damaged \([^)]+\); kept as "
                        rf"ledger.sqlite.damaged; rebuilt: 1 flight from the journal.sqlite of "
                        rf"{re.escape(str(damaged))}; lost: nothing\n", err), err
    assert _ledger_rows(damaged) == _ledger_rows(whole)
    assert (damaged / "ledger.sqlite.damaged").exists()


@pytest.mark.flight
def test_status_of_a_read_only_survey_folder_is_printed_then_one_line(
        lost_drone_survey: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from small_disk import read_only

    folder = _survey_copy(lost_drone_survey, tmp_path / "ro", ledger=True)
    (folder / "missing.geojson").unlink(missing_ok=True)
    (folder / "status.png").unlink(missing_ok=True)
    expected = _status(_survey_copy(lost_drone_survey, tmp_path / "rw", ledger=True), capsys)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with read_only(folder):
        code, out, err = _status(folder, capsys)
    assert code == 1
    assert out == expected[1].replace("wrote DIR/missing.geojson and DIR/status.png\n", ""), out
    assert re.fullmatch(rf"missionplan status: {re.escape(str(folder))}: missing.geojson and status.png could not be "
                        r"written \((?:Read-only file system|Permission denied)\); the status above is whole\n",
                        err), err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


# ------------------------------------------------------------------------------- live re-tasking
RETASK_SPEEDUP = 4.0  # slow enough that the survivors are still mid-survey when the loss is noticed


@pytest.fixture(scope="module")
def leonardo_3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leonardo-3") / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    return out


def _copy(plan: Path, to: Path) -> Path:
    to.mkdir()
    for path in plan.iterdir():
        (to / path.name).write_bytes(path.read_bytes())
    return to


@pytest.mark.flight
@pytest.mark.parametrize("flavour", ["ardupilot"])
def test_fly_replan_gives_a_lost_drones_share_to_the_others_in_flight(
        leonardo_3: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], flavour: str) -> None:
    plan = _copy(leonardo_3, tmp_path / "plan")
    mock = start_mock_fleet(plan, RETASK_SPEEDUP, flavour=flavour)
    mock.kill(2, at_item=8)
    try:
        code = main(["fly", str(plan), "--connect", mock.client_url, "--time-scale", str(RETASK_SPEEDUP),
                     "--timeout", "120", "--quiet", "--replan", "--replan-after", "3"])
        # What the vehicles themselves hold at the end: the survivors the new missions, all landed.
        held = {k: len(mock.vehicle(k).mission()) for k in (1, 3)}
        landed = all(not mock.vehicle(k).flight.state.armed for k in (1, 3))
    finally:
        mock.stop()
    text = capsys.readouterr()
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 1, text.out  # drone 2 was lost: a problem of the flight, said
    assert doc["problems"] == [p for p in doc["problems"] if p.startswith("uav2: link lost")], doc["problems"]
    (retask,) = doc["retasks"]
    assert retask["gone"] == [2] and retask["survivors"] == [1, 3] and retask["outcome"] == "re-tasked"
    assert retask["separation_m"] >= json.loads((plan / "report.json").read_text())["settings"]["safety"][
        "min_separation_m"]
    assert "re-tasked: new mission" in text.err and "re-plan: uav2 gone" in text.err
    # The same fly run ends at 99 % or more of the reachable targets, from the vehicles' own photo reports.
    assert doc["coverage"] >= 99.0 and doc["photos_from"] == "camera"
    assert doc["min_separation_m"]["kept"] is True
    drones = {d["id"]: d for d in doc["drones"]}
    assert drones[1]["finished"] and drones[3]["finished"] and landed
    for k in (1, 3):  # the vehicle holds the new mission the record says it was given
        assert any(n.startswith(f"re-tasked in flight: {held[k]} items") for n in drones[k]["notes"]), \
            (held[k], drones[k]["notes"])


@pytest.mark.flight
def test_survivors_that_do_not_stop_for_a_retask_go_back_to_their_own_missions(
        leonardo_3: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # A vehicle that never gets under the hold speed (a gusty day, a slow brake): the re-task is refused
    # with what each was doing, and no survivor is left hovering in GUIDED; they finish what they had.
    monkeypatch.setattr("missionplan.flight.retask_actions.HOLD_SPEED", 0.0)
    monkeypatch.setattr("missionplan.flight.retask_actions.HOLD_S", 1.0)
    plan = _copy(leonardo_3, tmp_path / "plan")
    planned = {k: read_mission_file(plan / f"uav{k}.plan").mission.items for k in (1, 3)}
    mock = start_mock_fleet(plan, RETASK_SPEEDUP)
    mock.kill(2, at_item=8)
    try:
        code = main(["fly", str(plan), "--connect", mock.client_url, "--time-scale", str(RETASK_SPEEDUP),
                     "--timeout", "120", "--quiet", "--replan", "--replan-after", "3"])
        held = {k: len(mock.vehicle(k).mission()) for k in (1, 3)}
    finally:
        mock.stop()
    err = capsys.readouterr().err
    doc = json.loads((plan / "flight.json").read_text())
    assert code == 1, err
    (retask,) = doc["retasks"]
    assert re.fullmatch(r"not re-tasked: could not hold uav1: did not stop in 1 s after GUIDED \(still at [\d.]+ m/s, "
                        r"in GUIDED\); uav3: did not stop in 1 s after GUIDED \(still at [\d.]+ m/s, in GUIDED\)",
                        retask["outcome"]), retask
    assert "not_released" not in retask and "re-plan refused: could not hold uav1" in err
    drones = {d["id"]: d for d in doc["drones"]}
    assert drones[1]["finished"] and drones[3]["finished"], doc["problems"]
    # Each still holds the mission fly uploaded before the flight (the vehicle's home item as well).
    assert all(held[k] == len(planned[k]) + 1 for k in (1, 3)), (held, planned)


def test_a_retask_beyond_the_battery_is_refused_with_the_reason(leonardo_3: Path) -> None:
    from missionplan.planning.errors import RetaskPlanningError
    from missionplan.planning.retask import Survivor, plan_retask

    record = read_plan_record(leonardo_3)
    budget = record.settings.safety.budget_s
    launch = [json.loads((leonardo_3 / f"uav{k}.plan").read_text())["mission"]["plannedHomePosition"][:2]
              for k in (1, 3)]
    tired = [Survivor(k, lat, lon, 1.2, (lat, lon), flown_s=budget - 5.0) for k, (lat, lon) in zip((1, 3), launch)]
    with pytest.raises(RetaskPlanningError, match=r"uav1 would need \d+ s more; its battery budget has 5 s left"):
        plan_retask(leonardo_3, record, tired, np.zeros((0, 2)))
    fresh = [Survivor(k, lat, lon, 1.2, (lat, lon), flown_s=0.0) for k, (lat, lon) in zip((1, 3), launch)]
    plan = plan_retask(leonardo_3, record, fresh, np.zeros((0, 2)))
    assert plan is not None and plan.targets_left == record.targets and set(plan.missions) == {1, 3}
    # Each new mission starts where its drone is, ends with RTL, and its fence holds its new track.
    for k in (1, 3):
        items = plan.missions[k].items
        assert items[0].command == CMD_NAV_TAKEOFF and items[-1].command == CMD_NAV_RETURN_TO_LAUNCH
        assert plan.resume_index[k] == 1
        assert plan.fences[k].items


def test_survivors_side_by_side_in_the_air_are_re_tasked_on_their_layers(leonardo_3: Path) -> None:
    """Two survivors held a metre apart, one above the other: the re-task's separation is measured on
    the tracks they fly from there, in the air (not as if both took off from that spot), and its layers
    keep them the minimum separation plus a corner each apart."""
    from missionplan.planning.retask import Survivor, plan_retask

    record = read_plan_record(leonardo_3)
    frame = frame_of(record)
    home1, home3 = (tuple(json.loads((leonardo_3 / f"uav{k}.plan").read_text())["mission"]["plannedHomePosition"][:2])
                    for k in (1, 3))
    lat, lon = home1
    r, c = (float(v) for v in np.ravel(frame.latlon_to_grid(np.array([lat]), np.array([lon]))))
    beside = frame.cell_to_latlon(np.array([round(r)]), np.array([round(c) + 1]))
    side_by_side = [Survivor(1, lat, lon, 30.0, home1, 0.0),
                    Survivor(3, float(beside[0][0]), float(beside[1][0]), 32.0, home3, 0.0)]
    plan = plan_retask(leonardo_3, record, side_by_side, np.zeros((0, 2)))
    assert plan is not None and set(plan.missions) == {1, 3}
    stored = record.settings
    required = stored.safety.min_separation_m + 2 * stored.mission.acceptance_m
    assert plan.separation_m is not None and plan.separation_m >= required - 1e-6


def test_a_retasks_promise_holds_with_the_survivors_out_of_step(leonardo_3: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The re-task's separation is measured with the survivors ahead of or behind each other by their
    autopilot's slack (retask.OUT_OF_STEP): the more slack, the smaller the promise, and once it would
    fall under the minimum separation the survivors fly on altitude layers instead."""
    from missionplan.planning.retask import OUT_OF_STEP, Survivor, plan_retask

    record = read_plan_record(leonardo_3)
    launch = [json.loads((leonardo_3 / f"uav{k}.plan").read_text())["mission"]["plannedHomePosition"][:2]
              for k in (1, 3)]
    fresh = [Survivor(k, lat, lon, 1.2, (lat, lon), flown_s=0.0) for k, (lat, lon) in zip((1, 3), launch)]
    stored = record.settings
    assert stored.mission.autopilot == "ardupilot"
    required = stored.safety.min_separation_m + 2 * stored.mission.acceptance_m

    def retask(floor_s: float, rate: float) -> tuple[float, float]:
        """The promise and the second survivor's survey altitude with that slack."""
        monkeypatch.setitem(OUT_OF_STEP, "ardupilot", (floor_s, rate))
        plan = plan_retask(leonardo_3, record, fresh, np.zeros((0, 2)))
        assert plan is not None and plan.separation_m is not None
        return plan.separation_m, max(item.z for item in plan.missions[3].items if item.command == CMD_NAV_WAYPOINT)

    in_step, ardupilot, px4_like, loose = retask(0.0, 0.0), retask(0.5, 0.05), retask(3.0, 0.1), retask(5.0, 0.2)
    assert in_step[0] > ardupilot[0] > px4_like[0] >= required  # all on one altitude (1.2 m)
    assert in_step[1] == ardupilot[1] == px4_like[1] == pytest.approx(1.2)
    assert loose[1] > 1.2 + required - 1e-6 and loose[0] >= required  # on its layer


def test_nothing_to_retask_when_everything_is_photographed(leonardo_3: Path) -> None:
    from missionplan.planning.retask import Survivor, plan_retask

    record = read_plan_record(leonardo_3)
    frame, targets = frame_of(record), target_cells(record)
    lat, lon = frame.cell_to_latlon(targets[:, 0], targets[:, 1])  # a photo over every target cell
    photos = np.column_stack([lat, lon])
    survivor = Survivor(1, float(lat[0]), float(lon[0]), 1.2, (float(lat[0]), float(lon[0])), 0.0)
    assert plan_retask(leonardo_3, record, [survivor], photos) is None


@pytest.mark.flight
def test_fly_replan_re_tasks_when_a_battery_failsafe_sends_a_drone_home(
        leonardo_3: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from missionplan.bridge.link.connection import Link, wait_vehicle

    plan = _copy(leonardo_3, tmp_path / "plan")
    mock = start_mock_fleet(plan, RETASK_SPEEDUP)
    result: list[int] = []
    try:
        with Link(mock.client_url, source_system=200) as crew:  # the crew's own ground station
            wait_vehicle(crew, 2, timeout=5)
            crew.mav.param_set_send(2, 1, b"BATT_FS_LOW_ACT", 2.0, 9)  # RTL on a low battery
            assert mock.wait_until(lambda m: m.vehicle(2).params["BATT_FS_LOW_ACT"] == 2.0, 5.0)
            import threading

            flying = threading.Thread(target=lambda: result.append(main(
                ["fly", str(plan), "--connect", mock.client_url, "--time-scale", str(RETASK_SPEEDUP), "--timeout",
                 "120", "--quiet", "--replan"])))
            flying.start()
            assert mock.wait_until(lambda m: m.vehicle(2).flight.state.current >= 8, 60.0), "uav2 never got going"
            crew.mav.param_set_send(2, 1, b"SIM_BATT_VOLTAGE", 10.0, 9)  # the pack sags: RTL
            flying.join(120)
    finally:
        mock.stop()
    text = capsys.readouterr()
    doc = json.loads((plan / "flight.json").read_text())
    assert result == [1], text.out + text.err  # drone 2's early end is a problem of the flight
    (retask,) = doc["retasks"]
    assert retask["gone"] == [2] and retask["why"]["2"] == "switched to RTL" and retask["outcome"] == "re-tasked"
    drones = {d["id"]: d for d in doc["drones"]}
    assert drones[2]["ended_early"] and drones[1]["finished"] and drones[3]["finished"]
    assert doc["coverage"] >= 99.0 and doc["min_separation_m"]["kept"] is True
