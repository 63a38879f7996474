"""Field safety of georeferenced plans: separation by construction, sorties, geofence, stale files."""

import json
from pathlib import Path

import numpy as np
import pytest
import shapely

from missionplan.bridge.formats.mission_items import (CMD_DO_SET_CAM_TRIGG_DIST, CMD_FENCE_POLYGON_VERTEX_INCLUSION,
                                                      CMD_NAV_LAND, CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, MissionType)
from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.cli import main
from missionplan.flight.plan_report import frame_of, to_grid_m
from missionplan.mission.plan_record import read_plan_record
from missionplan.mission.sorties import split_sorties
from missionplan.mission.timeline import FlightModel, closest_approach, planned_track


def _plan(out: Path, *args: str) -> int:
    return main(["plan", "--map", "leonardo", "--out", str(out), "--quiet", *args])


@pytest.fixture(scope="module")
def leonardo5(tmp_path_factory):
    out = tmp_path_factory.mktemp("safe5")
    assert _plan(out, "--uavs", "5") == 0
    return out, json.loads((out / "report.json").read_text())


def _tracks_from_files(out: Path, report: dict, sortie: int = 1) -> dict[int, np.ndarray]:
    """Every drone's timed track rebuilt from the written .plan files alone (not from the planner's memory)."""
    frame = frame_of(read_plan_record(out))
    speed = 5.0
    tracks = {}
    for drone in report["drones"]:
        if sortie > len(drone["sorties"]):
            continue
        plan = read_mission_file(out / drone["sorties"][sortie - 1]["file"]).mission
        home = to_grid_m(frame, plan.home[0], plan.home[1])[0]
        waypoints = [i for i in plan.items if i.command == CMD_NAV_WAYPOINT]
        points = to_grid_m(frame, [i.x for i in waypoints], [i.y for i in waypoints])
        altitude = next(i.z for i in plan.items if i.command == CMD_NAV_TAKEOFF)
        end = "land" if plan.items[-1].command == CMD_NAV_LAND else "rtl"
        model = FlightModel(speed_m_s=speed, acceptance_m=waypoints[0].param2)
        tracks[drone["id"]] = planned_track(home, points, altitude, end, model)
    return tracks


# ------------------------------------------------------------------------------------------ separation
def test_demo_plan_guarantees_the_maps_separation_on_the_timeline_of_its_files(leonardo5):
    out, report = leonardo5
    sep = report["separation"]
    assert sep["required_m"] == 1.0  # declared by maps/leonardo.map for its small drones
    assert sep["3d"] >= 1.0 and sep["guaranteed_m"] == sep["3d"]
    # The same closest approach, measured independently from what the files say the drones fly.
    again = closest_approach(_tracks_from_files(out, report))
    assert again["3d"] == pytest.approx(sep["3d"], abs=0.02)
    # One altitude brought two drones within 0.27 m: layers were needed and are in the files.
    altitudes = [d["altitude_m"] for d in report["drones"]]
    assert sep["altitude_step_m"] == 1.0 and altitudes == pytest.approx([1.2, 2.2, 3.2, 4.2, 5.2])


def test_a_ceiling_below_the_layers_is_refused_naming_the_pair_and_the_place(tmp_path, capsys):
    out = tmp_path / "run"
    assert _plan(out, "--uavs", "5", "--max-altitude", "3") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "--min-separation 1 m cannot be guaranteed: uav" in err and " near 45.4" in err
    assert "--max-altitude 3" in err
    assert not (out / "uav1.plan").exists()


def test_far_apart_drones_need_no_layers(tmp_path):
    out = tmp_path / "run"
    assert _plan(out, "--uavs", "2", "--min-separation", "0.5") == 0
    report = json.loads((out / "report.json").read_text())
    assert report["separation"]["altitude_step_m"] == 0.0 and report["separation"]["3d"] >= 0.5
    assert {d["altitude_m"] for d in report["drones"]} == {1.2}


@pytest.mark.parametrize("args, message", [
    (["--min-separation", "0"], "--min-separation"),
    (["--max-altitude", "1"], "--max-altitude"),
    (["--reserve", "1"], "--reserve"),
    (["--endurance", "-3"], "--endurance"),
    (["--clearance", "-1"], "--clearance"),
])
def test_bad_safety_values_are_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "run"
    assert _plan(out, "--uavs", "2", *args) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


# -------------------------------------------------------------------------------------------- sorties
def test_split_sorties_keeps_every_sortie_within_the_budget_and_resumes_where_it_stopped():
    model = FlightModel(speed_m_s=5.0, acceptance_m=0.5)
    launch = np.array([0.0, 0.0])
    route = np.array([[0, 0], [0, 400], [50, 400], [50, 0], [100, 0], [100, 400], [150, 400]], dtype=float)
    budget = 200.0
    sorties = split_sorties(launch, route, 20.0, "rtl", model, budget, step_m=10.0)
    assert len(sorties) >= 3
    for index, sortie in enumerate(sorties):
        track = planned_track(launch, sortie.waypoints_m, 20.0, sortie.end, model)
        assert track[-1, 0] <= budget + 1e-6
        assert sortie.resumes == (index > 0)
        if index:
            assert np.allclose(sortie.waypoints_m[0], sorties[index - 1].waypoints_m[-1])
            assert np.allclose(sortie.waypoints_m[0] % 10.0, 0.0)  # cut on a cell centre, 10 m apart
    # Together they fly the whole route: same vertices, in order, plus the cut points.
    flown = np.vstack([s.waypoints_m for s in sorties])
    for vertex in route:
        assert np.min(np.hypot(*(flown - vertex).T)) < 1e-9
    total = sum(float(np.hypot(*np.diff(s.waypoints_m, axis=0).T).sum()) for s in sorties)
    assert total == pytest.approx(float(np.hypot(*np.diff(route, axis=0).T).sum()))


def test_split_sorties_on_px4_counts_its_turns_and_fits_the_px4_timeline_uncut():
    """PX4 turns its nose before every leg: a splitter that timed sorties as ArduCopter flies would
    cut sorties that the PX4 timeline puts over the budget (flightplan then had to re-cut them with a
    shrunk budget: more sorties). Timed with PX4's model, every sortie fits as cut, and uses the budget."""
    model = FlightModel.for_autopilot("px4", speed_m_s=5.0, acceptance_m=0.5)
    launch = np.array([0.0, 0.0])
    # A street-like zigzag: 60 legs of 20-40 m, a right-angle turn at each waypoint.
    route = np.array([[20.0 * (k // 2), 40.0 * (k % 4 in (1, 2))] for k in range(60)])
    budget = 420.0
    sorties = split_sorties(launch, route, 20.0, "rtl", model, budget, step_m=10.0)
    times = [float(planned_track(launch, s.waypoints_m, 20.0, s.end, model)[-1, 0]) for s in sorties]
    assert len(sorties) >= 3
    assert max(times) <= budget
    assert min(times[:-1]) >= 0.8 * budget  # no sortie but the last cut much shorter than it could be


def test_a_budget_too_short_for_the_transit_is_refused():
    from missionplan.maps.gridmap import MapError

    model = FlightModel(speed_m_s=5.0, acceptance_m=0.5)
    with pytest.raises(MapError, match="uav2: a sortie cannot fly out"):
        split_sorties(np.zeros(2), np.array([[0.0, 0.0], [0.0, 2000.0]]), 20.0, "rtl", model, 100.0, "uav2")


@pytest.fixture(scope="module")
def leonardo_sorties(tmp_path_factory):
    out = tmp_path_factory.mktemp("sorties")
    # 1.4 min endurance, 20 % reserve: 67 s a sortie, of which ArduCopter's take-off, RTL (loiter, slow
    # final descent) and landing take some 35 s, on 57-61 s routes.
    assert _plan(out, "--uavs", "3", "--endurance", "1.4") == 0
    return out, json.loads((out / "report.json").read_text())


def test_long_routes_fly_in_sorties_with_files_and_report_entries(leonardo_sorties):
    out, report = leonardo_sorties
    for drone in report["drones"]:
        sorties = drone["sorties"]
        assert len(sorties) >= 2
        assert [s["file"] for s in sorties] == [f"uav{drone['id']}.plan"] + \
            [f"uav{drone['id']}-s{j}.plan" for j in range(2, len(sorties) + 1)]
        assert all(s["flight_s"] <= 1.4 * 60 * 0.8 + 1e-6 for s in sorties)
        assert sum(s["photos"] for s in sorties) == drone["photos"]
        for j, entry in enumerate(sorties):
            items = read_mission_file(out / entry["file"]).mission.items
            assert sum(i.command == CMD_NAV_WAYPOINT for i in items) == entry["waypoints"]
            if j:  # a resumed sortie: camera off on the way out (after the gimbal item), on from its first waypoint
                assert items[3].command == CMD_DO_SET_CAM_TRIGG_DIST and items[3].param1 == 0
                assert items[3].param3 == 0
        assert set(report["files"]) >= {s["file"] for s in sorties}


def test_each_sortie_keeps_the_separation_started_together(leonardo_sorties):
    out, report = leonardo_sorties
    count = max(len(d["sorties"]) for d in report["drones"])
    assert len(report["separation"]["sorties"]) == count
    for j in range(1, count + 1):
        tracks = _tracks_from_files(out, report, j)
        if len(tracks) > 1:
            assert closest_approach(tracks)["3d"] >= report["separation"]["required_m"] - 0.02


@pytest.mark.flight
def test_fly_flies_a_later_sortie_against_the_mock(leonardo_sorties):
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet

    out, _ = leonardo_sorties
    mock = start_mock_fleet(out, speedup=2.0)
    try:
        result = fly(out, mock.client_url, timeout_s=120, progress=False, time_scale=2.0, telemetry_hz=50.0,
                     sortie=2)
    finally:
        mock.stop()
    assert result.ok, result.problems
    assert 0 < result.targets < 1956  # judged on what sortie 2 photographs, not the whole arena
    assert result.separation["kept"]


# ------------------------------------------------------------------------------------------- geofence
def test_every_point_of_the_flight_lies_inside_the_drones_fence(leonardo_sorties, leonardo5):
    for out, report in (leonardo5, leonardo_sorties):
        for drone in report["drones"]:
            for entry in drone["sorties"]:
                plan = read_mission_file(out / entry["file"])
                fence = [i for i in plan.fence.items if i.command == CMD_FENCE_POLYGON_VERTEX_INCLUSION]
                assert len(fence) >= 3 and all(i.param1 == len(fence) for i in fence)
                polygon = shapely.Polygon([(i.y, i.x) for i in fence])
                assert polygon.is_valid
                home = plan.mission.home
                points = [(home[1], home[0])]  # take-off, return and (RTL) landing
                points += [(i.y, i.x) for i in plan.mission.items if i.command in (CMD_NAV_WAYPOINT, CMD_NAV_LAND)]
                for lon, lat in points:
                    assert polygon.contains(shapely.Point(lon, lat))
                altitude = next(i.z for i in plan.mission.items if i.command == CMD_NAV_TAKEOFF)
                assert plan.fence_max_altitude is not None and plan.fence_max_altitude > altitude


def test_fence_round_trips_through_the_mock(leonardo5):
    from missionplan.bridge.formats.mission_items import Flavour, to_wire
    from missionplan.bridge.sim.mock import MockAutopilot
    from missionplan.bridge.transfer.protocol import Timeouts
    from missionplan.bridge.transfer.uploader import open_backend, upload_plan

    out, _ = leonardo5
    plan = read_mission_file(out / "uav2.plan")
    assert plan.fence.items
    with MockAutopilot("udpin:127.0.0.1:0", sysids=[2], request_interval=0.02).start() as mock:
        backend = open_backend("pymavlink", mock.client_url, 2, timeouts=Timeouts(item_timeout=0.5, retries=10),
                               connect_timeout=5.0)
        try:
            upload_plan(backend, plan.parts(), verify=True)
            held = backend.download(MissionType.FENCE)
        finally:
            backend.close()
    sent = to_wire(plan.fence, Flavour.ARDUPILOT)
    assert [(w.command, w.x, w.y, w.param1) for w in held] == [(w.command, w.x, w.y, w.param1) for w in sent]


# ------------------------------------------------------------------------------------------ stale files
def test_a_replan_removes_only_the_files_the_previous_plan_wrote(tmp_path):
    out = tmp_path / "run"
    assert _plan(out, "--uavs", "4") == 0
    (out / "notes.txt").write_text("the crew's own file")
    (out / "uav9.plan").write_text("not ours: not in report.json")
    assert (out / "uav4.plan").exists()
    assert _plan(out, "--uavs", "2") == 0
    names = {p.name for p in out.iterdir()}
    assert not {"uav3.plan", "uav3.waypoints", "uav4.plan", "uav4.waypoints"} & names
    assert {"uav1.plan", "uav2.waypoints", "report.json", "plan.png", "notes.txt", "uav9.plan"} <= names
    assert json.loads((out / "report.json").read_text())["files"] == sorted(
        {"plan.png", "plan.html", "plan.gpkg", "plan.kmz", "report.json", "tracks.geojson",
         "uav1.plan", "uav1.waypoints", "uav2.plan", "uav2.waypoints"})


def test_a_replan_without_sorties_removes_the_old_sortie_files(tmp_path):
    out = tmp_path / "run"
    assert _plan(out, "--uavs", "2", "--endurance", "1.4") == 0
    assert (out / "uav1-s2.plan").exists()
    assert _plan(out, "--uavs", "2") == 0
    assert not list(out.glob("uav*-s*"))


# ------------------------------------------------------------------------------------------ clearance
TURIN_OSM = Path(__file__).resolve().parent.parent.parent / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"


@pytest.mark.skipif(not TURIN_OSM.is_file(), reason="../shared/maps/turin_cenisia_osm_buildings.geojson is absent")
def test_reported_clearance_is_a_true_lower_bound_against_the_buffered_buildings(tmp_path):
    from missionplan.geo.readers import read_buildings

    repo = Path(__file__).resolve().parent.parent
    out = tmp_path / "turin"
    assert main(["plan", "--area", str(repo / "examples" / "turin-cenisia-area.geojson"), "--osm", str(TURIN_OSM),
                 "--launch", "45.069450,7.652588", "--launch", "45.069513,7.657924", "--launch", "45.066065,7.652668",
                 "--launch", "45.066127,7.658004", "--altitude", "20", "--fov", "84", "--out", str(out),
                 "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    clearance = report["clearance"]
    assert clearance["required_m"] == 5.0  # max(5 m, one 4 m cell)
    frame = frame_of(read_plan_record(out))
    # Buildings the plan may not overfly (20 m less the 5 m margin, or of unknown height), in grid metres.
    tall = [b.geometry for b in read_buildings(TURIN_OSM) if b.height_m is None or b.height_m >= 15.0]
    buildings = shapely.union_all([frame.geometry_to_grid(g) for g in tall])
    buildings = shapely.transform(buildings, lambda xy: xy[:, ::-1] * frame.cell_m)  # (col, row) -> (row_m, col_m)
    buffered = buildings.buffer(clearance["kept_m"] - 0.01)
    closest = np.inf
    for drone in report["drones"]:
        plan = read_mission_file(out / f"uav{drone['id']}.plan").mission
        waypoints = [i for i in plan.items if i.command == CMD_NAV_WAYPOINT]
        track = to_grid_m(frame, [plan.home[0]] + [i.x for i in waypoints], [plan.home[1]] + [i.y for i in waypoints])
        for a, b in zip(track[:-1], track[1:]):
            steps = max(int(np.hypot(*(b - a)) / 0.25), 1)
            samples = a + (b - a) * np.linspace(0.0, 1.0, steps + 1)[:, None]
            assert not shapely.intersects_xy(buffered, samples[:, 0], samples[:, 1]).any()
            closest = min(closest, float(shapely.distance(buildings, shapely.points(samples)).min()))
    assert closest >= clearance["kept_m"] - 0.01
    # By construction: every track keeps the asked 5 m from the real buildings, not only from the grid.
    assert clearance["kept"] and clearance["kept_m"] >= 5.0 and closest >= 5.0 - 0.01
    # The band's targets are accounted for, not hidden: photographed from outside it, or unreachable.
    total = sum(row.count(".") for row in report["grid"])
    assert report["targets"] + report["unreachable"] == total
    assert clearance["band_targets_photographed"] + clearance["band_targets_missed"] == clearance["band_targets"] > 0


def test_clearance_band_is_exact_for_cell_centres():
    from missionplan.mission.clearance import clearance_band

    obstacle = np.zeros((9, 9), dtype=bool)
    obstacle[4, 4] = True
    # Half a cell: a neighbour's centre is exactly 0.5 cell from the square, so no band at all.
    assert not clearance_band(obstacle, 0.5).any()
    band = clearance_band(obstacle, 1.2)
    # Side neighbours at 0.5, diagonal at 0.707, two away in line at 1.5, knight's move at hypot(1.5, 0.5)=1.58.
    assert band[3, 4] and band[3, 3] and not band[2, 4] and not band[2, 3] and not band[4, 4]


def test_a_launch_point_inside_the_clearance_band_is_refused(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["plan", "--map", "grid-city", "--uavs", "3", "--clearance", "5", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "launch point of drone" in err and "--clearance 5 m" in err and err.count("\n") == 1


def test_band_targets_are_photographed_by_detours_that_stay_outside_the_band():
    from missionplan.geo.frame import GridFrame
    from missionplan.geo.georeference import Georeference
    from missionplan.mission.clearance import clearance_band, flight_map, footprint_union, photograph_band
    from missionplan.maps.gridmap import GridMap

    # A 30 x 30 open square with a wall; a 3 m clearance on 1 m cells bands three cells round the wall.
    obstacle = np.zeros((30, 30), dtype=bool)
    obstacle[10:20, 15] = True
    one_metre = Georeference(GridFrame.at(45.0, 7.0, 1.0, 30, 30))
    gmap = GridMap("t", obstacle, ~obstacle, launch=[(2, 2)], georef=one_metre)
    flight, band = flight_map(gmap, 3.0, 1)
    assert (band == clearance_band(obstacle, 3.0)).all() and band[15, 14] and not band[15, 10]
    # A path that never comes near the wall leaves the band targets out of its photos.
    path = np.array([[[2, c] for c in range(2, 28)]])
    assert (gmap.target & band & ~footprint_union(path, gmap.shape)).any()
    zone = np.where(flight.target, 0, -1)
    longer, added = photograph_band(path, flight, gmap, band, zone)
    assert added > 0 and longer.shape[1] == path.shape[1] + added
    assert not (gmap.target & band & ~footprint_union(longer, gmap.shape)).any()  # every band target is seen
    cells = longer[0]
    assert flight.free[cells[:, 0], cells[:, 1]].all()  # and the detours never enter the band
    assert (np.abs(np.diff(cells, axis=0)).sum(axis=1) <= 1).all()  # 4-connected moves (or hovers)
    assert (cells[-1] == path[0, -1]).all()  # the survey still ends where it did


# --------------------------------------------------------------------------------- zones and sorties
def test_balanced_zones_follow_the_shares_asked():
    from missionplan.grid.zones import split_zones

    targets = np.ones((40, 40), dtype=bool)
    zones = split_zones(targets, targets, [(5, 5), (34, 34)], balance=True, shares=np.array([0.65, 0.35]))
    sizes = zones.sizes() / targets.sum()
    assert sizes == pytest.approx([0.65, 0.35], abs=0.04)  # far from the even split below
    even = split_zones(targets, targets, [(5, 5), (34, 34)], balance=True).sizes() / targets.sum()
    assert even == pytest.approx([0.5, 0.5], abs=0.04)  # a diagonal boundary moves ~40 cells at a time
    assert sizes[0] - even[0] > 0.1


def test_sortie_shares_give_the_slower_drone_fewer_cells_and_none_without_sorties():
    from missionplan.mission.sorties import sortie_shares

    # Same cells, but drone 2 needs 1.5 x the time (its sorties transit far): it gets 40 %.
    shares = sortie_shares(np.array([100, 100]), np.array([1000.0, 1500.0]), np.array([3, 4]))
    assert shares == pytest.approx([0.6, 0.4])
    assert sortie_shares(np.array([100, 100]), np.array([1000.0, 1500.0]), np.array([1, 1])) is None
    assert sortie_shares(np.array([100, 100]), np.array([1000.0, 1020.0]), np.array([2, 2])) is None


def test_an_older_report_without_checksums_removes_nothing_and_names_what_it_keeps(tmp_path):
    from missionplan.mission.outputs import file_sha256, remove_stale_outputs

    # A report written before checksums (here also before `files`): its drones' files are named, none removed.
    (tmp_path / "report.json").write_text(json.dumps({"drones": [{"id": 1}, {"id": 3}]}))
    for name in ("uav1.plan", "uav3.plan", "uav3.waypoints", "tracks.geojson", "mine.plan"):
        (tmp_path / name).write_text("x")
    stale = remove_stale_outputs(tmp_path, keep={"uav1.plan", "report.json", "plan.png"})
    assert stale.removed == []
    assert sorted(p.name for p in stale.kept) == ["tracks.geojson", "uav3.plan", "uav3.waypoints"]
    # With checksums: only the file whose content is still the recorded one goes.
    (tmp_path / "report.json").write_text(json.dumps({
        "files": ["uav3.plan", "uav3.waypoints"],
        "files_sha256": {"uav3.plan": file_sha256(tmp_path / "uav3.plan"), "uav3.waypoints": "0" * 64}}))
    stale = remove_stale_outputs(tmp_path, keep=set())
    assert [p.name for p in stale.removed] == ["uav3.plan"] and [p.name for p in stale.kept] == ["uav3.waypoints"]
    # A report listing a name that is not one of ours, or a path, removes nothing of it.
    (tmp_path / "report.json").write_text(json.dumps({"files": ["../escape.plan", "notes.txt", "mine.plan"],
                                                      "files_sha256": {"mine.plan": file_sha256(tmp_path / "mine.plan")}}))
    assert remove_stale_outputs(tmp_path, keep=set()).removed == []
    assert (tmp_path / "mine.plan").exists() and (tmp_path / "uav1.plan").exists()


def test_a_fence_round_a_ragged_zone_stays_small_and_holds_every_point():
    from missionplan.geo.frame import GridFrame
    from missionplan.mission.geofence import MAX_VERTICES, drone_fence

    frame = GridFrame.at(45.0, 7.0, 2.0, 100, 100)
    rng = np.random.default_rng(1)
    cells = rng.integers(0, 100, size=(400, 2))  # a ragged zone: its hull has many corners
    points = rng.uniform(0, 200, size=(50, 2))
    fence = drone_fence(frame, cells, points, 20.0, 5.0, 120.0)
    assert 3 <= len(fence.latlon) <= MAX_VERTICES
    polygon = shapely.Polygon(fence.polygon_m)
    assert polygon.contains(shapely.MultiPoint(points)) and polygon.contains(shapely.MultiPoint(cells * 2.0))
    assert fence.max_altitude_m == 25.0


TURIN_OSM = Path(__file__).resolve().parents[2] / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"
TURIN_AREA = Path(__file__).resolve().parents[1] / "examples" / "turin-cenisia-area.geojson"


@pytest.mark.skipif(not TURIN_OSM.is_file(), reason=f"{TURIN_OSM} is absent (../shared/maps)")
def test_real_city_sorties_fit_the_battery_and_short_flights_stay_whole(tmp_path):
    """Turin: the way out and home go round buildings, which the splitter's straight transit legs
    underrate; every sortie must still fit on the timeline. And 11-13 minute flights under the
    default 20 minute battery are not cut at all (the splitter once counted a stop every cell)."""
    common = ["--area", str(TURIN_AREA), "--osm", str(TURIN_OSM), "--altitude", "20", "--fov", "84",
              "--launch", "45.069450,7.652588", "--launch", "45.069513,7.657924"]
    assert main(["plan", *common, "--endurance", "10", "--out", str(tmp_path / "short"), "--quiet"]) == 0
    report = json.loads((tmp_path / "short" / "report.json").read_text())
    flights = [s["flight_s"] for d in report["drones"] for s in d["sorties"]]
    assert len(flights) > 2 and max(flights) <= 10 * 60 * 0.8 + 1e-6

    assert main(["plan", *common, "--launch", "45.066065,7.652668", "--launch", "45.066127,7.658004",
                 "--out", str(tmp_path / "whole"), "--quiet"]) == 0
    report = json.loads((tmp_path / "whole" / "report.json").read_text())
    assert [len(d["sorties"]) for d in report["drones"]] == [1, 1, 1, 1]
    assert all(d["sorties"][0]["flight_s"] < 20 * 60 * 0.8 for d in report["drones"])
