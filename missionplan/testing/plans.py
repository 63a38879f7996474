"""Plans made for a test: a small area given as a GeoJSON ring, planned by the CLI (plan_area); single
mission items on the wire for the mission-protocol sessions (wire_item), the next message a vehicle sends
them (next_message); and how two autopilots' answers are compared (same_answer)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from collections.abc import Callable
from typing import Any

from missionplan.bridge.formats.mission_items import MissionType, WireItem


def plan_area(base: Path, ring: list[list[float]], launches: tuple[str, ...], altitude_m: float = 20.0,
              fov_deg: float = 84.0) -> Path:
    """`missionplan plan --area` of the [lon, lat] ring with one drone per "lat,lon" launch, into base/plan."""
    from missionplan.cli import main

    area = base / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    args = ["plan", "--area", str(area), "--altitude", f"{altitude_m:g}", "--fov", f"{fov_deg:g}",
            "--out", str(base / "plan"), "--quiet"]
    for point in launches:
        args += ["--launch", point]
    assert main(args) == 0
    return base / "plan"


def wire_item(seq: int, frame: int, cmd: int, p1: float = 0.0, p2: float = 0.0, p3: float = 0.0, p4: float = 0.0,
              x: int = 0, y: int = 0, z: float = 0.0, mission_type: int = MissionType.MISSION,
              autocontinue: int = 1) -> WireItem:
    """One item as sent: the mission's seq 0 flagged current, as to_wire does."""
    current = 1 if seq == 0 and mission_type == MissionType.MISSION else 0
    return WireItem(seq, frame, cmd, current, autocontinue, p1, p2, p3, p4, x, y, z, int(mission_type))


def next_message(link: Any, sysid: int, wanted: Callable[[Any], bool], seconds: float = 3.0) -> Any:
    """The next message from vehicle `sysid` that `wanted` accepts, within `seconds` (None: none came)."""
    deadline = time.monotonic() + seconds
    while (msg := link.recv(deadline)) is not None:
        if msg.get_srcSystem() == sysid and wanted(msg):
            return msg
    return None


def same_answer(a: Any, b: Any) -> bool:
    """Two autopilots' answers agree: equal, NaN where the other is NaN, element by element in lists and
    key by key in dicts."""
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same_answer(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_answer(a[k], b[k]) for k in a)
    return a == b
