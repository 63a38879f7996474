"""DEM files made in a test, so a test knows the true ground everywhere and downloads nothing.

- `hill`: an analytic smooth hill (a Gaussian on a flat base), the truth a test compares against;
- `write_geotiff`: a GeoTIFF (rasterio) of any ground function sampled on a grid in EPSG:4326 or a projected
  CRS (UTM), optionally with a hole of nodata;
- `write_srtm_tile`: a real SRTM .hgt tile, written with numpy as the format is (big-endian int16, rows from
  north to south, 3601 x 3601 at 1 arc-second, 1201 x 1201 at 3; edge rows and columns on the degree lines,
  shared with the neighbouring tiles), which GDAL reads by its name (N45E007.hgt);
- `write_flat_geotiff`: a large tiled, compressed GeoTIFF of one height, to show that reading a small box of
  a country-sized DEM reads only that box.

A ground function takes WGS84 latitudes and longitudes (numpy arrays) and gives metres above sea level:
`functools.partial(hill, centre=(45.07, 7.68))`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyproj

GroundFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
M_PER_DEG = 111_320.0  # the hill's local metres per degree (of latitude; of longitude times cos(latitude))
NODATA = -9999.0  # what write_geotiff writes where there is no ground (declared as the file's nodata)
SRTM_VOID = -32768  # the SRTM format's "no data"


def hill(lat: np.ndarray, lon: np.ndarray, centre: tuple[float, float], peak_m: float = 60.0,
         base_m: float = 230.0, radius_m: float = 400.0) -> np.ndarray:
    """base_m + peak_m * exp(-(d / radius_m)^2), d the distance in metres from `centre` (lat, lon) on a local
    flat Earth (M_PER_DEG): the true ground of a test, smooth, defined everywhere."""
    north = (np.asarray(lat, dtype=float) - centre[0]) * M_PER_DEG
    east = (np.asarray(lon, dtype=float) - centre[1]) * M_PER_DEG * math.cos(math.radians(centre[0]))
    return base_m + peak_m * np.exp(-(north ** 2 + east ** 2) / radius_m ** 2)


def write_geotiff(path: Path, ground_fn: GroundFn, bounds: tuple[float, float, float, float], resolution_m: float,
                  crs: str = "EPSG:4326", nodata_hole: tuple[float, float, float] | None = None) -> Path:
    """A float32 GeoTIFF of `ground_fn` at the centres of a grid of `resolution_m` that covers `bounds`
    (min_lat, min_lon, max_lat, max_lon) in `crs`: degrees of about `resolution_m` in a geographic CRS, CRS
    units (metres) in a projected one. nodata_hole = (lat, lon, radius_m): pixels whose centre lies that close
    to (lat, lon) hold NODATA. Returns `path`."""
    import rasterio
    from rasterio.transform import from_origin

    target = pyproj.CRS.from_user_input(crs)
    to_crs = pyproj.Transformer.from_crs(4326, target, always_xy=True)
    left, bottom, right, top = to_crs.transform_bounds(bounds[1], bounds[0], bounds[3], bounds[2], densify_pts=21)
    if target.is_geographic:
        mid_lat = math.radians((bounds[0] + bounds[2]) / 2)
        step_x, step_y = resolution_m / (M_PER_DEG * math.cos(mid_lat)), resolution_m / M_PER_DEG
    else:
        step_x = step_y = resolution_m
    cols, rows = math.ceil((right - left) / step_x), math.ceil((top - bottom) / step_y)
    x = left + (np.arange(cols) + 0.5) * step_x
    y = top - (np.arange(rows) + 0.5) * step_y
    xx, yy = np.meshgrid(x, y)
    lon, lat = pyproj.Transformer.from_crs(target, 4326, always_xy=True).transform(xx, yy)
    heights = np.asarray(ground_fn(lat, lon), dtype=np.float32)
    if nodata_hole is not None:
        hole_lat, hole_lon, radius_m = nodata_hole
        north = (lat - hole_lat) * M_PER_DEG
        east = (lon - hole_lon) * M_PER_DEG * math.cos(math.radians(hole_lat))
        heights[north ** 2 + east ** 2 <= radius_m ** 2] = NODATA
    with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=1, dtype="float32",
                       crs=target.to_wkt(), transform=from_origin(left, top, step_x, step_y), nodata=NODATA,
                       compress="deflate") as dst:
        dst.write(heights, 1)
    return path


def srtm_name(lat_deg: int, lon_deg: int) -> str:
    """The tile's file name from its south-west corner: N45E007.hgt, S23W044.hgt."""
    return f"{'N' if lat_deg >= 0 else 'S'}{abs(lat_deg):02d}{'E' if lon_deg >= 0 else 'W'}{abs(lon_deg):03d}.hgt"


def srtm_pixel_latlon(lat_deg: int, lon_deg: int, row: int, col: int, arcsec: int = 1) -> tuple[float, float]:
    """Where pixel (row, col) of the tile lies: row 0 on the tile's north edge, column 0 on its west edge."""
    return lat_deg + 1 - row * arcsec / 3600, lon_deg + col * arcsec / 3600


def write_srtm_tile(folder: Path, lat_deg: int, lon_deg: int, ground_fn: GroundFn, arcsec: int = 1) -> Path:
    """The SRTM tile whose south-west corner is (lat_deg, lon_deg), `ground_fn` rounded to whole metres (NaN:
    the void value), in `folder`. Returns its path."""
    if arcsec not in (1, 3):
        raise ValueError(f"SRTM tiles are 1 or 3 arc-seconds, not {arcsec}")
    size = 3600 // arcsec + 1
    path = Path(folder) / srtm_name(lat_deg, lon_deg)
    lon = lon_deg + np.arange(size) * arcsec / 3600
    with open(path, "wb") as out:
        for start in range(0, size, 400):  # bands of rows: a 1 arc-second tile is 13 million heights
            lat = lat_deg + 1 - np.arange(start, min(start + 400, size)) * arcsec / 3600
            heights = np.asarray(ground_fn(lat[:, None], lon[None, :]), dtype=float)
            ints = np.where(np.isfinite(heights), np.clip(np.rint(heights), -32767, 32767), SRTM_VOID)
            out.write(ints.astype(">i2").tobytes())
    return path


def write_flat_geotiff(path: Path, height_m: int, centre: tuple[float, float], size_px: int = 20_000,
                       resolution_m: float = 10.0, crs: str = "EPSG:32632") -> Path:
    """A size_px x size_px int16 GeoTIFF of `height_m` everywhere, centred on `centre` (lat, lon) in the
    projected `crs`, tiled 512 x 512 and ZSTD-compressed as national DEMs are served (20000 px at 10 m: a
    200 km square, 800 MB of heights in about 0.1 MB, written band by band in about a second)."""
    import rasterio
    from rasterio.transform import from_origin
    from rasterio.windows import Window

    x, y = pyproj.Transformer.from_crs(4326, crs, always_xy=True).transform(centre[1], centre[0])
    half = size_px * resolution_m / 2
    band = np.full((1024, size_px), height_m, dtype=np.int16)
    with rasterio.open(path, "w", driver="GTiff", width=size_px, height=size_px, count=1, dtype="int16", crs=crs,
                       transform=from_origin(x - half, y + half, resolution_m, resolution_m), tiled=True,
                       blockxsize=512, blockysize=512, compress="zstd", BIGTIFF="IF_SAFER") as dst:
        for row in range(0, size_px, band.shape[0]):
            rows = min(band.shape[0], size_px - row)
            dst.write(band[:rows], 1, window=Window(0, row, size_px, rows))
    return path


def map_hill(name: str, peak_m: float = 40.0, radius_m: float = 120.0) -> GroundFn:
    """The ground of a hill centred under a shipped map (or a .map file with an origin): `hill` there."""
    from missionplan.maps.catalog import load_shipped
    from missionplan.mission.georef import shipped_frame

    frame = shipped_frame(load_shipped(name))
    if frame is None:
        raise ValueError(f"{name}: the map has no origin, so no place on the Earth for a hill")
    box = frame.latlon_box()
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    return lambda lat, lon: hill(lat, lon, centre, peak_m=peak_m, radius_m=radius_m)


def hill_under_map(name: str, path: Path, peak_m: float = 40.0, radius_m: float = 120.0,
                   resolution_m: float = 5.0, reach_m: float = 6_000.0) -> Path:
    """A GeoTIFF of `map_hill` reaching `reach_m` beyond the map (ArduPilot asks for terrain grids kilometres
    around it): the ground of the docs' and benches' examples."""
    from missionplan.maps.catalog import load_shipped
    from missionplan.mission.georef import shipped_frame

    frame = shipped_frame(load_shipped(name))
    assert frame is not None  # map_hill refuses a map without one first
    ground = map_hill(name, peak_m, radius_m)
    box = frame.latlon_box()
    pad_lat = reach_m / M_PER_DEG
    pad_lon = pad_lat / math.cos(math.radians((box[0] + box[2]) / 2))
    return write_geotiff(path, ground, (box[0] - pad_lat, box[1] - pad_lon, box[2] + pad_lat, box[3] + pad_lon),
                         resolution_m)
