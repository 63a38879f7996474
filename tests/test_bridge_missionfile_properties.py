"""Property tests of the mission-file readers (.plan, .waypoints, QGroundControl's legacy .mission):
whatever the file holds, the reader either returns a plan or raises BridgeUsageError (one line naming the
file), never anything else; whatever it returns can go on the wire (every item packs into a
MISSION_ITEM_INT for both flavours), so an upload cannot die later of a number the reader let through;
and it is within the limits (missionplan.bridge.limits: item counts, altitudes by frame, angles, speeds,
DO_JUMP targets and loops), so no vehicle is asked to fly what no mission can mean.

Kept small: ~150 examples a test, no deadline (the machine is shared), no example database.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from missionplan.bridge import BridgeUsageError  # noqa: E402
from missionplan.bridge.formats.mission_items import CMD_DO_JUMP, CMD_NAV_LAST, Flavour, to_wire  # noqa: E402
from missionplan.bridge.formats.item_checks import AMSL_FRAMES, PARAM_RANGES, POSITIONAL_COMMANDS  # noqa: E402
from missionplan.bridge.formats.missionfile import PlanFile, read_mission_file  # noqa: E402
from missionplan.bridge.limits import (ALTITUDE_AMSL_M, ALTITUDE_RELATIVE_M, MAVLINK_MAX_ITEMS,  # noqa: E402
                                       MAX_MISSION_ITEMS)

SETTINGS = settings(max_examples=150, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])

numbers = (st.integers(min_value=-(2**70), max_value=2**70)
           | st.floats(allow_nan=True, allow_infinity=True)
           | st.sampled_from([0, 1, 2, 3, 16, 22, 177, 5001, 5100, 45.07, -91.0, 181.0, 1e300]))
scalars = st.none() | st.booleans() | numbers | st.text(max_size=8)
json_values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=5)
                           | st.dictionaries(st.text(max_size=12), inner, max_size=5), max_leaves=25)


def _valid_doc() -> dict[str, Any]:
    item = {"type": "SimpleItem", "command": mavlink.MAV_CMD_NAV_WAYPOINT,
            "frame": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, "doJumpId": 2, "autoContinue": True,
            "params": [0, 2, 0, None, 45.07, 7.68, 30]}
    return {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
            "mission": {"version": 2, "firmwareType": 3, "plannedHomePosition": [45.07, 7.68, 240],
                        "cruiseSpeed": 5, "hoverSpeed": 5,
                        "items": [{"type": "SimpleItem", "command": mavlink.MAV_CMD_NAV_TAKEOFF,
                                   "frame": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, "doJumpId": 1,
                                   "autoContinue": True, "params": [0, 0, 0, None, 45.07, 7.68, 30]}, item,
                                  {"type": "SimpleItem", "command": mavlink.MAV_CMD_DO_JUMP,
                                   "frame": mavlink.MAV_FRAME_MISSION, "doJumpId": 3,
                                   "autoContinue": True, "params": [2, 1, 0, 0, 0, 0, 0]}]},
            "geoFence": {"version": 2, "circles": [{"inclusion": False, "circle": {"center": [45.07, 7.68],
                                                                                     "radius": 20}, "version": 1}],
                         "polygons": [{"inclusion": True, "version": 1,
                                       "polygon": [[45.0, 7.6], [45.1, 7.6], [45.1, 7.7]]}]},
            "rallyPoints": {"version": 2, "points": [[45.05, 7.65, 20]]}}


def _places(node: Any, out: list[tuple[Any, Any]]) -> list[tuple[Any, Any]]:
    """Every (container, key) of a JSON document, depth first."""
    keys = list(node.keys()) if isinstance(node, dict) else list(range(len(node)))
    for key in keys:
        out.append((node, key))
        if isinstance(node[key], (dict, list)):
            _places(node[key], out)
    return out


@st.composite
def mutated_plans(draw: st.DrawFn) -> dict[str, Any]:
    """The valid plan with one or two places (any depth, chosen uniformly) replaced by arbitrary JSON."""
    doc = _valid_doc()
    for _ in range(draw(st.integers(1, 2))):
        container, key = draw(st.sampled_from(_places(doc, [])))
        container[key] = draw(json_values)
    return doc


# Found on earlier versions of the reader (each raised TypeError / ValueError / OverflowError / struct.error,
# or was accepted and failed later on the wire): kept as fixed examples.
REGRESSIONS: list[tuple[tuple[str | int, ...], Any]] = [
    (("geoFence", "polygons"), 5), (("rallyPoints", "points"), 5), (("geoFence", "circles"), True),
    (("mission", "items", 1, "frame"), math.nan), (("mission", "items", 1, "frame"), 300),
    (("mission", "items", 1, "command"), 1e300), (("mission", "items", 1, "params", 0), 10**400),
    (("mission", "items", 2, "params", 0), None), (("mission", "plannedHomePosition", 0), math.nan),
    (("mission", "items", 2, "params", 4), None), (("mission", "items", 1, "params", 4), 500),
    (("mission", "items", 1, "params", 4), math.nan), (("mission",), []), (("geoFence",), 7),
    (("mission", "items", 1, "params", 0), 3.4028235677973366e38),  # beyond float32: found by this test
    (("mission", "items", 1, "params", 6), -1e39), (("mission", "plannedHomePosition", 2), 1e39),
]


def _with(path: tuple[str | int, ...], value: Any) -> dict[str, Any]:
    doc = _valid_doc()
    node: Any = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return doc


def _check_uploadable(plan: PlanFile) -> None:
    """What the reader returned can be turned into wire items and packed for any flavour."""
    packer = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for flavour in (Flavour.ARDUPILOT, Flavour.PX4):
        for part in plan.parts():
            for item in to_wire(part, flavour):
                mavlink.MAVLink_mission_item_int_message(1, 1, **item.fields()).pack(packer)
        for item in plan.mission.items:
            assert all(math.isfinite(v) for v in (item.x, item.y))


def _check_within_limits(plan: PlanFile) -> None:
    """What the reader returned is within bridge.limits: counts, altitudes by frame, the parameters each
    command defines as an angle / speed / time, home's altitude, DO_JUMP targets and no endless jump in place."""
    items = plan.mission.items
    assert len(items) <= MAX_MISSION_ITEMS and len(plan.fence.items) <= MAVLINK_MAX_ITEMS
    assert len(plan.rally.items) <= MAVLINK_MAX_ITEMS
    if plan.mission.home is not None:
        assert ALTITUDE_AMSL_M[0] <= plan.mission.home[2] <= ALTITUDE_AMSL_M[1]
    for item in [*items, *plan.fence.items, *plan.rally.items]:
        if item.command in POSITIONAL_COMMANDS:
            low, high = ALTITUDE_AMSL_M if item.frame in AMSL_FRAMES else ALTITUDE_RELATIVE_M
            assert low <= item.z <= high, item
        for number, _, (low, high), _ in PARAM_RANGES.get(item.command, ()):
            value = item.params[number - 1]
            assert math.isnan(value) or low <= value <= high, item
    for number, item in enumerate(items, start=1):
        if item.command == CMD_DO_JUMP:
            target = round(item.param1)
            assert 1 <= target <= len(items)
            if item.param2 == -1 and target <= number:
                assert any(it.command < CMD_NAV_LAST for it in items[target - 1:number])


def _read(name: str, data: bytes) -> PlanFile | None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(data)
        try:
            plan = read_mission_file(path)
        except BridgeUsageError as err:
            assert "\n" not in str(err) and str(path) in str(err)
            return None
    _check_uploadable(plan)
    _check_within_limits(plan)
    return plan


@SETTINGS
@given(json_values)
def test_any_json_is_a_plan_or_a_usage_error(doc: Any) -> None:
    _read("any.plan", json.dumps(doc).encode())


@settings(SETTINGS, max_examples=300)
@given(mutated_plans())
def test_a_plan_broken_anywhere_is_a_plan_or_a_usage_error(doc: dict[str, Any]) -> None:
    _read("mutated.plan", json.dumps(doc).encode())


def test_known_breakages_are_usage_errors() -> None:
    for path, value in REGRESSIONS:
        _read("known.plan", json.dumps(_with(path, value)).encode())
    _read("deep.plan", b"[" * 100_000 + b"]" * 100_000)


def test_the_unmutated_plan_reads() -> None:
    plan = _read("valid.plan", json.dumps(_valid_doc()).encode())
    assert plan is not None and len(plan.mission.items) == 3 and len(plan.fence.items) == 4


cells = st.sampled_from(["0", "1", "3", "16", "45.07", "7.68", "30", "nan", "inf", "-inf", "1e400", "", "x",
                         "2147483648", "-1", "300", "65536", "91", "0.5"]) | st.text(max_size=6)
rows = st.lists(cells, min_size=10, max_size=13).map("\t".join)


@SETTINGS
@given(st.lists(rows, max_size=6), st.sampled_from(["m.waypoints", "m.waypoints.txt", "m.txt"]))
def test_any_waypoints_text_is_a_mission_or_a_usage_error(lines: list[str], name: str) -> None:
    _read(name, ("QGC WPL 110\n" + "\n".join(lines) + "\n").encode())


@SETTINGS
@given(st.binary(max_size=200), st.sampled_from(["m.plan", "m.waypoints", "m.txt"]))
def test_any_bytes_are_a_mission_or_a_usage_error(data: bytes, name: str) -> None:
    _read(name, data)


# Numbers near and beyond the limits, for the items' params, positions and altitudes.
limit_numbers = st.sampled_from([0, 1, -1, -2, 2, 3, 16, 22, 177, 178, 45.07, 7.68, 30, 82_999, 83_000, 30_000,
                                 30_001, -500, -501, -10_000, -10_001, 360, 361, -361, 65_535, 65_536, 300, 301,
                                 1e9, -1e9, 1e38, -1e38, 32_767, 32_768]) | numbers


@st.composite
def mutated_missions(draw: st.DrawFn) -> dict[str, Any]:
    """A QGroundControl .mission file (version "1.0" or 2) with one or two places replaced: by arbitrary JSON,
    or by a number near a limit."""
    items = [{"type": "missionItem" if version_1 else "SimpleItem", "command": command, "frame": frame,
              "autoContinue": True, **({"id": n} if version_1 else {"doJumpId": n}),
              **({"param1": p[0], "param2": p[1], "param3": p[2], "param4": p[3]} if version_1 else {"params": p}),
              "coordinate": coordinate}
             for version_1 in [draw(st.booleans())]
             for n, (command, frame, p, coordinate) in enumerate([
                 (22, 3, [0, 0, 0, 0], [45.07, 7.68, 30]), (16, 3, [0, 2, 0, 0], [45.0701, 7.68, 30]),
                 (177, 2, [2, 1, 0, 0], [0, 0, 0]), (178, 2, [1, 5, -1, 0], [0, 0, 0])], start=1)]
    doc: dict[str, Any] = ({"version": "1.0", "MAV_AUTOPILOT": 3, "items": items,
                            "plannedHomePosition": {"coordinate": [45.07, 7.68, 240]}}
                           if items[0]["type"] == "missionItem" else
                           {"fileType": "Mission", "version": 2, "firmwareType": 3, "items": items,
                            "plannedHomePosition": [45.07, 7.68, 240]})
    for _ in range(draw(st.integers(1, 2))):
        container, key = draw(st.sampled_from(_places(doc, [])))
        container[key] = draw(limit_numbers if draw(st.booleans()) else json_values)
    return doc


@SETTINGS
@given(mutated_missions())
def test_a_mission_file_broken_anywhere_is_a_mission_or_a_usage_error(doc: dict[str, Any]) -> None:
    _read("broken.mission", json.dumps(doc).encode())


@SETTINGS
@given(mutated_plans(), st.lists(limit_numbers, min_size=1, max_size=3))
def test_a_plan_with_numbers_near_the_limits_is_a_plan_or_a_usage_error(doc: dict[str, Any],
                                                                       values: list[Any]) -> None:
    items = doc.get("mission", {}).get("items") if isinstance(doc.get("mission"), dict) else None
    if isinstance(items, list):
        for index, value in enumerate(values):
            entry = items[index % len(items)] if items else None
            if isinstance(entry, dict) and isinstance(entry.get("params"), list) and entry["params"]:
                entry["params"][index * 3 % len(entry["params"])] = value
    _read("limits.plan", json.dumps(doc).encode())


wp_rows = st.tuples(st.sampled_from([0, 2, 3, 10]), st.sampled_from([16, 22, 177, 178, 19, 20]),
                    st.lists(limit_numbers, min_size=7, max_size=7))


@SETTINGS
@given(st.lists(wp_rows, max_size=6))
def test_waypoints_with_numbers_near_the_limits_are_a_mission_or_a_usage_error(rows: list[Any]) -> None:
    lines = [HOME_ROW] + ["\t".join([str(index), "0", str(frame), str(command)] + [str(v) for v in values] + ["1"])
                          for index, (frame, command, values) in enumerate(rows, start=1)]
    _read("limits.waypoints", ("QGC WPL 110\n" + "\n".join(lines) + "\n").encode())


HOME_ROW = "0\t1\t0\t16\t0\t0\t0\t0\t45.07\t7.68\t240\t1"
