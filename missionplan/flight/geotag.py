"""Every photo geotagged for photogrammetry: photos.csv, photos.geojson and OpenDroneMap's geo.txt, from the ledger.

Written by `fly` into the plan folder after each flight it judges, for every photo of that folder's
flights (ledger.Ledger.photos): where each photo was taken as the vehicle reported it (its
CAMERA_FEEDBACK / CAMERA_IMAGE_CAPTURED, or its own log), not where it was planned.

Image names: the vehicles do not say what their camera called a file, so each photo gets
IMAGE_NAME: f{flight}-uav{vehicle}-{img_idx:05d}.jpg (flight: the folder's flight number in its
journal; img_idx: the vehicle's own photo index). A crew renames its camera's files to these, or
these to its camera's (photos.csv lists both time and index to match them by), before loading
geo.txt into OpenDroneMap. geo.txt follows ODM's image geolocation format: a projection line
(EPSG:4326), then `image lon lat alt_amsl yaw pitch roll` per photo (angles 0 where not reported, as
ODM asks; the altitude is above mean sea level, as the vehicle reported it, or the launch-relative
height where it did not).
"""

from __future__ import annotations

import csv
import io
import json
from datetime import datetime, timezone
from pathlib import Path

from missionplan.base.atomic import write_text_atomic

from .ledger import LedgerPhoto

IMAGE_NAME = "f{flight}-uav{vehicle}-{img_idx:05d}.jpg"
CSV_COLUMNS = ("image", "flight", "vehicle", "img_idx", "time_utc", "lat", "lon", "alt_amsl_m", "alt_rel_m",
               "yaw_deg", "pitch_deg", "roll_deg", "source")
GEOTAG_FILES = ("photos.csv", "photos.geojson", "geo.txt")


def image_name(photo: LedgerPhoto) -> str:
    return IMAGE_NAME.format(flight=photo.flight, vehicle=photo.vehicle, img_idx=photo.img_idx)


def _utc(t: float | None) -> str:
    return "" if t is None else datetime.fromtimestamp(float(t), timezone.utc).isoformat(timespec="milliseconds")


def _num(value: float | None, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def photos_csv(photos: list[LedgerPhoto]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for p in photos:
        writer.writerow([image_name(p), p.flight, p.vehicle, p.img_idx, _utc(p.time), f"{p.lat:.7f}", f"{p.lon:.7f}",
                         _num(p.alt_amsl, 2), _num(p.alt_rel, 2), _num(p.yaw, 2), _num(p.pitch, 2), _num(p.roll, 2),
                         p.source])
    return out.getvalue()


def photos_geojson(photos: list[LedgerPhoto]) -> dict:
    """One Point per photo, [lon, lat, height above the launch point] (RFC 7946 order), its facts as properties."""
    features = []
    for p in photos:
        coords = [round(p.lon, 7), round(p.lat, 7)] + ([round(p.alt_rel, 2)] if p.alt_rel is not None else [])
        features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": coords},
                         "properties": {"image": image_name(p), "flight": p.flight, "vehicle": p.vehicle,
                                        "img_idx": p.img_idx, "time_utc": _utc(p.time), "alt_amsl_m": p.alt_amsl,
                                        "alt_rel_m": p.alt_rel, "yaw_deg": p.yaw, "pitch_deg": p.pitch,
                                        "roll_deg": p.roll, "source": p.source}})
    return {"type": "FeatureCollection", "features": features}


def geo_txt(photos: list[LedgerPhoto]) -> str:
    lines = ["EPSG:4326"]
    for p in photos:
        alt = p.alt_amsl if p.alt_amsl is not None else (p.alt_rel or 0.0)
        yaw, pitch, roll = (v if v is not None else 0.0 for v in (p.yaw, p.pitch, p.roll))
        lines.append(f"{image_name(p)} {p.lon:.7f} {p.lat:.7f} {alt:.2f} {yaw:.2f} {pitch:.2f} {roll:.2f}")
    return "\n".join(lines) + "\n"


def write_geotags(plan_dir: Path, photos: list[LedgerPhoto]) -> list[Path]:
    """photos.csv, photos.geojson and geo.txt in plan_dir (each written whole, then renamed into place)."""
    paths = [Path(plan_dir) / name for name in GEOTAG_FILES]
    write_text_atomic(paths[0], photos_csv(photos))
    write_text_atomic(paths[1], json.dumps(photos_geojson(photos)) + "\n")
    write_text_atomic(paths[2], geo_txt(photos))
    return paths
