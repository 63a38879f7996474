"""`plan --dem`: a plan over a hill holds its height above the ground, for ArduPilot (terrain-frame items)
and for PX4 (altitudes above sea level, legs split over the ground); a DEM that leaves the area without ground
is refused in one line; the plan folder keeps an exact copy of the ground it used."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rasterio", reason="plan --dem reads DEMs with rasterio: pip install -e '.[terrain]'")

from missionplan.bridge.formats.mission_items import (CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL,  # noqa: E402
                                                       FRAME_GLOBAL_TERRAIN_ALT)
from missionplan.bridge.formats.missionfile import read_mission_file  # noqa: E402
from missionplan.cli.app import main  # noqa: E402
from missionplan.geo.dem import read_ground  # noqa: E402
from missionplan.maps.catalog import load_shipped  # noqa: E402
from missionplan.mission.georef import shipped_frame  # noqa: E402
from missionplan.mission.plan_record import read_plan_record  # noqa: E402
from missionplan.mission.terrain_legs import sample_legs  # noqa: E402
from missionplan.testing.dem_files import map_hill, write_geotiff  # noqa: E402

MAP, UAVS = "old-town", 3
PEAK_M, RADIUS_M = 40.0, 120.0  # slopes up to about 29 %: a leg's straight line departs from the ground


def _box() -> tuple[float, float, float, float]:
    return shipped_frame(load_shipped(MAP)).latlon_box()


_ground = map_hill(MAP, PEAK_M, RADIUS_M)


@pytest.fixture(scope="module")
def dem(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A hill under the map, 5 m pixels, reaching well beyond it (ArduPilot asks for ground around it)."""
    box, pad = _box(), 0.05
    return write_geotiff(tmp_path_factory.mktemp("dem") / "hill.tif", _ground,
                         (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad), 5.0)


def _plan(out: Path, *args: str) -> int:
    return main(["plan", "--map", MAP, "--uavs", str(UAVS), "--quiet", "--out", str(out), *args])


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory, dem: Path) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("plans")
    folders = {}
    for autopilot in ("ardupilot", "px4"):
        assert _plan(root / autopilot, "--dem", str(dem), "--autopilot", autopilot) == 0
        folders[autopilot] = root / autopilot
    return folders


def _positions(path: Path) -> tuple[tuple[float, float, float], list]:
    mission = read_mission_file(path).mission
    assert mission.home is not None
    return mission.home, [item for item in mission.items if item.command in (CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT)]


def test_ardupilot_gets_terrain_frame_waypoints_and_a_home_on_the_ground(planned: dict[str, Path], dem: Path) -> None:
    folder = planned["ardupilot"]
    record = read_plan_record(folder)
    assert record.version == 2 and json.loads((folder / "report.json").read_text())["schema_version"] == 2
    terrain = record.georeference.terrain if record.georeference is not None else None
    assert terrain is not None and terrain.files == ("ground.tif",) and terrain.sources == (str(dem),)
    assert PEAK_M - 15 < terrain.highest_m - terrain.lowest_m <= PEAK_M  # the area reaches up the hill
    for drone in record.drones or ():
        home, positions = _positions(folder / f"uav{drone.id}.plan")
        assert home[2] == pytest.approx(float(_ground(np.array([home[0]]), np.array([home[1]]))[0]), abs=0.05)
        takeoff, waypoints = positions[0], positions[1:]
        assert takeoff.z == drone.altitude_m  # above the launch point, which is home
        assert waypoints and all(w.frame == FRAME_GLOBAL_TERRAIN_ALT and w.z == drone.altitude_m for w in waypoints)


def test_px4_gets_altitudes_above_sea_level_within_2_m_of_the_height_above_the_ground_along_every_leg(
        planned: dict[str, Path]) -> None:
    folder = planned["px4"]
    record = read_plan_record(folder)
    ground = read_ground([folder / "ground.tif"], _box())
    added = 0
    for drone in record.drones or ():
        home, positions = _positions(folder / f"uav{drone.id}.plan")
        waypoints = positions[1:]
        assert all(w.frame == FRAME_GLOBAL for w in waypoints)
        lat = np.array([home[0]] + [w.x for w in waypoints])
        lon = np.array([home[1]] + [w.y for w in waypoints])
        amsl = np.array([home[2] + drone.altitude_m] + [w.z for w in waypoints])
        at_lat, at_lon, leg = sample_legs(lat, lon, 1.0)
        # The altitude flown along each leg: a straight line between its ends' altitudes.
        east_m = 111_132.0 * np.cos(np.radians(lat[leg]))
        along = np.hypot((at_lat - lat[leg]) * 111_132.0, (at_lon - lon[leg]) * east_m)
        length = np.hypot((lat[leg + 1] - lat[leg]) * 111_132.0,
                          (lon[leg + 1] - lon[leg]) * 111_132.0 * np.cos(np.radians(lat[leg])))
        flown = amsl[leg] + (amsl[leg + 1] - amsl[leg]) * np.divide(along, length, out=np.zeros_like(along),
                                                                     where=length > 0)
        above = flown - ground.height_amsl(at_lat, at_lon)
        assert np.abs(above - drone.altitude_m).max() <= 2.0 + 0.1, f"uav{drone.id}"
        assert drone.waypoints == len(waypoints)  # the report counts the points the legs were split at
        added += len(waypoints)
    flat_frame = sum(d.waypoints for d in read_plan_record(planned["ardupilot"]).drones or ())
    assert added > flat_frame  # the same tracks as ArduPilot's, and the hill is steep enough to split some legs


def test_the_plan_folder_keeps_the_ground_exactly_as_read(planned: dict[str, Path], dem: Path) -> None:
    box = _box()
    original, copy = read_ground([dem], box), read_ground([planned["ardupilot"] / "ground.tif"], box)
    rng = np.random.default_rng(7)
    lat = rng.uniform(box[0], box[2], 2000)
    lon = rng.uniform(box[1], box[3], 2000)
    # The same pixels at the same places: equal but for the rounding of the transform written (a micrometre).
    assert np.abs(original.height_amsl(lat, lon) - copy.height_amsl(lat, lon)).max() < 1e-6
    assert copy.crs == original.crs


def test_a_dem_that_leaves_part_of_the_area_without_ground_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    box = _box()
    half = write_geotiff(tmp_path / "half.tif", _ground, (box[0] - 0.05, box[1] - 0.05, box[2] + 0.05,
                                                          (box[1] + box[3]) / 2), 5.0)
    assert _plan(tmp_path / "out", "--dem", str(half)) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"missionplan: DEM {half}: no ground height at ")
    assert err.endswith("(the area): outside the DEM")
    assert not (tmp_path / "out").exists()  # refused before any folder was made


def test_a_hole_in_the_dem_under_the_area_is_refused_in_one_line(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    box, pad = _box(), 0.05
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    holed = write_geotiff(tmp_path / "holed.tif", _ground, (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad),
                          5.0, nodata_hole=(centre[0], centre[1], 15.0))
    assert _plan(tmp_path / "out", "--dem", str(holed)) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.endswith("(the area): a hole (nodata) in the DEM")


def test_dem_needs_a_plan_on_the_earth(tmp_path: Path, capsys: pytest.CaptureFixture[str], dem: Path) -> None:
    grid = tmp_path / "yard.map"
    grid.write_text("name: yard\nlaunch: 1,1\ngrid:\n....\n....\n....\n")  # no origin: not on the Earth
    code = main(["plan", "--map", str(grid), "--uavs", "1", "--quiet", "--dem", str(dem), "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "--dem needs a plan on the Earth" in err


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_map_layers_give_heights_above_the_ground(planned: dict[str, Path], autopilot: str) -> None:
    """tracks.geojson's paths (and so the KMZ's relativeToGround lines): every waypoint at its height above the
    ground, for both autopilots, though PX4's file holds altitudes above sea level."""
    folder = planned[autopilot]
    record = read_plan_record(folder)
    heights = {d.id: d.altitude_m for d in record.drones or ()}
    features = json.loads((folder / "tracks.geojson").read_text())["features"]
    paths = [f for f in features if f["properties"]["layer"] == "paths"]
    assert len(paths) == UAVS
    for path in paths:
        ups = np.array([point[2] for point in path["geometry"]["coordinates"]])
        flying = ups[(ups > 0.5)]
        assert np.allclose(flying, heights[path["properties"]["uav"]], atol=0.01), path["properties"]["uav"]


def test_a_replan_of_a_survey_over_a_dem_plans_over_the_same_ground(planned: dict[str, Path], tmp_path: Path) -> None:
    """`replan` reads the survey's ground from its folder (the crew's DEM may be gone): the new folder keeps its
    own copy and flies terrain-frame waypoints from the same home heights."""
    out = tmp_path / "rest"
    assert main(["replan", str(planned["ardupilot"]), "--drones", "1,2", "--out", str(out), "--quiet"]) == 0
    record = read_plan_record(out)
    terrain = record.georeference.terrain if record.georeference is not None else None
    assert record.version == 2 and terrain is not None and (out / "ground.tif").is_file()
    first = read_plan_record(planned["ardupilot"]).georeference.terrain
    assert terrain.sources == (str(planned["ardupilot"] / "ground.tif"),)
    assert (terrain.lowest_m, terrain.highest_m) == (first.lowest_m, first.highest_m)
    for drone in record.drones or ():
        home, positions = _positions(out / f"uav{drone.id}.plan")
        assert home[2] == pytest.approx(float(_ground(np.array([home[0]]), np.array([home[1]]))[0]), abs=0.05)
        assert all(w.frame == FRAME_GLOBAL_TERRAIN_ALT for w in positions[1:])


def test_ardupilot_terrain_grid_is_chosen_fine_enough_to_hold_the_height(planned: dict[str, Path]) -> None:
    """On ArduCopter's default 100 m terrain grid this hill (40 m high, 120 m across) would be flown metres off;
    the plan picks the coarsest TERRAIN_SPACING that holds every leg within FOLLOW_TOLERANCE_M and says it."""
    from missionplan.mission.terrain_missions import FOLLOW_TOLERANCE_M, flown_above_ground

    folder = planned["ardupilot"]
    record = read_plan_record(folder)
    terrain = record.georeference.terrain if record.georeference is not None else None
    assert terrain is not None and terrain.spacing_m is not None and terrain.spacing_m < 100
    ground = read_ground([folder / "ground.tif"], _box())
    for drone in record.drones or ():
        mission = read_mission_file(folder / f"uav{drone.id}.plan").mission
        assert drone.above_ground_m is not None
        low, high = drone.above_ground_m
        assert drone.altitude_m - FOLLOW_TOLERANCE_M <= low <= high <= drone.altitude_m + FOLLOW_TOLERANCE_M
        on_default = flown_above_ground(mission, ground.height_amsl, 100)
        assert np.abs(on_default - drone.altitude_m).max() > 2.0  # why the default grid is not kept
    px4 = read_plan_record(planned["px4"]).georeference
    assert px4 is not None and px4.terrain is not None and px4.terrain.spacing_m is None  # PX4: above sea level


def test_the_served_ground_is_the_dem_rounded_at_ardupilots_grid_points() -> None:
    """terrain_grid.served_heights looks the ground up where ArduPilot's grid puts its points (the layout
    TerrainServer serves): at those points it is the DEM rounded to whole metres."""
    from missionplan.bridge.formats.terrain_grid import grid_info, grid_points, served_heights

    def plane(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return 200.0 + (lat - 44.41) * 1.3e4 + (lon - 8.93) * 5.1e3

    info = grid_info(int(44.4123e7), int(8.9281e7), 30)
    lat, lon = grid_points(info.grid_lat_e7, info.grid_lon_e7, 30, list(range(56)))
    served = served_heights(lat, lon, 30, plane)
    assert np.abs(served - np.rint(plane(lat, lon))).max() < 0.02


@pytest.mark.parametrize("kind", ["srtm-folder", "utm-geotiff"])
def test_a_real_srtm_tile_and_a_dem_in_another_crs_give_the_same_heights_above_the_ground(
        tmp_path: Path, kind: str) -> None:
    """The hill as a 1 arc-second SRTM tile (a folder of tiles, whole metres) and as a GeoTIFF in UTM 32N: PX4's legs
    hold within 2 m of the height above that ground, ArduPilot's within 1 m on the grid the plan chose."""
    from missionplan.testing.dem_files import write_srtm_tile

    box = _box()
    if kind == "srtm-folder":
        folder = tmp_path / "tiles"
        folder.mkdir()
        write_srtm_tile(folder, int(np.floor(box[0])), int(np.floor(box[1])), _ground)
        dem = folder
    else:
        pad = 0.05
        dem = write_geotiff(tmp_path / "hill-utm.tif", _ground,
                            (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad), 5.0, crs="EPSG:32632")
    for autopilot in ("ardupilot", "px4"):
        out = tmp_path / autopilot
        assert _plan(out, "--dem", str(dem), "--autopilot", autopilot) == 0
        record = read_plan_record(out)
        terrain = record.georeference.terrain if record.georeference is not None else None
        assert terrain is not None and terrain.crs == (("EPSG:4326",) if kind == "srtm-folder" else ("EPSG:32632",))
        for drone in record.drones or ():
            assert drone.above_ground_m is not None
            low, high = drone.above_ground_m
            allowed = 1.0 if autopilot == "ardupilot" else 2.0
            wanted = drone.altitude_m
            assert wanted - allowed - 1e-6 <= low <= high <= wanted + allowed + 1e-6, (autopilot, drone.id)
        home, _ = _positions(out / "uav1.plan")
        # The home is on the ground: the tile's whole metres or the UTM raster, within their rounding of the hill.
        assert home[2] == pytest.approx(float(_ground(np.array([home[0]]), np.array([home[1]]))[0]), abs=0.6)


def test_a_dem_that_ends_before_ardupilot_stops_asking_is_said_in_one_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """ArduPilot arms only with every terrain block it asked for, kilometres around its track: a DEM that covers the
    area but ends 1 km beyond it is planned, with one warning line; PX4, which is served nothing, gets none."""
    box, pad = _box(), 0.01  # about 1 km
    small = write_geotiff(tmp_path / "small.tif", _ground, (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad),
                          5.0)
    assert _plan(tmp_path / "ardupilot", "--dem", str(small)) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "ArduPilot asks" in line]
    assert len(warnings) == 1 and warnings[0].startswith("missionplan: warning: the DEM reaches only 0.75 km beyond")
    assert _plan(tmp_path / "px4", "--dem", str(small), "--autopilot", "px4") == 0
    assert "ArduPilot asks" not in capsys.readouterr().err
