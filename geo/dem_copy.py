"""The plan folder's copy of the ground it was planned over: each DEM window read, written as a GeoTIFF.

A plan over a DEM keeps the ground it used beside report.json (`ground.tif`, or `ground-1.tif`, ... when
several files gave ground), so `fly` can serve it to the vehicles, the mock can fly over it and the judge
can measure heights above it, all from the plan folder, whatever happens to the crew's DEM files later.
Each window is written exactly as it was read (its pixels, its CRS, its position; heights in metres, NaN
as nodata), never resampled: reading the copy with dem.read_ground over the same box gives the same
heights at every point (tests/test_plan_terrain.py checks it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyproj

from .dem import Ground, _rasterio, read_ground
from .frame import GridFrame
from .georeference import TerrainRecord

NODATA = -32768.0  # written for NaN: SRTM's own void value, outside every real ground


def copy_names(ground: Ground) -> list[str]:
    """The file names the copy of `ground` takes in a plan folder."""
    count = len(ground.windows)
    return ["ground.tif"] if count == 1 else [f"ground-{k}.tif" for k in range(1, count + 1)]


def write_ground_copy(ground: Ground, folder: Path) -> list[Path]:
    """Write each of `ground`'s windows into `folder` (copy_names), in the order they answer; the paths."""
    rasterio = _rasterio()
    from affine import Affine
    from rasterio.crs import CRS

    paths = []
    for window, name in zip(ground.windows, copy_names(ground)):
        a, b, c, d, e, f = window.to_pixel
        # to_pixel puts pixel centres at integers; a GeoTIFF's transform maps pixel corners.
        to_corner = Affine(a, b, c + 0.5, d, e, f + 0.5)
        crs = window.to_file_crs.target_crs if window.to_file_crs is not None else pyproj.CRS.from_epsg(4326)
        heights = np.where(np.isnan(window.heights), np.float32(NODATA), window.heights).astype(np.float32)
        rows, cols = heights.shape
        path = folder / name
        profile = {"driver": "GTiff", "height": rows, "width": cols, "count": 1, "dtype": "float32",
                   "crs": CRS.from_wkt(crs.to_wkt()), "transform": ~to_corner, "nodata": NODATA,
                   "compress": "deflate", "predictor": 3, "tiled": rows >= 256 and cols >= 256}
        try:
            with rasterio.open(path, "w", **profile) as out:
                out.write(heights, 1)
                out.update_tags(1, source=window.name)
                out.set_band_unit(1, "metre")
        except rasterio.errors.RasterioError as err:  # a full disk, say: the plan folder's writer says it in one line
            raise OSError(f"{path}: cannot write the plan's ground ({err})") from None
        paths.append(path)
    return paths


def read_ground_copy(folder: Path, terrain: TerrainRecord, frame: GridFrame, margin_m: float = 200.0) -> Ground:
    """The ground a plan folder keeps (report.json's georeference.terrain), read around its grid plus margin_m:
    what fly serves, the mock flies over, a re-plan plans over and the judge measures against. GeoError, one
    line, when a copy is gone or unreadable (or rasterio is not installed)."""
    return read_ground([Path(folder) / name for name in terrain.files], frame.latlon_box(), margin_m=margin_m)
