"""The judge over a plan made with `plan --dem`: every sample of each drone's survey measured above the plan's
ground (flight.json's `above_ground`), a drone that left the tolerance named in one problem line, and the
photos' geotags carrying their height above the ground and the ground under them; a plan taken as flat is
judged and geotagged as before. The records are synthetic: tracks along the plans' own missions, at the
height a vehicle following the terrain would report above its home."""

from __future__ import annotations

import csv
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rasterio", reason="plan --dem reads DEMs with rasterio: pip install -e '.[terrain]'")

from missionplan.bridge.formats.mission_items import (CMD_NAV_TAKEOFF, CMD_NAV_WAYPOINT, Flavour,  # noqa: E402
                                                       to_wire)
from missionplan.bridge.formats.missionfile import read_mission_file  # noqa: E402
from missionplan.cli.app import main  # noqa: E402
from missionplan.flight.flight_plot import flight_figure  # noqa: E402
from missionplan.flight.flight_report import judge  # noqa: E402
from missionplan.flight.geotag import CSV_COLUMNS  # noqa: E402
from missionplan.flight.plan_report import planned_grid  # noqa: E402
from missionplan.flight.record import DroneRecord  # noqa: E402
from missionplan.geo.dem import read_ground  # noqa: E402
from missionplan.maps.catalog import load_shipped  # noqa: E402
from missionplan.mission.georef import shipped_frame  # noqa: E402
from missionplan.mission.plan_record import PlanRecord, read_plan_record  # noqa: E402
from missionplan.mission.terrain_legs import sample_legs  # noqa: E402
from missionplan.testing.dem_files import map_hill, write_geotiff  # noqa: E402

MAP, UAVS = "old-town", 2
PEAK_M, RADIUS_M = 40.0, 120.0
SAG_M = 6.0  # the sagging drone flies this much lower wherever the hill rises SAG_ABOVE_M over its home
SAG_ABOVE_M = 10.0
STEP_M, SPEED = 2.0, 5.0  # a sample every STEP_M along the track, flown at SPEED
PHOTO_EVERY = 5  # samples
GPS_OFFSET_M = 3.5  # the vehicle's own sea-level altitude is off the DEM's by this much: it is kept as reported


def _box() -> tuple[float, float, float, float]:
    return shipped_frame(load_shipped(MAP)).latlon_box()


_ground = map_hill(MAP, PEAK_M, RADIUS_M)


@pytest.fixture(scope="module")
def plans(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same plan over the hill (ArduPilot: terrain-frame waypoints) and taken as flat."""
    box, pad = _box(), 0.05
    dem = write_geotiff(tmp_path_factory.mktemp("dem") / "hill.tif", _ground,
                        (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad), 5.0)
    root = tmp_path_factory.mktemp("plans")
    for name, extra in (("hill", ["--dem", str(dem)]), ("flat", [])):
        assert main(["plan", "--map", MAP, "--uavs", str(UAVS), "--quiet", "--out", str(root / name), *extra]) == 0
    return {"hill": root / "hill", "flat": root / "flat"}


def _folder(plans: dict[str, Path], name: str, tmp_path: Path) -> Path:
    """A fresh copy of a plan folder: the judge writes into it."""
    return Path(shutil.copytree(plans[name], tmp_path / name))


def _flown(folder: Path, record: PlanRecord, sag: dict[int, float] | None = None) -> list[DroneRecord]:
    """One record per drone: its climb at the launch point, its survey along the uploaded mission at the planned
    height above the ground (less `sag[id]` where the hill rises SAG_ABOVE_M over its home), photos every
    PHOTO_EVERY samples, and its way down after the last waypoint."""
    terrain = record.georeference is not None and record.georeference.terrain is not None
    ground = read_ground([folder / "ground.tif"], _box()) if terrain else None
    records = []
    for drone in record.drones or ():
        mission = read_mission_file(folder / f"uav{drone.id}.plan").mission
        assert mission.home is not None
        wire = to_wire(mission, Flavour.ARDUPILOT)
        takeoff = next(it for it in wire if it.command == CMD_NAV_TAKEOFF)
        waypoints = [it for it in wire if it.command == CMD_NAV_WAYPOINT]
        lat = np.array([mission.home[0]] + [w.x / 1e7 for w in waypoints])
        lon = np.array([mission.home[1]] + [w.y / 1e7 for w in waypoints])
        at_lat, at_lon, leg = sample_legs(lat, lon, STEP_M)
        rise = ground.height_amsl(at_lat, at_lon) - mission.home[2] if ground is not None else np.zeros(len(at_lat))
        up = drone.altitude_m + rise - np.where(rise > SAG_ABOVE_M, (sag or {}).get(drone.id, 0.0), 0.0)
        rec = DroneRecord(id=drone.id, wire=wire, flavour="ardupilot", uploaded=True, started=True, finished=True)
        t0 = 1000.0
        climb = np.linspace(0.0, drone.altitude_m, 6)[:-1]  # below the planned height, not judged
        times = t0 + np.arange(len(climb) + len(at_lat) + len(climb)) * STEP_M / SPEED
        heights = np.concatenate([climb, up, climb[::-1]])
        lats = np.concatenate([np.full(len(climb), lat[0]), at_lat, np.full(len(climb), lat[-1])])
        lons = np.concatenate([np.full(len(climb), lon[0]), at_lon, np.full(len(climb), lon[-1])])
        for t, a, b, h in zip(times, lats, lons, heights):
            rec.add_sample((float(t), float(a), float(b), float(h), SPEED, float(t - t0), 0.0))
        survey = times[len(climb):len(climb) + len(at_lat)]
        rec.add_reached(float(survey[0]), takeoff.seq)
        for k, w in enumerate(waypoints):  # leg k ends at waypoint k
            rec.add_reached(float(survey[np.flatnonzero(leg == k)[-1]]), w.seq)
        for n, k in enumerate(range(0, len(at_lat), PHOTO_EVERY)):
            rec.add_photo(n, float(survey[k]), float(at_lat[k]), float(at_lon[k]), float(up[k]),
                          amsl=mission.home[2] + float(up[k]) + GPS_OFFSET_M)
        rec.set(captures=len(rec.camera), t_start=t0, t_end=float(times[-1]))
        records.append(rec)
    return records


def _judged(folder: Path, sag: dict[int, float] | None = None) -> tuple[dict, list[DroneRecord]]:
    record = read_plan_record(folder)
    records = _flown(folder, record, sag)
    result = judge(folder, record, records, 1.0, wall_s=60.0, telemetry_hz=2.5, flight=1)
    return json.loads(result.json_path.read_text()), records


def test_drones_that_held_their_height_above_the_hill_pass(plans: dict[str, Path], tmp_path: Path) -> None:
    doc, records = _judged(_folder(plans, "hill", tmp_path))
    assert not [p for p in doc["problems"] if "above the ground" in p]
    assert "height above the ground" in doc["above_ground_rule"]
    for row, rec in zip(doc["drones"], records):
        block = row["above_ground"]
        planned = block["planned_m"]
        assert planned == 10.0 and block["tolerance_m"] == 2.5  # 2 m + the acceptance radius, a quarter of 2 m
        survey = len(rec.samples) - 10  # the climb's and the descent's samples are not judged
        assert block["samples"]["count"] == survey and block["photos"]["count"] == len(rec.camera)
        for stats in (block["samples"], block["photos"]):
            assert [stats[k] for k in ("min", "p5", "median", "p95", "max")] == pytest.approx([planned] * 5, abs=0.01)
        # The home is on the plan's ground at the launch point, where the mission file put it.
        home = read_mission_file(tmp_path / "hill" / f"uav{rec.id}.plan").mission.home
        assert home is not None and block["home_amsl_m"] == pytest.approx(home[2], abs=0.01)


def test_a_drone_that_sagged_over_the_hill_is_named_where_it_flew_lowest(plans: dict[str, Path],
                                                                         tmp_path: Path) -> None:
    doc, _ = _judged(_folder(plans, "hill", tmp_path), sag={2: SAG_M})
    lines = [p for p in doc["problems"] if "above the ground" in p]
    assert len(lines) == 1, doc["problems"]
    found = re.fullmatch(r"uav2 flew (\d+\.\d) m above the ground at (\d+\.\d{5}), (\d+\.\d{5}) "
                         r"\(planned 10 m, tolerance 2\.5 m\)", lines[0])
    assert found, lines[0]
    assert float(found.group(1)) == pytest.approx(10.0 - SAG_M, abs=0.05)
    lat, lon = float(found.group(2)), float(found.group(3))
    box = _box()
    assert box[0] <= lat <= box[2] and box[1] <= lon <= box[3]
    assert _ground(np.array([lat]), np.array([lon]))[0] > SAG_ABOVE_M  # up the hill, where it sagged
    sagged = next(row["above_ground"] for row in doc["drones"] if row["id"] == 2)
    assert sagged["samples"]["min"] == pytest.approx(10.0 - SAG_M, abs=0.01)
    assert sagged["samples"]["max"] == pytest.approx(10.0, abs=0.01)
    assert sagged["photos"]["min"] < 10.0 - 2.5


def test_photos_carry_their_height_above_the_ground_and_the_sea_level_altitude_in_the_dems_datum(
        plans: dict[str, Path], tmp_path: Path) -> None:
    folder = _folder(plans, "hill", tmp_path)
    _, records = _judged(folder, sag={2: SAG_M})
    with (folder / "photos.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    header = (folder / "photos.csv").read_text().splitlines()[0].split(",")
    assert header[header.index("alt_rel_m") + 1:header.index("alt_rel_m") + 3] == ["alt_agl_m", "ground_amsl_m"]
    assert len(rows) == sum(len(rec.camera) for rec in records)
    geo = {line.split()[0]: float(line.split()[3]) for line in (folder / "geo.txt").read_text().splitlines()[1:]}
    features = {f["properties"]["image"]: f["properties"]
                for f in json.loads((folder / "photos.geojson").read_text())["features"]}
    homes: dict[str, list[float]] = {}
    for row in rows:
        agl, ground, rel = float(row["alt_agl_m"]), float(row["ground_amsl_m"]), float(row["alt_rel_m"])
        lat, lon = float(row["lat"]), float(row["lon"])
        assert ground == pytest.approx(_ground(np.array([lat]), np.array([lon]))[0], abs=0.3)  # 5 m pixels
        assert agl == pytest.approx(10.0, abs=0.02) or (row["vehicle"] == "2" and agl == pytest.approx(4.0, abs=0.02))
        # geo.txt: above sea level in the DEM's datum (the ground at home plus the reported height), not the GPS's.
        assert geo[row["image"]] == pytest.approx(agl + ground, abs=0.02)
        assert float(row["alt_amsl_m"]) == pytest.approx(agl + ground + GPS_OFFSET_M, abs=0.02)  # as reported
        homes.setdefault(row["vehicle"], []).append(geo[row["image"]] - rel)  # one home per vehicle
        assert features[row["image"]]["alt_agl_m"] == pytest.approx(agl, abs=0.006)
        assert features[row["image"]]["ground_amsl_m"] == pytest.approx(ground, abs=0.006)
    assert len(homes) == UAVS and all(np.ptp(h) <= 0.021 for h in homes.values())  # each rounded to 0.01


def test_a_plan_taken_as_flat_is_judged_and_geotagged_as_before(plans: dict[str, Path], tmp_path: Path) -> None:
    folder = _folder(plans, "flat", tmp_path)
    doc, _ = _judged(folder)
    assert "above_ground_rule" not in doc and all("above_ground" not in row for row in doc["drones"])
    assert (folder / "photos.csv").read_text().splitlines()[0] == ",".join(CSV_COLUMNS)
    feature = json.loads((folder / "photos.geojson").read_text())["features"][0]["properties"]
    assert "alt_agl_m" not in feature and "ground_amsl_m" not in feature


def test_a_plan_folder_without_its_ground_is_a_problem_not_a_crash(plans: dict[str, Path], tmp_path: Path) -> None:
    folder = _folder(plans, "hill", tmp_path)
    record = read_plan_record(folder)
    records = _flown(folder, record)
    (folder / "ground.tif").unlink()
    result = judge(folder, record, records, 1.0, wall_s=60.0, telemetry_hz=2.5)
    lines = [p for p in result.problems if p.startswith("heights above the ground not judged: ")]
    assert len(lines) == 1 and "ground.tif" in lines[0] and "\n" not in lines[0]
    assert all("above_ground" not in row for row in result.doc["drones"])


def test_flight_png_draws_the_heights_above_the_ground_only_for_a_plan_over_a_dem(plans: dict[str, Path]) -> None:
    import matplotlib.pyplot as plt

    record = read_plan_record(plans["hill"])
    frame = record.georeference.frame if record.georeference is not None else None
    empty, track = np.zeros((0, 2), dtype=np.int64), {1: np.zeros((2, 2))}
    seconds = np.arange(5.0)
    for heights, panels in ((None, 2), ({1: (seconds, 10.0 - seconds, 10.0, 2.5)}, 3)):
        fig = flight_figure(planned_grid(record), frame, empty, np.zeros(0, dtype=bool), track, {1: 5.0}, 100.0,
                            heights=heights)
        try:
            assert len(fig.axes) == panels
            drawn = [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == "height-uav1"]
            assert len(drawn) == (panels - 2)
        finally:
            plt.close(fig)
