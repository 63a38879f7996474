"""The ground from a DEM (geo/dem.py) on DEM files written in the test (missionplan/testing/dem_files.py): a
hill in WGS84 and in UTM, SRTM tiles alone and side by side, a window of a large file, and every refusal."""

from __future__ import annotations

import functools
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
import rasterio.errors
import rasterio.warp
from rasterio.transform import from_origin

from missionplan.cli.errors import said
from missionplan.geo.dem import Ground, read_ground
from missionplan.geo.errors import GeoError
from missionplan.testing.dem_files import (hill, srtm_pixel_latlon, write_flat_geotiff, write_geotiff,
                                           write_srtm_tile)

TOP = (45.07, 7.68)  # the hill's top, in Turin's UTM zone (32N)
GROUND = functools.partial(hill, centre=TOP)
FILE_BOUNDS = (45.06, 7.665, 45.08, 7.695)  # what the hill files cover
BOX = (45.065, 7.67, 45.075, 7.69)  # what is asked: inside the files with a margin to spare
GDALLOCATIONINFO = shutil.which("gdallocationinfo")


def _random_points(box: tuple[float, float, float, float], count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(box[0], box[2], count), rng.uniform(box[1], box[3], count)


def _gdal_value(path: Path, lat: float, lon: float) -> float:
    """GDAL's own reader: the value of the pixel holding (lat, lon)."""
    assert GDALLOCATIONINFO is not None
    out = subprocess.run([GDALLOCATIONINFO, "-wgs84", "-valonly", str(path), repr(lon), repr(lat)], check=True,
                         capture_output=True, text=True, timeout=60)
    return float(out.stdout.strip())


def _one_line(err: pytest.ExceptionInfo[GeoError]) -> str:
    line = str(err.value)
    assert "\n" not in line
    return line


@pytest.fixture
def hill_tif(tmp_path: Path) -> Path:
    return write_geotiff(tmp_path / "hill.tif", GROUND, FILE_BOUNDS, 10.0)


@pytest.mark.parametrize("crs", ["EPSG:4326", "EPSG:32632"])
def test_a_hill_reads_back_in_wgs84_and_in_utm(tmp_path: Path, crs: str) -> None:
    path = write_geotiff(tmp_path / "hill.tif", GROUND, FILE_BOUNDS, 10.0, crs=crs)
    ground = read_ground([path], BOX)
    assert (ground.sources, ground.crs) == ((str(path),), (crs,))
    assert ground.resolution_m == pytest.approx(10.0, abs=0.1)
    lat, lon = _random_points(BOX, 5000)
    error = ground.height_amsl(lat, lon) - GROUND(lat, lon)
    # Bilinear on a 10 m grid misses this hill by 2 cm at most; half a pixel off would be 0.6 m on its slope.
    assert np.abs(error).max() < 0.05
    assert ground.height_amsl(lat.reshape(50, 100), lon.reshape(50, 100)).shape == (50, 100)
    assert ground.height_amsl(TOP[0], TOP[1]) == pytest.approx(290.0, abs=0.05)


@pytest.mark.skipif(GDALLOCATIONINFO is None, reason="gdallocationinfo (gdal-bin) is not installed")
@pytest.mark.parametrize("crs", ["EPSG:4326", "EPSG:32632"])
def test_at_a_pixel_centre_the_height_is_the_pixel_gdal_reads(tmp_path: Path, crs: str) -> None:
    path = write_geotiff(tmp_path / "hill.tif", GROUND, FILE_BOUNDS, 10.0, crs=crs)
    ground = read_ground([path], BOX)
    with rasterio.open(path) as dataset:
        centres = [dataset.xy(row, col) for row, col in ((60, 70), (101, 133), (77, 150))]
    to_wgs84 = rasterio.warp.transform(crs, "EPSG:4326", [x for x, _ in centres], [y for _, y in centres])
    for lon, lat in zip(*to_wgs84):
        assert float(ground.height_amsl(lat, lon)) == pytest.approx(_gdal_value(path, lat, lon), abs=1e-3)


def test_an_srtm_tile_reads_its_int16_heights_exactly(tmp_path: Path) -> None:
    tile = write_srtm_tile(tmp_path, 45, 7, GROUND)
    assert tile.name == "N45E007.hgt" and tile.stat().st_size == 3601 * 3601 * 2
    ground = read_ground([tile], BOX)
    assert ground.crs == ("EPSG:4326",) and ground.resolution_m == pytest.approx(30.87, abs=0.01)
    row, col = 3349, 2448  # the pixel nearest the top of the hill
    lat, lon = srtm_pixel_latlon(45, 7, row, col)
    in_file = int(np.fromfile(tile, dtype=">i2")[row * 3601 + col])
    assert in_file == round(float(GROUND(lat, lon))) == 290
    assert float(ground.height_amsl(lat, lon)) == pytest.approx(in_file, abs=1e-6)
    window = ground.windows[0]
    assert window.heights[row - window.offset[0], col - window.offset[1]] == in_file
    points = _random_points(BOX, 2000)
    assert np.abs(ground.height_amsl(*points) - GROUND(*points)).max() < 0.7  # whole metres, a 31 m grid
    if GDALLOCATIONINFO is not None:
        assert _gdal_value(tile, lat, lon) == in_file


def test_two_tiles_answer_across_their_seam(tmp_path: Path) -> None:
    on_seam = functools.partial(hill, centre=(45.5, 8.0), radius_m=1500.0)  # smooth enough for a 90 m grid
    west = write_srtm_tile(tmp_path, 45, 7, on_seam, arcsec=3)
    east = write_srtm_tile(tmp_path, 45, 8, on_seam, arcsec=3)
    (tmp_path / "N47E008.hgt").write_bytes(b"broken")  # far from the box: its name says so, it is not opened
    (tmp_path / "readme.txt").write_text("SRTM tiles\n")  # not a raster: a folder's other files are not read
    box = (45.49, 7.99, 45.51, 8.01)
    ground = read_ground([tmp_path], box)
    assert ground.sources == (str(tmp_path / west.name), str(tmp_path / east.name))
    lat, lon = _random_points(box, 2000)
    lat[:3], lon[:3] = 45.5013, [8.0 - 1e-9, 8.0, 8.0 + 1e-9]  # on the seam and either side of it
    heights = ground.heights(lat, lon, "the test's points")
    assert np.abs(heights - on_seam(lat, lon)).max() < 0.6  # whole metres
    assert np.ptp(heights[:3]) < 1e-6
    assert ground == read_ground([west, east], box)  # the tiles named one by one read the same


def test_where_files_overlap_the_first_with_data_answers(tmp_path: Path) -> None:
    hole = (TOP[0], TOP[1], 60.0)
    first = write_geotiff(tmp_path / "first.tif", lambda lat, lon: np.full(np.shape(lat), 100.0), FILE_BOUNDS, 10.0,
                          nodata_hole=hole)
    second = write_geotiff(tmp_path / "second.tif", lambda lat, lon: np.full(np.shape(lat), 200.0), FILE_BOUNDS, 20.0,
                           crs="EPSG:32632")
    ground = read_ground([first, second], BOX)
    assert ground.crs == ("EPSG:4326", "EPSG:32632") and ground.resolution_m == pytest.approx(20.0)
    assert ground.height_amsl(np.array([45.066, TOP[0]]), np.array([7.671, TOP[1]])).tolist() == [100.0, 200.0]


def test_a_large_file_is_read_only_around_the_box(tmp_path: Path) -> None:
    big = write_flat_geotiff(tmp_path / "country.tif", 250, TOP)  # 20000 x 20000 pixels of 10 m
    box = (45.0655, 7.6736, 45.0745, 7.6864)  # about 1 km x 1 km
    ground = read_ground([big], box)
    window = ground.windows[0]
    # 1 km and 200 m on each side at 10 m, a pixel or two to spare: far from the file's 400 million.
    assert window.heights.shape[0] <= 150 and window.heights.shape[1] <= 150 and window.heights.size > 100 * 100
    assert window.file_shape == (20_000, 20_000)
    assert np.all(ground.heights(*_random_points(box, 1000), "the area") == 250.0)


def test_a_box_no_file_covers_is_refused_in_one_line(hill_tif: Path) -> None:
    with pytest.raises(GeoError) as err:
        read_ground([hill_tif], (45.5, 7.5, 45.51, 7.51))
    assert _one_line(err) == (f"DEM {hill_tif}: no file covers lat 45.50000..45.51000, lon 7.50000..7.51000 "
                              f"(the area and its launch points)")


def test_a_point_without_ground_is_named_with_why(tmp_path: Path) -> None:
    hole = (45.07012, 7.68543, 30.0)
    path = write_geotiff(tmp_path / "a.tif", GROUND, FILE_BOUNDS, 10.0, nodata_hole=hole)
    ground = read_ground([path], BOX)
    lat, lon = np.array([45.066, hole[0], 45.067]), np.array([7.671, hole[1], 7.672])
    assert np.isnan(ground.height_amsl(lat, lon)).tolist() == [False, True, False]
    with pytest.raises(GeoError) as err:
        ground.heights(lat, lon, "uav2's track")
    assert _one_line(err) == (f"DEM {path}: no ground height at 45.07012, 7.68543 (uav2's track): "
                              f"a hole (nodata) in the DEM")
    # West of the hole: between its last pixels with data no height is missing; half a pixel further east,
    # where a nodata pixel is among the four used, there is no height.
    with rasterio.open(path) as dataset:
        nodata = dataset.read(1) == dataset.nodata
        row = int(np.flatnonzero(nodata.any(axis=1)).mean())  # a row through the middle of the hole
        col = min(int(np.argmax(nodata[row])), int(np.argmax(nodata[row + 1]))) - 1  # the last with data
        # Pixel (r, c) spans corners c..c+1, r..r+1: these points lie halfway between four pixel centres.
        (west_x, y), (east_x, _) = dataset.xy(row + 1, col, offset="ul"), dataset.xy(row + 1, col + 1, offset="ul")
    assert np.isnan(ground.height_amsl(np.array([y, y]), np.array([west_x, east_x]))).tolist() == [False, True]
    with pytest.raises(GeoError, match=r": no ground height at 45\.10000, 7\.68000 \(the launch point\): "
                                       r"outside the DEM$"):
        ground.heights(np.array([45.1]), np.array([7.68]), "the launch point")
    with pytest.raises(GeoError, match=r"at 45\.07900, 7\.68000 \(the area\): outside the part of the DEM read "
                                       r"\(lat 45\.06"):
        ground.heights(np.array([45.079]), np.array([7.68]), "the area")  # in the file, beyond the window read


def test_files_that_are_not_dems_are_refused_in_one_line_naming_them(tmp_path: Path) -> None:
    text = tmp_path / "notes.tif"
    text.write_text("not a raster\n")
    bare = tmp_path / "bare.tif"
    with pytest.warns(rasterio.errors.NotGeoreferencedWarning), \
            rasterio.open(bare, "w", driver="GTiff", width=8, height=8, count=1, dtype="float32") as dst:
        dst.write(np.zeros((8, 8), dtype=np.float32), 1)
    photo = tmp_path / "photo.tif"
    with rasterio.open(photo, "w", driver="GTiff", width=8, height=8, count=3, dtype="uint8", crs="EPSG:4326",
                       transform=from_origin(7.6, 45.1, 0.01, 0.01), photometric="RGB") as dst:
        dst.write(np.zeros((3, 8, 8), dtype=np.uint8))
    cut = write_geotiff(tmp_path / "cut.tif", GROUND, FILE_BOUNDS, 10.0, crs="EPSG:32632")
    cut.write_bytes(cut.read_bytes()[:20_000])  # a download cut short: its header whole, its heights not
    cases = [(text, f"{text}: not a raster GDAL can read ("),
             (cut, f"{cut}: cannot read its heights (TIFF"),
             (bare, f"{bare}: the DEM has no coordinate reference system"),
             (photo, f"{photo}: an image (band 1 is red), not a DEM's heights"),
             (tmp_path / "absent.tif", f"{tmp_path / 'absent.tif'}: no such DEM file or folder")]
    for path, start in cases:
        with pytest.raises(GeoError) as err:
            read_ground([path], BOX)
        assert _one_line(err).startswith(start)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(GeoError, match=rf"^{empty}: no DEM file in this folder \(\.asc, "):
        read_ground([empty], BOX)


def _constant_tif(path: Path, value: float, crs: str, units: str | None = None, nodata: float | None = None) -> Path:
    with rasterio.open(path, "w", driver="GTiff", width=300, height=300, count=1, dtype="float32", crs=crs,
                       transform=from_origin(7.66, 45.085, 0.0001, 0.0001), nodata=nodata) as dst:
        dst.write(np.full((300, 300), value, dtype=np.float32), 1)
        if units is not None:
            dst.units = (units,)
    return path


def test_heights_in_feet_are_metres_and_other_units_are_refused(tmp_path: Path) -> None:
    feet = _constant_tif(tmp_path / "feet.tif", 1000.0, "EPSG:4326", units="ft")
    assert float(read_ground([feet], BOX).height_amsl(*TOP)) == pytest.approx(304.8)
    # A compound CRS whose vertical axis is in feet (NAVD88 height (ft)), the band's unit left to GDAL.
    compound = tmp_path / "compound.tif"
    with rasterio.open(compound, "w", driver="GTiff", width=300, height=300, count=1, dtype="float32",
                       crs=rasterio.crs.CRS.from_user_input("EPSG:4326+8228"),
                       transform=from_origin(7.66, 45.085, 0.0001, 0.0001)) as dst:
        dst.write(np.full((300, 300), 1000.0, dtype=np.float32), 1)
    ground = read_ground([compound], BOX)
    assert float(ground.height_amsl(*TOP)) == pytest.approx(304.8) and ground.crs == ("EPSG:4326+EPSG:8228",)
    stated = _constant_tif(tmp_path / "metres.tif", 300.0, "EPSG:4326", units="metre")
    assert float(read_ground([stated], BOX).height_amsl(*TOP)) == 300.0
    odd = _constant_tif(tmp_path / "odd.tif", 300.0, "EPSG:4326", units="furlong")
    with pytest.raises(GeoError) as err:
        read_ground([odd], BOX)
    assert _one_line(err) == f"{odd}: the DEM gives its heights in 'furlong', neither metres nor feet"


def test_heights_no_ground_has_are_nodata(tmp_path: Path) -> None:
    undeclared = _constant_tif(tmp_path / "fill.tif", -9999.0, "EPSG:4326")  # a fill value the file does not declare
    with pytest.raises(GeoError, match=r"a hole \(nodata\) in the DEM$"):
        read_ground([undeclared], BOX).heights(np.array([TOP[0]]), np.array([TOP[1]]), "the area")
    everest = _constant_tif(tmp_path / "high.tif", 9500.0, "EPSG:4326")
    assert np.isnan(read_ground([everest], BOX).height_amsl(*TOP))


def test_without_rasterio_the_option_and_the_extra_are_named(monkeypatch: pytest.MonkeyPatch, hill_tif: Path) -> None:
    monkeypatch.setitem(sys.modules, "rasterio", None)  # import rasterio raises ImportError
    with pytest.raises(GeoError) as err:
        read_ground([hill_tif], BOX)
    assert said(err.value) == "plan --dem needs rasterio: pip install 'missionplan[terrain]'"


def test_ground_is_a_value(hill_tif: Path) -> None:
    ground = read_ground([hill_tif], BOX, margin_m=50.0)
    assert isinstance(ground, Ground) and "windows" not in repr(ground)
    assert ground.around[0] < BOX[0] - 50 / 111_320 and ground.around[3] > BOX[3]
    with pytest.raises(GeoError, match=r"^DEM box \(45\.1, 7\.6, 45\.0, 7\.7\): not \(min_lat"):
        read_ground([hill_tif], (45.1, 7.6, 45.0, 7.7))
