"""`missionplan geotag`: a crew's camera cards geotagged from the survey ledger, into copies; the originals are
never written.

For each card (a folder of one camera's JPEGs, searched in its subfolders too):
1. read each image's capture time (EXIF DateTimeOriginal + SubSecTimeOriginal, the camera's own clock);
2. place the card: by file name first, where a MAVLink camera's capture records name their files (ledger
   file_url, `plan --capture camera`): the one vehicle whose records name more than half of the card's images
   has each image matched to the record that names it, no clock needed (image_match.match_names); else
   match it against every vehicle's capture records of the survey (image_match.py finds the
   camera clock's offset and pairs image and record one to one); the card belongs to the vehicle that lines up
   the most images, and more than half of its timed images, at one offset. A vehicle's records across the
   survey's flights form one UTC time line, so a card that went on several flights is placed whole;
3. write each matched image's copy, OUT/CARD/<its path on the card>, with its geotag: EXIF GPS (latitude,
   longitude, altitude above sea level by geo.txt's rule, the record's UTC date and time, datum WGS-84) and XMP in
   DJI's drone-dji namespace (gimbal and airframe angles, absolute and relative altitude), which OpenDroneMap,
   Pix4D and Metashape read. Each copy is written whole to a temp file, then renamed; it keeps the original's
   modification time;
4. write OUT/CARD/photos.csv and OUT/CARD/geo.txt for the matched images, naming the copies.

A card per folder under OUT keeps every camera's own file names (two cameras both have a DSC00001.JPG), lets a
card be geotagged again alone, and gives OpenDroneMap a folder of images with its geo.txt beside them.

EXIF and XMP are written with pyexiv2 (exiv2's Python binding, the `geotag` extra): it edits the metadata
segments without touching the compressed image, writes EXIF and XMP both, and keeps the camera's own XMP.

Gimbal angles: the ledger keeps the airframe's roll / pitch / yaw as the vehicle reported them, not the gimbal's.
The copies say the camera pointed `gimbal_pitch_deg` (default -90, straight down, DJI's convention) with the
airframe's heading and no roll; a record that carries the camera's own pitch should be passed here instead.
"""

from __future__ import annotations

import os
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.base.atomic import atomic_path, write_text_atomic

from ..maps.gridmap import MapError
from .geotag import geo_altitudes, geo_txt, photos_csv
from .image_match import Match, match_images, match_names
from .ledger import Ledger, LedgerPhoto

JPEG_SUFFIXES = (".jpg", ".jpeg")
DEFAULT_OUT = "geotagged"
NADIR_PITCH_DEG = -90.0  # DJI's convention: 0 level, -90 straight down
DJI_NS = "http://www.dji.com/drone-dji/1.0/"
INSTALL_HINT = "missionplan geotag needs pyexiv2 to write EXIF and XMP: pip install 'missionplan[geotag]'"
# Two drones flying the same pattern at once line a card up almost as well: the wrong one's images lie anywhere
# within the tolerance of their records, the right one's within the clocks' jitter. A card is not placed when a
# runner-up lines up this share of the best one's images with residuals as small (within twice, plus a tenth of
# the tolerance).
AMBIGUOUS_CARD = 0.95
DRIFT_WORTH_SAYING_S = 0.1
ARCSEC_DEN = 100_000  # GPS seconds as a rational over this: 1e-5 arc second, 0.3 mm


class GeotagError(MapError):
    """A card, an image or the survey that cannot be geotagged: one line for the user."""


def exiv2() -> Any:
    """pyexiv2, quiet (its warnings would be lines on stderr of ours), with DJI's XMP namespace registered."""
    try:
        import pyexiv2
    except ImportError:
        raise GeotagError(INSTALL_HINT) from None
    pyexiv2.set_log_level(4)  # mute: what matters is raised as an exception
    try:
        pyexiv2.registerNs(DJI_NS, "drone-dji")
    except Exception:  # registered already (a second call in one process)
        pass
    return pyexiv2


# ------------------------------------------------------------------------------------------------ reading a card
@dataclass(frozen=True)
class CardImage:
    path: Path
    relative: str  # its path on the card, with / between folders
    time: float | None  # the camera clock, as seconds of a naive timestamp read as UTC; None without one


@dataclass(frozen=True)
class Card:
    name: str  # the copies' folder under OUT
    folder: Path
    images: list[CardImage]  # in file order
    resolution_s: float  # the images' time resolution: 1 s without SubSecTimeOriginal

    @property
    def untimed(self) -> list[CardImage]:
        return [im for im in self.images if im.time is None]


def camera_time(exif: dict[str, str]) -> tuple[float | None, int]:
    """The image's capture time on the camera's clock (seconds; the naive time read as UTC) and the number of
    sub-second digits it had; (None, 0) without a DateTimeOriginal."""
    text = (exif.get("Exif.Photo.DateTimeOriginal") or "").strip().strip("\x00")
    try:
        when = datetime.strptime(text, "%Y:%m:%d %H:%M:%S").replace(tzinfo=timezone.utc)
    except ValueError:
        return None, 0
    sub = "".join(ch for ch in (exif.get("Exif.Photo.SubSecTimeOriginal") or "") if ch.isdigit())
    return when.timestamp() + (int(sub) / 10 ** len(sub) if sub else 0.0), len(sub)


def read_card(folder: Path, name: str) -> Card:
    """A card's JPEGs (its subfolders too, in path order) and their capture times. GeotagError when the folder
    is missing, holds no JPEG, or holds one that cannot be read."""
    pyexiv2 = exiv2()
    if not folder.is_dir():
        raise GeotagError(f"{folder}: no such folder of images")
    paths = sorted(p for p in folder.rglob("*") if p.suffix.lower() in JPEG_SUFFIXES and p.is_file()
                   and not p.name.startswith("."))
    if not paths:
        raise GeotagError(f"{folder}: no JPEG images (.jpg, .jpeg) in it or its subfolders")
    images, digits = [], []
    for path in paths:
        try:
            with pyexiv2.Image(str(path)) as img:
                exif = img.read_exif()
        except (RuntimeError, OSError, UnicodeDecodeError) as err:
            raise GeotagError(f"{path}: not a JPEG that can be read ({str(err).strip() or type(err).__name__})") \
                from None
        t, sub = camera_time(exif)
        images.append(CardImage(path, path.relative_to(folder).as_posix(), t))
        if t is not None:
            digits.append(sub)
    resolution = 10.0 ** -min(digits) if digits else 1.0
    return Card(name, folder, images, resolution)


def card_names(folders: Sequence[Path]) -> list[str]:
    """Each card's folder name under OUT: its own name, -2, -3... after it where two cards share one
    (two cameras' DCIM/100MSDCF)."""
    names: list[str] = []
    for folder in folders:
        base = folder.resolve().name or "card"
        name, k = base, 2
        while name in names:
            name, k = f"{base}-{k}", k + 1
        names.append(name)
    return names


# ------------------------------------------------------------------------------------------------ placing a card
@dataclass
class Placement:
    """A card placed on a vehicle: which record each image is."""

    card: Card
    vehicle: int
    match: Match
    records: list[LedgerPhoto]  # the vehicle's timed records, the match's indices
    written: list[Path] = field(default_factory=list)
    by_name: bool = False  # matched by the file names its records name (file_url), not by the clock
    clock_known: bool = True  # by name: whether any image had a time to say the camera clock by

    def photo_of(self) -> list[tuple[CardImage, LedgerPhoto]]:
        return [(im, self.records[j]) for im, j in zip(self.card.images, self.match.record_of) if j is not None]

    @property
    def records_without_image(self) -> int:
        return len(self.records) - self.match.matched


def place_by_name(card: Card, by_vehicle: dict[int, list[LedgerPhoto]]) -> Placement | None:
    """The card placed by its file names (a MAVLink camera's records name their files, ledger file_url): on the one
    vehicle whose records name more than half of its images, each image matched to the record naming it; None when
    no vehicle's do (records without file_url), or two vehicles' do alike (two cameras that number their files the
    same way): then the clock decides."""
    names = [im.path.name for im in card.images]
    tried = sorted(((match_names(names, [p.file_url for p in records]), vehicle, records)
                    for vehicle, records in by_vehicle.items()), key=lambda t: (-t[0].matched, t[1]))
    if not tried or tried[0][0].matched * 2 <= len(names):
        return None
    match, vehicle, records = tried[0]
    if len(tried) > 1 and tried[1][0].matched * 2 > len(names):
        return None
    # The camera clock, for the report: the median of record time minus image time over the images with both.
    pairs = [(im.time, records[j].time) for im, j in zip(card.images, match.record_of)
             if j is not None and im.time is not None and records[j].time is not None]
    offset = float(np.median([r - t for t, r in pairs])) if pairs else 0.0
    return Placement(card, vehicle, replace(match, offset_s=offset), records, by_name=True, clock_known=bool(pairs))


def place_card(card: Card, by_vehicle: dict[int, list[LedgerPhoto]]) -> Placement | str:
    """The vehicle the card's images belong to, or why none: a line to print. By file name first (place_by_name),
    else by the camera clock: the vehicle whose capture records its images' times line up with."""
    by_name = place_by_name(card, by_vehicle)
    if by_name is not None:
        return by_name
    timed = [im.time for im in card.images]
    times = np.array([np.nan if t is None else t for t in timed], dtype=float)
    n_timed = int(np.isfinite(times).sum())
    if not n_timed:
        return (f"card {card.name}: none of its {len(card.images)} images has a capture time (EXIF "
                "DateTimeOriginal): it cannot be matched to the capture records")
    tried = []
    for vehicle, records in sorted(by_vehicle.items()):
        match = match_images(times, np.array([p.time for p in records], dtype=float), card.resolution_s)
        tried.append((match.matched, vehicle, match, records))
    tried.sort(key=lambda t: (-t[0], t[2].residual_s, t[1]))
    if not tried:
        return f"card {card.name}: the survey has no capture record with a time to match images to"
    best, vehicle, match, records = tried[0]
    if best * 2 <= n_timed:
        counts = ", ".join(f"drone {v}: {len(r)}" for _, v, _, r in sorted(tried, key=lambda t: t[1]))
        return (f"card {card.name}: fits no drone of the survey: {n_timed} timed images, capture records {counts}; "
                f"at best {best} images line up with drone {vehicle}'s at one clock offset (more than half must)")
    runner = tried[1] if len(tried) > 1 else None
    if runner is not None and runner[0] >= AMBIGUOUS_CARD * best and \
            runner[2].residual_s <= 2 * match.residual_s + 0.1 * match.tolerance_s:
        return (f"card {card.name}: lines up with drone {vehicle} ({best} images) and drone {runner[1]} "
                f"({runner[0]}) alike: not placed")
    return Placement(card, vehicle, match, records)


def place_cards(cards: Sequence[Card], by_vehicle: dict[int, list[LedgerPhoto]]) -> list[Placement | str]:
    """Each card placed (place_card); then every card left unplaced is tried again on the capture records that
    no placed card holds, until no more is placed. A record is one photo on one card: two drones photographing at
    one interval line a card up with both, but not once the other drone's card holds that drone's records."""
    outcomes: list[Placement | str] = [place_card(card, by_vehicle) for card in cards]
    while any(isinstance(o, str) for o in outcomes):
        held = {id(record) for o in outcomes if isinstance(o, Placement) for _, record in o.photo_of()}
        if not held:
            break
        left = {v: [p for p in records if id(p) not in held] for v, records in by_vehicle.items()}
        again = {k: place_card(cards[k], left) for k, o in enumerate(outcomes) if isinstance(o, str)}
        newly = {k: o for k, o in again.items() if isinstance(o, Placement)}
        if not newly:
            break
        for k, placed in newly.items():
            outcomes[k] = placed
    return outcomes


def clock_words(offset_s: float) -> str:
    """`2 h 00 min 03.4 s behind UTC`: how far the camera clock is from UTC (offset = UTC - camera)."""
    size = abs(offset_s)
    hours, rest = divmod(size, 3600.0)
    minutes, seconds = divmod(rest, 60.0)
    if round(seconds, 1) >= 60.0:  # 59.96 s shows as 60.0: carry it
        minutes, seconds = minutes + 1, 0.0
    if minutes >= 60:
        hours, minutes = hours + 1, minutes - 60
    if hours:
        text = f"{int(hours)} h {int(minutes):02d} min {seconds:04.1f} s"
    elif minutes:
        text = f"{int(minutes)} min {seconds:04.1f} s"
    else:
        text = f"{seconds:.1f} s"
    if text in ("0.0 s",):
        return "on UTC"
    return f"{text} {'behind' if offset_s > 0 else 'ahead of'} UTC"


def _flights(photos: list[LedgerPhoto]) -> str:
    """`flight 1`, `flights 1 and 2`, `flight 1 of ../day2`: the survey's flights the card's images come from."""
    by_plan: dict[str, list[int]] = defaultdict(list)
    for p in photos:
        if p.flight not in by_plan[p.plan]:
            by_plan[p.plan].append(p.flight)
    parts = []
    for plan, flights in by_plan.items():
        numbers = sorted(flights)
        words = (f"flight {numbers[0]}" if len(numbers) == 1
                 else f"flights {', '.join(map(str, numbers[:-1]))} and {numbers[-1]}")
        parts.append(words if plan == "." else f"{words} of {plan}")
    return "; ".join(parts) or "no flight"


def card_line(placed: Placement) -> str:
    """`card DCIM-A: drone 2, flight 1: 412 matched, 3 unmatched images, 0 ambiguous, camera clock ... UTC`."""
    m = placed.match
    # The drift is said where it adds up to a tenth of a second over the card; below that it is the fit's noise.
    drifting = (f", {'gaining' if m.drift < 0 else 'losing'} {abs(m.drift) * 3600:.2f} s an hour"
                if abs(m.drift * m.span_s) >= DRIFT_WORTH_SAYING_S else "")
    lost = placed.records_without_image
    how = ("by file name (the camera's file_url)" + (f", camera clock {clock_words(m.offset_s)}" if placed.clock_known
                                                     else "") if placed.by_name
           else f"camera clock {clock_words(m.offset_s)}{drifting}")
    return (f"card {placed.card.name}: drone {placed.vehicle}, {_flights([p for _, p in placed.photo_of()])}: "
            f"{m.matched} matched, {m.unmatched} unmatched image{'' if m.unmatched == 1 else 's'}, "
            f"{m.ambiguous_count} ambiguous, {how}"
            + (f"; {lost} capture record{'' if lost == 1 else 's'} without an image" if lost else ""))


# ------------------------------------------------------------------------------------------------ writing
def _rational_dms(degrees: float) -> str:
    """|degrees| as EXIF's three rationals, degrees minutes seconds (seconds to 1e-5 arc second)."""
    total = round(abs(degrees) * 3600 * ARCSEC_DEN)
    d, rest = divmod(total, 3600 * ARCSEC_DEN)
    m, s = divmod(rest, 60 * ARCSEC_DEN)
    return f"{d}/1 {m}/1 {s}/{ARCSEC_DEN}"


def _signed(value: float) -> str:
    return f"{value:+.2f}"


def _angle(deg: float) -> float:
    """An angle in (-180, 180], as DJI writes yaw."""
    wrapped = (deg + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped


def geotag_fields(photo: LedgerPhoto, altitude_m: float, gimbal_pitch_deg: float = NADIR_PITCH_DEG
                  ) -> tuple[dict[str, str], dict[str, str]]:
    """The EXIF GPS tags and the XMP drone-dji tags of one photo, as pyexiv2 takes them."""
    when = datetime.fromtimestamp(float(photo.time or 0.0), timezone.utc)
    seconds_ms = round((when.second + when.microsecond / 1e6) * 1000)
    exif = {
        "Exif.GPSInfo.GPSVersionID": "2 3 0 0",
        "Exif.GPSInfo.GPSLatitudeRef": "N" if photo.lat >= 0 else "S",
        "Exif.GPSInfo.GPSLatitude": _rational_dms(photo.lat),
        "Exif.GPSInfo.GPSLongitudeRef": "E" if photo.lon >= 0 else "W",
        "Exif.GPSInfo.GPSLongitude": _rational_dms(photo.lon),
        "Exif.GPSInfo.GPSAltitudeRef": "0" if altitude_m >= 0 else "1",  # above / below sea level
        "Exif.GPSInfo.GPSAltitude": f"{round(abs(altitude_m) * 1000)}/1000",
        "Exif.GPSInfo.GPSTimeStamp": f"{when.hour}/1 {when.minute}/1 {seconds_ms}/1000",
        "Exif.GPSInfo.GPSDateStamp": when.strftime("%Y:%m:%d"),
        "Exif.GPSInfo.GPSMapDatum": "WGS-84",
    }
    yaw = _angle(photo.yaw) if photo.yaw is not None else 0.0
    xmp = {
        "Xmp.drone-dji.GpsLatitude": f"{photo.lat:.8f}",
        "Xmp.drone-dji.GpsLongitude": f"{photo.lon:.8f}",
        "Xmp.drone-dji.AbsoluteAltitude": _signed(altitude_m),
        "Xmp.drone-dji.GimbalPitchDegree": _signed(gimbal_pitch_deg),
        "Xmp.drone-dji.GimbalYawDegree": _signed(yaw),  # a nadir gimbal follows the airframe's heading
        "Xmp.drone-dji.GimbalRollDegree": _signed(0.0),
        "Xmp.drone-dji.FlightYawDegree": _signed(yaw),
        "Xmp.drone-dji.FlightPitchDegree": _signed(photo.pitch or 0.0),
        "Xmp.drone-dji.FlightRollDegree": _signed(photo.roll or 0.0),
    }
    if photo.alt_rel is not None:
        xmp["Xmp.drone-dji.RelativeAltitude"] = _signed(photo.alt_rel)
    return exif, xmp


def write_copy(source: Path, target: Path, exif: dict[str, str], xmp: dict[str, str]) -> None:
    """`source`'s bytes with the geotag added, as `target` (a temp file beside it first, then renamed);
    `source` is only read. The copy keeps its modification time."""
    pyexiv2 = exiv2()
    data = source.read_bytes()
    stat = source.stat()
    try:
        with pyexiv2.ImageData(data) as img:
            img.modify_exif(exif)
            img.modify_xmp(xmp)
            tagged = img.get_bytes()
    except RuntimeError as err:
        raise GeotagError(f"{source}: its metadata cannot be rewritten ({str(err).strip()})") from None
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as tmp:
        tmp.write_bytes(tagged)
        os.utime(tmp, ns=(stat.st_atime_ns, stat.st_mtime_ns))


def write_card(placed: Placement, out: Path, altitude_of: Callable[[list[LedgerPhoto]], list[float]],
               gimbal_pitch_deg: float = NADIR_PITCH_DEG) -> Path:
    """The card's geotagged copies, photos.csv and geo.txt in out/CARD; returns that folder."""
    folder = out / placed.card.name
    pairs = placed.photo_of()
    photos = [p for _, p in pairs]
    for (image, photo), altitude in zip(pairs, altitude_of(photos)):
        exif, xmp = geotag_fields(photo, altitude, gimbal_pitch_deg)
        target = folder / image.relative
        write_copy(image.path, target, exif, xmp)
        placed.written.append(target)
    names = {photo: image.relative for image, photo in pairs}
    folder.mkdir(parents=True, exist_ok=True)
    write_text_atomic(folder / "photos.csv", photos_csv(photos, names=names))
    write_text_atomic(folder / "geo.txt", geo_txt(photos, names=names))
    return folder


# ------------------------------------------------------------------------------------------------ the command
@dataclass
class GeotagRun:
    """What `geotag` did: one line per card, the cards placed."""

    lines: list[str]
    placed: list[Placement]
    out: Path


def timed_records(ledger: Ledger) -> dict[int, list[LedgerPhoto]]:
    """The survey's photos with a time (a photo placed on the track has none), per vehicle, in time order."""
    by_vehicle: dict[int, list[LedgerPhoto]] = defaultdict(list)
    for p in ledger.photos():
        if p.time is not None:
            by_vehicle[p.vehicle].append(p)
    return {v: sorted(ps, key=lambda p: p.time or 0.0) for v, ps in by_vehicle.items()}


def geotag_cards(survey_dir: Path, image_dirs: Sequence[Path], out: Path | None = None,
                 gimbal_pitch_deg: float = NADIR_PITCH_DEG) -> GeotagRun:
    """Place every card on a vehicle of the survey and write the copies of each card placed.

    Every card is read before anything is written: a folder missing or an image that cannot be read is a
    GeotagError and nothing is written."""
    from .above_ground import plan_ground
    from .ledger import read_plan
    from .ledger_repair import open_ledger

    exiv2()  # say how to install it before reading anything
    survey_dir = Path(survey_dir)
    out = survey_dir / DEFAULT_OUT if out is None else Path(out)
    names = card_names([Path(d) for d in image_dirs])
    cards = [read_card(Path(d), name) for d, name in zip(image_dirs, names)]
    notices: list[str] = []
    with open_ledger(survey_dir, notices.append) as ledger:
        by_vehicle = timed_records(ledger)
        root = ledger.survey.root
    if not by_vehicle:
        raise GeotagError(f"{survey_dir}: the survey's ledger has no capture record with a time (fly it first; "
                          "photos placed along the track have none)")
    ground = plan_ground(root, read_plan(root))
    lines = [f"missionplan geotag: {n}" for n in notices]
    outcomes = place_cards(cards, by_vehicle)
    placed = [o for o in outcomes if isinstance(o, Placement)]
    out.mkdir(parents=True, exist_ok=True)
    for card, outcome in zip(cards, outcomes):
        if isinstance(outcome, str):
            lines.append(outcome)
            continue
        if card.untimed and not outcome.by_name:
            lines.append(f"card {card.name}: {len(card.untimed)} images have no capture time (EXIF "
                         f"DateTimeOriginal), e.g. {card.untimed[0].relative}: left unmatched")
        write_card(outcome, out, lambda photos: geo_altitudes(photos, ground), gimbal_pitch_deg)
        lines.append(card_line(outcome))
    return GeotagRun(lines, placed, out)
