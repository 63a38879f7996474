"""A plan over the ground on ArduPilot, as `upload` and `fly` take it: the parameters the upload sets (the
terrain ones and RTL_ALT_TYPE, beside WPNAV_RADIUS; nothing for PX4 or a mission above home), the geofence's
ceiling raised by the ground's rise above home, the points a vehicle is asked about, and a fleet whose vehicles
never load the ground: none armed, one line naming each. The real terrain protocol against ArduCopter is
sitl_tests/test_fly_terrain_sitl.py's."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from missionplan.bridge.errors import BridgeError
from missionplan.bridge.formats.mission_items import (CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT,
                                                      FRAME_GLOBAL_TERRAIN_ALT, Flavour, Mission, MissionItem,
                                                      WireItem)
from missionplan.bridge.link.connection import VehicleInfo, mavlink
from missionplan.bridge.transfer.uploader import UploadReport, set_plan_params
from missionplan.flight.terrain_service import MAX_CHECKED_POINTS, served_line, terrain_points
from missionplan.geo.frame import GridFrame
from missionplan.mission.geofence import drone_fence
from missionplan.testing.dem_files import hill

COPTER = VehicleInfo(1, 1, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_TYPE_QUADROTOR, Flavour.ARDUPILOT, False)
PX4_VEHICLE = VehicleInfo(1, 1, mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_TYPE_QUADROTOR, Flavour.PX4, False)


class ParamTable:
    """A backend's parameters, as a vehicle holds them (a name it lacks is not answered: BridgeError)."""

    name = "pymavlink"

    def __init__(self, vehicle: VehicleInfo, values: dict[str, float]) -> None:
        self.vehicle, self.values = vehicle, dict(values)
        self.sent: list[tuple[str, float]] = []

    def set_param(self, name: str, value: float) -> tuple[float | None, float]:
        if name not in self.values:
            raise BridgeError(f"vehicle 1 did not answer for parameter {name}")
        self.sent.append((name, value))
        old, self.values[name] = self.values[name], value
        return old, value


ARDUCOPTER = {"WPNAV_RADIUS": 200.0, "TERRAIN_ENABLE": 1.0, "TERRAIN_OPTIONS": 0.0, "WPNAV_RFND_USE": 1.0,
              "TERRAIN_SPACING": 100.0, "RTL_ALT_TYPE": 0.0}


def _mission(frame: int) -> Mission:
    return Mission([MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.0, y=7.0, z=20.0),
                    MissionItem(CMD_NAV_WAYPOINT, frame, param2=1.5, x=45.001, y=7.0, z=20.0),
                    MissionItem(CMD_NAV_WAYPOINT, frame, param2=1.5, x=45.001, y=7.001, z=20.0)])


def test_a_mission_over_the_ground_sets_the_terrain_parameters_and_rtl_alt_type_and_says_each():
    table = ParamTable(COPTER, ARDUCOPTER)
    said = set_plan_params(table, _mission(FRAME_GLOBAL_TERRAIN_ALT))  # type: ignore[arg-type]
    assert table.sent == [("WPNAV_RADIUS", 150.0), ("TERRAIN_ENABLE", 1.0), ("TERRAIN_OPTIONS", 0.0),
                          ("WPNAV_RFND_USE", 0.0), ("RTL_ALT_TYPE", 1.0)]
    assert said[-2:] == [
        "set WPNAV_RFND_USE = 0 (was 1): terrain-frame waypoints follow the terrain database (the DEM), not a "
        "rangefinder",
        "set RTL_ALT_TYPE = 1 (was 0): RTL returns at its altitude above the ground (terrain), not above home"]
    report = UploadReport(1, "ardupilot", "pymavlink", params=said)
    assert "; set TERRAIN_ENABLE = 1: keep a terrain database" in report.summary()  # reported as WPNAV_RADIUS is


def test_the_terrain_grid_the_plan_checked_its_heights_on_is_set_as_terrain_spacing():
    table = ParamTable(COPTER, ARDUCOPTER)
    said = set_plan_params(table, _mission(FRAME_GLOBAL_TERRAIN_ALT), terrain_spacing=30)  # type: ignore[arg-type]
    assert ("TERRAIN_SPACING", 30.0) in table.sent
    assert "set TERRAIN_SPACING = 30 m (was 100): the terrain grid the plan checked its heights above the ground on" \
        in said


def test_a_mission_above_home_sets_only_wpnav_radius_and_px4_nothing():
    table = ParamTable(COPTER, ARDUCOPTER)
    said = set_plan_params(table, _mission(FRAME_GLOBAL_RELATIVE_ALT))  # type: ignore[arg-type]
    assert table.sent == [("WPNAV_RADIUS", 150.0)] and len(said) == 1
    assert UploadReport(1, "ardupilot", "pymavlink", params=said).summary().count("; set WPNAV_RADIUS = 150 cm") == 1
    px4 = ParamTable(PX4_VEHICLE, {})
    assert set_plan_params(px4, _mission(FRAME_GLOBAL_TERRAIN_ALT)) == [] and px4.sent == []  # type: ignore[arg-type]


def test_an_arducopter_without_rtl_alt_type_is_told_so_and_the_rest_is_set():
    table = ParamTable(COPTER, {k: v for k, v in ARDUCOPTER.items() if k != "RTL_ALT_TYPE"})
    said = set_plan_params(table, _mission(FRAME_GLOBAL_TERRAIN_ALT))  # type: ignore[arg-type]
    assert [name for name, _ in table.sent] == ["WPNAV_RADIUS", "TERRAIN_ENABLE", "TERRAIN_OPTIONS", "WPNAV_RFND_USE"]
    assert said[-1] == "RTL_ALT_TYPE not set: the vehicle has no such parameter (its RTL altitude stays above home)"
    without_terrain = ParamTable(COPTER, {"WPNAV_RADIUS": 200.0})
    with pytest.raises(BridgeError, match="TERRAIN_ENABLE"):  # one it must have: the upload fails, as for WPNAV_RADIUS
        set_plan_params(without_terrain, _mission(FRAME_GLOBAL_TERRAIN_ALT))  # type: ignore[arg-type]


# ------------------------------------------------------------------ the fence's ceiling
FRAME = GridFrame.at(45.0, 7.0, 2.0, 100, 100)  # 200 x 200 m from its origin, rows north
CELLS = np.array([[r, c] for r in range(10, 90, 5) for c in range(10, 90, 5)])
POINTS = np.array([[10.0, 10.0], [40.0, 40.0], [160.0, 160.0]])  # the launch point first (grid metres)


def _latlon(row_m: float, col_m: float) -> tuple[float, float]:
    lat, lon = FRAME.grid_to_latlon(np.array([row_m / FRAME.cell_m]), np.array([col_m / FRAME.cell_m]))
    return float(lat[0]), float(lon[0])


def test_the_fence_ceiling_rises_by_the_ground_above_home_inside_it():
    flat = drone_fence(FRAME, CELLS, POINTS, 20.0, 5.0, 120.0)
    assert flat.max_altitude_m == 25.0 and flat.ground_rise_m is None
    # A 40 m hill whose top is inside the fence, 150 m from the launch point: the launch point is on its slope.
    top = _latlon(120.0, 120.0)
    ground = functools.partial(hill, centre=top, peak_m=40.0, base_m=300.0, radius_m=120.0)
    fence = drone_fence(FRAME, CELLS, POINTS, 20.0, 5.0, 120.0, ground=ground)
    home_ground = float(ground(*map(np.array, _latlon(10.0, 10.0))))
    rise = 340.0 - home_ground
    assert fence.ground_rise_m == pytest.approx(rise, abs=0.3)  # sampled every 5 m: the top within centimetres
    assert fence.max_altitude_m == pytest.approx(25.0 + rise, abs=0.3)
    assert np.array_equal(fence.latlon, flat.latlon)  # the polygon is the same
    # Launched from the hilltop, nothing inside the fence is higher: the ceiling stays where it was.
    on_top = drone_fence(FRAME, CELLS, np.array([[120.0, 120.0], *POINTS[1:]]), 20.0, 5.0, 120.0, ground=ground)
    assert on_top.ground_rise_m == 0.0 and on_top.max_altitude_m == 25.0


def test_the_fence_ceiling_over_the_ground_keeps_max_altitude_as_a_height_above_the_ground():
    ground = functools.partial(hill, centre=_latlon(120.0, 120.0), peak_m=40.0, base_m=300.0, radius_m=120.0)
    capped = drone_fence(FRAME, CELLS, POINTS, 20.0, 5.0, 22.0, ground=ground)
    assert capped.ground_rise_m is not None
    assert capped.max_altitude_m == pytest.approx(22.0 + capped.ground_rise_m, abs=0.01)


# ------------------------------------------------------------------ what a vehicle is asked, what is said
def _wire(points: list[tuple[float, float]], frame: int = 10) -> list[WireItem]:
    return [WireItem(k, frame, CMD_NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(lon * 1e7), 20.0, 0)
            for k, (lat, lon) in enumerate(points)]


def test_the_points_checked_are_the_terrain_frame_waypoints_thinned_to_one_per_grid_cell():
    near = [(45.0, 7.0), (45.00001, 7.00001), (45.002, 7.0)]  # the first two 1.4 m apart
    assert terrain_points(_wire(near)) == [(45.0, 7.0), (45.002, 7.0)]
    assert terrain_points(_wire(near, frame=3)) == []  # above home: nothing to ask
    long_survey = [(45.0 + 0.002 * k, 7.0) for k in range(200)]
    checked = terrain_points(_wire(long_survey))
    assert len(checked) == MAX_CHECKED_POINTS and checked[0] == long_survey[0] and checked[-1] == long_survey[-1]


def test_the_served_line_says_what_was_sent_and_where_the_ground_ended():
    from missionplan.bridge.session.terrain import TerrainServed

    assert served_line(TerrainServed(12, 300, 14_400)) == (
        "terrain served: 12 TERRAIN_REQUESTs answered, 300 blocks sent (14.4 kB)")
    assert served_line(TerrainServed(1, 0, 0, 3, (45.1, 7.2))).endswith(
        "; no ground in the DEM for 3 terrain blocks (the first at 45.10000, 7.20000)")


# ------------------------------------------------------------------ a fleet that never loads its ground
pytest.importorskip("rasterio", reason="plan --dem reads DEMs with rasterio: pip install -e '.[terrain]'")


@pytest.mark.flight
def test_fly_arms_no_drone_when_one_never_reports_its_terrain_loaded(tmp_path: Path) -> None:
    from missionplan.cli.app import main
    from missionplan.flight.fly import fly
    from missionplan.flight.mock_fleet import start_mock_fleet
    from missionplan.maps.catalog import load_shipped
    from missionplan.mission.georef import shipped_frame
    from missionplan.mission.plan_record import read_plan_record
    from missionplan.testing.dem_files import write_geotiff

    box = shipped_frame(load_shipped("old-town")).latlon_box()
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    dem = write_geotiff(tmp_path / "hill.tif", functools.partial(hill, centre=centre, peak_m=30.0, radius_m=150.0),
                        (box[0] - 0.04, box[1] - 0.05, box[2] + 0.04, box[3] + 0.05), 10.0)
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--map", "old-town", "--uavs", "2", "--policy", "nn", "--dem", str(dem), "--out",
                 str(plan_dir), "--quiet"]) == 0
    fences = [d.geofence for d in read_plan_record(plan_dir).drones or ()]
    assert all(f is not None and f.ground_rise_m is not None and f.ground_rise_m > 0 for f in fences)
    # An ArduCopter with the terrain parameters that never says what terrain it has (the mock without a DEM
    # sends no TERRAIN_REPORT): it must not be armed, nor any other. (The mock fleet stands on the plan's ground
    # unless told otherwise: ground=None.)
    mock = start_mock_fleet(plan_dir, 20.0, ground=None)
    for k in (1, 2):
        mock.vehicle(k).params.update(ARDUCOPTER)
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=60.0, progress=False, time_scale=20.0, ready_s=2.0)
        armed_seen = {k for k in (1, 2) if mock.vehicle(k).flight.state.armed or mock.vehicle(k).reached}
    finally:
        mock.stop()
    assert armed_seen == set()
    for sysid in (1, 2):
        said = f"uav{sysid}: not armed: terrain not loaded after 2.0 s: "
        line = next(p for p in result.problems if p.startswith(said))
        assert "no TERRAIN_REPORT heard (is TERRAIN_ENABLE 1?)" in line and "\n" not in line
    doc_notes = [note for drone in result.doc["drones"] for note in drone["notes"]]
    assert any(note.startswith("set WPNAV_RADIUS = ") and "; set RTL_ALT_TYPE = 1" in note for note in doc_notes)
    assert sum(note.startswith("terrain served: 0 TERRAIN_REQUESTs answered") for note in doc_notes) == 2
