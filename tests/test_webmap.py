"""plan.html / flight.html (missionplan/mission/webmap.py): self-contained, safe to inline, drawn right.

The first tests read the written file; the rest open it in headless Chromium (Playwright, Debian's
/usr/bin/chromium) and check what a crew would see: every layer drawn with its class, the legend,
scale, north arrow and pointer position, no errors and no request but the file itself.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import shutil
import tomllib
import zlib
from fnmatch import fnmatch
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from missionplan.mission import webmap
from missionplan.mission.webmap import LEAFLET_VERSION, render_html_map, write_html_map

ROOT = Path(__file__).resolve().parents[1]
MISSION = ROOT / "missionplan" / "mission"
ASSETS = MISSION / "webmap_assets" / "leaflet"
LAT0, LON0 = 45.07, 7.65
COLOURS = {1: "#1f77b4", 2: "#ff7f0e"}
CAUSES = {"clearance band": "closer than --clearance to an obstacle",
          "unknown-height buildings": "cut off only by buildings of unknown height",
          "pocket": "walled in by obstacles"}
TIMEOUT_MS = 20_000  # every browser wait is bounded by this


# ---- a small realistic plan near Turin, built in metres east/north of (LAT0, LON0) --------------

def lonlat(x: float, y: float, alt: float | None = None) -> list[float]:
    point = [LON0 + x / (111_320 * math.cos(math.radians(LAT0))), LAT0 + y / 110_540]
    return point if alt is None else point + [alt]


def ring(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [lonlat(x0, y0), lonlat(x1, y0), lonlat(x1, y1), lonlat(x0, y1), lonlat(x0, y0)]


def feature(geometry_type: str, coordinates: Any, **properties: Any) -> dict:
    return {"type": "Feature", "properties": properties, "geometry": {"type": geometry_type, "coordinates": coordinates}}


def collection(*features: dict) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


BUILDINGS = [(40, 40, 90, 80, 18.0), (120, 30, 170, 90, 31.5), (220, 50, 260, 110, None),
             (300, 40, 360, 70, 12.0), (60, 160, 110, 230, None), (250, 180, 330, 240, 24.0)]
ALTITUDES = {1: 40.0, 2: 45.0}


def lawnmower(uav: int) -> list[tuple[float, float]]:
    x0 = 10 if uav == 1 else 210
    return [(x, y) for k, x in enumerate(range(x0, x0 + 181, 30)) for y in ((10, 290) if k % 2 == 0 else (290, 10))]


def plan_layers() -> dict[str, dict]:
    buildings = [feature("Polygon", [ring(x0, y0, x1, y1)], height_m=h, known_height=h is not None)
                 for x0, y0, x1, y1, h in BUILDINGS]
    band = [[ring(x0 - 6, y0 - 6, x1 + 6, y1 + 6), ring(x0, y0, x1, y1)[::-1]] for x0, y0, x1, y1, _ in BUILDINGS]
    paths, photos = [], []
    for uav, alt in ALTITUDES.items():
        track = lawnmower(uav)
        paths.append(feature("LineString", [lonlat(x, y, alt) for x, y in track], uav=uav, sortie=1, altitude_m=alt,
                             waypoints=len(track), length_m=2140.0, flight_s=431.0, photos=25))
        photos += [feature("Point", lonlat(track[0][0] + 30 * (k // 5), 20 + 60 * (k % 5), alt), uav=uav, index=k)
                   for k in range(25)]
    return {
        "area": collection(feature("Polygon", [ring(0, 0, 400, 300)], name="turin-cenisia-area")),
        "buildings": collection(*buildings),
        "clearance": collection(feature("MultiPolygon", band, clearance_m=6.0)),
        "zones": collection(feature("Polygon", [ring(0, 0, 200, 300)], uav=1, cells=480),
                            feature("Polygon", [ring(200, 0, 400, 300)], uav=2, cells=470)),
        "unreachable": collection(*(feature("MultiPolygon", [[ring(x, 260, x + 10, 270)], [ring(x + 10, 270, x + 20, 280)]],
                                            cause=cause, cells=2, reason=reason)
                                    for x, (cause, reason) in zip((20, 150, 350), CAUSES.items()))),
        "fences": collection(*(feature("Polygon", [ring(x0 - 15, -15, x0 + 215, 315)], uav=uav, max_altitude_m=60.0)
                               for uav, x0 in ((1, 0), (2, 200)))),
        "paths": collection(*paths),
        "photos": collection(*photos),
        "launch": collection(feature("Point", lonlat(5, 5), uav=1, label="UAV 1 launch"),
                             feature("Point", lonlat(395, 5), uav=2, label="UAV 2 launch")),
    }


def flight_layers() -> dict[str, dict]:
    layers = plan_layers()
    flown = [feature("LineString", [lonlat(x + 1.5, y - 1.0, ALTITUDES[uav] + 0.4) for x, y in lawnmower(uav)],
                     uav=uav, flight_s=455.0) for uav in ALTITUDES]
    taken = [feature("Point", f["geometry"]["coordinates"], uav=f["properties"]["uav"], image=f"IMG_{k:04d}.JPG",
                     source="camera") for k, f in enumerate(layers["photos"]["features"][:40])]
    cells = {"covered": collection(feature("MultiPolygon", [[ring(0, 0, 180, 300)], [ring(220, 0, 400, 300)]], cells=900)),
             "missed": collection(feature("MultiPolygon", [[ring(180, 100, 220, 160)]], cells=12, area_m2=2400.0))}
    # The cells under the tracks and photos, the way a crew reads them best (drawing order = this order).
    order = list(layers)
    order[order.index("unreachable") + 1:order.index("unreachable") + 1] = list(cells)
    layers.update(cells, flown=collection(*flown), photos_taken=collection(*taken))
    return {name: layers[name] for name in order + ["flown", "photos_taken"]}


def summary(kind: str = "plan", **extra: Any) -> dict:
    return {"title": "turin-cenisia-area: 2 drones, expert",
            "subtitle": "coverage 100.0 % of 950 reachable targets",
            "kind": kind,
            "drones": [{"uav": uav, "colour": COLOURS[uav],
                        "figures": {"altitude": f"{ALTITUDES[uav]:.0f} m", "flight time": "7 min 11 s", "photos": "25"}}
                       for uav in (1, 2)],
            "figures": {"drones": "2", "photos": "50", "longest flight": "7 min 11 s"},
            "notes": ["6 target cells are unreachable: see the legend"], **extra}


def counts(layers: dict[str, dict]) -> dict[str, int]:
    return {name: len(fc["features"]) for name, fc in layers.items()}


def data_block(text: str) -> Any:
    found = re.search(r'<script type="application/json" id="mp-data">(.*?)</script>', text, re.S)
    assert found, "no data block"
    return json.loads(found.group(1))


# ---- the file itself ------------------------------------------------------------------------------

def test_the_page_is_self_contained(tmp_path):
    out = tmp_path / "plan.html"
    write_html_map(out, plan_layers(), summary())
    text = out.read_text(encoding="utf-8")
    # No script, stylesheet, font or image is loaded from anywhere: everything is inline.
    assert not re.search(r"<script[^>]*\ssrc\s*=", text, re.I)
    assert not re.search(r"<link\b", text, re.I)
    assert not re.search(r"@import|url\(\s*['\"]?(https?:)?//", text, re.I)
    assert not re.search(r"<(img|iframe|object|embed)\b", text, re.I)
    assert text.count("<script") == 3 and "<style>" in text
    assert f"Leaflet {LEAFLET_VERSION}" in text and "BSD 2-Clause License" in text  # the licence travels along
    assert "sourceMappingURL" not in text
    # The page's own script asks nothing of the network.
    for call in ("fetch(", "XMLHttpRequest", "WebSocket", "EventSource", "sendBeacon", "import(", "importScripts"):
        assert call not in webmap.page_script(), call
    # The panel is plain HTML, readable with scripts off.
    assert "turin-cenisia-area: 2 drones, expert" in text and "longest flight" in text and "#ff7f0e" in text


def drone_table(text: str) -> list[list[str]]:
    """The per-drone table's cells, row by row (header row first), as text."""
    table = re.search(r'<section id="mp-drones">.*?</table>', text, re.S).group(0)
    return [[re.sub(r"<[^>]+>", "", cell) for cell in re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", row, re.S)]
            for row in re.findall(r"<tr>(.*?)</tr>", table, re.S)]


@pytest.mark.parametrize("fleet", [2, webmap.DRONE_COLUMNS, webmap.DRONE_COLUMNS + 1, 20])
def test_a_small_fleet_reads_across_and_a_big_one_down_the_panel(tmp_path, fleet):
    drones = [{"uav": uav, "colour": "#1f77b4", "figures": {"flight": f"{100 + uav} s", "photos": str(uav)}}
              for uav in range(1, fleet + 1)]
    out = tmp_path / "plan.html"
    write_html_map(out, plan_layers(), summary(drones=drones))
    rows = drone_table(out.read_text(encoding="utf-8"))
    if fleet <= webmap.DRONE_COLUMNS:  # a column per drone
        assert rows[0] == [""] + [f"UAV {uav}" for uav in range(1, fleet + 1)]
        assert rows[1:] == [["flight"] + [f"{100 + uav} s" for uav in range(1, fleet + 1)],
                            ["photos"] + [str(uav) for uav in range(1, fleet + 1)]]
    else:  # a row per drone: no sideways scrolling for a big fleet
        assert rows[0] == ["", "flight", "photos"]
        assert rows[1:] == [[f"UAV {uav}", f"{100 + uav} s", str(uav)] for uav in range(1, fleet + 1)]


def test_a_script_end_in_a_property_cannot_close_the_data_block(tmp_path):
    evil = "</script><script>window.pwned = 1</script><!--"
    layers = plan_layers()
    layers["area"]["features"][0]["properties"]["name"] = evil
    info = summary(title=f"<b>{evil}</b>", notes=[evil])
    out = tmp_path / "plan.html"
    write_html_map(out, layers, info)
    text = out.read_text(encoding="utf-8")
    assert "window.pwned" in text  # it is there, as data
    assert text.lower().count("</script") == 3  # but closes only the page's three script elements
    assert "<script>window.pwned" not in text and "<b>" not in text
    data = data_block(text)
    assert data["layers"][0] == ["area", layers["area"]] and data["summary"] == info


def test_numpy_values_and_nan_become_plain_json(tmp_path):
    layers = plan_layers()
    props = layers["buildings"]["features"][0]["properties"]
    props.update(height_m=np.float32(18.5), floors=np.int64(6), outline=np.array([1.0, 2.0]), bad=float("nan"))
    layers["buildings"]["features"][1]["properties"]["inf"] = np.float64("inf")
    out = tmp_path / "plan.html"
    write_html_map(out, layers, summary())
    data = dict(data_block(out.read_text(encoding="utf-8"))["layers"])
    first, second = data["buildings"]["features"][0]["properties"], data["buildings"]["features"][1]["properties"]
    assert first["height_m"] == 18.5 and first["floors"] == 6 and first["outline"] == [1.0, 2.0]
    assert first["bad"] is None and second["inf"] is None


def test_layer_order_survives_numeric_names():
    layers = {"zones": collection(), "2": collection(), "area": collection(), "10": collection()}
    data = data_block(render_html_map(layers, summary()))
    assert [name for name, _ in data["layers"]] == ["zones", "2", "area", "10"]


def test_a_failed_write_leaves_the_old_file_and_no_temp_file(tmp_path):
    out = tmp_path / "plan.html"
    out.write_text("old page")
    layers = plan_layers()
    layers["area"]["features"][0]["properties"]["name"] = object()  # cannot be JSON
    with pytest.raises(TypeError):
        write_html_map(out, layers, summary())
    assert out.read_text() == "old page" and os.listdir(tmp_path) == ["plan.html"]
    # Failing at the rename itself (the target is a folder): the temp file written so far is removed.
    folder = tmp_path / "taken"
    folder.mkdir()
    (folder / "keep").write_text("x")
    with pytest.raises(OSError):
        write_html_map(folder, plan_layers(), summary())
    assert sorted(os.listdir(tmp_path)) == ["plan.html", "taken"] and os.listdir(folder) == ["keep"]


@pytest.mark.parametrize("change, match", [
    ({"kind": "report"}, "kind"),
    ({"drones": [{"uav": 1, "colour": "blue", "figures": {}}]}, "colour"),
    ({"drones": [{"uav": 1, "colour": "#12345", "figures": {}}]}, "colour"),
])
def test_a_malformed_summary_is_refused(tmp_path, change, match):
    with pytest.raises(ValueError, match=match):
        write_html_map(tmp_path / "plan.html", plan_layers(), summary(**{**summary(), **change}))
    assert not list(tmp_path.iterdir())


def test_a_basemap_must_be_a_tile_template(tmp_path):
    with pytest.raises(ValueError, match="basemap"):
        write_html_map(tmp_path / "plan.html", plan_layers(), summary(), basemap="https://tile.example/map.png")
    data = data_block(render_html_map(plan_layers(), summary(), "https://tile.openstreetmap.org/{z}/{x}/{y}.png"))
    assert data["basemap"]["host"] == "tile.openstreetmap.org" and "OpenStreetMap" in data["basemap"]["attribution"]


def test_the_vendored_leaflet_is_complete_and_ships_in_the_wheel():
    assert sorted(p.name for p in ASSETS.iterdir()) == ["LICENSE", "README.md", "leaflet.css", "leaflet.js"]
    assert f"Leaflet {LEAFLET_VERSION}," in (ASSETS / "leaflet.js").read_text()[:200]
    assert "BSD 2-Clause License" in (ASSETS / "LICENSE").read_text()
    assert LEAFLET_VERSION in (ASSETS / "README.md").read_text()
    for path in ASSETS.iterdir():
        assert ships(path), f"{path} would not ship"


def test_the_page_style_and_script_are_package_files_that_ship_in_the_wheel():
    files = sorted(p.name for p in (MISSION / "webmap_assets").iterdir() if p.is_file())
    assert files == ["page.css", "page.js"]
    for name in files:
        assert ships(MISSION / "webmap_assets" / name), f"{name} would not ship"
    # What the page inlines is the files' text, read from the package.
    text = render_html_map(plan_layers(), summary())
    assert (MISSION / "webmap_assets" / "page.js").read_text(encoding="utf-8") in text
    assert (MISSION / "webmap_assets" / "page.css").read_text(encoding="utf-8") in text


def ships(path: Path) -> bool:
    """Whether the wheel carries `path` (a file under missionplan/mission/): package data of
    missionplan.mission (a path pattern), or of the folder it sits in, listed as a package itself."""
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    data = setuptools["package-data"]
    folder_package = ".".join(["missionplan", "mission", *path.parent.relative_to(MISSION).parts])
    relative = path.relative_to(MISSION).as_posix()
    return (any(fnmatch(relative, pattern) for pattern in data.get("missionplan.mission", []))
            or folder_package in setuptools["packages"]
            and any(fnmatch(path.name, pattern) for pattern in data.get(folder_package, [])))


# ---- in a browser ---------------------------------------------------------------------------------

def _chromium() -> str | None:
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else shutil.which("chromium")


@pytest.fixture(scope="module")
def browser_context(tmp_path_factory):
    sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed")
    executable = _chromium()
    if executable is None:
        pytest.skip("no Chromium: neither /usr/bin/chromium nor `chromium` on PATH")
    with sync_api.sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")), executable_path=executable, headless=True,
            args=["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"],
            viewport={"width": 1280, "height": 800}, timeout=TIMEOUT_MS)
        context.set_default_timeout(TIMEOUT_MS)
        yield context
        context.close()


class Opened:
    """A page opened on a written map, with everything it logged and requested."""

    def __init__(self, context, path: Path, route=None) -> None:
        self.page = context.new_page()
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda msg: msg.type == "error" and self.errors.append(f"console: {msg.text}"))
        self.page.on("pageerror", lambda err: self.errors.append(f"page: {err}"))
        self.page.on("requestfailed", lambda req: self.errors.append(f"request failed: {req.url}"))
        self.page.on("request", lambda req: self.requests.append(req.url))
        if route:
            self.page.route("**/*", route)
        self.url = path.resolve().as_uri()
        self.page.goto(self.url, timeout=TIMEOUT_MS)
        self.page.wait_for_function("window.mpReady === true || window.mpError !== undefined", timeout=TIMEOUT_MS)
        assert self.page.evaluate("window.mpError === undefined"), self.page.evaluate("window.mpError")

    def count(self, selector: str) -> int:
        return self.page.locator(selector).count()

    def legend(self, layer: str) -> list[str]:
        return self.page.locator(f'#mp-legend li[data-layer="{layer}"]').all_inner_texts()

    def map_pixels(self) -> np.ndarray:
        """The map part of the screen as (H, W, 3) integers 0..255."""
        import matplotlib.image

        png = self.page.locator("#mp-map").screenshot(timeout=TIMEOUT_MS)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
        return np.round(matplotlib.image.imread(io.BytesIO(png), format="png")[..., :3] * 255).astype(int)

    def close(self) -> None:
        self.page.close()


def pixels_near(image: np.ndarray, colour: str, tolerance: int = 10) -> int:
    rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(image - rgb).max(axis=-1) <= tolerance).sum())


def distinct_colours(image: np.ndarray) -> int:
    return len(np.unique(image.reshape(-1, 3), axis=0))


def test_the_plan_page_draws_every_layer_in_the_browser(browser_context, tmp_path):
    layers = plan_layers()
    out = tmp_path / "plan.html"
    write_html_map(out, layers, summary())
    view = Opened(browser_context, out)
    try:
        page = view.page
        # One SVG path (or launch icon) per feature, found by its layer's class.
        for name, n in counts(layers).items():
            assert view.count(f".mp-layer-{name}") == n, name
        assert page.evaluate("window.mpDrawn") == counts(layers)
        unknown = sum(h is None for *_, h in BUILDINGS)
        assert view.count('path.mp-layer-buildings[fill="url(#mp-hatch-unknown)"]') == unknown
        assert view.count("path.mp-layer-paths[stroke='#1f77b4']") == 1
        assert view.count("path.mp-layer-fences[stroke-dasharray]") == 2
        assert view.count("img.leaflet-marker-icon, .leaflet-marker-shadow") == 0  # no image markers
        # Legend: every cause with its reason, each drone's path with its altitude, both kinds of building.
        causes = page.locator('#mp-legend li[data-layer="unreachable"]')
        assert sorted(causes.evaluate_all("rows => rows.map(r => r.dataset.cause)")) == sorted(CAUSES)
        for cause, reason in CAUSES.items():
            text = page.locator(f'#mp-legend li[data-cause="{cause}"]').inner_text()
            assert cause in text and reason in text and "2 cells" in text
        assert [t.split("\n")[0] for t in view.legend("paths")] == ["UAV 1 waypoint path at 40 m",
                                                                     "UAV 2 waypoint path at 45 m"]
        assert len(view.legend("buildings")) == 2 and "12 m to 31.5 m" in view.legend("buildings")[0]
        for name in layers:
            assert view.legend(name), f"no legend row for {name}"
        # Panel, controls.
        assert page.locator("#mp-title").inner_text() == "turin-cenisia-area: 2 drones, expert"
        assert view.count("#mp-drones th[data-uav]") == 2 and view.count("#mp-notes li") == 1
        assert view.count(".leaflet-control-scale-line") == 1
        assert re.fullmatch(r"\d+ k?m", page.locator(".leaflet-control-scale-line").inner_text())
        assert page.locator("#mp-north").is_visible() and "N" in page.locator("#mp-north").inner_text()
        assert view.count(".leaflet-control-layers-overlays input") == len(layers)
        assert view.count(".leaflet-tile") == 0  # no background unless asked for
        # The whole area is in view and fills most of it; the pointer position reads in lat/lon.
        south, west, north, east = page.evaluate(
            "(() => { const b = window.mpMap.getBounds(); return [b.getSouth(), b.getWest(), b.getNorth(), b.getEast()]; })()")
        (lon0, lat0), (lon1, lat1) = lonlat(0, 0), lonlat(400, 300)
        assert south < lat0 < lat1 < north and west < lon0 < lon1 < east
        assert (lat1 - lat0) / (north - south) > 0.6 or (lon1 - lon0) / (east - west) > 0.6
        box = page.locator("#mp-map").bounding_box()
        page.mouse.move(box["x"] + 300, box["y"] + 200)
        page.wait_for_function("document.getElementById('mp-mouse').textContent.startsWith('lat 45.07')",
                               timeout=TIMEOUT_MS)
        lat, lon = map(float, re.findall(r"-?\d+\.\d+", page.locator("#mp-mouse").inner_text()))
        expected = page.evaluate("window.mpMap.containerPointToLatLng([300, 200])")
        assert abs(lat - expected["lat"]) < 2e-6 and abs(lon - expected["lng"]) < 2e-6
        assert lat0 < lat < lat1 and lon0 < lon < lon1
        # A path's popup says what the drone flies.
        page.evaluate("window.mpLayers.paths.getLayers()[1].openPopup()")
        popup = page.locator(".leaflet-popup-content").inner_text()
        assert "UAV 2" in popup and "45 m above home" in popup and "2.14 km" in popup and "7 min 11 s" in popup
        # The screen: many colours, each drone's exact colour on its path and launch mark.
        pixels = view.map_pixels()
        assert distinct_colours(pixels) > 200
        for colour in COLOURS.values():
            assert pixels_near(pixels, colour) > 100, colour
        # Switching a layer off in the layer control removes its paths.
        page.locator(".leaflet-control-layers-overlays label", has_text="Buildings").locator("input").uncheck()
        assert view.count(".mp-layer-buildings") == 0
        assert view.errors == []
        assert set(view.requests) == {view.url}  # the file itself, nothing else (not even Leaflet's images)
    finally:
        view.close()


def test_the_flight_page_draws_what_was_flown_missed_and_covered(browser_context, tmp_path):
    layers = flight_layers()
    out = tmp_path / "flight.html"
    write_html_map(out, layers, summary("flight", subtitle="coverage 98.7 % of 950 reachable targets"))
    view = Opened(browser_context, out)
    try:
        for name, n in counts(layers).items():
            assert view.count(f".mp-layer-{name}") == n, name
        assert "12 cells" in view.legend("missed")[0] and "2400 m²" in view.legend("missed")[0]
        assert "900" in view.legend("covered")[0]
        assert [t for t in view.legend("flown")] == ["UAV 1 flown track", "UAV 2 flown track"]
        assert all("as planned" in t for t in view.legend("paths"))  # the plan is the faint band under the track
        view.page.evaluate("window.mpLayers.photos_taken.getLayers()[3].openPopup()")
        assert "IMG_0003.JPG" in view.page.locator(".leaflet-popup-content").inner_text()
        pixels = view.map_pixels()
        red = (pixels[..., 0] - pixels[..., 1] > 80) & (pixels[..., 0] - pixels[..., 2] > 80)
        assert red.sum() > 500  # the missed cells
        for colour in COLOURS.values():
            assert pixels_near(pixels, colour) > 100, colour  # the flown tracks, at full colour
        assert view.errors == [] and set(view.requests) == {view.url}
    finally:
        view.close()


def tiny_png() -> bytes:
    """A 4 x 4 pale green PNG: the tile the intercepted tile server answers with."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")
    raw = b"".join(b"\x00" + bytes([200, 230, 200]) * 4 for _ in range(4))  # filter byte + 4 RGB pixels a row
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", (4).to_bytes(4, "big") * 2 + b"\x08\x02\x00\x00\x00")
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def test_a_basemap_loads_tiles_from_its_server(browser_context, tmp_path):
    """Tiles come from the URL template; here every request is intercepted, none reaches a network."""
    tile, tiles, elsewhere = tiny_png(), [], []

    def route(request_route) -> None:
        url = request_route.request.url
        if url.startswith("https://tiles.example.test/"):
            tiles.append(url)
            request_route.fulfill(status=200, content_type="image/png", body=tile)
        elif url.startswith("file://"):
            request_route.continue_()
        else:
            elsewhere.append(url)
            request_route.abort()

    out = tmp_path / "plan.html"
    write_html_map(out, plan_layers(), summary(), basemap="https://tiles.example.test/{z}/{x}/{y}.png")
    view = Opened(browser_context, out, route=route)
    try:
        view.page.wait_for_function("document.querySelectorAll('img.leaflet-tile-loaded').length > 0",
                                    timeout=TIMEOUT_MS)
        assert tiles and all(re.fullmatch(r"https://tiles\.example\.test/\d+/\d+/\d+\.png", u) for u in tiles)
        assert elsewhere == []
        assert "tiles.example.test" in view.page.locator(".leaflet-control-attribution").inner_text()
        assert "tiles.example.test" in view.legend("basemap")[0]
        assert view.count(".mp-layer-paths") == 2 and view.errors == []
    finally:
        view.close()


def test_ten_thousand_photos_draw_on_a_canvas(browser_context, tmp_path):
    layers = plan_layers()
    layers["photos"] = collection(*(feature("Point", lonlat(2 + (k % 100) * 4, 2 + (k // 100) * 3, 40.0),
                                            uav=1 + k % 2, index=k) for k in range(10_000)))
    out = tmp_path / "plan.html"
    write_html_map(out, layers, summary())
    view = Opened(browser_context, out)
    try:
        assert view.page.evaluate("window.mpDrawn.photos") == 10_000
        assert view.page.evaluate("window.mpRenderer.photos") == "canvas"
        assert view.count(".mp-layer-photos") == 0 and view.count(".leaflet-overlay-pane canvas") == 1
        assert view.count(".mp-layer-paths") == 2  # the rest stays SVG
        assert "(10000)" in view.legend("photos")[0]
        assert view.errors == []
    finally:
        view.close()


def test_unknown_empty_and_missing_layers_still_draw(browser_context, tmp_path):
    layers = {"buildings": collection(),  # empty
              "obstacles_extra": collection(feature("Polygon", [ring(0, 0, 50, 50)], kind="crane", note="<i>x</i>"),
                                            feature("Point", lonlat(80, 80), kind="mast")),
              "paths": plan_layers()["paths"],  # no area: the view fits what there is
              "odd name <b>": collection(feature("LineString", [lonlat(0, 0), lonlat(30, 30)]))}
    out = tmp_path / "plan.html"
    write_html_map(out, layers, {"title": "bare", "kind": "plan"})
    view = Opened(browser_context, out)
    try:
        assert view.count(".mp-layer-obstacles_extra") == 2 and view.count(".mp-layer-paths") == 2
        assert view.legend("obstacles_extra") == ["obstacles_extra (2 features)"]
        assert view.legend("buildings") == []
        assert view.count(".mp-layer-odd_name__b_") == 1  # one class name, whatever the layer's name
        assert "odd name <b> (1)" in view.page.locator(".leaflet-control-layers-overlays").inner_text()
        view.page.evaluate("window.mpLayers.obstacles_extra.getLayers()[0].openPopup()")
        assert "<i>x</i>" in view.page.locator(".leaflet-popup-content").inner_text()  # shown as text
        bounds = view.page.evaluate("(() => { const b = window.mpMap.getBounds(); "
                                    "return [b.getSouth(), b.getWest(), b.getNorth(), b.getEast()]; })()")
        assert bounds[0] < LAT0 < bounds[2] and bounds[1] < LON0 < bounds[3]
        assert view.errors == [] and set(view.requests) == {view.url}
    finally:
        view.close()
