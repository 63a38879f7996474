"""Georeferenced output of `missionplan plan`: missions, .plan / .waypoints / GeoJSON files, drones report."""

import json
from pathlib import Path
import math

import pytest
from pymavlink import mavwp

from missionplan.bridge.formats.mission_items import (CMD_DO_CHANGE_SPEED, CMD_DO_MOUNT_CONTROL, CMD_DO_SET_CAM_TRIGG_DIST, CMD_NAV_LAND,
                                                      CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT,
                                                      FRAME_GLOBAL_RELATIVE_ALT)
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.bridge.flight_models import copter_model as cm
from missionplan.cli import main
from missionplan.flight.plan_report import frame_of, to_grid_m
from missionplan.mission.plan_record import read_plan_record
from missionplan.mission.timeline import FlightModel, planned_seconds


def _timeline_of_file(out: Path, report: dict, sysid: int) -> float:
    """The timeline's duration of uavK.plan as written (waypoints read back from the file)."""
    mission = read_mission_file(out / f"uav{sysid}.plan").mission
    frame = frame_of(read_plan_record(out))
    points = [(it.x, it.y) for it in mission.items if it.command == CMD_NAV_WAYPOINT]
    waypoints = to_grid_m(frame, [p[0] for p in points], [p[1] for p in points])
    launch = to_grid_m(frame, [mission.home[0]], [mission.home[1]])[0]
    speed = next(it.param2 for it in mission.items if it.command == CMD_DO_CHANGE_SPEED)
    end = "land" if mission.items[-1].command == CMD_NAV_LAND else "rtl"
    return planned_seconds(launch, waypoints, mission.items[0].z, end,
                           FlightModel(speed, report["georeference"]["footprint_m"] / 36))


def _lower_bound(altitude: float, length_m: float, speed: float) -> float:
    """Every term a floor: spool-up, climb at full rate, legs at full speed, the last metres of the
    landing at LAND_SPEED, touchdown."""
    return (cm.TAKEOFF_SPOOL_S + altitude / 2.5 + (length_m - 2 * altitude) / speed + min(altitude, 10.0) / 0.5
            + cm.TOUCHDOWN_S)


@pytest.fixture(scope="module")
def leonardo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("leonardo5")
    assert main(["plan", "--map", "leonardo", "--uavs", "5", "--out", str(out), "--quiet"]) == 0
    return out, json.loads((out / "report.json").read_text())


def test_every_drone_gets_plan_waypoints_and_a_report_entry(leonardo_run):
    out, report = leonardo_run
    names = sorted(p.name for p in out.iterdir())
    for k in range(1, 6):
        assert f"uav{k}.plan" in names and f"uav{k}.waypoints" in names
    assert "tracks.geojson" in names and not [n for n in names if n.startswith(".")]
    assert [d["id"] for d in report["drones"]] == [1, 2, 3, 4, 5]
    for drone in report["drones"]:
        for key in ("cells", "waypoints", "length_m", "flight_s", "photos"):
            assert drone[key] > 0
        # The timeline (ArduCopter's flight) of the mission as written, and longer than distance over speed.
        assert drone["flight_s"] == pytest.approx(_timeline_of_file(out, report, drone["id"]), abs=0.06)
        assert drone["flight_s"] > _lower_bound(drone["altitude_m"], drone["length_m"], 5.0)
    separation = report["separation"]
    assert separation["3d"] >= separation["horizontal"] > 0 and len(separation["pair_3d"]) == 2


def test_waypoints_files_load_in_mavwp_with_the_same_items(leonardo_run):
    out, _ = leonardo_run
    for k in range(1, 6):
        ours = read_mission_file(out / f"uav{k}.plan").mission
        loader = mavwp.MAVWPLoader()
        count = loader.load(str(out / f"uav{k}.waypoints"))
        assert count == len(ours.items) + 1  # line 0 is home
        for item, wp in zip(ours.items, [loader.wp(i) for i in range(1, count)]):
            assert wp.command == item.command and wp.frame == item.frame
            assert wp.x == pytest.approx(item.x, abs=1e-7) and wp.y == pytest.approx(item.y, abs=1e-7)
            assert wp.z == pytest.approx(item.z, abs=1e-4)


def test_plan_files_read_back_to_the_mission_shape(leonardo_run):
    out, report = leonardo_run
    launch_cells = report["launch"]
    for k in range(1, 6):
        plan = read_mission_file(out / f"uav{k}.plan")
        items = plan.mission.items
        # layered 1 m apart (the map's min_separation_m) when one altitude would bring two drones too close
        assert items[0].command == CMD_NAV_TAKEOFF and items[0].z == pytest.approx(report["drones"][k - 1]["altitude_m"])
        # the camera pointed straight down (ArduPilot's mount command) before the first photo
        assert items[2].command == CMD_DO_MOUNT_CONTROL and items[2].param1 == -90
        assert items[3].command == CMD_DO_SET_CAM_TRIGG_DIST and items[3].param1 > 0
        assert items[-1].command == CMD_NAV_RETURN_TO_LAUNCH
        # The camera stops after the last survey waypoint; then only the way home round the walls, over the launch
        # point.
        stop = max(i for i, item in enumerate(items) if item.command == CMD_DO_SET_CAM_TRIGG_DIST)
        assert items[stop].param1 == 0
        home_way = items[stop + 1:-1]
        assert all(item.command == CMD_NAV_WAYPOINT for item in home_way)
        if home_way:
            assert (home_way[-1].x, home_way[-1].y) == pytest.approx(plan.mission.home[:2], abs=1e-7)
        # every survey waypoint is followed by "trigger once now" (a photo at each corner), the last one stopping the
        # camera
        for index, item in enumerate(items[:stop]):
            if item.command == CMD_NAV_WAYPOINT:
                after = items[index + 1]
                assert after.command == CMD_DO_SET_CAM_TRIGG_DIST and after.param3 == 1
        waypoints = [i for i in items if i.command == CMD_NAV_WAYPOINT]
        assert len(waypoints) == report["drones"][k - 1]["waypoints"]
        assert all(i.frame == FRAME_GLOBAL_RELATIVE_ALT for i in waypoints)
        # plannedHomePosition is the launch point, which is also the first waypoint
        home_lat, home_lon, _ = plan.mission.home
        assert (waypoints[0].x, waypoints[0].y) == pytest.approx((home_lat, home_lon), abs=1e-7)
        assert launch_cells[k - 1] is not None


def test_corrector_cuts_waypoints_at_least_five_fold_on_leonardo(leonardo_run):
    _, report = leonardo_run
    cells = sum(len(path) for path in report["paths"])  # one waypoint per cell, hovers included
    waypoints = sum(d["waypoints"] for d in report["drones"])
    assert 5 * waypoints <= cells


def test_tracks_geojson_has_every_plan_layer(leonardo_run):
    out, report = leonardo_run
    doc = json.loads((out / "tracks.geojson").read_text())
    layers = [f["properties"]["layer"] for f in doc["features"]]
    assert layers.count("zones") == 5 and layers.count("paths") == 5 and layers.count("launch") == 5
    assert layers.count("photos") == sum(d["photos"] for d in report["drones"])
    for feature in doc["features"]:
        if feature["properties"]["layer"] == "paths":
            lon, lat, up = feature["geometry"]["coordinates"][0]  # 3-D: metres above home
            assert 45.47 < lat < 45.48 and 9.22 < lon < 9.23  # the arena's origin is in Milan
            assert up == 0 and max(c[2] for c in feature["geometry"]["coordinates"]) == pytest.approx(
                feature["properties"]["altitude_m"])


def test_land_and_altitude_step_options(tmp_path):
    out = tmp_path / "run"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet", "--end", "land",
                 "--altitude-step", "0.5", "--speed", "2"]) == 0
    altitudes = []
    for k in range(1, 4):
        items = read_mission_file(out / f"uav{k}.plan").mission.items
        assert items[-1].command == CMD_NAV_LAND
        altitudes.append(items[0].z)
    assert altitudes == pytest.approx([1.2, 1.7, 2.2])
    report = json.loads((out / "report.json").read_text())
    first = report["drones"][0]
    assert first["flight_s"] == pytest.approx(_timeline_of_file(out, report, 1), abs=0.06)  # legs at --speed 2
    assert first["flight_s"] > _lower_bound(1.2, first["length_m"], 2.0)


@pytest.mark.parametrize("args, message", [
    (["--overlap", "1.0"], "--overlap"),
    (["--speed", "0"], "--speed"),
    (["--altitude-step", "-1"], "--altitude-step"),
])
def test_bad_mission_values_are_one_line_and_no_output(tmp_path, capsys, args, message):
    out = tmp_path / "run"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_trigger_distance_follows_the_overlap(tmp_path):
    out = tmp_path / "run"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet", "--overlap", "0.5"]) == 0
    items = read_mission_file(out / "uav1.plan").mission.items
    footprint = 9 * 0.238
    first = next(item for item in items if item.command == CMD_DO_SET_CAM_TRIGG_DIST)
    assert first.param1 == pytest.approx(footprint * 0.5, rel=1e-6)
    assert not math.isnan(first.param1)


SHARED_MAPS = Path(__file__).resolve().parents[1].parent / "shared" / "maps"
TURIN_BUILDINGS = SHARED_MAPS / "turin_cenisia_osm_buildings.geojson"
TURIN_AREA = Path(__file__).resolve().parents[1] / "examples" / "turin-cenisia-area.geojson"
TURIN_LAUNCH = ["45.069450,7.652588", "45.069513,7.657924", "45.066065,7.652668"]
needs_shared = pytest.mark.skipif(not TURIN_BUILDINGS.is_file(), reason="../shared/maps (real OSM data) not beside the repo")


def _area_args(out, *extra, launch=TURIN_LAUNCH):
    args = ["plan", "--area", str(TURIN_AREA), "--osm", str(TURIN_BUILDINGS), "--altitude", "30", "--fov", "84",
            "--out", str(out), "--quiet"]
    for point in launch:
        args += ["--launch", point]
    return args + list(extra)


@needs_shared
def test_real_city_area_plans_to_missions_at_the_launch_points(tmp_path):
    out = tmp_path / "turin"
    assert main(_area_args(out)) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["uavs"] == 3 and report["metrics"]["coverage"] == 100.0
    assert report["georeference"]["footprint_m"] == pytest.approx(2 * 30 * math.tan(math.radians(42)), rel=1e-6)
    for k, point in enumerate(TURIN_LAUNCH, start=1):
        lat, lon = (float(v) for v in point.split(","))
        home = read_mission_file(out / f"uav{k}.plan").mission.home
        # the launch cell's centre: within half a cell diagonal of the given point
        assert abs(home[0] - lat) * 111_000 < 5 and abs(home[1] - lon) * 78_000 < 5


@needs_shared
@pytest.mark.parametrize("change, message", [
    ({"launch": [TURIN_LAUNCH[0], "0,0"]}, "outside the area"),
    ({"launch": ["45.0680,7.6560"]}, "inside a building"),
    ({"extra": ["--fov", "180"]}, "180"),
    ({"extra": ["--altitude", "0.5"]}, "grid"),
])
def test_area_errors_are_one_line_exit_2_and_leave_nothing(tmp_path, capsys, change, message):
    out = tmp_path / "turin"
    args = _area_args(out, launch=change.get("launch", TURIN_LAUNCH))
    for flag_value in zip(change.get("extra", [])[::2], change.get("extra", [])[1::2]):
        index = args.index(flag_value[0])
        args[index + 1] = flag_value[1]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_area_file_of_the_wrong_type_is_named(tmp_path, capsys):
    bad = tmp_path / "area.shp"
    bad.write_text("x")
    assert main(["plan", "--area", str(bad), "--launch", "45,7", "--altitude", "30", "--fov", "84",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "area.shp" in err and err.count("\n") == 1


def test_plan_files_read_back_to_exactly_the_built_missions(tmp_path):
    from missionplan.maps.catalog import load_shipped
    from missionplan.mission.flightplan import make_flight_plans, write_flight_files
    from missionplan.mission.georef import shipped_frame
    from missionplan.mission.drone_missions import MissionSettings
    from missionplan.planning.pipeline import plan_map

    gmap = load_shipped("leonardo")
    result = plan_map(gmap, 3)
    frame = shipped_frame(gmap)
    plans = make_flight_plans(result, frame, MissionSettings(altitude_m=1.2, footprint_m=9 * 0.238))
    write_flight_files(tmp_path, plans)
    for drone in plans.drones:
        back = read_mission_file(tmp_path / f"uav{drone.sysid}.plan").mission
        assert back.home == pytest.approx(drone.mission.home)
        assert len(back.items) == len(drone.mission.items)
        for sent, got in zip(drone.mission.items, back.items):
            assert (got.command, got.frame, got.autocontinue) == (sent.command, sent.frame, sent.autocontinue)
            assert got.params == pytest.approx(sent.params, abs=1e-9)


def test_waypoints_carry_a_quarter_cell_acceptance_radius(leonardo_run):
    out, _ = leonardo_run
    for item in read_mission_file(out / "uav1.plan").mission.items:
        if item.command == CMD_NAV_WAYPOINT:
            assert item.param2 == pytest.approx(0.238 / 4, rel=1e-6)
