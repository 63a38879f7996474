"""QGroundControl's older JSON layouts, rewritten into the current `.plan` shapes formats.qgc_plan reads.

Owns the two translations QGroundControl itself applies when it loads its own files, and nothing else
(no numbers are checked here: the rewritten shapes go through formats.item_checks like any plan):
- one mission item's parameters, from any of the three layouts QGroundControl reads
  (MissionItem::load with _convertJsonV1ToV2 and _convertJsonV2ToV3):
    current: `params` of 7 values (lat, lon, alt are params 5-7);
    V2 (QGC's SectionTest.plan): `params` of 4 values and `coordinate` [lat, lon, alt];
    V1: `param1`..`param4` keys and `coordinate` [lat, lon, alt] (item type "missionItem");
- a legacy `.mission` file (QGroundControl's format before `.plan`, e.g. its OldFileFormat.mission)
  into the `mission` object of a `.plan` (MissionController::_loadItemsFromJson and
  _loadJsonMissionFileV1 / _loadJsonMissionFileV2):
    version 2: the `.plan` mission object itself, at the top level (no fence, no rally points);
    version "1.0" (or 1): `items` in the V1 item layout, `plannedHomePosition` as an item object,
    `MAV_AUTOPILOT` for the firmware, DO_JUMP targets named by the items' `id`, and `complexItems`
    (surveys whose waypoints QGroundControl generated when it loaded them: refused).
Anything it cannot translate raises BridgeUsageError naming the file, the item and the problem.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import BridgeUsageError

V1_PARAM_KEYS = ("param1", "param2", "param3", "param4")
MISSION_FILE_TYPE = "Mission"  # QGroundControl's fileType for .mission files (absent in version 1 files)


def _kind(value: Any) -> str:
    """What a JSON value is, for a message (never the value itself: it may be a large structure)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true / false"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return "an object"


def _coordinate(entry: dict[str, Any], where: str, path: Path) -> list[Any]:
    """An item's `coordinate`: exactly [lat, lon, alt], as QGroundControl requires of a mission item."""
    value = entry.get("coordinate")
    if not isinstance(value, list) or len(value) != 3:
        raise BridgeUsageError(f"{path}: {where}: coordinate must be [lat, lon, alt], got {_kind(value)}")
    return value


def item_params(entry: dict[str, Any], where: str, path: Path) -> list[Any]:
    """The item's 7 parameters (raw JSON values, null meaning NaN) from whichever layout it uses."""
    if "params" in entry:
        params = entry["params"]
        if "coordinate" in entry:
            # V2: params 1-4, then the coordinate supplies params 5-7 (QGC appends it to the list).
            if not isinstance(params, list) or len(params) != 4:
                raise BridgeUsageError(f"{path}: {where}: params must be a list of 4 numbers beside a coordinate "
                                       f"[lat, lon, alt], got {_kind(params)}")
            return params + _coordinate(entry, where, path)
        if not isinstance(params, list) or len(params) != 7:
            raise BridgeUsageError(f"{path}: {where}: params must be a list of 7 numbers (or of 4 beside a "
                                   f"coordinate [lat, lon, alt]), got {_kind(params)}")
        return params
    if any(key in entry for key in V1_PARAM_KEYS):
        missing = [key for key in V1_PARAM_KEYS if key not in entry]
        if missing:
            raise BridgeUsageError(f"{path}: {where}: a version 1 item needs param1 to param4, "
                                   f"{', '.join(missing)} missing")
        return [entry[key] for key in V1_PARAM_KEYS] + _coordinate(entry, where, path)
    raise BridgeUsageError(f"{path}: {where}: params must be a list of 7 numbers (the item has no params)")


def mission_object(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """The `.plan` mission object a legacy `.mission` document stands for (fileType checked by the caller)."""
    version = doc.get("version")
    # QGroundControl wrote version 1 as the string "1.0" and later versions as integers.
    if version == "1.0" or (type(version) is int and version == 1):
        return _version_1(doc, path)
    if type(version) is int and version == 2:
        if not isinstance(doc.get("items"), list):
            raise BridgeUsageError(f"{path}: the mission file has no items list")
        # Version 2 is the .plan mission object (mission.version 2) at the top level of the file.
        return {key: value for key, value in doc.items() if key not in ("fileType", "groundStation")}
    raise BridgeUsageError(f"{path}: unsupported .mission version {_kind(version)} (QGroundControl wrote "
                           "\"1.0\" and 2)")


def _version_1(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    items = doc.get("items")
    if not isinstance(items, list):
        raise BridgeUsageError(f"{path}: the mission file has no items list")
    complex_items = doc.get("complexItems")
    if isinstance(complex_items, list) and complex_items:
        # Version 1 surveys stored their settings only; QGroundControl generated the waypoints on load.
        raise BridgeUsageError(f"{path}: complexItems item 1 is a QGroundControl survey pattern, whose waypoints "
                               "QGroundControl generates when it loads the file, and this tool does not: open the "
                               "file in QGroundControl and save it as a .plan (the survey then carries its "
                               "waypoints), or upload it with QGroundControl and read it back with "
                               "`missionplan download`")
    converted: list[Any] = []
    for index, entry in enumerate(items):
        if isinstance(entry, dict):
            entry = dict(entry)
            # Version 1 DO_JUMP param1 is the target's sequence number, the item's "id": the .plan
            # layout names targets by doJumpId, so the id becomes one.
            item_id = entry.pop("id", None)
            if item_id is not None and type(item_id) is not int:
                raise BridgeUsageError(f"{path}: mission item {index + 1}: id must be an integer, got {_kind(item_id)}")
            entry["doJumpId"] = item_id
        converted.append(entry)
    mission: dict[str, Any] = {"version": 2, "items": converted}
    home = doc.get("plannedHomePosition")
    if home is not None:
        if not isinstance(home, dict):
            raise BridgeUsageError(f"{path}: plannedHomePosition must be an item with a coordinate "
                                   f"[lat, lon, alt], got {_kind(home)}")
        mission["plannedHomePosition"] = _coordinate(home, "plannedHomePosition", path)
    if "MAV_AUTOPILOT" in doc:
        mission["firmwareType"] = doc["MAV_AUTOPILOT"]
    return mission
