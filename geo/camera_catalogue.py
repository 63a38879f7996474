"""The shipped catalogue of survey cameras: `missionplan cameras` lists it, `plan --camera NAME` picks one.

Each row is a camera body with one lens: a short id (what --camera takes, any case), its full name, the
sensor's width and height (mm), the image's width and height (px), the focal length (mm) and the shortest
time between two photos it can take (s; None where no maker's sheet or public list gives one: give
--capture-interval). The facts come from QGroundControl's camera list (src/Camera/CameraMetaData.json in
mavlink/qgroundcontrol, the list its survey offers) and the makers' specification sheets; each row names
its source. The sensor sizes are the active imaging area, not the marketing class ("1-inch" is 13.2 x 8.8 mm).

`camera(name)` gives the row as a geo.camera.Camera (its field of view the narrower side's, SPEC section 7);
an unknown name is a GeoError of one line naming the nearest ids.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from missionplan.base.naming import Named

from .camera import Camera
from .errors import GeoError


@dataclass(frozen=True)
class CatalogueCamera:
    """One row: a camera body with its lens."""

    id: str
    title: str
    sensor_width_mm: float
    sensor_height_mm: float
    image_width_px: int
    image_height_px: int
    focal_length_mm: float
    capture_interval_s: float | None

    def camera(self) -> Camera:
        return Camera.from_sensor(self.sensor_width_mm, self.sensor_height_mm, self.focal_length_mm, name=self.id,
                                  image_width_px=self.image_width_px, image_height_px=self.image_height_px,
                                  capture_interval_s=self.capture_interval_s)


CATALOGUE: tuple[CatalogueCamera, ...] = (
    # DJI Phantom 4 Pro V2.0 specifications (dji.com): 1" CMOS 20 MP, lens 8.8 mm (24 mm equivalent), image
    # 5472 x 3648 (3:2), interval shooting from 2 s. The same camera as the Phantom 4 RTK's FC6310R.
    CatalogueCamera("dji-phantom4pro", "DJI Phantom 4 Pro (FC6310, 1-inch 20 MP)", 13.2, 8.8, 5472, 3648, 8.8, 2.0),
    # DJI Mavic 2 Pro specifications (dji.com): Hasselblad L1D-20c, 1" CMOS 20 MP, 28 mm equivalent (10.26 mm,
    # as its EXIF records), image 5472 x 3648, JPEG interval shooting from 2 s.
    CatalogueCamera("dji-mavic2pro", "DJI Mavic 2 Pro (Hasselblad L1D-20c)", 13.2, 8.8, 5472, 3648, 10.26, 2.0),
    # DJI Mavic 3 Enterprise specifications (enterprise.dji.com): wide camera 4/3 CMOS 20 MP, 24 mm
    # equivalent (12.29 mm, as its EXIF records), image 5280 x 3956, minimum photo interval 0.7 s.
    CatalogueCamera("dji-mavic3e", "DJI Mavic 3 Enterprise, wide camera (4/3 20 MP)", 17.3, 13.0, 5280, 3956,
                    12.29, 0.7),
    # DJI Zenmuse P1 specifications (enterprise.dji.com): full frame 35.9 x 24 mm, 45 MP, image 8192 x 5460,
    # DJI DL 35 mm F2.8 LS ASPH lens, minimum photo interval 0.7 s.
    CatalogueCamera("dji-zenmuse-p1-35mm", "DJI Zenmuse P1, DL 35 mm lens (full frame 45 MP)", 35.9, 24.0, 8192,
                    5460, 35.0, 0.7),
    # QGroundControl's list, "Sony a6000 16mm": 23.5 x 15.6 mm, 6000 x 4000, 16 mm, minTriggerInterval 1 s.
    CatalogueCamera("sony-a6000-16mm", "Sony a6000, 16 mm lens (APS-C 24 MP)", 23.5, 15.6, 6000, 4000, 16.0, 1.0),
    # QGroundControl's list for the a6000 body (as above) with Sony's E 20 mm F2.8 pancake (SEL20F28).
    CatalogueCamera("sony-a6000-20mm", "Sony a6000, 20 mm lens (APS-C 24 MP)", 23.5, 15.6, 6000, 4000, 20.0, 1.0),
    # Sony a6100 specifications (sony.com): APS-C 23.5 x 15.6 mm, 6000 x 4000 (24.2 MP); the a6000's 1 s
    # interval in QGroundControl's list; Sony's E 20 mm F2.8 (SEL20F28).
    CatalogueCamera("sony-a6100-20mm", "Sony a6100, 20 mm lens (APS-C 24 MP)", 23.5, 15.6, 6000, 4000, 20.0, 1.0),
    # QGroundControl's list, "Sony a6300 Zeiss 21mm f/2.8": 23.5 x 15.6 mm, 6000 x 4000, 21 mm, 1 s.
    CatalogueCamera("sony-a6300-21mm", "Sony a6300, Zeiss 21 mm f/2.8 (APS-C 24 MP)", 23.5, 15.6, 6000, 4000,
                    21.0, 1.0),
    # QGroundControl's list, "Sony a7r IV 35mm": 35.7 x 23.8 mm, 9504 x 6336, 35 mm, 1 s.
    CatalogueCamera("sony-a7r4-35mm", "Sony a7R IV, 35 mm lens (full frame 61 MP)", 35.7, 23.8, 9504, 6336, 35.0,
                    1.0),
    # QGroundControl's list, "Sony RX100 II 28mm": 13.2 x 8.8 mm, 5472 x 3648, 10.4 mm; its interval is not
    # given there (0).
    CatalogueCamera("sony-rx100ii", "Sony RX100 II at 28 mm (1-inch 20 MP)", 13.2, 8.8, 5472, 3648, 10.4, None),
    # QGroundControl's list, "Ricoh GR II": 23.7 x 15.7 mm, 4928 x 3264, 18.3 mm; interval not given (0).
    CatalogueCamera("ricoh-gr2", "Ricoh GR II (APS-C 16 MP)", 23.7, 15.7, 4928, 3264, 18.3, None),
    # MicaSense RedEdge-MX data sheet: each band 1280 x 960 px of 3.75 um (4.8 x 3.6 mm), 5.4 mm focal length,
    # 1 capture a second (all bands); GSD 8 cm at 120 m.
    CatalogueCamera("micasense-rededge-mx", "MicaSense RedEdge-MX (multispectral, each band)", 4.8, 3.6, 1280, 960,
                    5.4, 1.0),
    # QGroundControl's list, "Parrot Sequioa Monochrome": 4.8 x 3.6 mm, 1280 x 960, 4.0 mm, 0.8 s.
    CatalogueCamera("parrot-sequoia", "Parrot Sequoia (multispectral, each band)", 4.8, 3.6, 1280, 960, 4.0, 0.8),
    # QGroundControl's list, "Parrot Sequioa RGB": 6.17 x 4.63 mm, 4608 x 3456, 4.9 mm, 1 s.
    CatalogueCamera("parrot-sequoia-rgb", "Parrot Sequoia, RGB camera (16 MP)", 6.17, 4.63, 4608, 3456, 4.9, 1.0),
)

NEAREST_NAMES = 3  # ids an unknown name's line suggests


def catalogue_ids() -> list[str]:
    return [row.id for row in CATALOGUE]


def _normal(name: str) -> str:
    """A name as ids are spelled: lower case, spaces and underscores as hyphens."""
    return "-".join(name.strip().lower().replace("_", " ").split())


def find(name: str) -> CatalogueCamera:
    """The row whose id is `name` (any case; spaces or underscores for hyphens); GeoError of one line naming the
    nearest ids when there is none."""
    wanted = _normal(name)
    for row in CATALOGUE:
        if row.id == wanted:
            return row
    ids = catalogue_ids()
    nearest = difflib.get_close_matches(wanted, ids, n=NEAREST_NAMES, cutoff=0.0)
    # A name that is the start of several ids (sony-a6000) is nearest to them, whatever difflib scores.
    prefixed = [i for i in ids if i.startswith(wanted)] if wanted else []
    nearest = (prefixed + [i for i in nearest if i not in prefixed])[:NEAREST_NAMES]
    raise GeoError(Named("{camera} {0}: no such camera in the catalogue; nearest: {1} (`missionplan cameras` lists "
                         "all {2})", name, ", ".join(nearest), len(ids)))


def camera(name: str) -> Camera:
    """The catalogue camera `name` as a Camera (GeoError naming the nearest ids when there is none)."""
    return find(name).camera()
