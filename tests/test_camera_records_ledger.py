"""A MAVLink camera's image_index and file_url, from its CAMERA_IMAGE_CAPTURED to photos.csv.

A flight of a `plan --capture camera` plan keeps each photo's file_url in the flight journal, the survey ledger
keeps the camera's image_index and file_url (nullable columns, added when a camera's flight is first recorded, every
row kept: a relay survey's ledger stays as it was; one without them reads NULL), photos.csv lists both last when any photo has them, and a
ledger rebuilt from the journals holds the same rows. Mocks listen on 127.0.0.1 only."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
from pathlib import Path

import pytest

from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.flight.ledger import LEDGER_NAME, Ledger, open_survey
from missionplan.flight.ledger_repair import open_ledger
from missionplan.flight.mock_fleet import start_mock_fleet
from missionplan.flight.salvage import connect_read_only

SPEEDUP = 10.0
AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
# The ledger's schema before the camera's columns (as ledgers written until then have it).
OLD_SCHEMA = """
CREATE TABLE flights (id INTEGER PRIMARY KEY, plan TEXT NOT NULL, flight INTEGER NOT NULL, sortie INTEGER NOT NULL,
                      recorded REAL NOT NULL, UNIQUE (plan, flight));
CREATE TABLE photos (id INTEGER PRIMARY KEY, flight_id INTEGER NOT NULL, vehicle INTEGER NOT NULL,
                     img_idx INTEGER NOT NULL, time REAL, lat REAL NOT NULL, lon REAL NOT NULL, alt_amsl REAL,
                     alt_rel REAL, roll REAL, pitch REAL, yaw REAL, source TEXT NOT NULL);
CREATE TABLE covered (photo INTEGER NOT NULL, row INTEGER NOT NULL, col INTEGER NOT NULL);
CREATE INDEX photos_by_flight ON photos (flight_id);
CREATE INDEX covered_by_photo ON covered (photo);
"""


def _plan(tmp_path: Path, capture: str) -> Path:
    area = tmp_path / "block.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--out", str(plan_dir), "--quiet",
                 "--capture", capture, "--launch", "45.4641,9.1891"]) == 0
    return plan_dir


def test_an_old_ledger_is_migrated_with_every_row_kept(tmp_path: Path) -> None:
    plan_dir = _plan(tmp_path, "relay")
    path = plan_dir / LEDGER_NAME
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    db.execute("INSERT INTO flights VALUES (1, '.', 1, 1, 1000.0)")
    db.executemany("INSERT INTO photos VALUES (?, 1, 1, ?, 1000.0, 45.4642, 9.1895, 140.0, 20.0, 0, 0, 0, 'camera')",
                   [(k + 1, k) for k in range(3)])
    db.execute("INSERT INTO covered VALUES (1, 2, 3)")
    db.commit()
    db.close()
    survey = open_survey(plan_dir)
    # Read-only (a folder that cannot be written): read as it is, the new columns as NULL, nothing written.
    before = path.read_bytes()
    with Ledger(survey, connect_read_only(path)) as ledger:
        old_rows = ledger.photos()
    assert path.read_bytes() == before and len(old_rows) == 3
    assert all(p.image_index is None and p.file_url is None for p in old_rows)

    def columns() -> list[str]:
        with sqlite3.connect(path) as db:
            return [row[1] for row in db.execute("PRAGMA table_info(photos)")]

    with Ledger(survey) as ledger:  # a relay flight recorded: the table stays as it was (relay surveys unchanged)
        ledger.record_flight(plan_dir, 2, 1, [{"vehicle": 1, "img_idx": 5, "lat": 45.4642, "lon": 9.1895,
                                               "source": "camera"}])
    assert columns()[-1] == "source"
    with Ledger(survey) as ledger:  # a MAVLink camera's flight: migrated, the camera's columns beside the old rows
        ledger.record_flight(plan_dir, 3, 1, [{"vehicle": 1, "img_idx": 0, "lat": 45.4642, "lon": 9.1895,
                                               "source": "camera", "image_index": 0, "file_url": "DCIM/IMG_0000.JPG"}])
        rows = ledger.photos()
        assert [f["photos"] for f in ledger.flights()] == [3, 1, 1]
    assert columns()[-2:] == ["image_index", "file_url"]
    assert rows[:3] == old_rows and rows[3].image_index is None
    assert (rows[4].image_index, rows[4].file_url) == (0, "DCIM/IMG_0000.JPG")
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT COUNT(*) FROM covered").fetchone()[0] >= 1


@pytest.mark.flight
def test_a_camera_flights_photos_csv_names_the_cameras_files_and_a_rebuilt_ledger_agrees(tmp_path: Path) -> None:
    plan_dir = _plan(tmp_path, "camera")
    mock = start_mock_fleet(plan_dir, SPEEDUP, mavlink_camera=True, camera_failures=(2,))
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=120.0, progress=False, time_scale=SPEEDUP)
        images = {image.image_index: image.file_url for image in mock.vehicle(1).mavlink_camera.images
                  if image.capture_result == 1}
    finally:
        mock.stop()
    assert result.ok, result.doc["problems"]
    with (plan_dir / "photos.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[-3:] == ["source", "image_index", "file_url"]
    assert {int(r["image_index"]): r["file_url"] for r in rows} == images  # 2 failed: not a photo
    assert all(int(r["img_idx"]) == int(r["image_index"]) for r in rows)
    geojson = json.loads((plan_dir / "photos.geojson").read_text())
    assert {f["properties"]["file_url"] for f in geojson["features"]} == set(images.values())
    with Ledger.of(plan_dir) as ledger:
        kept = ledger.photos()
    # The ledger rebuilt from the journal (file_url journaled with each photo) holds the same rows.
    (plan_dir / LEDGER_NAME).unlink()
    said: list[str] = []
    with open_ledger(plan_dir, said.append) as ledger:
        assert ledger.photos() == kept
    assert len(said) == 1 and "rebuilt from the journal.sqlite" in said[0]
    # geotag: a card whose files are named as the records' file_url is matched by name, with no clock at all
    # (no DateTimeOriginal), but for one image the camera did not take.
    Image = pytest.importorskip("PIL.Image")
    pytest.importorskip("pyexiv2")
    from missionplan.flight.exif_geotag import geotag_cards

    card = tmp_path / "DCIM-1"
    card.mkdir()
    for name in [url.rsplit("/", 1)[-1] for url in images.values()] + ["IMG_9999.JPG"]:
        Image.new("RGB", (16, 12)).save(card / name)
    run = geotag_cards(plan_dir, [card], tmp_path / "out")
    assert run.lines == [f"card DCIM-1: drone 1, flight 1: {len(images)} matched, 1 unmatched image, 0 ambiguous, "
                         "by file name (the camera's file_url)"]
    with (tmp_path / "out" / "DCIM-1" / "photos.csv").open() as f:
        tagged = {r["image"]: r for r in csv.DictReader(f)}
    by_index = {int(r["image_index"]): r for r in rows}
    for index, url in images.items():
        name = url.rsplit("/", 1)[-1]
        assert (tagged[name]["lat"], tagged[name]["lon"]) == (by_index[index]["lat"], by_index[index]["lon"])
    shutil.rmtree(plan_dir)
