"""The ground under a point, from a crew's DEM (digital elevation model): `read_ground` and `Ground`.

`read_ground(sources, around)` reads, through rasterio (GDAL), the DEM files a crew brings (a GeoTIFF, SRTM
.hgt tiles, any raster GDAL reads) or folders of them, and keeps of each file only the window that covers the
box `around` (the area and its launch points) plus a margin: a country-wide DEM costs what its few square
kilometres cost. Each window stays in its file's own CRS; `Ground.height_amsl` brings the query points (WGS84
lat/lon) into that CRS with pyproj and interpolates bilinearly between the four pixel centres around each: a
DEM in another CRS is reprojected by moving the points, never by resampling the raster.

Heights are the DEM's own: metres above the geoid (sea level) for SRTM, Copernicus and national DEMs. A band
whose unit (or whose CRS's vertical axis) is feet is converted; a band scale / offset is applied. No height
is made up: a point where no file has data (outside every window, or a nodata pixel among the four it uses,
or a value no ground has, below -500 m or above 9000 m) is NaN, and `Ground.heights` refuses it in one line
that names the point, what it belongs to and why.

A `Ground` is a value: its arrays are read-only and pyproj's transformers are thread-safe (pyproj 3.1+), so
the threads of a flight may share one. rasterio is the `terrain` extra: it is imported only when a DEM is
read, so missionplan without it plans as before and says, when asked for a DEM, how to install it.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pyproj

from missionplan.base.naming import Named

from .errors import GeoError

# What a folder of tiles is searched for: the raster formats DEMs come in (not sidecars such as .aux.xml,
# .hdr, .prj, .tfw, nor images that are never heights).
DEM_EXTENSIONS = frozenset({".tif", ".tiff", ".hgt", ".vrt", ".img", ".asc", ".bil", ".flt", ".dem", ".dt0", ".dt1",
                            ".dt2", ".nc", ".grd", ".sdat", ".xyz", ".bt", ".ter", ".sigdem"})
LOWEST_GROUND_M, HIGHEST_GROUND_M = -500.0, 9000.0  # outside: a fill value, not a ground
_SRTM_NAME = re.compile(r"^([NS])(\d{2})([EW])(\d{3})", re.IGNORECASE)  # N45E007.hgt: its south-west corner
_METRES = frozenset({"", "m", "metre", "metres", "meter", "meters"})
_FEET = {"ft": 0.3048, "foot": 0.3048, "feet": 0.3048, "international foot": 0.3048, "foot (international)": 0.3048,
         "us survey foot": 1200 / 3937, "us-ft": 1200 / 3937, "ftus": 1200 / 3937, "us_survey_foot": 1200 / 3937}
_M_PER_DEG_LAT_LEAST = 110_500.0  # a degree of latitude is never shorter: the margin is at least what was asked
_WGS84 = pyproj.CRS.from_epsg(4326)
_GEOD = pyproj.Geod(ellps="WGS84")
_NAMES_SHOWN = 3  # files an error line names before "and N more"


@dataclass(frozen=True)
class DemWindow:
    """The part of one DEM file that was read: its heights in metres and where they lie in the file's CRS."""

    name: str  # the file, as given (a folder's tile: the folder as given / the tile's name)
    crs: str  # the file's CRS as text: EPSG:4326, EPSG:32632, or its name without an EPSG code
    heights: np.ndarray = field(repr=False)  # float32 (rows, cols), NaN where the file has no data
    # (col, row) of a point in `heights`, pixel centres at integers: x, y in the file's CRS through this affine
    to_pixel: tuple[float, float, float, float, float, float] = field(repr=False)
    offset: tuple[int, int] = field(repr=False)  # (row, col) of heights[0, 0] in the whole file
    file_shape: tuple[int, int] = field(repr=False)  # (rows, cols) of the whole file
    to_file_crs: pyproj.Transformer | None = field(repr=False)  # WGS84 lon/lat -> the file's x, y; None: the same
    resolution_m: float  # the file's coarser pixel side, in metres on the ground

    def pixel_position(self, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of each point in `heights`, pixel centres at integers (NaN where pyproj cannot place it)."""
        if self.to_file_crs is None:
            x, y = lon, lat
        else:
            x, y = self.to_file_crs.transform(lon, lat, errcheck=False)
            x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        a, b, c, d, e, f = self.to_pixel
        return d * x + e * y + f, a * x + b * y + c

    def interpolate(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """Bilinear height at each point; NaN outside the window's pixel centres or next to a nodata pixel."""
        row, col = self.pixel_position(lat, lon)  # fresh arrays: worked on in place (1e6 points: 8 MB each)
        rows, cols = self.heights.shape
        outside = ~((row >= 0) & (row <= rows - 1) & (col >= 0) & (col <= cols - 1))  # NaN is outside too
        row[outside] = 0.0
        col[outside] = 0.0
        # The last row / column is reached from the one before with a weight of 1, so the four pixels exist.
        i00 = np.minimum(row.astype(np.intp), rows - 2)
        row -= i00  # the weight of the lower row
        i00 *= cols
        left = np.minimum(col.astype(np.intp), cols - 2)
        col -= left  # the weight of the right column
        i00 += left
        flat = self.heights.ravel()
        top: np.ndarray = np.subtract(flat[i00 + 1], flat[i00], dtype=np.float64)  # float32 heights, float64 sums
        top *= col
        top += flat[i00]
        i00 += cols
        bottom = np.subtract(flat[i00 + 1], flat[i00], dtype=np.float64)
        bottom *= col
        bottom += flat[i00]
        bottom -= top
        bottom *= row
        top += bottom  # NaN when any of the four pixels is NaN
        top[outside] = np.nan
        return top

    def why_not(self, lat: float, lon: float) -> str | None:
        """Why this window gives no height at the point: 'hole', 'unread' (in the file, not in the window read)
        or None (the file does not reach it)."""
        row, col = (float(v[0]) for v in self.pixel_position(np.array([lat]), np.array([lon])))
        rows, cols = self.heights.shape
        if 0 <= row <= rows - 1 and 0 <= col <= cols - 1:
            return "hole"
        row, col = row + self.offset[0], col + self.offset[1]
        # Between the file's outer pixel centres and its edge no height is interpolated: that is outside too.
        if 0 <= row <= self.file_shape[0] - 1 and 0 <= col <= self.file_shape[1] - 1:
            return "unread"
        return None


@dataclass(frozen=True)
class Ground:
    """The ground heights of the DEM windows read, asked for at WGS84 points."""

    sources: tuple[str, ...]  # the files read, as given (a folder's tiles: folder / tile name), in the order asked
    crs: tuple[str, ...]  # each file's CRS as text (EPSG:4326, EPSG:32632, ...)
    resolution_m: float  # the coarsest pixel size read, in metres on the ground
    around: tuple[float, float, float, float]  # (min_lat, min_lon, max_lat, max_lon) read: the box and its margin
    windows: tuple[DemWindow, ...] = field(repr=False, compare=False)

    def height_amsl(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """The DEM's height (metres, as the DEM gives them: above sea level) at each WGS84 point, bilinear between
        pixel centres; NaN where no file has data. Where windows overlap, the first with data answers."""
        lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float))
        flat_lat, flat_lon = lat.ravel(), lon.ravel()
        out = self.windows[0].interpolate(flat_lat, flat_lon)
        for window in self.windows[1:]:
            todo = np.flatnonzero(np.isnan(out))
            if todo.size == 0:
                break
            out[todo] = window.interpolate(flat_lat[todo], flat_lon[todo])
        return out.reshape(lat.shape)

    def heights(self, lat: np.ndarray, lon: np.ndarray, what: str) -> np.ndarray:
        """`height_amsl`, or a GeoError in one line naming the first point without a height, `what` it belongs
        to (e.g. "uav2's track") and why: outside the DEM, or a hole (nodata) in it."""
        out = self.height_amsl(lat, lon)
        missing = np.flatnonzero(np.isnan(out))
        if missing.size:
            lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float))
            first_lat, first_lon = float(lat.ravel()[missing[0]]), float(lon.ravel()[missing[0]])
            raise GeoError(f"DEM {_listed(self.sources)}: no ground height at {first_lat:.5f}, {first_lon:.5f} "
                           f"({what}): {self._why_not(first_lat, first_lon)}")
        return out

    def _why_not(self, lat: float, lon: float) -> str:
        reasons = {window.why_not(lat, lon) for window in self.windows}
        if "hole" in reasons:
            return "a hole (nodata) in the DEM"
        if "unread" in reasons:
            return f"outside the part of the DEM read ({_box_text(self.around)})"
        return "outside the DEM"


def read_ground(sources: Sequence[Path | str], around: tuple[float, float, float, float],
                margin_m: float = 200.0) -> Ground:
    """The ground of the DEM files `sources` (files and / or folders of tiles) over the box `around` =
    (min_lat, min_lon, max_lat, max_lon) and `margin_m` metres about it: only that window of each file is read.

    Files that do not reach the box are skipped (a folder's SRTM tiles by their names, unopened); GeoError, one
    line, when none does, or for a file that is not a raster GDAL reads, has no CRS, is an image rather than
    heights or gives its heights in a unit that is neither metres nor feet."""
    rasterio = _rasterio()
    box = _checked_box(around)
    if not math.isfinite(margin_m) or margin_m < 0:
        raise GeoError(f"DEM margin {margin_m!r} m: not a distance")
    wide = _widened(box, margin_m)
    if not sources:
        raise GeoError("no DEM file given")
    candidates = [tile for source in sources for tile in _dem_files(Path(source), str(source), wide)]
    windows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)  # refused below, in one line
        with rasterio.Env():
            for path, name in candidates:
                window = _read_window(rasterio, path, name, wide)
                if window is not None:
                    windows.append(window)
    if not windows:
        raise GeoError(f"DEM {_listed([str(s) for s in sources])}: no file covers {_box_text(box)} "
                       f"(the area and its launch points)")
    return Ground(sources=tuple(w.name for w in windows), crs=tuple(w.crs for w in windows),
                  resolution_m=max(w.resolution_m for w in windows), around=wide, windows=tuple(windows))


def _rasterio() -> ModuleType:
    try:
        import rasterio
        import rasterio.enums
        import rasterio.errors
        import rasterio.windows
    except ImportError:
        raise GeoError(Named("plan {dem} needs rasterio: pip install 'missionplan[terrain]'")) from None
    return rasterio


def _checked_box(around: Sequence[float]) -> tuple[float, float, float, float]:
    try:
        min_lat, min_lon, max_lat, max_lon = (float(v) for v in around)
    except (TypeError, ValueError):
        raise GeoError(f"DEM box {around!r}: not (min_lat, min_lon, max_lat, max_lon)") from None
    if not (-90 <= min_lat <= max_lat <= 90 and -180 <= min_lon <= max_lon <= 180):
        raise GeoError(f"DEM box {around!r}: not (min_lat, min_lon, max_lat, max_lon) in WGS84 degrees")
    return min_lat, min_lon, max_lat, max_lon


def _widened(box: tuple[float, float, float, float], margin_m: float) -> tuple[float, float, float, float]:
    """The box and at least `margin_m` metres on every side (degrees of longitude shrink towards the poles)."""
    min_lat, min_lon, max_lat, max_lon = box
    dlat = margin_m / _M_PER_DEG_LAT_LEAST
    widest = max(abs(min_lat - dlat), abs(max_lat + dlat))
    dlon = margin_m / (_M_PER_DEG_LAT_LEAST * max(math.cos(math.radians(min(widest, 90.0))), 0.01))
    return (max(min_lat - dlat, -90.0), max(min_lon - dlon, -180.0), min(max_lat + dlat, 90.0),
            min(max_lon + dlon, 180.0))


def _box_text(box: tuple[float, float, float, float]) -> str:
    return f"lat {box[0]:.5f}..{box[2]:.5f}, lon {box[1]:.5f}..{box[3]:.5f}"


def _listed(names: Sequence[str]) -> str:
    shown = ", ".join(names[:_NAMES_SHOWN])
    return shown + (f" and {len(names) - _NAMES_SHOWN} more" if len(names) > _NAMES_SHOWN else "")


def _dem_files(path: Path, name: str, wide: tuple[float, float, float, float]) -> list[tuple[Path, str]]:
    """(path, name as given) of a DEM file, or of a folder's raster files (by name, sorted) that may reach the
    box: an SRTM tile's name says where it lies, so the others are not even opened."""
    if path.is_file():
        return [(path, name)]
    if not path.is_dir():
        raise GeoError(f"{name}: no such DEM file or folder")
    found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in DEM_EXTENSIONS)
    if not found:
        raise GeoError(f"{name}: no DEM file in this folder ({', '.join(sorted(DEM_EXTENSIONS))})")
    return [(p, str(Path(name) / p.name)) for p in found if _may_reach(p, wide)]


def _may_reach(path: Path, wide: tuple[float, float, float, float]) -> bool:
    match = _SRTM_NAME.match(path.name)
    if path.suffix.lower() != ".hgt" or match is None:
        return True
    south = int(match[2]) * (1 if match[1].upper() == "N" else -1)
    west = int(match[4]) * (1 if match[3].upper() == "E" else -1)
    edge = 0.001  # the tile's edge pixels reach half a pixel past its degree lines
    return (south - edge <= wide[2] and wide[0] <= south + 1 + edge
            and west - edge <= wide[3] and wide[1] <= west + 1 + edge)


def _first_line(err: BaseException) -> str:
    """GDAL's own words: rasterio's "Read failed. See previous exception" carries them as its cause."""
    while err.__cause__ is not None:
        err = err.__cause__
    text = (str(err).strip().splitlines() or [type(err).__name__])[0]
    return text if len(text) <= 200 else text[:197] + "..."


def _crs_text(crs: pyproj.CRS) -> str:
    epsg = crs.to_epsg()
    if epsg:
        return f"EPSG:{epsg}"
    codes = [sub.to_epsg() for sub in crs.sub_crs_list]
    if codes and all(codes):
        return "+".join(f"EPSG:{code}" for code in codes)
    return crs.name


def _file_crs(dataset: Any, name: str) -> pyproj.CRS:
    if dataset.crs is None:
        raise GeoError(f"{name}: the DEM has no coordinate reference system (a GeoTIFF without its georeferencing, "
                       f"or a .prj / .aux.xml beside it missing)")
    try:
        crs = pyproj.CRS.from_wkt(dataset.crs.to_wkt())
    except pyproj.exceptions.CRSError as err:
        raise GeoError(f"{name}: the DEM's coordinate reference system is not one pyproj knows "
                       f"({_first_line(err)})") from None
    if not (crs.is_geographic or crs.is_projected):
        raise GeoError(f"{name}: the DEM's coordinate reference system {_crs_text(crs)} is neither geographic "
                       f"nor projected")
    return crs


def _horizontal(crs: pyproj.CRS) -> pyproj.CRS:
    """The horizontal part of a compound CRS (UTM + a vertical datum), or the CRS itself."""
    return crs.sub_crs_list[0] if crs.is_compound else crs


def _metres_per_unit(dataset: Any, crs: pyproj.CRS, name: str) -> float:
    """What one of band 1's values is in metres: its unit if it has one, else its CRS's vertical axis's, else
    metres (SRTM, Copernicus and most national DEMs say nothing and mean metres)."""
    unit = (dataset.units[0] or "").strip()
    if not unit and crs.is_compound and len(crs.sub_crs_list) > 1 and crs.sub_crs_list[1].axis_info:
        axis = crs.sub_crs_list[1].axis_info[0]
        unit = axis.unit_name or ""
        if unit.lower() not in _METRES and unit.lower() not in _FEET and axis.unit_conversion_factor:
            return float(axis.unit_conversion_factor)  # a length unit pyproj knows the metres of
    key = unit.lower()
    if key in _METRES:
        return 1.0
    if key in _FEET:
        return _FEET[key]
    raise GeoError(f"{name}: the DEM gives its heights in {unit!r}, neither metres nor feet")


def _transformer(crs: pyproj.CRS) -> pyproj.Transformer | None:
    horizontal = _horizontal(crs)
    if horizontal.equals(_WGS84, ignore_axis_order=True):
        return None
    return pyproj.Transformer.from_crs(_WGS84, horizontal, always_xy=True)


def _read_window(rasterio: ModuleType, path: Path, name: str,
                 wide: tuple[float, float, float, float]) -> DemWindow | None:
    """The window of one file that covers `wide`, with a pixel to spare on every side; None when the file does
    not reach it."""
    try:
        dataset = rasterio.open(path)
    except rasterio.errors.RasterioError as err:
        raise GeoError(f"{name}: not a raster GDAL can read ({_first_line(err)})") from None
    with dataset:
        crs = _file_crs(dataset, name)
        if dataset.colorinterp[0] in (rasterio.enums.ColorInterp.red, rasterio.enums.ColorInterp.palette):
            raise GeoError(f"{name}: an image (band 1 is {dataset.colorinterp[0].name}), not a DEM's heights")
        metres = _metres_per_unit(dataset, crs, name)
        to_file_crs = _transformer(crs)
        window = _window_over(rasterio, dataset, to_file_crs, wide)
        if window is None:
            return None
        try:
            heights = dataset.read(1, window=window, out_dtype="float32")
            valid = dataset.read_masks(1, window=window) != 0
        except rasterio.errors.RasterioError as err:
            raise GeoError(f"{name}: cannot read its heights ({_first_line(err)})") from None
        scale, offset = dataset.scales[0], dataset.offsets[0]
        if scale != 1.0 or offset != 0.0:
            heights = heights * np.float32(scale) + np.float32(offset)
        if metres != 1.0:
            heights = heights * np.float32(metres)
        with np.errstate(invalid="ignore"):
            no_ground = ~valid | ~np.isfinite(heights) | (heights < LOWEST_GROUND_M) | (heights > HIGHEST_GROUND_M)
        heights[no_ground] = np.nan
        heights.setflags(write=False)
        # Pixel centres at integers: the affine from x, y to the window's (col, row) of pixel corners, less half.
        inverse = ~rasterio.windows.transform(window, dataset.transform)
        to_pixel = (inverse.a, inverse.b, inverse.c - 0.5, inverse.d, inverse.e, inverse.f - 0.5)
        return DemWindow(name=name, crs=_crs_text(crs), heights=heights, to_pixel=to_pixel,
                         offset=(int(window.row_off), int(window.col_off)),
                         file_shape=(dataset.height, dataset.width), to_file_crs=to_file_crs,
                         resolution_m=_resolution_m(dataset.transform, _horizontal(crs), wide))


def _window_over(rasterio: ModuleType, dataset: Any, to_file_crs: pyproj.Transformer | None,
                 wide: tuple[float, float, float, float]) -> Any:
    """The rasterio Window of the file's pixels needed to interpolate anywhere in `wide` (at least 2 x 2), or
    None when the file does not reach it."""
    min_lat, min_lon, max_lat, max_lon = wide
    if to_file_crs is None:
        left, bottom, right, top = min_lon, min_lat, max_lon, max_lat
    else:
        try:
            left, bottom, right, top = to_file_crs.transform_bounds(min_lon, min_lat, max_lon, max_lat,
                                                                     densify_pts=21)
        except pyproj.exceptions.ProjError:
            return None  # the box lies where the file's CRS has no place
        if not all(math.isfinite(v) for v in (left, bottom, right, top)):
            return None
    inverse = ~dataset.transform
    corners = [inverse @ (x, y) for x in (left, right) for y in (bottom, top)]
    cols = [c - 0.5 for c, _ in corners]  # pixel centres at integers
    rows = [r - 0.5 for _, r in corners]
    # The pixels whose centres surround any point of the box, and one more on each side.
    col_start, col_stop = max(math.floor(min(cols)) - 1, 0), min(math.floor(max(cols)) + 3, dataset.width)
    row_start, row_stop = max(math.floor(min(rows)) - 1, 0), min(math.floor(max(rows)) + 3, dataset.height)
    if col_stop - col_start < 2 or row_stop - row_start < 2:
        return None
    return rasterio.windows.Window(col_start, row_start, col_stop - col_start, row_stop - row_start)


def _resolution_m(transform: Any, crs: pyproj.CRS, wide: tuple[float, float, float, float]) -> float:
    """The coarser side of a pixel of `transform` in `crs`, in metres on the ground at the middle of the box."""
    across, down = math.hypot(transform.a, transform.d), math.hypot(transform.b, transform.e)  # in the CRS's units
    if crs.is_projected:
        return max(across, down) * crs.axis_info[0].unit_conversion_factor
    lat, lon = (wide[0] + wide[2]) / 2, (wide[1] + wide[3]) / 2
    _, _, east_m = _GEOD.inv(lon, lat, lon + across, lat)
    _, _, north_m = _GEOD.inv(lon, lat, lon, lat + down)
    return float(max(east_m, north_m))
