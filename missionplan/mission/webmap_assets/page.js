(function () {
  "use strict";

  const TAB10 = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                 "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
  const CAUSE_COLOURS = {"clearance band": "#a66d00", "unknown-height buildings": "#6a3d9a", "pocket": "#e7298a"};
  const OTHER_CAUSE = "#525252";
  const MISSED = "#d7191c", COVERED = "#1a9641", CLEARANCE = "#f2b701", GENERIC = "#37474f";
  const LOW = [224, 224, 220], HIGH = [72, 72, 82];    // building shade: lowest .. highest known height
  const CANVAS_ABOVE = 2000;  // point layers bigger than this draw on one canvas: 10k SVG circles pan slowly
  const LABELS = {
    area: "Survey area", buildings: "Buildings", clearance: "Clearance band", zones: "Zones",
    unreachable: "Unreachable cells", fences: "Geofences", paths: "Waypoint paths", photos: "Planned photos",
    launch: "Launch points", flown: "Flown tracks", photos_taken: "Photos taken", missed: "Missed cells",
    covered: "Covered cells"
  };

  function main() {
    const data = JSON.parse(document.getElementById("mp-data").textContent);
    const summary = data.summary || {};
    const layers = data.layers || [];
    const flight = summary.kind === "flight";
    const droneColours = new Map((summary.drones || []).map(d => [String(d.uav), d.colour]));
    const colourOf = uav => droneColours.get(String(uav)) ||
      TAB10[(((Number(uav) || 1) - 1) % TAB10.length + TAB10.length) % TAB10.length];
    const hasFlown = layers.some(([name, fc]) => name === "flown" && featuresOf(fc).length > 0);

    const heights = [];
    for (const [name, fc] of layers) {
      if (name !== "buildings") continue;
      for (const f of featuresOf(fc)) if (knownHeight(f.properties)) heights.push(f.properties.height_m);
    }
    const hMin = heights.length ? Math.min(...heights) : 0, hMax = heights.length ? Math.max(...heights) : 0;
    const heightColour = h => mix(LOW, HIGH, hMax > hMin ? (h - hMin) / (hMax - hMin) : 0.5);

    const map = L.map("mp-map", {zoomSnap: data.basemap ? 1 : 0.25, zoomDelta: 0.5, maxZoom: 22, minZoom: 1});
    const canvas = L.canvas({padding: 0.5});
    const control = L.control.layers(null, null, {collapsed: false, position: "topright"}).addTo(map);

    if (data.basemap) {
      const tiles = L.tileLayer(data.basemap.url, {attribution: data.basemap.attribution,
                                                   maxNativeZoom: 19, maxZoom: 22}).addTo(map);
      control.addOverlay(tiles, "Background tiles (" + esc(data.basemap.host) + ")");
    }

    // Per layer: its style (the className hook included) and, for points, what marker to draw.
    function styleFor(name, big) {
      const className = "mp-layer-" + name.replace(/[^A-Za-z0-9_-]/g, "_");  // one class, whatever the name
      const renderer = big ? canvas : undefined;
      return function (f) {
        const p = (f && f.properties) || {};
        const c = colourOf(p.uav);
        switch (name) {
          case "area":
            return {className, color: "#1b1b1b", weight: 2, fillColor: "#ffffff",
                    fillOpacity: data.basemap ? 0.08 : 0.85, interactive: false};
          case "buildings":
            return knownHeight(p)
              ? {className, color: "#505058", weight: 0.6, fillColor: heightColour(p.height_m), fillOpacity: 1}
              : {className, color: "#6a3d9a", weight: 0.8, fillColor: "url(#mp-hatch-unknown)", fillOpacity: 1};
          case "clearance":
            return {className, stroke: false, fillColor: CLEARANCE, fillOpacity: 0.35, interactive: false};
          case "zones":
            return {className, color: c, weight: 1, opacity: 0.5, fillColor: c, fillOpacity: 0.13, interactive: false};
          case "unreachable": {
            const k = CAUSE_COLOURS[p.cause] || OTHER_CAUSE;
            return {className, color: k, weight: 0.5, fillColor: k, fillOpacity: 0.6};
          }
          case "fences":
            return {className, color: c, weight: 2, dashArray: "9 6", fill: false};
          case "paths":  // in a flight page the plan is the faint band the flown track goes along
            return hasFlown ? {className, color: c, weight: 6, opacity: 0.3, lineJoin: "round"}
                            : {className, color: c, weight: 3, opacity: 1, lineJoin: "round"};
          case "photos":
            return {className, renderer, radius: 2.5, stroke: false, fillColor: c, fillOpacity: 1};
          case "flown":
            return {className, color: c, weight: 2, opacity: 1, lineJoin: "round"};
          case "photos_taken":
            return {className, renderer, radius: 3.5, color: c, weight: 1.5, fillColor: "#ffffff", fillOpacity: 1};
          case "missed":
            return {className, color: MISSED, weight: 0.5, fillColor: MISSED, fillOpacity: 0.55};
          case "covered":
            return {className, stroke: false, fillColor: COVERED, fillOpacity: 0.25, interactive: false};
          default:
            return {className, renderer, radius: 4, color: GENERIC, weight: 1.5, fillColor: "#90a4ae", fillOpacity: 0.3};
        }
      };
    }

    function pointFor(name, style) {
      return function (f, latlng) {
        const p = f.properties || {};
        if (name === "launch") {
          const label = p.label != null ? String(p.label) : "UAV " + p.uav;
          return L.marker(latlng, {icon: launchIcon(colourOf(p.uav), label), title: label,
                                   keyboard: false, zIndexOffset: 1000});
        }
        return L.circleMarker(latlng, style(f));
      };
    }

    function launchIcon(colour, label) {
      const box = document.createElement("div");
      box.appendChild(triangle(colour, 16));
      const text = document.createElement("span");
      text.className = "mp-launch-label";
      text.textContent = label;
      box.appendChild(text);
      return L.divIcon({className: "mp-launch-icon mp-layer-launch", html: box, iconSize: [16, 16],
                        iconAnchor: [8, 9], popupAnchor: [0, -8]});
    }

    const groups = {}, drawn = {}, renderers = {};
    const legendRows = [];
    for (const [name, fc] of layers) {
      const features = featuresOf(fc).filter(f => f && f.geometry);
      drawn[name] = features.length;
      if (!features.length) continue;
      const points = features.filter(f => /Point$/.test(f.geometry.type)).length;
      const big = name !== "launch" && points > CANVAS_ABOVE;
      renderers[name] = big ? "canvas" : "svg";
      const style = styleFor(name, big);
      const interactive = style(features[0]).interactive !== false;
      const group = L.geoJSON({type: "FeatureCollection", features}, {
        style, pointToLayer: pointFor(name, style),
        onEachFeature: (f, layer) => {
          if (!interactive) return;
          layer.bindPopup(() => popup(name, f), {maxWidth: 320});
          if (name === "paths" || name === "flown") layer.bindTooltip(() => pathTip(name, f), {sticky: true});
        }
      }).addTo(map);
      groups[name] = group;
      control.addOverlay(group, esc(LABELS[name] || name) + " (" + features.length + ")");
      legendRows.push(...legend(name, features));
    }
    if (data.basemap) {
      legendRows.push(row("basemap", null, "Background tiles load from " + data.basemap.host +
                          " when this page is opened (network needed); without it the background stays blank."));
    }
    const list = document.querySelector("#mp-legend ul");
    for (const li of legendRows) list.appendChild(li);

    // Fit the area (without one, whatever was drawn), clear of the open layer control on the right.
    let bounds = groups.area && groups.area.getBounds();
    if (!bounds || !bounds.isValid()) bounds = L.featureGroup(Object.values(groups)).getBounds();
    const right = Math.min(control.getContainer().offsetWidth + 24, map.getSize().x / 3);
    if (bounds.isValid()) map.fitBounds(bounds, {paddingTopLeft: [24, 24], paddingBottomRight: [right, 24]});
    else map.setView([0, 0], 2);

    L.control.scale({metric: true, imperial: false, maxWidth: 160, position: "bottomleft"}).addTo(map);
    northArrow().addTo(map);
    mousePosition().addTo(map);

    window.mpMap = map;
    window.mpLayers = groups;
    window.mpDrawn = drawn;
    window.mpRenderer = renderers;
    window.mpReady = true;

    // ---- legend -------------------------------------------------------------------------------
    function legend(name, features) {
      const props = features.map(f => f.properties || {});
      const uavs = [...new Set(props.map(p => p.uav).filter(u => u != null))].sort((a, b) => a - b);
      const n = features.length;
      switch (name) {
        case "area": {
          const names = [...new Set(props.map(p => p.name).filter(Boolean))].join(", ");
          return [row(name, sw.fill("#ffffff", "#1b1b1b"), "Survey area" + (names ? ": " + names : ""))];
        }
        case "buildings": {
          const out = [];
          const unknown = props.filter(p => !knownHeight(p)).length;
          if (n - unknown) {
            out.push(row(name, sw.ramp([mix(LOW, HIGH, 0), mix(LOW, HIGH, 0.5), mix(LOW, HIGH, 1)]),
                         `Buildings (${n - unknown}), darker is taller: ${fmt(hMin)} m to ${fmt(hMax)} m`,
                         {kind: "known"}));
          }
          if (unknown) {
            out.push(row(name, sw.fill("url(#mp-hatch-unknown)", "#6a3d9a"),
                         `Buildings of unknown height (${unknown}), hatched: the plan treats them as obstacles`,
                         {kind: "unknown"}));
          }
          return out;
        }
        case "clearance": {
          const m = [...new Set(props.map(p => p.clearance_m).filter(isNum))];
          return [row(name, sw.fill(CLEARANCE, null, 0.35),
                      "Clearance band" + (m.length ? ` (${m.map(v => fmt(v)).join(", ")} m)` : "") +
                      ": too close to an obstacle to fly")];
        }
        case "zones":
          return [row(name, sw.stripes(uavs.map(colourOf), 0.25), "Zones: each drone's share, tinted in its colour")];
        case "unreachable": {
          const causes = new Map();
          for (const p of props) {
            const key = p.cause != null ? String(p.cause) : "other";
            const c = causes.get(key) || {cells: 0, reason: ""};
            c.cells += isNum(p.cells) ? p.cells : 0;
            c.reason = c.reason || (p.reason ? String(p.reason) : "");
            causes.set(key, c);
          }
          return [...causes].map(([cause, c]) => row(name, sw.fill(CAUSE_COLOURS[cause] || OTHER_CAUSE, null, 0.6),
            `Unreachable, ${cause}: ${c.cells} cell${c.cells === 1 ? "" : "s"}`, {cause}, c.reason));
        }
        case "fences": {
          const ceilings = [...new Set(props.map(p => p.max_altitude_m).filter(isNum))].sort((a, b) => a - b);
          return [row(name, sw.line(uavs.map(colourOf), "5 3", 2),
                      "Geofences, dashed in the drone's colour" +
                      (ceilings.length ? `, ceiling ${ceilings.map(v => fmt(v)).join(" / ")} m` : ""))];
        }
        case "paths":
        case "flown":
          return uavs.map(u => {
            const mine = props.filter(p => p.uav === u);
            if (name === "flown") {
              return row(name, sw.line([colourOf(u)], null, 2), `UAV ${u} flown track`, {uav: u});
            }
            const alts = [...new Set(mine.map(p => p.altitude_m).filter(isNum))].sort((a, b) => a - b);
            return row(name, sw.line([colourOf(u)], null, hasFlown ? 5 : 3, hasFlown ? 0.3 : 1),
                       `UAV ${u} waypoint path` + (alts.length ? ` at ${alts.map(v => fmt(v)).join(" / ")} m` : "") +
                       (mine.length > 1 ? ` (${mine.length} sorties)` : "") + (hasFlown ? ", as planned" : ""),
                       {uav: u});
          });
        case "photos":
          return [row(name, sw.dots(uavs.map(colourOf), false), `Planned photo positions (${n})`)];
        case "photos_taken":
          return [row(name, sw.dots(uavs.map(colourOf), true), `Photos taken (${n}), hollow circles`)];
        case "launch":
          return [row(name, sw.triangle(uavs.length ? colourOf(uavs[0]) : GENERIC), `Launch points (${n})`)];
        case "missed": {
          const cells = sum(props, "cells"), area = sum(props, "area_m2");
          return [row(name, sw.fill(MISSED, null, 0.55),
                      `Missed cells: ${cells} cell${cells === 1 ? "" : "s"}` + (area ? `, ${fmt(area, 0)} m\u00b2` : ""))];
        }
        case "covered":
          return [row(name, sw.fill(COVERED, null, 0.25), `Covered cells: ${sum(props, "cells")}`)];
        default:
          return [row(name, sw.fill("#90a4ae", GENERIC, 0.3), `${name} (${n} feature${n === 1 ? "" : "s"})`)];
      }
    }

    // ---- map controls -------------------------------------------------------------------------
    function northArrow() {
      const Arrow = L.Control.extend({
        options: {position: "topleft"},
        onAdd: function () {
          const div = L.DomUtil.create("div", "mp-north leaflet-control");
          div.id = "mp-north";
          div.title = "North is up";
          div.appendChild(svg("svg", {width: 26, height: 38, viewBox: "0 0 26 38"}, [
            svg("text", {x: 13, y: 11, "text-anchor": "middle", "font-size": 11, "font-weight": 700,
                         "font-family": "sans-serif", fill: "#111"}, [], "N"),
            svg("polygon", {points: "13,13 20,36 13,30", fill: "#111"}),
            svg("polygon", {points: "13,13 6,36 13,30", fill: "#fff", stroke: "#111", "stroke-width": 1})
          ]));
          return div;
        }
      });
      return new Arrow();
    }

    function mousePosition() {
      const Mouse = L.Control.extend({
        options: {position: "bottomright"},
        onAdd: function (m) {
          const div = L.DomUtil.create("div", "mp-mouse leaflet-control");
          div.id = "mp-mouse";
          const idle = "lat, lon: pointer off the map";
          div.textContent = idle;
          m.on("mousemove", e => {
            div.textContent = `lat ${e.latlng.lat.toFixed(6)}, lon ${e.latlng.lng.toFixed(6)}`;
          });
          m.on("mouseout", () => { div.textContent = idle; });
          return div;
        }
      });
      return new Mouse();
    }

    // ---- popups -------------------------------------------------------------------------------
    function popup(name, f) {
      const p = f.properties || {};
      const coords = f.geometry && f.geometry.coordinates;
      const alt = f.geometry.type === "Point" && coords.length > 2 ? coords[2] : null;
      let title = LABELS[name] || name, rows = [], shown = [];
      switch (name) {
        case "buildings":
          title = "Building";
          rows = [["height", knownHeight(p) ? fmt(p.height_m) + " m"
                   : "unknown" + (isNum(p.height_m) ? ` (${fmt(p.height_m)} m assumed)` : "")]];
          shown = ["height_m", "known_height"];
          break;
        case "unreachable":
          title = "Unreachable cells";
          rows = [["cause", p.cause], ["cells", p.cells], ["why", p.reason]];
          shown = ["cause", "cells", "reason"];
          break;
        case "fences":
          title = `Geofence of UAV ${p.uav}`;
          rows = [["ceiling", isNum(p.max_altitude_m) ? fmt(p.max_altitude_m) + " m" : "-"]];
          shown = ["uav", "max_altitude_m"];
          break;
        case "paths":
          title = `UAV ${p.uav}` + (p.sortie != null ? `, sortie ${p.sortie}` : "");
          rows = [["altitude", isNum(p.altitude_m) ? fmt(p.altitude_m) + " m above home" : "-"],
                  ["length", metres(p.length_m)], ["flight time", duration(p.flight_s)],
                  ["waypoints", p.waypoints], ["photos", p.photos]];
          shown = ["uav", "sortie", "altitude_m", "length_m", "flight_s", "waypoints", "photos"];
          break;
        case "photos":
          title = `Photo ${p.index != null ? p.index : ""} of UAV ${p.uav}`;
          rows = [["altitude", alt != null ? fmt(alt) + " m above home" : "-"]];
          shown = ["uav", "index"];
          break;
        case "launch":
          title = p.label != null ? String(p.label) : `Launch of UAV ${p.uav}`;
          rows = [["drone", `UAV ${p.uav}`]];
          shown = ["uav", "label"];
          break;
        case "flown":
          title = `UAV ${p.uav}, flown`;
          rows = [["flight time", duration(p.flight_s)]];
          shown = ["uav", "flight_s"];
          break;
        case "photos_taken":
          title = `Photo ${p.index != null ? p.index + " " : ""}taken by UAV ${p.uav}`;
          rows = [...(p.image != null ? [["image", p.image]] : []), ["source", p.source],
                  ["altitude", alt != null ? fmt(alt) + " m above home" : "-"]];
          shown = ["uav", "index", "image", "source"];
          break;
        case "missed":
          title = "Missed cells";
          rows = [["cells", p.cells], ["area", isNum(p.area_m2) ? fmt(p.area_m2, 0) + " m\u00b2" : "-"]];
          shown = ["cells", "area_m2"];
          break;
      }
      // Whatever else a feature carries is shown too, as it is.
      for (const [k, v] of Object.entries(p)) if (!shown.includes(k)) rows.push([k, v]);
      const box = el("div", "mp-popup");
      box.appendChild(el("strong", null, title));
      const table = el("table");
      for (const [k, v] of rows) {
        const tr = el("tr");
        tr.appendChild(el("th", null, k));
        tr.appendChild(el("td", null, v == null ? "-" : typeof v === "object" ? JSON.stringify(v) : String(v)));
        table.appendChild(tr);
      }
      box.appendChild(table);
      return box;
    }

    function pathTip(name, f) {
      const p = f.properties || {};
      const text = name === "flown" ? `UAV ${p.uav} flown, ${duration(p.flight_s)}`
        : `UAV ${p.uav}` + (p.sortie != null ? `, sortie ${p.sortie}` : "") +
          (isNum(p.altitude_m) ? `, ${fmt(p.altitude_m)} m` : "") +
          (isNum(p.length_m) ? `, ${metres(p.length_m)}` : "") +
          (isNum(p.flight_s) ? `, ${duration(p.flight_s)}` : "") +
          (p.waypoints != null ? `, ${p.waypoints} waypoints` : "");
      return el("span", null, text);
    }
  }

  // ---- helpers (no page state) ------------------------------------------------------------------
  function featuresOf(fc) {
    if (!fc) return [];
    if (fc.type === "FeatureCollection") return fc.features || [];
    return fc.type === "Feature" ? [fc] : [{type: "Feature", properties: {}, geometry: fc}];
  }

  function knownHeight(p) { return !!p && p.known_height !== false && isNum(p.height_m); }
  function isNum(v) { return typeof v === "number" && isFinite(v); }
  function sum(props, key) { return props.reduce((s, p) => s + (isNum(p[key]) ? p[key] : 0), 0); }
  function fmt(v, digits) { return isNum(v) ? v.toFixed(digits == null ? (Number.isInteger(v) ? 0 : 1) : digits) : "-"; }
  function metres(m) { return !isNum(m) ? "-" : m >= 1000 ? (m / 1000).toFixed(2) + " km" : m.toFixed(0) + " m"; }
  function duration(s) {
    if (!isNum(s)) return "-";
    s = Math.round(s);
    const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
    return h ? `${h} h ${m} min` : m ? `${m} min ${r} s` : `${r} s`;
  }
  function mix(a, b, t) {
    t = Math.max(0, Math.min(1, t));
    return "#" + a.map((v, i) => Math.round(v + (b[i] - v) * t).toString(16).padStart(2, "0")).join("");
  }
  function esc(s) {
    return String(s).replace(/[&<>"']/g, c => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;"})[c]);
  }
  function el(tag, className, text) {
    const e = document.createElement(tag);
    if (className) e.className = className;
    if (text != null) e.textContent = text;
    return e;
  }
  function svg(tag, attrs, children, text) {
    const e = document.createElementNS("http://www.w3.org/2000/svg", tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    for (const c of children || []) e.appendChild(c);
    if (text != null) e.textContent = text;
    return e;
  }
  function triangle(colour, size) {
    return svg("svg", {width: size, height: size, viewBox: "0 0 16 16"},
               [svg("polygon", {points: "8,1 15,15 1,15", fill: colour, stroke: "#111", "stroke-width": 1.5})]);
  }

  // One legend row: a swatch, its text, and data-* attributes to find it by.
  function row(layer, swatch, text, attrs, reason) {
    const li = el("li");
    li.dataset.layer = layer;
    for (const [k, v] of Object.entries(attrs || {})) li.dataset[k] = v;
    li.appendChild(swatch || svg("svg", {width: 30, height: 16}));
    const span = el("span", null, text);
    if (reason) span.appendChild(el("span", "mp-reason", reason));
    li.appendChild(span);
    return li;
  }

  // Legend swatches, 30 x 16, drawn like the map draws the layer.
  const box = children => svg("svg", {width: 30, height: 16, viewBox: "0 0 30 16"}, children);
  const sw = {
    fill: (fill, stroke, opacity) => box([svg("rect", {x: 1, y: 1, width: 28, height: 14, fill,
      "fill-opacity": opacity == null ? 1 : opacity, stroke: stroke || fill, "stroke-width": stroke ? 1.5 : 1})]),
    ramp: colours => box(colours.map((c, i) => svg("rect", {x: 1 + i * 28 / colours.length, y: 1,
      width: 28 / colours.length, height: 14, fill: c}))),
    stripes: (colours, opacity) => box((colours.length ? colours : [GENERIC]).map((c, i, all) =>
      svg("rect", {x: 1 + i * 28 / all.length, y: 1, width: 28 / all.length, height: 14, fill: c,
                   "fill-opacity": opacity, stroke: c, "stroke-opacity": 0.5}))),
    line: (colours, dash, width, opacity) => box((colours.length ? colours : [GENERIC]).map((c, i, all) =>
      svg("line", {x1: 1, x2: 29, y1: 8 + (i - (all.length - 1) / 2) * Math.min(4, 12 / all.length),
                   y2: 8 + (i - (all.length - 1) / 2) * Math.min(4, 12 / all.length), stroke: c,
                   "stroke-width": width || 3, "stroke-opacity": opacity == null ? 1 : opacity,
                   "stroke-dasharray": dash || "none"}))),
    dots: (colours, hollow) => box((colours.length ? colours : [GENERIC]).slice(0, 5).map((c, i, all) =>
      svg("circle", {cx: 15 + (i - (all.length - 1) / 2) * 6, cy: 8, r: hollow ? 3 : 2.5,
                     fill: hollow ? "#fff" : c, stroke: hollow ? c : "none", "stroke-width": 1.5}))),
    triangle: colour => box([svg("polygon", {points: "15,1 22,15 8,15", fill: colour, stroke: "#111",
                                             "stroke-width": 1.5})])
  };

  // Last, once every constant above is set.
  try {
    main();
  } catch (err) {
    window.mpError = String((err && err.stack) || err);
    throw err;  // still reported to the console as a page error
  }
})();
