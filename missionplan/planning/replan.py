"""Who flies a re-plan, and with which settings: what `missionplan replan DIR --out NEW` (missionplan/cli/survey.py)
plans from, which is only what the survey ledger says is still missing.

The survey DIR belongs to (its root plan, flight/ledger.py) keeps its grid and georeference: NEW's
grid is the root's with only the missing target cells left as targets, so a cell is the same ground
in both folders and NEW's flights add to the root's ledger (NEW/report.json `survey` points back).
The planning is `plan`'s own (plan_folder.write_plan_folder: clearance band, separation layers, geofences,
endurance sorties, the autopilot's flavour), with the settings the root plan recorded
(report.json `settings`: stored_settings).

Who flies it is said, never assumed: `--drones 2,3` (the survey's drones 2 and 3, from their launch
points, as system ids 2 and 3: launch_of_drones), or `--launch LAT,LON` once per drone with `--sysid K=ID`
for each (drone K of the new plan is the vehicle with system id ID: launch_at). The files are named by
system id (uav2.plan for the vehicle with id 2), which is how `fly` matches them to vehicles. The errors
name each setting by what it means (missionplan.base.naming); the command line spells it as its option.

NEW is written as `plan` writes its --out (write_plan_folder: held by this run alone, written whole or
not at all): NEW may not be the survey's own folder, nor any folder that holds a flight (another
survey's, whose ledger a re-plan there would orphan), nor the root folder or the user's home.
"""

from __future__ import annotations

import numpy as np

from missionplan.base.naming import Named

from ..flight.ledger import LedgerError, Survey
from ..mission.plan_blocks import PlanSettings
from .errors import ReplanError


def stored_settings(survey: Survey) -> PlanSettings:
    """The mission and safety settings the survey's root plan was made with (report.json `settings`)."""
    stored = survey.record.settings
    if stored is None:
        raise LedgerError(f"{survey.root / 'report.json'}: no `settings` (planned by an older missionplan): plan the "
                          "area again with `missionplan plan`, then re-plan from that folder")
    return stored


def parse_assignments(texts: list[str]) -> dict[int, int]:
    """`--sysid K=ID` values -> {drone K: system id ID}."""
    from missionplan.bridge.link.connection import parse_sysid

    out: dict[int, int] = {}
    for text in texts:
        drone, sep, sysid = text.partition("=")
        if not sep or not drone.strip().isdigit():
            raise ReplanError(Named("{sysid} {0}: expected K=ID (drone K of the re-plan is the vehicle with system id ID)",
                                 text))
        k = int(drone)
        if k in out:
            raise ReplanError(Named("{sysid} {0}: drone {1} is given twice", text, k))
        out[k] = parse_sysid(sysid.strip())
    if len(set(out.values())) != len(out):
        raise ReplanError(Named("{sysid}: one system id for two drones ({0})", ", ".join(texts)))
    return out


def launch_of_drones(survey: Survey, drones: str) -> tuple[list[tuple[int, int]], list[int]]:
    """`--drones 2,3`: the root plan's launch cells of those drones, and their ids."""
    from missionplan.bridge.link.connection import parse_sysids

    ids = parse_sysids(drones, "drones")
    launch = survey.record.launch
    known = list(survey.record.drone_ids or range(1, len(launch) + 1))
    cells = []
    for sysid in ids:
        if sysid not in known:
            raise ReplanError(Named("{drones} {0}: the survey's plan has no drone {1} (it has {2}); give new launch "
                                 "points with {launch} and {sysid}", drones, sysid, ", ".join(map(str, known))))
        cells.append(launch[known.index(sysid)])
    return cells, ids


def launch_at(survey: Survey, launch: list[str], sysid: list[str]) -> tuple[list[tuple[int, int]], list[int]]:
    """`--launch LAT,LON ... --sysid K=ID ...`: the grid cells of the points and the vehicles flying from them."""
    from ..mission.georef import parse_latlon

    assignment = parse_assignments(sysid)
    missing = [k for k in range(1, len(launch) + 1) if k not in assignment]
    extra = sorted(k for k in assignment if not 1 <= k <= len(launch))
    if missing or extra:
        raise ReplanError(Named("{sysid}: say which vehicle flies each {launch} point: no {sysid} for drone {0}",
                             ", ".join(map(str, missing))) if missing else
                       Named("{sysid}: say which vehicle flies each {launch} point: drone {0} has no {launch} point "
                             "({1} given)", extra[0], len(launch)))
    cells = []
    for text in launch:
        lat, lon = parse_latlon(text)
        r, c = survey.frame.latlon_to_grid(np.array([lat]), np.array([lon]))
        cell = (int(np.rint(np.atleast_1d(r)[0])), int(np.rint(np.atleast_1d(c)[0])))
        rows, cols = survey.shape
        if not (0 <= cell[0] < rows and 0 <= cell[1] < cols):
            raise ReplanError(Named("{launch} {0}: outside the survey's grid", text))
        cells.append(cell)
    return cells, [assignment[k] for k in range(1, len(launch) + 1)]
