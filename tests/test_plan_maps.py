"""The maps a crew carries away: plan.gpkg / .kmz / .html and tracks.geojson from `plan`, the same for
`fly`, read back with GDAL (pyogrio) and checked against report.json and flight.json."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import shape

from lost_drone import fly_with_a_lost_drone
from test_webmap import Opened, browser_context  # noqa: F401  (the browser fixture, shared)
from missionplan.cli import main
from missionplan.geo.frame import GridFrame
from missionplan.geo.georeference import Georeference
from missionplan.maps.gridmap import GridMap
from missionplan.mission.coverage_check import CLEARANCE_BAND, POCKET, UNKNOWN_HEIGHT, unreachable_causes

pyogrio = pytest.importorskip("pyogrio", reason="pyogrio (GDAL) reads the GeoPackage back: pip install -e '.[test]'")

SHARED = Path(__file__).resolve().parents[2] / "shared" / "maps"
TURIN = ["--area", "examples/turin-cenisia-area.geojson", "--osm", str(SHARED / "turin_cenisia_osm_buildings.geojson"),
         "--launch", "45.069450,7.652588", "--launch", "45.069513,7.657924", "--launch", "45.066065,7.652668",
         "--launch", "45.066127,7.658004", "--altitude", "20", "--fov", "84"]


def _layers(path: Path) -> dict[str, int]:
    return {name: pyogrio.read_info(path, layer=name)["features"] for name, _ in pyogrio.list_layers(path)}


@pytest.fixture(scope="module")
def leonardo_plan(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("maps") / "leo"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(out), "--quiet"]) == 0
    return out, json.loads((out / "report.json").read_text())


def test_plan_writes_the_maps_and_lists_them(leonardo_plan: tuple[Path, dict]) -> None:
    out, report = leonardo_plan
    for name in ("plan.html", "plan.gpkg", "plan.kmz", "tracks.geojson"):
        assert (out / name).stat().st_size > 1000 and name in report["files"]


def test_the_geopackage_holds_each_layer_as_the_report_counts_it(leonardo_plan: tuple[Path, dict]) -> None:
    out, report = leonardo_plan
    counts = _layers(out / "plan.gpkg")
    assert list(counts)[:3] == ["area", "buildings", "clearance"]
    assert counts["zones"] == counts["paths"] == counts["launch"] == counts["fences"] == 3
    assert counts["photos"] == sum(d["photos"] for d in report["drones"])
    assert counts["unreachable"] == 1  # leonardo's 44 unreachable targets are all pockets
    meta, _, geometry, fields = pyogrio.raw.read(out / "plan.gpkg", layer="paths")
    assert meta["crs"] == "EPSG:4326" and meta["geometry_type"] == "LineString Z"
    by_uav = dict(zip(fields[list(meta["fields"]).index("uav")], geometry))
    for drone in report["drones"]:
        line = shapely.from_wkb(by_uav[drone["id"]])
        ups = shapely.get_coordinates(line, include_z=True)[:, 2]
        # up from the launch point to the drone's altitude, and back down at the end (RTL)
        assert ups[0] == 0 and ups[-1] == 0 and ups.max() == pytest.approx(drone["altitude_m"])


def test_tracks_geojson_is_rfc7946_and_splits_back_into_the_layers(leonardo_plan: tuple[Path, dict]) -> None:
    out, _ = leonardo_plan
    features = json.loads((out / "tracks.geojson").read_text())["features"]
    by_layer: dict[str, int] = {}
    for item in features:
        by_layer[item["properties"]["layer"]] = by_layer.get(item["properties"]["layer"], 0) + 1
        geom = shape(item["geometry"])
        for polygon in getattr(geom, "geoms", [geom]):
            if isinstance(polygon, shapely.Polygon):
                assert polygon.exterior.is_ccw and not any(ring.is_ccw for ring in polygon.interiors)
    assert {k: v for k, v in _layers(out / "plan.gpkg").items() if v} == by_layer


def test_the_kmz_opens_in_gdal_with_the_paths_at_their_altitudes(leonardo_plan: tuple[Path, dict]) -> None:
    out, report = leonardo_plan
    assert "LIBKML" in pyogrio.list_drivers()
    names = [name for name, _ in pyogrio.list_layers(out / "plan.kmz")]
    assert {"paths", "photos", "launch", "zones", "fences"} <= set(names)
    _, _, geometry, _ = pyogrio.raw.read(out / "plan.kmz", layer="paths")
    highest = sorted(shapely.get_coordinates(shapely.from_wkb(g), include_z=True)[:, 2].max() for g in geometry)
    assert highest == pytest.approx(sorted(d["altitude_m"] for d in report["drones"]))


def test_an_area_plan_draws_its_buildings_with_heights_and_every_cause(tmp_path: Path) -> None:
    if not (SHARED / "turin_cenisia_osm_buildings.geojson").exists():
        pytest.skip(f"the Turin OSM extract is not in {SHARED}")
    out = tmp_path / "turin"
    assert main(["plan", *TURIN, "--out", str(out), "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    meta, _, _, fields = pyogrio.raw.read(out / "plan.gpkg", layer="buildings")
    names = list(meta["fields"])
    known = fields[names.index("known_height")]
    assert len(known) == 134 and int((~known.astype(bool)).sum()) == 13  # the warning's 13 unknown of 134
    heights = fields[names.index("height_m")]
    assert np.nanmax(heights.astype(float)) > 20  # the tall ones are why the streets are narrow
    meta, _, _, fields = pyogrio.raw.read(out / "plan.gpkg", layer="unreachable")
    cells = dict(zip(fields[list(meta["fields"]).index("cause")], fields[list(meta["fields"]).index("cells")]))
    cover = report["coverage"]
    assert cells == {UNKNOWN_HEIGHT: cover["unreachable_by_unknown_height"], CLEARANCE_BAND: cover["unreachable_by_clearance"],
                     POCKET: report["unreachable"] - cover["unreachable_by_unknown_height"] - cover["unreachable_by_clearance"]}
    assert _layers(out / "plan.gpkg")["clearance"] == 1


def test_unreachable_causes_do_not_overlap_and_name_every_cell() -> None:
    rows = ["##########",
            "#........#",
            "#.####...#",
            "#.#..#...#",
            "#.####...#",
            "#........#",
            "##########"]
    gmap = GridMap.from_rows("pocket", rows, georef=Georeference(GridFrame.at(45.0, 7.0, 1.0, len(rows), len(rows[0]))))
    unreachable = np.zeros(gmap.shape, dtype=bool)
    unreachable[3, 3] = unreachable[3, 4] = True  # the courtyard
    unreachable[1, 1] = True  # a corner in the band of a 0.6 m clearance
    causes = unreachable_causes(gmap, [(5, 7)], unreachable, clearance_m=0.6)
    assert causes[POCKET].sum() == 2 and causes[POCKET][3, 3] and causes[POCKET][3, 4]
    assert causes[CLEARANCE_BAND].sum() == 1 and causes[CLEARANCE_BAND][1, 1]
    assert sum(mask.astype(int) for mask in causes.values()).max() == 1


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Leonardo for 3 drones flown on the mock with drone 2 killed at item 8: cells are missed."""
    root = tmp_path_factory.mktemp("flown") / "day1"
    fly_with_a_lost_drone(root)
    return root


@pytest.mark.flight
def test_fly_writes_the_flights_maps_beside_the_plans(flown: Path) -> None:
    flight = json.loads((flown / "flight.json").read_text())
    counts = _layers(flown / "flight.gpkg")
    assert counts["flown"] == 3 and counts["photos_taken"] == sum(d["photos"] for d in flight["drones"])
    assert counts["paths"] == 3  # the plan's layers come along
    for name, expected in (("missed", len(flight["missed_cells"])), ("covered", flight["covered"])):
        meta, _, _, fields = pyogrio.raw.read(flown / "flight.gpkg", layer=name)
        assert int(fields[list(meta["fields"]).index("cells")][0]) == expected
    # missed.geojson and the GeoPackage's missed layer are the same area
    missed = shape(json.loads((flown / "missed.geojson").read_text())["features"][0]["geometry"])
    _, _, geometry, _ = pyogrio.raw.read(flown / "flight.gpkg", layer="missed")
    assert shapely.from_wkb(geometry[0]).symmetric_difference(missed).area < 1e-12
    _, _, geometry, _ = pyogrio.raw.read(flown / "flight.gpkg", layer="flown")
    assert max(shapely.get_coordinates(shapely.from_wkb(g), include_z=True)[:, 2].max() for g in geometry) > 1.0
    html = (flown / "flight.html").read_text()
    assert '<p class="mp-kind">missionplan flight</p>' in html and '"photos_taken"' in html


@pytest.mark.flight
def test_the_real_plan_and_flight_pages_draw_in_chromium(browser_context, leonardo_plan: tuple[Path, dict],
                                                         flown: Path) -> None:
    """The pages `plan` and `fly` wrote (not a fixture's layers) open with no error and no request but
    themselves, and draw as many elements as their GeoPackages hold features."""
    for folder, name in ((leonardo_plan[0], "plan"), (flown, "flight")):
        view = Opened(browser_context, folder / f"{name}.html")
        try:
            assert view.errors == [] and set(view.requests) == {view.url}
            drawn = {layer: n for layer, n in view.page.evaluate("window.mpDrawn").items() if n}
            in_gpkg = {layer: n for layer, n in _layers(folder / f"{name}.gpkg").items() if n}
            assert drawn == in_gpkg
            assert view.count(".mp-layer-paths") == 3 and view.count(".mp-layer-launch") == 3
            assert len(view.page.locator('#mp-legend li[data-layer="unreachable"]').all_inner_texts()) == 1
        finally:
            view.close()


@pytest.mark.parametrize("url", ["tiles.example/{z}/{x}.png", "file:///tiles/{z}/{x}/{y}.png"])
def test_a_bad_basemap_fails_before_any_folder(tmp_path: Path, url: str, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "never"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--basemap", url, "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"missionplan: --basemap {url}: must be") and not out.exists()


def test_a_basemap_is_kept_for_the_flights_pages(tmp_path: Path) -> None:
    url = "https://tiles.example.org/{z}/{x}/{y}.png"
    out = tmp_path / "tiles"
    assert main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--basemap", url, "--quiet"]) == 0
    assert json.loads((out / "report.json").read_text())["basemap"] == url  # fly's flight.html reads it here
    assert "tiles.example.org" in (out / "plan.html").read_text()
