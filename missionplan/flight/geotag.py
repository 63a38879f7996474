"""Every photo geotagged for photogrammetry: photos.csv, photos.geojson and OpenDroneMap's geo.txt, from the ledger.

Written by `fly` into the plan folder after each flight it judges, for every photo of that folder's
flights (ledger.Ledger.photos): where each photo was taken as the vehicle reported it (its
CAMERA_FEEDBACK / CAMERA_IMAGE_CAPTURED, or its own log), not where it was planned.

Image names: the vehicles do not say what their camera called a file, so each photo gets
IMAGE_NAME: f{flight}-uav{vehicle}-{img_idx:05d}.jpg (flight: the folder's flight number in its
journal; img_idx: the vehicle's own photo index). A crew renames its camera's files to these, or
these to its camera's (photos.csv lists both time and index to match them by), before loading
geo.txt into OpenDroneMap. geo.txt follows ODM's image geolocation format: a projection line
(EPSG:4326), then `image lon lat alt_amsl yaw pitch roll` per photo (angles 0 where not known, as
ODM asks; the altitude is above mean sea level, as the vehicle reported it, or the launch-relative
height where it did not).

A flight whose photos a MAVLink camera took (`plan --capture camera`, `camera-interval`: its CAMERA_IMAGE_CAPTURED
are the capture records) adds, last in photos.csv and in photos.geojson's properties, the camera's own
`image_index` (img_idx is then that) and the `file_url` it named for each photo, where any photo of the folder has
them (empty for the others); `missionplan geotag` matches a card's files by that name first (image_match).

The angles are the camera's, not the airframe's (photo_positions.camera_attitude: the gimbal's pitch and
roll as the vehicle reported them, else the pitch the mission's gimbal item asked for; yaw the vehicle's
heading). photos.csv and photos.geojson give them in MAVLink's convention, the one DJI's and the XMP
GimbalPitchDegree use: pitch -90 straight down, 0 level. geo.txt gives them in OpenDroneMap's own: ODM reads
a geo.txt's yaw, pitch and roll into its photo as they are (opendm/photo.py, update_with_geo_entry), where
pitch 0 is a nadir camera and 90 one looking forward (it adds 90 to a DJI GimbalPitchDegree to get there), so
geo.txt's pitch is the camera's pitch plus 90: 0 for a nadir photo.

A plan made over a DEM (above_ground.PlanGround) adds, after alt_rel_m, each photo's height above the ground
(`alt_agl_m`, above ground level, the height DJI, UgCS and Pix4D crews plan and check by) and the DEM's
height under it (`ground_amsl_m`), in photos.csv and photos.geojson. Their sum, the ground at the launch
point plus the height the vehicle reported above it, is then geo.txt's altitude above sea level: the datum
the plan was made in, steadier from one flight to the next than the vehicle's GPS altitude (alt_amsl_m,
kept as reported).
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path

from missionplan.base.atomic import write_text_atomic

import numpy as np

from .above_ground import PlanGround, photo_heights
from .ledger import LedgerPhoto

IMAGE_NAME = "f{flight}-uav{vehicle}-{img_idx:05d}.jpg"
CSV_COLUMNS = ("image", "flight", "vehicle", "img_idx", "time_utc", "lat", "lon", "alt_amsl_m", "alt_rel_m",
               "yaw_deg", "pitch_deg", "roll_deg", "source")
TERRAIN_COLUMNS = ("alt_agl_m", "ground_amsl_m")  # after alt_rel_m, for a plan over a DEM
CAMERA_COLUMNS = ("image_index", "file_url")  # last, when any photo is a MAVLink camera's record
GEOTAG_FILES = ("photos.csv", "photos.geojson", "geo.txt")
ODM_NADIR_OFFSET_DEG = 90.0  # OpenDroneMap's pitch is MAVLink's plus this: its 0 is straight down


def image_name(photo: LedgerPhoto, names: Mapping[LedgerPhoto, str] | None = None) -> str:
    """The photo's file name: the real one where `names` has it (`missionplan geotag`), else IMAGE_NAME."""
    if names is not None and photo in names:
        return names[photo]
    return IMAGE_NAME.format(flight=photo.flight, vehicle=photo.vehicle, img_idx=photo.img_idx)


def _utc(t: float | None) -> str:
    return "" if t is None else datetime.fromtimestamp(float(t), timezone.utc).isoformat(timespec="milliseconds")


def _num(value: float | None, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def _over_ground(photos: list[LedgerPhoto], ground: PlanGround | None) -> list[tuple[float | None, float | None]]:
    """Per photo: (its height above the ground, the ground under it), None where unknown; [] without a DEM."""
    if ground is None:
        return []
    under, agl = photo_heights(ground, [p.vehicle for p in photos], [p.lat for p in photos],
                               [p.lon for p in photos], [p.alt_rel for p in photos])
    return [(float(a) if np.isfinite(a) else None, float(g) if np.isfinite(g) else None) for a, g in zip(agl, under)]


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 2)


def photos_csv(photos: list[LedgerPhoto], ground: PlanGround | None = None,
               names: Mapping[LedgerPhoto, str] | None = None) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    over = _over_ground(photos, ground)
    at = CSV_COLUMNS.index("alt_rel_m") + 1
    camera = any(p.image_index is not None for p in photos)
    header = CSV_COLUMNS if ground is None else CSV_COLUMNS[:at] + TERRAIN_COLUMNS + CSV_COLUMNS[at:]
    writer.writerow(header + (CAMERA_COLUMNS if camera else ()))
    for k, p in enumerate(photos):
        row = [image_name(p, names), p.flight, p.vehicle, p.img_idx, _utc(p.time), f"{p.lat:.7f}", f"{p.lon:.7f}",
               _num(p.alt_amsl, 2), _num(p.alt_rel, 2), _num(p.yaw, 2), _num(p.pitch, 2), _num(p.roll, 2), p.source]
        if over:
            row[at:at] = [_num(over[k][0], 2), _num(over[k][1], 2)]
        if camera:
            row += ["" if p.image_index is None else p.image_index, p.file_url or ""]
        writer.writerow(row)
    return out.getvalue()


def photos_geojson(photos: list[LedgerPhoto], ground: PlanGround | None = None,
                   names: Mapping[LedgerPhoto, str] | None = None) -> dict:
    """One Point per photo, [lon, lat, height above the launch point] (RFC 7946 order), its facts as properties."""
    features = []
    over = _over_ground(photos, ground)
    camera = any(p.image_index is not None for p in photos)
    for k, p in enumerate(photos):
        coords = [round(p.lon, 7), round(p.lat, 7)] + ([round(p.alt_rel, 2)] if p.alt_rel is not None else [])
        heights = {"alt_amsl_m": p.alt_amsl, "alt_rel_m": p.alt_rel}
        if over:
            heights.update({"alt_agl_m": _rounded(over[k][0]), "ground_amsl_m": _rounded(over[k][1])})
        features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": coords},
                         "properties": {"image": image_name(p, names), "flight": p.flight, "vehicle": p.vehicle,
                                        "img_idx": p.img_idx, "time_utc": _utc(p.time), **heights,
                                        "yaw_deg": p.yaw, "pitch_deg": p.pitch,
                                        "roll_deg": p.roll, "source": p.source,
                                        **({"image_index": p.image_index, "file_url": p.file_url} if camera else {})}})
    return {"type": "FeatureCollection", "features": features}


def odm_pitch(pitch_deg: float | None) -> float:
    """A camera pitch (MAVLink's: -90 straight down) as OpenDroneMap's geo.txt takes it (0 straight down, 90
    forward); 0, ODM's "not known", for an unknown one (the module docstring says where ODM says so)."""
    return 0.0 if pitch_deg is None else pitch_deg + ODM_NADIR_OFFSET_DEG


def geo_altitudes(photos: list[LedgerPhoto], ground: PlanGround | None = None) -> list[float]:
    """Each photo's altitude above sea level as geo.txt and the EXIF geotags give it (the module docstring says
    which: over a DEM the ground at the launch point plus the reported height, else the vehicle's own)."""
    over = _over_ground(photos, ground)
    heights = []
    for k, p in enumerate(photos):
        agl, under = over[k] if over else (None, None)
        if agl is not None and under is not None:
            heights.append(agl + under)
        else:
            heights.append(p.alt_amsl if p.alt_amsl is not None else (p.alt_rel or 0.0))
    return heights


def geo_txt(photos: list[LedgerPhoto], ground: PlanGround | None = None,
            names: Mapping[LedgerPhoto, str] | None = None) -> str:
    lines = ["EPSG:4326"]
    for p, alt in zip(photos, geo_altitudes(photos, ground)):
        yaw, roll = (v if v is not None else 0.0 for v in (p.yaw, p.roll))
        pitch = odm_pitch(p.pitch)
        lines.append(f"{image_name(p, names)} {p.lon:.7f} {p.lat:.7f} {alt:.2f} {yaw:.2f} {pitch:.2f} {roll:.2f}")
    return "\n".join(lines) + "\n"


def write_geotags(plan_dir: Path, photos: list[LedgerPhoto], ground: PlanGround | None = None,
                  names: Mapping[LedgerPhoto, str] | None = None) -> list[Path]:
    """photos.csv, photos.geojson and geo.txt in plan_dir (each written whole, then renamed into place);
    `ground`: the plan was made over a DEM (the module docstring says what it adds); `names`: the real file
    of each photo that has one (`missionplan geotag`'s copies)."""
    paths = [Path(plan_dir) / name for name in GEOTAG_FILES]
    write_text_atomic(paths[0], photos_csv(photos, ground, names))
    write_text_atomic(paths[1], json.dumps(photos_geojson(photos, ground, names)) + "\n")
    write_text_atomic(paths[2], geo_txt(photos, ground, names))
    return paths
