"""Coverage honesty (both coverage numbers, unreachable and small-share warnings,
--unknown-building-height) and the plan command's input errors (negative coordinates,
unwritable --out, structurally wrong files).

The real-city cases read ../shared/maps/ (OpenStreetMap data, © OpenStreetMap contributors,
ODbL) and skip when it is absent.
"""

import dataclasses
import json
import os
import stat
import tempfile
from pathlib import Path

import numpy as np
import pytest

from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import Georeference
from missionplan.geo.readers import read_buildings
from missionplan.cli import main
from missionplan.cli.parsing import attach_negative_values
from missionplan.grid.world import reachable_targets
from missionplan.mission.coverage_check import coverage_report
from missionplan.maps.gridmap import GridMap

MAPS = Path(__file__).resolve().parents[1].parent / "shared" / "maps"
VIENNA_PBF = MAPS / "vienna_rabenhof.osm.pbf"
needs_vienna = pytest.mark.skipif(not VIENNA_PBF.is_file(), reason=f"shared OSM data not found at {VIENNA_PBF}")

# The bounding box of the Vienna extract, and launch points found on its 25 m grid: one on a
# street of the big connected part, one in a closed courtyard block (162 targets).
VIENNA_BOX = [[16.39886, 48.19437], [16.40559, 48.19437], [16.40559, 48.19887], [16.39886, 48.19887],
              [16.39886, 48.19437]]
STREET = "48.1981119,16.3998498"
COURTYARD = "48.195117,16.401551"


def _geojson(path, ring):
    path.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    return path


def _plan_area(tmp_path, area, osm, altitude, launches, *extra, out="run"):
    args = ["plan", "--area", str(area), "--altitude", str(altitude), "--fov", "84", "--out", str(tmp_path / out),
            "--quiet", *extra]
    if osm is not None:
        args += ["--osm", str(osm)]
    for point in launches:
        args += ["--launch", point]  # a space, never '=': as a user types it
    return main(args)


def _report(tmp_path, out="run"):
    return json.loads((tmp_path / out / "report.json").read_text())


# ---- coverage numbers and warnings on a hand-made grid ----------------------------------------

def _grid(n=12):
    # An n x n open square with a walled 4 x 4 courtyard in the corner (16 targets no one
    # reaches from outside).
    grid = [list("#" * (n + 2))] + [list("#" + "." * n + "#") for _ in range(n)] + [list("#" * (n + 2))]
    for k in range(n - 4, n + 1):
        grid[k][n - 4] = "#"
        grid[n - 4][k] = "#"
    return GridMap.from_rows("yard", ["".join(row) for row in grid])


def test_both_coverage_numbers_and_the_unreachable_warning():
    gmap = _grid()
    starts = [(1, 1)]
    reachable = int(gmap.target.sum()) - 16  # the 4 x 4 corner behind the wall
    block = coverage_report(gmap, starts, reachable, 16, 100.0, [reachable]).to_json()
    assert block["reachable_pct"] == 100.0 and block["targets_all"] == reachable + 16
    assert block["all_pct"] == pytest.approx(100 * reachable / (reachable + 16), abs=0.01)
    assert block["unreachable_pct"] > 5 and len(block["warnings"]) == 1
    warning = block["warnings"][0]
    assert warning.startswith(f"16 of {reachable + 16} target cells") and "pockets walled in" in warning
    assert block["unreachable_by_unknown_height"] is None  # no buildings: no such claim


def test_no_warning_at_or_under_five_percent():
    gmap = _grid()
    total = int(gmap.target.sum())
    unreachable = int(0.05 * total)  # exactly 5 % or just under: no warning
    block = coverage_report(gmap, [(1, 1)], total - unreachable, unreachable, 100.0, [total - unreachable]).to_json()
    assert block["warnings"] == []


def test_unknown_height_cause_is_counted_from_the_overflown_grid():
    gmap = _grid()
    crossed = GridMap(gmap.name, gmap.obstacle.copy(), gmap.target.copy())
    crossed.obstacle[8, 10] = False  # the wall had a door the unknown building stood in
    block = coverage_report(gmap, [(1, 1)], int(gmap.target.sum()) - 16, 16, 100.0, [1], unknown_buildings=3,
                            total_buildings=10, if_overflown=lambda: crossed).to_json()
    assert block["unreachable_by_unknown_height"] == 16
    assert "16 of them are cut off only by the 3 of 10 buildings of unknown height" in block["warnings"][0]
    assert "--unknown-building-height M" in block["warnings"][0]


def test_clearance_band_is_named_as_its_own_cause():
    # The open square's cells next to the walls (1 m cells, 1.2 m clearance) are the band; 6 of its
    # targets missed plus the 16 walled in: both causes with their counts, not all 22 blamed on pockets.
    gmap = _grid()
    gmap = dataclasses.replace(gmap, georef=Georeference(GridFrame.at(45.0, 7.0, 1.0, *gmap.shape)))  # 1 m cells
    unreachable = ~reachable_targets(gmap, [(1, 1)]) & gmap.target
    unreachable[1, 3:9] = True  # along the top wall: in the band
    count = int(unreachable.sum())
    block = coverage_report(gmap, [(1, 1)], int(gmap.target.sum()) - count, count, 100.0, [1],
                            unreachable_mask=unreachable, clearance_m=1.2).to_json()
    warning = block["warnings"][0]
    assert block["unreachable_by_clearance"] == 6
    assert "6 of them lie within --clearance 1.2 m of an obstacle" in warning
    assert "the other 16 lie in pockets" in warning


def test_a_drone_under_a_fifth_of_the_mean_is_named():
    gmap = _grid()
    starts = [(1, 1), (10, 10)]  # the second inside the courtyard
    block = coverage_report(gmap, starts, int(gmap.target.sum()), 0, 100.0, [200, 16],
                            launch_labels=["45.0,7.0", "45.1,7.1"]).to_json()
    assert [s["uav"] for s in block["small_shares"]] == [2]
    assert block["small_shares"][0]["launch_pocket_targets"] == 16
    assert block["warnings"] == ["uav2 gets 16 target cells, under a fifth of the mean share (108): its launch point "
                                 "45.1,7.1 is in a pocket of 16 target cells walled off from the rest; move it into "
                                 "the open street"]
    balanced = coverage_report(gmap, [(1, 1), (2, 2)], int(gmap.target.sum()), 0, 100.0, [120, 96]).to_json()
    assert balanced["small_shares"] == [] and balanced["warnings"] == []


def test_a_drone_walled_in_alone_is_named_even_with_more_than_a_fifth():
    # A pocket of 16 targets against a mean share of 40: over a fifth, but it flies less than half as
    # long as the others whatever the zones do.
    gmap = _grid()
    starts = [(1, 1), (10, 10), (1, 8)]
    block = coverage_report(gmap, starts, 120, 0, 100.0, [52, 16, 52], launch_labels=["a", "45.1,7.1", "b"]).to_json()
    assert [s["uav"] for s in block["small_shares"]] == [2]
    assert block["warnings"] == ["uav2 gets 16 target cells, less than the mean share (40): its launch point "
                                 "45.1,7.1 is in a pocket of 16 target cells walled off from the rest; move it into "
                                 "the open street"]


def test_shipped_map_report_and_printout_carry_both_numbers(tmp_path, capsys):
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    out, err = capsys.readouterr()
    report = _report(tmp_path)
    cov = report["coverage"]
    assert cov["targets_reachable"] == report["targets"] and cov["unreachable"] == report["unreachable"]
    assert cov["targets_all"] == report["targets"] + report["unreachable"] == 2000
    assert cov["reachable_pct"] == 100.0 and cov["all_pct"] == pytest.approx(100 * report["targets"] / 2000, abs=0.01)
    assert f"coverage all      {cov['all_pct']:.1f}  % of all 2000 targets (44 unreachable)" in out
    assert "warning" not in err  # 2.2 % unreachable, two equal shares


# ---- input errors ----------------------------------------------------------------------------

def test_negative_values_after_a_space_are_values():
    assert attach_negative_values(["--launch", "-33.86,151.21", "--rotation", "-30", "--launch", "45,-7.5"]) == \
        ["--launch=-33.86,151.21", "--rotation=-30", "--launch", "45,-7.5"]
    assert attach_negative_values(["--quiet", "--", "-1,2"]) == ["--quiet", "--", "-1,2"]


def test_southern_hemisphere_launch_with_a_space(tmp_path):
    # Sydney, a 120 m square: the launch latitude is negative and given as a separate argument.
    lat0, lon0 = -33.8610, 151.2100
    d = 0.0012
    ring = [[lon0, lat0], [lon0 + d, lat0], [lon0 + d, lat0 + d], [lon0, lat0 + d], [lon0, lat0]]
    area = _geojson(tmp_path / "sydney.geojson", ring)
    assert _plan_area(tmp_path, area, None, 40, [f"{lat0 + d / 2},{lon0 + d / 2}"]) == 0
    report = _report(tmp_path)
    assert report["metrics"]["coverage"] == 100.0 and float(report["georeference"]["origin_lat"]) < 0


def _unwritable_folder(tmp_path) -> Path:
    if os.geteuid() != 0:
        folder = tmp_path / "locked"
        folder.mkdir()
        folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
        return folder
    # root writes through any mode bits; sysfs refuses new files even to root
    folder = Path("/sys/kernel")
    try:
        fd, probe = tempfile.mkstemp(dir=folder)
    except OSError:
        return folder
    os.close(fd)
    os.unlink(probe)
    pytest.skip("no folder here refuses files to this user")


def test_existing_unwritable_out_is_one_line_exit_2(tmp_path, capsys):
    folder = _unwritable_folder(tmp_path)
    try:
        assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(folder), "--quiet"]) == 2
    finally:
        if folder.is_relative_to(tmp_path):
            folder.chmod(stat.S_IRWXU)
    err = capsys.readouterr().err
    assert err.startswith(f"missionplan: --out {folder}: cannot write files there (") and err.count("\n") == 1


@pytest.mark.parametrize("flag, content, message", [
    ("--area", {"type": "FeatureCollection", "features": 3}, "'features' is not a list"),
    ("--area", {"type": "Polygon", "coordinates": [[[7.65, 45.06], [7.66, 45.06], [7.66, 45.07]]]},
     "outer ring is not closed"),
    ("--obstacles", {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": "x"}]},
     "'geometry' is not an object"),
    ("--osm", {"type": "Feature", "properties": [1], "geometry": None}, "'properties' is not an object"),
])
def test_structurally_wrong_files_through_the_cli(tmp_path, capsys, flag, content, message):
    good = _geojson(tmp_path / "area.geojson", [[7.650, 45.060], [7.652, 45.060], [7.652, 45.062],
                                                 [7.650, 45.062], [7.650, 45.060]])
    bad = tmp_path / "bad.geojson"
    bad.write_text(json.dumps(content))
    args = ["plan", "--area", str(good), "--launch", "45.061,7.651", "--altitude", "40", "--fov", "84",
            "--out", str(tmp_path / "o")]
    if flag == "--area":
        args[2] = str(bad)
    else:
        args += [flag, str(bad)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"missionplan: {bad}") and message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, message", [
    (["--map", "leonardo", "--uavs", "2", "--unknown-building-height", "10"], "is for --area with --osm"),
    (["--area", "A", "--launch", "45.061,7.651", "--altitude", "40", "--fov", "84", "--unknown-building-height", "9"],
     "--unknown-building-height needs --osm"),
    (["--area", "A", "--osm", "A", "--launch", "45.061,7.651", "--altitude", "40", "--fov", "84",
      "--unknown-building-height", "-3"], "--unknown-building-height -3: must be a height in metres"),
    (["--area", "A", "--osm", "A", "--launch", "45.061,7.651", "--altitude", "40", "--fov", "84",
      "--unknown-building-height", "nan"], "must be a height in metres"),
])
def test_unknown_building_height_is_checked(tmp_path, capsys, args, message):
    area = _geojson(tmp_path / "area.geojson", [[7.650, 45.060], [7.652, 45.060], [7.652, 45.062],
                                                 [7.650, 45.062], [7.650, 45.060]])
    args = [str(area) if a == "A" else a for a in args]
    assert main(["plan", *args, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


# ---- real OpenStreetMap data ---------------------------------------------------------------------

@needs_vienna
def test_vienna_pockets_are_reported_and_warned(tmp_path, capsys):
    area = _geojson(tmp_path / "vienna.geojson", VIENNA_BOX)
    # 25 m: buildings of 20 m and more are obstacles; closed blocks hold unreachable courtyards.
    assert _plan_area(tmp_path, area, VIENNA_PBF, 25, [STREET]) == 0  # exit 0: all that is reachable
    cov = _report(tmp_path)["coverage"]
    assert cov["reachable_pct"] == 100.0 and cov["unreachable_pct"] > 5
    assert cov["all_pct"] == pytest.approx(100 - cov["unreachable_pct"], abs=0.01)
    blds = read_buildings(VIENNA_PBF)
    assert cov["unknown_height_buildings"] == sum(b.height_m is None for b in blds) > 0
    assert 0 <= cov["unreachable_by_unknown_height"] < cov["unreachable"]
    err = capsys.readouterr().err.splitlines()
    # first the inputs' line (the extract's broken multipolygons, the buildings without a height), then coverage
    assert err == [f"missionplan: warning: {warning}" for warning in cov["warnings"]] and len(err) == 2
    assert "5 buildings not read: relation 1982408 (broken multipolygon: inner member ways" in err[0]
    assert f"{cov['unknown_height_buildings']} of the 187 buildings in the area have no height" in err[0]
    assert f"{cov['unreachable']} of {cov['targets_all']} target cells" in err[1]
    assert "lie in pockets walled in" in err[1]

    # A second drone launched inside a courtyard: named, with its pocket.
    assert _plan_area(tmp_path, area, VIENNA_PBF, 25, [STREET, COURTYARD], out="two") == 0
    cov = _report(tmp_path, "two")["coverage"]
    assert [s["uav"] for s in cov["small_shares"]] == [2]
    pocket = cov["small_shares"][0]["launch_pocket_targets"]
    assert 0 < pocket < 0.2 * cov["targets_reachable"] / 2
    # its share is the pocket less the pocket's clearance band
    assert 0 < cov["small_shares"][0]["targets"] <= pocket
    assert any(w.startswith("uav2 gets ") and f"in a pocket of {pocket} target cells" in w and COURTYARD in w
               for w in cov["warnings"])


@needs_vienna
def test_city_without_heights_and_unknown_building_height(tmp_path, capsys):
    # The Vienna footprints with every height tag dropped: an "unseen city" with heights on none.
    blds = read_buildings(VIENNA_PBF)
    bare = tmp_path / "footprints.geojson"
    bare.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"building": "yes"}, "geometry": b.geometry.__geo_interface__}
        for b in blds]}))
    area = _geojson(tmp_path / "vienna.geojson", VIENNA_BOX)
    assert _plan_area(tmp_path, area, bare, 40, [STREET]) == 0
    cov = _report(tmp_path)["coverage"]
    assert cov["unknown_height_buildings"] == len(blds)
    assert cov["unreachable_pct"] > 50  # the streets between unknown blocks fall apart into pockets
    # all but a handful (pockets that only the clearance margin closes) are the unknown heights' doing
    assert 0.99 * cov["unreachable"] <= cov["unreachable_by_unknown_height"] <= cov["unreachable"]
    warning = capsys.readouterr().err
    assert f"are cut off only by the {len(blds)} of {len(blds)} buildings of unknown height" in warning
    assert "--unknown-building-height M" in warning

    # Said to be 12 m (4 storeys), they are overflown at 40 m: every target is reachable again.
    assert _plan_area(tmp_path, area, bare, 40, [STREET], "--unknown-building-height", "12", out="low") == 0
    cov = _report(tmp_path, "low")["coverage"]
    assert cov["unreachable"] == 0 and cov["all_pct"] == 100.0 and cov["unknown_building_height_m"] == 12.0
    assert cov["warnings"] == [] and "warning" not in capsys.readouterr().err
    # Said to be 36 m, above the 35 m ceiling (altitude - 5 m margin): obstacles as before.
    assert _plan_area(tmp_path, area, bare, 40, [STREET], "--unknown-building-height", "36", out="tall") == 0
    assert _report(tmp_path, "tall")["coverage"]["unreachable"] == _report(tmp_path)["coverage"]["unreachable"]
    capsys.readouterr()


def test_old_grids_stay_exit_0_with_warnings(tmp_path):
    # Warnings never change the exit code: 0 is "the plan covers what is reachable".
    gmap = _grid(20)
    path = tmp_path / "yard.map"
    from missionplan.maps.gridmap import save_map

    gmap.launch = [(1, 1), (18, 18)]
    save_map(gmap, path)
    assert main(["plan", "--map", str(path), "--uavs", "2", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    cov = _report(tmp_path)["coverage"]
    assert cov["small_shares"] and cov["small_shares"][0]["uav"] == 2
    assert np.isclose(cov["all_pct"], 100.0)


@pytest.mark.parametrize("flag, value, message", [
    ("--rotation", "nan", "--rotation nan: must be a grid angle, from -360 to 360 degrees"),
    ("--rotation", "inf", "--rotation inf: must be a grid angle, from -360 to 360 degrees"),
    ("--speed", "inf", "--speed inf: must be a waypoint speed ArduCopter and PX4 fly, above 0 and at most 20 m/s"),
    ("--altitude-step", "nan", "--altitude-step nan: must be from 0 to 5,000 m"),
    ("--altitude-step", "inf", "--altitude-step inf: must be from 0 to 5,000 m"),
    ("--launch", "nan,7.651", "latitude must be in [-90, 90]"),
])
def test_non_finite_numbers_on_the_command_line(tmp_path, capsys, flag, value, message):
    area = _geojson(tmp_path / "area.geojson", [[7.650, 45.060], [7.652, 45.060], [7.652, 45.062],
                                                 [7.650, 45.062], [7.650, 45.060]])
    args = ["plan", "--area", str(area), "--altitude", "40", "--fov", "84", "--out", str(tmp_path / "o"), "--quiet"]
    args += [flag, value] + ([] if flag == "--launch" else ["--launch", "45.061,7.651"])
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_train_into_an_unwritable_folder_is_one_line_exit_2(tmp_path, capsys):
    folder = _unwritable_folder(tmp_path)
    try:
        assert main(["train", "--out", str(folder / "w.pt"), "--maps", "4", "--quiet"]) == 2
    finally:
        if folder.is_relative_to(tmp_path):
            folder.chmod(stat.S_IRWXU)
    err = capsys.readouterr().err
    assert err.startswith(f"missionplan: --out {folder / 'w.pt'}: cannot write files in {folder} (") and err.count("\n") == 1
