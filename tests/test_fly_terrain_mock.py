"""A fleet flown over a hill on mock autopilots that know the ground: planned with `plan --dem`, the ArduPilot mocks
ask fly for their terrain as ArduCopter does (bridge/sim/mock_terrain.py), fly their terrain-frame waypoints over the
ground they were served and land on the true ground; the judge measures every sample's height above the ground."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("rasterio", reason="plan --dem reads DEMs with rasterio: pip install -e '.[terrain]'")

from missionplan.cli.app import main  # noqa: E402
from missionplan.flight.fly import fly  # noqa: E402
from missionplan.flight.mock_fleet import start_mock_fleet  # noqa: E402
from missionplan.mission.plan_record import read_plan_record  # noqa: E402
from missionplan.testing.dem_files import hill_under_map  # noqa: E402

pytestmark = pytest.mark.flight
# The mocks fly in this process, beside fly, over UDP: at the tail of a loaded full run, 20x with 25 Hz positions
# (1,500 packets a second) lost a vehicle's photos and left another's TERRAIN_SPACING unset. 10x with 10 Hz is
# 300 a second, still over 4,000 samples per drone.
SPEEDUP = 10.0
TELEMETRY_HZ = 10.0


def test_a_mock_fleet_over_a_hill_covers_the_streets_at_its_height_above_the_ground(tmp_path: Path) -> None:
    dem = hill_under_map("old-town", tmp_path / "hill.tif", peak_m=40.0, radius_m=120.0)
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--map", "old-town", "--uavs", "3", "--policy", "nn", "--endurance", "0", "--dem", str(dem),
                 "--out", str(plan_dir), "--quiet"]) == 0
    record = read_plan_record(plan_dir)
    spacing = record.georeference.terrain.spacing_m if record.georeference and record.georeference.terrain else None
    assert spacing is not None and spacing < 100  # the hill needs a finer terrain grid than ArduCopter's default
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    try:
        result = fly(plan_dir, mock.client_url, timeout_s=300.0, progress=False, time_scale=SPEEDUP,
                     telemetry_hz=TELEMETRY_HZ)
        spacings = {k: mock.vehicle(k).params["TERRAIN_SPACING"] for k in (1, 2, 3)}
    finally:
        mock.stop()
    assert spacings == {1: spacing, 2: spacing, 3: spacing}  # the upload set the plan's grid
    assert result.coverage >= 99.0, result.problems
    assert not [p for p in result.problems if "above the ground" in p], result.problems
    for drone, planned in zip(result.doc["drones"], record.drones or ()):
        heights = drone["above_ground"]["samples"]
        assert heights["count"] > 100
        tolerance = drone["above_ground"]["tolerance_m"]
        assert planned.altitude_m - tolerance <= heights["min"] <= heights["max"] <= planned.altitude_m + tolerance
        assert any(note.startswith("terrain loaded after ") for note in drone["notes"])


def test_upload_serves_the_plans_ground_until_the_vehicle_has_it(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """`missionplan upload` of a terrain plan's mission: the terrain parameters and the plan's TERRAIN_SPACING set
    and said, the ground served on the upload's own link until the vehicle reports it loaded, said in a line."""
    dem = hill_under_map("old-town", tmp_path / "hill.tif", peak_m=40.0, radius_m=120.0)
    plan_dir = tmp_path / "plan"
    assert main(["plan", "--map", "old-town", "--uavs", "1", "--dem", str(dem), "--out", str(plan_dir), "--quiet"]) == 0
    spacing = read_plan_record(plan_dir).georeference.terrain.spacing_m  # type: ignore[union-attr]
    capsys.readouterr()
    mock = start_mock_fleet(plan_dir, SPEEDUP)
    try:
        code = main(["upload", str(plan_dir / "uav1.plan"), "--sysid", "1", "--connect", mock.client_url, "--quiet"])
        pending, loaded = mock.vehicle(1).terrain.statistics()
        params = dict(mock.vehicle(1).params)
    finally:
        mock.stop()
    out = capsys.readouterr().out
    assert code == 0 and pending == 0 and loaded > 0
    assert params["TERRAIN_SPACING"] == spacing and params["WPNAV_RFND_USE"] == 0 and params["RTL_ALT_TYPE"] == 1
    assert f"set TERRAIN_SPACING = {spacing} m" in out
    line = next(line for line in out.splitlines() if line.startswith("uav1: terrain loaded after "))
    assert "0 blocks pending" in line
