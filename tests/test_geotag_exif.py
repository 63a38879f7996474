"""`missionplan geotag`: a crew's camera cards placed on the survey's drones by their capture times, and copies
written with EXIF GPS and XMP gimbal tags, read back by an independent reader (exiftool where installed, as CI
installs it; Pillow otherwise). The matching itself (image_match.py) is checked on made-up time lines first."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from missionplan.cli import main
from missionplan.flight.exif_geotag import INSTALL_HINT, clock_words
from missionplan.flight.image_match import match_images
from missionplan.flight.ledger import Ledger

pytest.importorskip("pyexiv2", reason="the geotag extra (make test installs it)")

CLOCK_BEHIND_S = 2 * 3600 + 3.4  # the camera clock is this far behind UTC
DRIFT = 40e-6  # and gains 40 µs a second on it (0.14 s an hour)
START = datetime(2026, 5, 14, 9, 30, tzinfo=timezone.utc).timestamp()


def capture_times(rng: np.random.Generator, start: float, legs: int = 6, per_leg: int = 15) -> np.ndarray:
    """A survey camera's UTC capture times: legs of photos 0.67 s apart (3.33 m at 5 m/s, with the link's
    jitter), turns of 4-9 s between legs."""
    times, t = [], start
    for _ in range(legs):
        for _ in range(per_leg):
            times.append(t + rng.normal(0, 0.02))
            t += 0.667
        t += rng.uniform(4, 9)
    return np.array(times)


def on_camera_clock(utc: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The same moments as the camera stamped them: behind UTC, drifting, with its own shutter jitter."""
    return utc - CLOCK_BEHIND_S + DRIFT * (utc - utc[0]) + rng.normal(0, 0.01, len(utc))


# ------------------------------------------------------------------------------------------------ the matching
def test_the_clock_offset_is_found_with_photos_missing_on_either_side() -> None:
    rng = np.random.default_rng(3)
    records = capture_times(rng, START, legs=20, per_leg=30)
    camera = on_camera_clock(records, rng)
    skipped = [5, 40]  # the camera skipped these triggers: records without an image
    lost = [17, 63]  # these reports were lost on the link: images without a record
    images = np.delete(camera, skipped)
    truth = np.delete(np.arange(len(records)), skipped)  # the record each image really is
    kept = np.delete(np.arange(len(records)), lost)
    match = match_images(images, records[kept], resolution_s=0.001)
    got = [None if j is None else int(kept[j]) for j in match.record_of]
    want = [None if t in lost else int(t) for t in truth]
    assert got == want
    assert match.matched == len(records) - 4 and match.unmatched == 2 and match.ambiguous_count == 0
    assert match.offset_s == pytest.approx(CLOCK_BEHIND_S, abs=0.1)
    assert match.drift == pytest.approx(-DRIFT, abs=1e-5)  # UTC - camera shrinks as the camera gains


def test_an_image_within_the_tolerance_of_two_records_is_ambiguous() -> None:
    records = np.array([0.0, 1.0, 2.0, 3.0, 3.2, 5.0, 6.0, 7.0, 8.0, 9.0, 11.0, 12.5, 13.5])
    images = np.delete(records, [3, 4]) - 100.0
    images = np.insert(images, 3, 3.1 - 100.0)  # one image halfway between the records at 3.0 and 3.2
    match = match_images(images, records, resolution_s=0.001)
    assert match.ambiguous == [k == 3 for k in range(len(images))]
    assert match.matched == len(images) - 1 and match.offset_s == pytest.approx(100.0, abs=0.01)


def test_images_without_a_capture_time_are_left_unmatched() -> None:
    records = np.arange(10.0) * 0.7 + np.array([0, 0, 0, 3, 3, 3, 3, 7, 7, 7])
    images = records - 50.0
    images[4] = np.nan
    match = match_images(images, records)
    assert match.record_of[4] is None and match.unmatched == 1 and match.matched == 9


@pytest.mark.parametrize("offset, words", [(7203.43, "2 h 00 min 03.4 s behind UTC"),
                                           (-125.0, "2 min 05.0 s ahead of UTC"),
                                           (0.8, "0.8 s behind UTC"), (0.01, "on UTC"),
                                           (3599.97, "1 h 00 min 00.0 s behind UTC")])
def test_the_clock_is_said_in_hours_minutes_and_seconds(offset: float, words: str) -> None:
    assert clock_words(offset) == words


# ------------------------------------------------------------------------------------------------ a survey's cards
def write_jpeg(path: Path, camera_s: float | None, seed: int) -> None:
    """A small real JPEG, stamped with the camera's clock (DateTimeOriginal + SubSecTimeOriginal)."""
    pixels = np.random.default_rng(seed).integers(0, 255, (24, 32, 3), dtype=np.uint8)
    exif = Image.Exif()
    exif[0x010F] = "TestCam"  # Make
    if camera_s is not None:
        when = datetime.fromtimestamp(camera_s, timezone.utc)
        sub = exif.get_ifd(0x8769)
        sub[0x9003] = when.strftime("%Y:%m:%d %H:%M:%S")  # DateTimeOriginal
        sub[0x9291] = f"{when.microsecond // 1000:03d}"  # SubSecTimeOriginal
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path, quality=85, exif=exif)


def survey_photos(vehicle: int, times: np.ndarray, rng: np.random.Generator) -> list[dict]:
    lat0, lon0 = 45.4780 + 0.001 * vehicle, 9.2270
    return [{"vehicle": vehicle, "img_idx": k, "time": float(t), "lat": lat0 + 1e-5 * k + rng.uniform(0, 1e-6),
             "lon": lon0 + 3e-5 * (k % 15) + rng.uniform(0, 1e-6), "alt_amsl": 152.5 + 0.01 * k, "alt_rel": 30.0,
             "roll": 1.5, "pitch": -2.0, "yaw": 271.0 + k % 2, "source": "camera"} for k, t in enumerate(times)]


@pytest.fixture(scope="module")
def survey(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A plan whose ledger holds one flight of two drones, and a card per drone plus a stray card."""
    base = tmp_path_factory.mktemp("geotag")
    plan = base / "plan"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(plan), "--quiet"]) == 0
    rng = np.random.default_rng(11)
    times = {1: capture_times(rng, START), 2: capture_times(rng, START + 2.1, legs=5, per_leg=18)}
    photos = survey_photos(1, times[1], rng) + survey_photos(2, times[2], rng)
    with Ledger.of(plan) as ledger:
        ledger.record_flight(plan, 1, 1, photos)
    cards = {}
    for vehicle, skipped in ((1, [7, 50]), (2, [0, 30])):  # skipped triggers: records without an image
        card = base / f"DCIM-{'AB'[vehicle - 1]}"
        camera = on_camera_clock(times[vehicle], rng)
        for k, t in enumerate(camera):
            if k not in skipped:
                write_jpeg(card / "100CAM" / f"DSC{k + 1:05d}.JPG", float(t), seed=k)
        cards[vehicle] = card
    stray = base / "holiday"
    for k, t in enumerate(START - 86400 * 3 + np.sort(rng.uniform(0, 600, 40))):
        write_jpeg(stray / f"IMG_{k:04d}.JPG", float(t), seed=100 + k)
    originals = {p: (p.read_bytes(), p.stat().st_mtime_ns) for card in (*cards.values(), stray)
                 for p in card.rglob("*.JPG")}
    return {"plan": plan, "cards": cards, "stray": stray, "photos": photos, "originals": originals, "base": base}


@pytest.fixture(scope="module")
def geotagged(survey: dict) -> dict:
    """`missionplan geotag` run once on the survey's cards (captured output, exit code)."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["geotag", str(survey["plan"]), str(survey["cards"][1]), str(survey["cards"][2]),
                     str(survey["stray"])])
    return {"code": code, "out": out.getvalue(), "err": err.getvalue(), "dir": survey["plan"] / "geotagged"}


def read_gps(path: Path) -> dict:
    """Latitude, longitude, altitude and the XMP gimbal pitch of a copy, read by exiftool (or Pillow)."""
    if shutil.which("exiftool"):
        doc = json.loads(subprocess.run(["exiftool", "-j", "-n", "-GPSLatitude", "-GPSLongitude", "-GPSAltitude",
                                         "-GPSAltitudeRef", "-GPSMapDatum", "-XMP-drone-dji:all", str(path)],
                                        capture_output=True, text=True, check=True, timeout=60).stdout)[0]
        lat, lon = doc["GPSLatitude"], doc["GPSLongitude"]
        return {"lat": lat, "lon": lon, "alt": doc["GPSAltitude"], "datum": doc["GPSMapDatum"],
                "pitch": float(doc["GimbalPitchDegree"]), "yaw": float(doc["FlightYawDegree"])}
    gps = Image.open(path).getexif().get_ifd(0x8825)  # no exiftool: Pillow reads EXIF (not XMP without defusedxml)

    def degrees(dms: tuple, ref: str) -> float:
        value = float(dms[0]) + float(dms[1]) / 60 + float(dms[2]) / 3600
        return -value if ref in "SW" else value

    return {"lat": degrees(gps[2], gps[1]), "lon": degrees(gps[4], gps[3]), "alt": float(gps[6]),
            "datum": gps[18], "pitch": None, "yaw": None}


def test_each_card_is_placed_on_its_drone_with_its_clock(geotagged: dict) -> None:
    lines = geotagged["out"].splitlines()
    assert geotagged["code"] == 0, geotagged["err"]
    assert lines[0] == ("card DCIM-A: drone 1, flight 1: 88 matched, 0 unmatched images, 0 ambiguous, camera clock "
                        "2 h 00 min 03.4 s behind UTC; 2 capture records without an image")
    assert lines[1].startswith("card DCIM-B: drone 2, flight 1: 88 matched, 0 unmatched images, 0 ambiguous, "
                               "camera clock 2 h 00 min 03.4 s behind UTC")
    assert lines[2].startswith("card holiday: fits no drone of the survey: 40 timed images")
    assert lines[3] == f"wrote 176 geotagged copies into {geotagged['dir']}"


def test_every_copy_carries_its_capture_records_position(survey: dict, geotagged: dict) -> None:
    by_key = {(p["vehicle"], p["img_idx"]): p for p in survey["photos"]}
    for vehicle, card in survey["cards"].items():
        copies = sorted((geotagged["dir"] / card.name / "100CAM").glob("*.JPG"))
        assert len(copies) == 88
        for copy in copies[::9]:
            record = by_key[(vehicle, int(copy.stem[3:]) - 1)]  # DSC00008.JPG is the camera's 8th: index 7
            got = read_gps(copy)
            assert got["lat"] == pytest.approx(record["lat"], abs=1e-6)
            assert got["lon"] == pytest.approx(record["lon"], abs=1e-6)
            assert got["alt"] == pytest.approx(record["alt_amsl"], abs=0.01)
            assert got["datum"] == "WGS-84"
            if got["pitch"] is not None:
                assert got["pitch"] == -90.0 and got["yaw"] == pytest.approx((record["yaw"] + 180) % 360 - 180)
            with Image.open(copy) as im, Image.open(card / "100CAM" / copy.name) as orig:
                assert np.array_equal(np.asarray(im), np.asarray(orig))  # the pixels untouched


def test_the_originals_are_untouched_and_the_stray_card_gets_no_copy(survey: dict, geotagged: dict) -> None:
    for path, (data, mtime) in survey["originals"].items():
        assert path.read_bytes() == data and path.stat().st_mtime_ns == mtime
    assert not (geotagged["dir"] / "holiday").exists()
    assert not [p for p in geotagged["dir"].rglob(".*")]  # no temp file left


def test_photos_csv_and_geo_txt_name_the_copies(survey: dict, geotagged: dict) -> None:
    folder = geotagged["dir"] / "DCIM-A"
    rows = list(csv.DictReader((folder / "photos.csv").open()))
    assert len(rows) == 88 and rows[0]["image"] == "100CAM/DSC00001.JPG" and rows[0]["img_idx"] == "0"
    assert all((folder / r["image"]).is_file() for r in rows)
    geo = (folder / "geo.txt").read_text().splitlines()
    assert geo[0] == "EPSG:4326" and len(geo) == 89 and geo[8].startswith("100CAM/DSC00009.JPG ")  # 8th skipped


def test_a_card_with_no_drone_alone_exits_1(survey: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["geotag", str(survey["plan"]), str(survey["stray"]), "--out", str(tmp_path / "out")]) == 1
    out, err = capsys.readouterr()
    assert out.startswith("card holiday: fits no drone of the survey: 40 timed images, capture records drone 1: 90, "
                          "drone 2: 90; at best")
    assert err == "missionplan geotag: no card could be placed on a drone of the survey: nothing written\n"
    assert not list((tmp_path / "out").rglob("*.JPG"))


def test_bad_input_is_one_line(survey: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    card = survey["cards"][1]
    assert main(["geotag", str(survey["plan"]), str(tmp_path / "nowhere")]) == 2
    assert capsys.readouterr().err == f"missionplan: {tmp_path / 'nowhere'}: no such folder of images\n"
    assert main(["geotag", str(tmp_path), str(card)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "report.json" in err
    broken = tmp_path / "broken"
    shutil.copytree(card, broken)
    (broken / "100CAM" / "DSC00003.JPG").write_bytes(b"\xff\xd8\xff\xe0 not really a JPEG")
    out_dir = tmp_path / "out"
    assert main(["geotag", str(survey["plan"]), str(broken), "--out", str(out_dir)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"missionplan: {broken / '100CAM' / 'DSC00003.JPG'}: not a JPEG that can be read")
    assert err.count("\n") == 1 and not out_dir.exists()  # every card is read before anything is written


def test_without_pyexiv2_geotag_says_how_to_install_it(survey: dict, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "pyexiv2", None)  # import pyexiv2 raises ImportError
    assert main(["geotag", str(survey["plan"]), str(survey["cards"][1])]) == 2
    assert capsys.readouterr().err == f"missionplan: {INSTALL_HINT}\n"


def test_two_drones_flying_at_once_are_told_apart_by_their_turns_or_the_card_is_refused() -> None:
    """Legs of photos at one interval line a card up with any drone; the turns between legs place it. Two
    drones with the very same turns cannot be told apart by time: the card is refused, not guessed."""
    from missionplan.flight.exif_geotag import Card, CardImage, Placement, place_card
    from missionplan.flight.ledger import LedgerPhoto

    rng = np.random.default_rng(5)

    def records(vehicle: int, turns: list[float]) -> list[LedgerPhoto]:
        times = START + np.arange(120) * 0.667 + np.repeat(np.cumsum([0.0, *turns]), 20)
        return [LedgerPhoto(".", 1, vehicle, k, float(t + rng.normal(0, 0.005)), 45.0, 9.0, None, None, None,
                            None, None, "camera") for k, t in enumerate(times)]

    def card_of(photos: list[LedgerPhoto]) -> Card:
        camera = np.array([p.time for p in photos]) - CLOCK_BEHIND_S
        return Card("DCIM", Path("DCIM"), [CardImage(Path(f"{k}.JPG"), f"{k}.JPG", float(t))
                                          for k, t in enumerate(camera)], 0.001)

    fleet = {1: records(1, [5.2, 7.9, 4.4, 6.1, 8.3]), 2: records(2, [6.6, 4.9, 8.1, 5.5, 7.0])}
    placed = place_card(card_of(fleet[2]), fleet)
    assert isinstance(placed, Placement) and placed.vehicle == 2 and placed.match.matched == 120
    twins = {1: records(1, [6.0] * 5), 2: records(2, [6.0] * 5)}
    assert place_card(card_of(twins[2]), twins) == \
        "card DCIM: lines up with drone 2 (120 images) and drone 1 (120) alike: not placed"


def test_a_card_that_lines_up_with_two_drones_goes_to_the_one_whose_records_no_other_card_holds() -> None:
    """Drone 2 flies six legs at one interval; drone 1 flies the same six legs, then three more with its own
    turns. Drone 2's card lines up with both alike; drone 1's card holds drone 1's records, so it goes to drone 2."""
    from missionplan.flight.exif_geotag import Card, CardImage, Placement, place_card, place_cards
    from missionplan.flight.ledger import LedgerPhoto

    rng = np.random.default_rng(6)

    def records(vehicle: int, turns: list[float]) -> list[LedgerPhoto]:
        times = START + np.arange(20 * (len(turns) + 1)) * 0.667 + np.repeat(np.cumsum([0.0, *turns]), 20)
        return [LedgerPhoto(".", 1, vehicle, k, float(t + rng.normal(0, 0.005)), 45.0, 9.0, None, None, None,
                            None, None, "camera") for k, t in enumerate(times)]

    def card_of(name: str, photos: list[LedgerPhoto]) -> Card:
        camera = np.array([p.time for p in photos]) - CLOCK_BEHIND_S
        return Card(name, Path(name), [CardImage(Path(f"{k}.JPG"), f"{k}.JPG", float(t))
                                       for k, t in enumerate(camera)], 0.001)

    fleet = {1: records(1, [6.0] * 5 + [3.1, 9.7, 4.4]), 2: records(2, [6.0] * 5)}
    cards = [card_of("DCIM-2", fleet[2]), card_of("DCIM-1", fleet[1])]
    assert place_card(cards[0], fleet) == \
        "card DCIM-2: lines up with drone 2 (120 images) and drone 1 (120) alike: not placed"
    second, first = place_cards(cards, fleet)
    assert isinstance(first, Placement) and first.vehicle == 1 and first.match.matched == 180
    assert isinstance(second, Placement) and second.vehicle == 2 and second.match.matched == 120
    assert {id(r) for _, r in second.photo_of()} == {id(r) for r in fleet[2]}
