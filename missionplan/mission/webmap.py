"""plan.html / flight.html: one self-contained page that shows a plan (or a flight) over the real city.

Owns `write_html_map`: the page's HTML, put together from its parts. The page's own style and the
JavaScript that draws it are package files, webmap_assets/page.css and webmap_assets/page.js; they, the
map library (Leaflet 1.9.4, BSD-2-Clause, vendored in webmap_assets/leaflet with its licence) and the
data are inlined, so the file opens in any browser with no network, from a USB stick in the field. Layers
arrive as GeoJSON FeatureCollections (missionplan/mission/layers.py builds them) and are drawn in
the order given; the side panel holds the title, the figures, the per-drone table, the notes and
the legend. No background tiles unless `basemap` names a tile server.

Every drawn SVG path (and launch icon) carries the class `mp-layer-<layer name>`, legend rows carry
`data-layer`, and the page sets `window.mpReady = true` when it has drawn everything, with
`window.mpDrawn` (features drawn per layer) and `window.mpRenderer` ("svg", or "canvas" for a point
layer of more than 2000 features, which then has no DOM paths); tests/test_webmap.py relies on them.
"""

from __future__ import annotations

import html
import json
import math
import os
import re
from collections.abc import Mapping
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from missionplan.base.atomic import write_text_atomic

LEAFLET_VERSION = "1.9.4"
KINDS = ("plan", "flight")
DRONE_COLUMNS = 4  # past this many drones the panel lists one drone per row
_COLOUR = re.compile(r"#[0-9a-fA-F]{6}")


def write_html_map(path: str | os.PathLike[str], layers: dict[str, dict], summary: dict,
                   basemap: str | None = None) -> None:
    """Write the page to `path` atomically (a failed write leaves the old file, and no temp file).

    `layers`: layer name -> GeoJSON FeatureCollection (EPSG:4326), drawn in insertion order; the known
    names get their own style, others a generic one. `summary`: title, subtitle, kind ("plan" or
    "flight"), drones [{uav, colour "#rrggbb", figures}], figures, notes. `basemap`: a tile URL
    template with {z}, {x} and {y} (e.g. "https://tile.openstreetmap.org/{z}/{x}/{y}.png"), drawn
    under the layers; the page then needs the network for its background.
    """
    write_text_atomic(path, render_html_map(layers, summary, basemap))


def render_html_map(layers: dict[str, dict], summary: dict, basemap: str | None = None) -> str:
    """The page's text (write_html_map writes it); raises ValueError/TypeError on a malformed input."""
    if not isinstance(layers, Mapping) or not all(isinstance(fc, Mapping) for fc in layers.values()):
        raise TypeError("layers must map layer names to GeoJSON FeatureCollections (dicts)")
    kind = summary.get("kind", "plan")
    if kind not in KINDS:
        raise ValueError(f"summary kind must be one of {KINDS}, not {kind!r}")
    for drone in summary.get("drones") or []:
        if not _COLOUR.fullmatch(str(drone.get("colour", ""))):
            raise ValueError(f"drone {drone.get('uav')}: colour must be #rrggbb, not {drone.get('colour')!r}")
    # Layers as [name, collection] pairs: a JSON object would put numeric names first. All of it is
    # serialised before write_html_map opens a file, so a bad input fails with nothing written.
    data = {"layers": [[str(name), fc] for name, fc in layers.items()], "summary": summary,
            "basemap": _basemap(basemap) if basemap else None}
    return _page(summary, kind, _script_json(data))


def basemap_problem(url: str) -> str | None:
    """What is wrong with `url` as a tile server's address, or None: an http(s) URL template with
    {z}, {x} and {y}."""
    if not all(part in url for part in ("{z}", "{x}", "{y}")):
        return "must be a tile URL template with {z}, {x} and {y}"
    if urlsplit(url).scheme not in ("http", "https") or not urlsplit(url).hostname:
        return "must be the http:// or https:// address of a tile server"
    return None


def _basemap(url: str) -> dict[str, str]:
    problem = basemap_problem(url)
    if problem is not None:
        raise ValueError(f"basemap {url!r}: {problem}")
    host = urlsplit(url).hostname or url
    if host == "openstreetmap.org" or host.endswith(".openstreetmap.org"):
        # The OSM tile policy asks for this credit, linked to the copyright page.
        attribution = ('&copy; <a href="https://www.openstreetmap.org/copyright">OpenStreetMap</a> '
                       'contributors')
    else:
        attribution = f"Background tiles: {html.escape(host)}"
    return {"url": url, "host": host, "attribution": attribution}


def _plain(value: Any) -> Any:
    """json.dumps fallback for numpy scalars and arrays (the layers are often built with numpy)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _finite(value: Any) -> Any:
    """`value` with NaN and infinities as null: JSON has no such numbers and JSON.parse rejects them."""
    if isinstance(value, Mapping):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, "tolist") or hasattr(value, "item"):
        return _finite(_plain(value))
    return value


def _script_json(data: Any) -> str:
    """JSON to inline in a <script> element: no "<" at all, so no "</script>" or "<!--" in a property
    can end the element or change how the HTML parser reads it (JSON.parse reads \\u003c back as "<")."""
    options: dict[str, Any] = {"ensure_ascii": False, "separators": (",", ":"), "default": _plain}
    try:
        text = json.dumps(data, allow_nan=False, **options)
    except ValueError:  # a NaN or an infinity somewhere: the rare slow path
        text = json.dumps(_finite(data), allow_nan=False, **options)
    # "<" appears only inside JSON strings, where \u003c is the same character. U+2028/9 are escaped
    # too, for any reader that takes the block as JavaScript rather than JSON.
    return text.replace("<", "\\u003c").replace("\u2028", "\\u2028").replace("\u2029", "\\u2029")


def _asset(*path: str) -> str:
    """A file of webmap_assets/, from the installed package (wheel or source tree alike)."""
    folder = resources.files("missionplan.mission").joinpath("webmap_assets")
    return folder.joinpath(*path).read_text(encoding="utf-8")


def _leaflet() -> tuple[str, str, str]:
    """Leaflet's JS and CSS, ready to inline, and its licence text."""
    js = re.sub(r"^//# sourceMappingURL=.*$", "", _asset("leaflet", "leaflet.js"), flags=re.M)  # no map file ships
    css = re.sub(r"/\*# sourceMappingURL=.*?\*/", "", _asset("leaflet", "leaflet.css"))
    if re.search(r"</script|<!--", js, re.I) or re.search(r"</style", css, re.I):
        raise ValueError("the vendored Leaflet cannot be inlined: it would end its own element")
    licence = _asset("leaflet", "LICENSE").replace("--", "- -")  # "--" never ends the comment it goes in
    return js, css, licence


def page_script() -> str:
    """The page's own JavaScript (webmap_assets/page.js: plain ES2017, no modules, no network)."""
    return _asset("page.js")


def page_style() -> str:
    """The page's own CSS (webmap_assets/page.css), after Leaflet's."""
    return _asset("page.css")


def _text(value: Any) -> str:
    return html.escape("" if value is None else str(value))


def _drone_table(drones: list[dict]) -> str:
    """The per-drone figures. Up to DRONE_COLUMNS drones: a column per drone, a row per figure (the
    panel is narrow and figures outnumber drones); more: a row per drone, so a fleet of 20 reads
    down the panel instead of scrolling sideways."""
    labels = list(dict.fromkeys(label for d in drones for label in (d.get("figures") or {})))

    def heading(d: dict, scope: str) -> str:
        return (f'<th scope="{scope}" data-uav="{_text(d.get("uav"))}"><span class="mp-chip" style="background:'
                f'{d["colour"]}"></span>UAV {_text(d.get("uav"))}</th>')

    def value(d: dict, label: str) -> str:
        return f"<td>{_text((d.get('figures') or {}).get(label, '-'))}</td>"

    if len(drones) <= DRONE_COLUMNS:
        head = "".join(heading(d, "col") for d in drones)
        body = "".join(f'<tr><th scope="row">{_text(label)}</th>' + "".join(value(d, label) for d in drones) + "</tr>"
                       for label in labels)
    else:
        head = "".join(f'<th scope="col">{_text(label)}</th>' for label in labels)
        body = "".join("<tr>" + heading(d, "row") + "".join(value(d, label) for label in labels) + "</tr>"
                       for d in drones)
    wide = "" if len(drones) <= DRONE_COLUMNS else " mp-fleet"
    return f'<table class="mp-table{wide}"><thead><tr><th></th>{head}</tr></thead><tbody>{body}</tbody></table>'


def _panel(summary: dict, kind: str) -> str:
    """The side panel's fixed part: title, subtitle, figures, the per-drone table, notes. Written
    here rather than by the script, so a browser with JavaScript off still shows the figures."""
    parts = [f'<p class="mp-kind">missionplan {kind}</p>',
             f'<h1 id="mp-title">{_text(summary.get("title", "missionplan"))}</h1>',
             f'<p id="mp-subtitle">{_text(summary.get("subtitle", ""))}</p>']
    figures = summary.get("figures") or {}
    if figures:
        rows = "".join(f"<tr><th>{_text(k)}</th><td>{_text(v)}</td></tr>" for k, v in figures.items())
        parts.append(f'<section id="mp-figures"><h2>Figures</h2><table class="mp-table">{rows}</table></section>')
    drones = summary.get("drones") or []
    if drones:
        parts.append(f'<section id="mp-drones"><h2>Drones</h2><div class="mp-scroll">{_drone_table(drones)}</div>'
                     "</section>")
    notes = summary.get("notes") or []
    if notes:
        items = "".join(f"<li>{_text(note)}</li>" for note in notes)
        parts.append(f'<section id="mp-notes"><h2>Notes</h2><ul>{items}</ul></section>')
    parts.append('<section id="mp-legend"><h2>Legend</h2><ul></ul></section>')
    parts.append(f'<footer>Drawn with <a href="https://leafletjs.com">Leaflet</a> {LEAFLET_VERSION} '
                 "(BSD-2-Clause), inlined: this file needs no network.</footer>")
    return "\n".join(parts)


def _page(summary: dict, kind: str, data_json: str) -> str:
    js, css, licence = _leaflet()
    return "".join([
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n",
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n',
        '<meta name="generator" content="missionplan">\n',
        f"<title>{_text(summary.get('title', 'missionplan'))}</title>\n",
        f"<!-- Leaflet {LEAFLET_VERSION}, inlined below, is under this licence:\n\n{licence}\n-->\n",
        # The page's own style and script start after a blank line.
        "<style>\n", css, "\n</style>\n<style>\n\n", page_style(), "</style>\n</head>\n<body>\n",
        _SVG_DEFS,
        '<aside id="mp-panel">\n', _panel(summary, kind), "\n</aside>\n",
        '<main id="mp-map"><noscript>The map needs JavaScript; the figures are beside it.</noscript></main>\n',
        '<script type="application/json" id="mp-data">', data_json, "</script>\n",
        "<script>\n", js, "\n</script>\n<script>\n\n", page_script(), "</script>\n</body>\n</html>\n",
    ])


# The hatch of buildings of unknown height: an SVG pattern the map's paths and the legend both use.
# Zero-sized rather than display:none, which would stop some browsers painting the pattern.
_SVG_DEFS = """<svg id="mp-defs" width="0" height="0" aria-hidden="true" style="position:absolute">
<defs><pattern id="mp-hatch-unknown" patternUnits="userSpaceOnUse" width="7" height="7" patternTransform="rotate(45)">
<rect width="7" height="7" fill="#efe7f5"/><rect width="2.5" height="7" fill="#6a3d9a"/></pattern></defs>
</svg>
"""
