"""`missionplan fly` serves a plan's ground to real ArduCopter SITL (../shared/sitl/arducopter), which then flies
its terrain-frame waypoints at the planned height above that ground.

A 120 x 90 m block in Milan planned for 2 drones over a hill made here (a GeoTIFF written with rasterio: a round
hill 60 m high and 400 m wide whose top is 270 m north of the launch points, so the ground rises about 10 m
across the block and never dips below the launch points: SITL's own simulated ground is flat at home, and a
track below home's ground would fly into it). One SITL vehicle per drone at its launch point, its home at the
DEM's height there (missionplan.testing.sitl_fleet), the camera configured, then `missionplan fly` as a crew
runs it. SITL has no terrain files: it asks fly for the ground (TERRAIN_REQUEST) and fly answers from the plan
folder's copy of the DEM.

Required: each vehicle reported its terrain loaded (TERRAIN_REPORT: 0 blocks pending, ground at its position
and at its waypoints) before it was armed, as flight.json's notes say; along the survey legs (from its first
terrain-frame waypoint reached to its last) every position it reported is within 2 m of the DEM + the planned
height above sea level (its relative altitude + its home's, the DEM's at the launch point: ArduPilot's own
terrain grid, bilinear between 100 m points of int16 metres, included); both finish; the photos it reported
cover the block (>= 99 %). What was measured is printed (`pytest -s`). Skipped when the binary is absent.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rasterio", reason="plan --dem reads DEMs with rasterio: pip install -e '.[terrain]'")

from missionplan.bridge.formats.missionfile import read_mission_file  # noqa: E402
from missionplan.bridge.link.params import TERRAIN_FRAMES  # noqa: E402
from missionplan.cli import main  # noqa: E402
from missionplan.flight.journal_read import read_flight  # noqa: E402
from missionplan.mission.plan_record import read_plan_record  # noqa: E402
from missionplan.testing.dem_files import hill, write_geotiff  # noqa: E402
from missionplan.testing.sitl_fleet import FLY_TIMEOUT_S, SPEEDUP, Fleet, configure, flight_doc, summary  # noqa: E402

pytestmark = pytest.mark.sitl  # starts real autopilots: `pytest -m "not sitl"` leaves it out

AREA = [[9.1890, 45.4640], [9.1905, 45.4640], [9.1905, 45.4648], [9.1890, 45.4648], [9.1890, 45.4640]]
LAUNCHES = ("45.4641,9.1891", "45.4641,9.1904")
HILL = functools.partial(hill, centre=(45.4665, 9.1898), peak_m=60.0, base_m=120.0, radius_m=400.0)
# Beyond the block the DEM reaches farther than the plan reads (planning.terrain.DEM_MARGIN_M, 5.5 km: the
# terrain grids ArduPilot asks for around where it is, 28 x 32 points 100 m apart aligned to whole degrees).
DEM_PAD_DEG = 0.08  # 8.9 km north and south, 6.2 km east and west
HEIGHT_TOLERANCE_M = 2.0


@pytest.fixture(scope="module")
def hill_plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The block planned over the hill for its two launch points (once per module)."""
    base = tmp_path_factory.mktemp("terrain-block")
    lons, lats = [p[0] for p in AREA], [p[1] for p in AREA]
    dem = write_geotiff(base / "hill.tif", HILL, (min(lats) - DEM_PAD_DEG, min(lons) - DEM_PAD_DEG,
                                                  max(lats) + DEM_PAD_DEG, max(lons) + DEM_PAD_DEG), 20.0)
    area = base / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [AREA]}))
    args = ["plan", "--area", str(area), "--altitude", "20", "--fov", "84", "--dem", str(dem), "--out",
            str(base / "plan"), "--quiet"]
    for point in LAUNCHES:
        args += ["--launch", point]
    assert main(args) == 0
    return base / "plan"


def _survey_window(reached: list[tuple[float, int]], first: int, last: int) -> tuple[float, float] | None:
    """Our times of reaching the first and the last survey waypoint (None: not both reached)."""
    times = dict((seq, t) for t, seq in reversed(reached))  # the first arrival at each item
    return (times[first], times[last]) if first in times and last in times else None


def test_fly_serves_the_ground_and_sitl_flies_the_planned_height_above_it(
        arducopter_fleet, fly_runs, hill_plan: Path, tmp_path: Path) -> None:
    plan_dir = tmp_path / "plan"
    plan_dir.mkdir()
    for path in hill_plan.iterdir():
        (plan_dir / path.name).write_bytes(path.read_bytes())
    fleet: Fleet = arducopter_fleet(plan_dir, speedup=SPEEDUP)
    configure(fleet)
    run = fly_runs(plan_dir, fleet.url)
    code = run.finish(FLY_TIMEOUT_S)
    doc, rows = flight_doc(plan_dir)
    print(run.out)
    assert code == 0, (summary(fleet, run), doc["problems"])
    record = read_plan_record(plan_dir)
    planned = {d.id: d.altitude_m for d in record.drones or ()}
    _, _, records = read_flight(plan_dir)
    for rec in records:
        notes = rows[rec.id]["notes"]
        loaded = [n for n in notes if n.startswith("terrain loaded after ")]
        served = [n for n in notes if n.startswith("terrain served: ")]
        assert len(loaded) == 1 and ": 0 blocks pending, " in loaded[0], notes  # its TERRAIN_REPORT, before arming
        assert served and "no ground in the DEM" not in served[0], notes
        assert any("set RTL_ALT_TYPE = 1" in n and "set TERRAIN_ENABLE = 1" in n for n in notes), notes
        assert rows[rec.id]["finished"], doc["problems"]
        # The survey legs: from the first terrain-frame waypoint reached to the last.
        survey = [w.seq for w in rec.wire if w.frame in TERRAIN_FRAMES]
        assert len(survey) >= 2, rec.wire
        window = _survey_window(rec.reached, survey[0], survey[-1])
        assert window is not None, rec.reached
        home = read_mission_file(plan_dir / f"uav{rec.id}.plan").mission.home
        assert home is not None
        home_amsl = home[2]  # the DEM's height at the launch point: SITL's --home (sitl_fleet.plan_home)
        samples = np.array([s[:4] for s in rec.samples if window[0] <= s[0] <= window[1]])
        assert len(samples) > 20, len(samples)
        flown_amsl = home_amsl + samples[:, 3]
        wanted_amsl = HILL(samples[:, 1], samples[:, 2]) + planned[rec.id]
        departure = flown_amsl - wanted_amsl
        worst = float(np.abs(departure).max())
        ground = HILL(samples[:, 1], samples[:, 2])
        print(f"uav{rec.id}: {len(samples)} positions on its survey legs, ground {ground.min():.1f}-"
              f"{ground.max():.1f} m, "
              f"planned {planned[rec.id]:g} m above it: flown {departure.mean():+.2f} m on average, worst "
              f"{worst:.2f} m (median |d| {np.median(np.abs(departure)):.2f} m); {loaded[0]}; {served[-1]}")
        assert worst <= HEIGHT_TOLERANCE_M, (rec.id, worst)
    assert doc["photos_from"] == "camera"
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
