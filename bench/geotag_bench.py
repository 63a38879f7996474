"""Geotag throughput: images a second `missionplan geotag` reads, places and writes, at three image sizes.

Each run: a survey's ledger with one flight of two drones (records made up, 0.67 s apart along legs, a turn
between legs), one card per drone of JPEGs stamped on a camera clock 2 h 00 min 03.4 s behind UTC, then geotag
timed on both cards. Columns: the image size, the images on the two cards, the JPEG size, the seconds geotag took
(wall), images a second.

`--make-cards SURVEY OUT` instead writes cards for a flown survey (docs/capture.md runs it): a card per drone of
the survey's ledger, an image per capture record with a time but every 25th (a camera that skipped a trigger),
stamped on that camera clock, and a stray card `holiday` of 30 images from three days before.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from PIL import Image

import doctable  # bench/doctable.py: --write-doc

from missionplan.flight.ledger import Ledger

CLOCK_BEHIND_S = 2 * 3600 + 3.4
SKIP_EVERY = 25
SIZES = ((640, 480), (1600, 1200), (4000, 3000))


def write_jpeg(path: Path, camera_s: float, pixels: np.ndarray) -> None:
    """A JPEG stamped with the camera's clock (DateTimeOriginal + SubSecTimeOriginal)."""
    exif = Image.Exif()
    exif[0x010F] = "BenchCam"
    when = datetime.fromtimestamp(camera_s, timezone.utc)
    sub = exif.get_ifd(0x8769)
    sub[0x9003] = when.strftime("%Y:%m:%d %H:%M:%S")
    sub[0x9291] = f"{when.microsecond // 1000:03d}"  # truncated, as cameras write it
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path, quality=90, exif=exif)


def make_cards(survey: Path, out: Path, size: tuple[int, int] = (64, 48)) -> int:
    """One card per drone of the survey (DCIM-<system id>) and a stray card; prints what it wrote."""
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)
    with Ledger.of(survey) as ledger:
        photos = [p for p in ledger.photos() if p.time is not None]
    written = 0
    for vehicle in sorted({p.vehicle for p in photos}):
        own = sorted((p for p in photos if p.vehicle == vehicle), key=lambda p: p.time or 0.0)
        for k, p in enumerate(own):
            if k % SKIP_EVERY != SKIP_EVERY - 1:
                write_jpeg(out / f"DCIM-{vehicle}" / f"DSC{k + 1:05d}.JPG", (p.time or 0.0) - CLOCK_BEHIND_S, pixels)
                written += 1
    start = min(p.time or 0.0 for p in photos) - 3 * 86400
    for k, t in enumerate(np.sort(rng.uniform(0, 300, 30))):
        write_jpeg(out / "holiday" / f"IMG_{k:04d}.JPG", start + float(t), pixels)
    print(f"wrote {written} images on {len({p.vehicle for p in photos})} drones' cards and 30 on holiday/ into {out}")
    return 0


def run(size: tuple[int, int], per_drone: int, base: Path) -> tuple[int, float, float]:
    """(images, JPEG MB, seconds) of one geotag run at one image size."""
    from missionplan.cli import main

    plan = base / "plan"
    if not plan.exists():
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(plan), "--quiet"]) == 0
        rng = np.random.default_rng(1)
        photos = []
        for vehicle in (1, 2):
            t = 1.78e9 + vehicle * 0.3
            for k in range(per_drone):
                photos.append({"vehicle": vehicle, "img_idx": k, "time": t, "lat": 45.478 + 1e-5 * k,
                               "lon": 9.227 + 1e-3 * vehicle, "alt_amsl": 150.0, "alt_rel": 30.0, "source": "camera"})
                t += 0.667 + (rng.uniform(4, 9) if k % 20 == 19 else 0.0)
        with Ledger.of(plan) as ledger:
            ledger.record_flight(plan, 1, 1, photos)
    cards = base / f"cards-{size[0]}"
    rng = np.random.default_rng(2)
    pixels = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)
    with Ledger.of(plan) as ledger:
        photos = ledger.photos()
    for p in photos:
        write_jpeg(cards / f"DCIM-{p.vehicle}" / f"DSC{p.img_idx + 1:05d}.JPG", (p.time or 0.0) - CLOCK_BEHIND_S, pixels)
    jpegs = sorted(cards.rglob("*.JPG"))
    mb = sum(p.stat().st_size for p in jpegs) / len(jpegs) / 1e6
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["geotag", str(plan), str(cards / "DCIM-1"), str(cards / "DCIM-2"),
                     "--out", str(base / f"out-{size[0]}")]) == 0
    return len(jpegs), mb, time.perf_counter() - start


def table(per_drone: int) -> int:
    print(f"{'image':>11}  {'images':>6}  {'JPEG MB':>7}  {'wall s':>6}  {'images/s':>8}")
    print("-" * 46)
    with tempfile.TemporaryDirectory() as tmp:
        for size in SIZES:
            images, mb, seconds = run(size, per_drone, Path(tmp))
            print(f"{size[0]:>5} x {size[1]:<4}  {images:>6}  {mb:>7.2f}  {seconds:>6.2f}  {images / seconds:>8.0f}")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-drone", type=int, default=200, help="images on each drone's card")
    parser.add_argument("--make-cards", nargs=2, metavar=("SURVEY", "OUT"),
                        help="write camera cards for a flown survey instead (docs/capture.md)")
    doctable.add_option(parser)
    args = parser.parse_args()
    if args.make_cards:
        return make_cards(Path(args.make_cards[0]), Path(args.make_cards[1]))
    with doctable.Recorder(args.write_doc, __file__):
        return table(args.per_drone)


if __name__ == "__main__":
    sys.exit(main())
