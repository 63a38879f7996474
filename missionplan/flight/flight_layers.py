"""A flight's map layers: the plan's layers (read back from its tracks.geojson) and what was flown.

Added to the plan's (missionplan/mission/layers.py, same conventions): `flown` each vehicle's
recorded track, 3-D (lon, lat, metres above home); `photos_taken` every confirmed photo where the
vehicle reported it; `covered` and `missed` the reachable target cells a confirmed photo did and did
not cover. flight.html, flight.gpkg and flight.kmz are drawn from them (mission/mapfiles.py).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.geo.frame import GridFrame

from ..mission.layers import Layers, cells_geometry, collection, feature, layers_from_geojson, uav_colour
from ..mission.plan_record import PlanRecord


LINES_AND_POINTS = ("fences", "paths", "photos", "launch")


def plan_layers_on_disk(plan_dir: Path) -> Layers:
    """The plan's layers from its tracks.geojson (none when the file is missing or unreadable)."""
    try:
        return layers_from_geojson(json.loads((plan_dir / "tracks.geojson").read_text(encoding="utf-8")))
    except (OSError, ValueError):
        return {}


def flight_layers(plan: Layers, frame: GridFrame, tracks: dict[int, np.ndarray], photos: list[dict[str, Any]],
                  targets: np.ndarray, covered: np.ndarray, flight_s: dict[int, float]) -> Layers:
    """`plan`'s layers and the flight's. tracks: vehicle -> (n, 3) lat, lon, metres above home as
    recorded; photos: the confirmed photos as the ledger keeps them (vehicle, img_idx, lat, lon,
    alt_rel, source); targets (n, 2) cells and `covered` whether a confirmed photo covered each."""
    flown = collection([
        feature("flown", {"type": "LineString", "coordinates": [[round(float(lon), 7), round(float(lat), 7),
                                                                  round(float(up), 2)] for lat, lon, up in track]},
                uav=uid, flight_s=round(float(flight_s.get(uid, 0.0)), 1))
        for uid, track in sorted(tracks.items()) if len(track) >= 2])
    taken = collection([
        feature("photos_taken", {"type": "Point", "coordinates": [round(float(p["lon"]), 7), round(float(p["lat"]), 7),
                                                                   round(float(p.get("alt_rel") or 0.0), 2)]},
                uav=int(p["vehicle"]), index=int(p["img_idx"]), source=str(p.get("source") or ""))
        for p in photos])
    cells: Layers = {}
    mask = np.zeros((frame.rows, frame.cols), dtype=bool)
    for name, which in (("covered", targets[covered]), ("missed", targets[~covered])):
        mask[:] = False
        mask[which[:, 0], which[:, 1]] = True
        cells[name] = collection([feature(name, cells_geometry(frame, mask), cells=int(len(which)),
                                          area_m2=round(float(len(which)) * frame.cell_m ** 2, 1))]
                                 if len(which) else [])
    # Cells under lines and points: covered / missed go in after the plan's area layers.
    layers: Layers = {}
    for name, layer in plan.items():
        if name in LINES_AND_POINTS:
            layers.update(cells)
        layers[name] = layer
    layers.update(cells)  # a plan of area layers only: at the end (re-inserting keeps the first place)
    layers["flown"] = flown
    layers["photos_taken"] = taken
    return layers


def flight_summary(record: PlanRecord, doc: dict[str, Any], layers: Layers) -> dict[str, Any]:
    """flight.html's side panel: what flight.json says, per drone and in all."""
    drones = []
    for k, row in enumerate(doc["drones"]):
        drones.append({"uav": row["id"], "colour": uav_colour(k), "figures": {
            "flight": f"{row['flight_s']:.0f} s (planned {row['planned_flight_s']:.0f} s)",
            "photos": f"{row['photos']} of {row['planned_photos']} planned" if row.get("planned_photos") is not None
            else str(row["photos"]),
            "finished": "yes" if row["finished"] else "no"}})
    sep = doc.get("min_separation_m") or {}
    figures = {"coverage": f"{doc['coverage']:.2f} % of {doc['targets']} target cells",
               "photos from": str(doc.get("photos_from"))}
    if sep.get("3d") is not None:
        figures["closest approach"] = f"{sep['3d']} m (promised {sep.get('planned_3d')} m)"
    if record.credit:
        figures["map data"] = record.credit
    if doc.get("survey"):
        figures["survey"] = f"{doc['survey']['coverage']:.2f} % over {doc['survey']['flights']} flights"
    return {"kind": "flight", "title": f"flight of {record.map}: {len(drones)} drones",
            "subtitle": f"coverage {doc['coverage']:.2f} % (green photographed, red missed)",
            "drones": drones, "figures": figures, "notes": list(doc.get("problems") or []),
            "layers": {name: len(layer["features"]) for name, layer in layers.items()}}
