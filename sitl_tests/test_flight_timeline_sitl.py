"""The planned timeline against real ArduCopter SITL: a 20 m street plan in Turin flown by `fly`.

One vehicle (the fixture starts it in its own folder and session, kills it in teardown, skips when
../shared/sitl/arducopter is absent), its camera configured once as a team does (CAM1_TYPE = 1 and a
reboot), flown with `fly` and judged from its own CAMERA_FEEDBACK. The flown time is the vehicle's
simulated time (GLOBAL_POSITION_INT time_boot_ms), not wall time: the machine may be loaded.
The street map is read in place from ../shared/maps (the test skips without it).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missionplan.bridge.formats.missionfile import read_mission_file
from missionplan.cli import main
from missionplan.flight.fly import fly
from missionplan.testing.arducopter import configure_camera_and_wait_ready

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

REPO = Path(__file__).resolve().parent.parent
OSM = REPO.parent / "shared" / "maps" / "turin_cenisia_osm_buildings.geojson"
LAUNCH = (45.069450, 7.652588)  # a street corner of Cenisia (README's first launch point)
# A block of streets south-east of it: about 150 x 160 m, one drone, some 40 waypoints.
AREA = [[7.652188, 45.069850], [7.654088, 45.069850], [7.654088, 45.068250], [7.652188, 45.068250],
        [7.652188, 45.069850]]
TOLERANCE = 0.15  # the promise: planned within 15 % of flown


@pytest.fixture()
def street_plan(tmp_path: Path) -> Path:
    if not OSM.is_file():
        pytest.skip(f"{OSM} is absent (the Turin street map, read in place)")
    area = tmp_path / "area.geojson"
    area.write_text(json.dumps({"type": "Feature", "properties": {"name": "cenisia-block"},
                                "geometry": {"type": "Polygon", "coordinates": [AREA]}}))
    out = tmp_path / "plan"
    assert main(["plan", "--area", str(area), "--osm", str(OSM), "--launch", f"{LAUNCH[0]},{LAUNCH[1]}",
                 "--altitude", "20", "--fov", "84", "--out", str(out), "--quiet"]) == 0
    return out


def test_a_street_plan_flies_on_arducopter_within_15_percent_of_its_planned_time(street_plan, arducopter):
    home = read_mission_file(street_plan / "uav1.plan").mission.home
    vehicle = arducopter(sysid=1, home=(home[0], home[1], 240.0, 0.0))
    configure_camera_and_wait_ready(vehicle)
    result = fly(street_plan, vehicle.url, timeout_s=600, progress=False, time_scale=vehicle.speedup,
                 telemetry_hz=10.0)
    assert result.problems == [], result.problems
    assert result.photo_source == "camera" and result.coverage >= 99.0
    drone = result.drones[0]
    assert drone["finished"] and drone["held_after_flight"]
    planned, flown = drone["planned_flight_s"], drone["flight_s"]
    assert flown > 100.0  # a real street flight, timed on the vehicle's clock
    assert abs(planned - flown) <= TOLERANCE * flown, f"planned {planned} s, flown {flown} s"
