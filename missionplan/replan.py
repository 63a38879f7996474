"""`missionplan replan DIR --out NEW`: plan only what the survey ledger says is still missing.

The survey DIR belongs to (its root plan, flight/ledger.py) keeps its grid and georeference: NEW's
grid is the root's with only the missing target cells left as targets, so a cell is the same ground
in both folders and NEW's flights add to the root's ledger (NEW/report.json `survey` points back).
The planning is `plan`'s own (plan_folder.write_plan_folder: clearance band, separation layers, geofences,
endurance sorties, the autopilot's flavour), with the settings the root plan recorded
(report.json `settings`).

Who flies it is said, never assumed: `--drones 2,3` (the survey's drones 2 and 3, from their launch
points, as system ids 2 and 3), or `--launch LAT,LON` once per drone with `--sysid K=ID` for each
(drone K of the new plan is the vehicle with system id ID). The files are named by system id
(uav2.plan for the vehicle with id 2), which is how `fly` matches them to vehicles.

NEW is written as `plan` writes its --out (write_plan_folder: held by this run alone, written whole or
not at all): NEW may not be the survey's own folder, nor any folder that holds a flight (another
survey's, whose ledger a re-plan there would orphan), nor the root folder or the user's home.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.bridge.limits import SEED_MAX, check_integer
from missionplan.bridge.terminal_text import printable

from .flight.plan_report import missing_map
from .flight.ledger import LedgerError, Survey
from .flight.ledger_repair import open_ledger
from .grid.world import check_starts
from .maps.gridmap import MapError
from .mission.plan_blocks import PlanSettings, SurveyPointer
from .pipeline import POLICIES
from .plan_display import EXIT_FAILED, print_plan
from .plan_folder import PlanGround, PlanOptions, check_out_folder, write_plan_folder


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
            raise MapError(f"--sysid {text}: expected K=ID (drone K of the re-plan is the vehicle with system id ID)")
        k = int(drone)
        if k in out:
            raise MapError(f"--sysid {text}: drone {k} is given twice")
        out[k] = parse_sysid(sysid.strip())
    if len(set(out.values())) != len(out):
        raise MapError(f"--sysid: one system id for two drones ({', '.join(texts)})")
    return out


def launch_of_drones(survey: Survey, drones: str) -> tuple[list[tuple[int, int]], list[int]]:
    """`--drones 2,3`: the root plan's launch cells of those drones, and their ids."""
    from missionplan.bridge.link.connection import parse_sysids

    ids = parse_sysids(drones, option="--drones")
    launch = survey.record.launch
    known = list(survey.record.drone_ids or range(1, len(launch) + 1))
    cells = []
    for sysid in ids:
        if sysid not in known:
            raise MapError(f"--drones {drones}: the survey's plan has no drone {sysid} (it has "
                           f"{', '.join(map(str, known))}); give new launch points with --launch and --sysid")
        cells.append(launch[known.index(sysid)])
    return cells, ids


def launch_at(survey: Survey, launch: list[str], sysid: list[str]) -> tuple[list[tuple[int, int]], list[int]]:
    """`--launch LAT,LON ... --sysid K=ID ...`: the grid cells of the points and the vehicles flying from them."""
    from .mission.georef import parse_latlon

    assignment = parse_assignments(sysid)
    missing = [k for k in range(1, len(launch) + 1) if k not in assignment]
    extra = sorted(k for k in assignment if not 1 <= k <= len(launch))
    if missing or extra:
        raise MapError("--sysid: say which vehicle flies each --launch point: "
                       + (f"no --sysid for drone {', '.join(map(str, missing))}" if missing else
                          f"drone {extra[0]} has no --launch point ({len(launch)} given)"))
    cells = []
    for text in launch:
        lat, lon = parse_latlon(text)
        r, c = survey.frame.latlon_to_grid(np.array([lat]), np.array([lon]))
        cell = (int(np.rint(np.atleast_1d(r)[0])), int(np.rint(np.atleast_1d(c)[0])))
        rows, cols = survey.shape
        if not (0 <= cell[0] < rows and 0 <= cell[1] < cols):
            raise MapError(f"--launch {text}: outside the survey's grid")
        cells.append(cell)
    return cells, [assignment[k] for k in range(1, len(launch) + 1)]


def cmd_replan(args: argparse.Namespace) -> int:
    check_integer(args.seed, "--seed", 0, SEED_MAX, error=MapError)
    plan_dir, out = Path(args.dir), Path(args.out)
    with open_ledger(plan_dir, lambda text: print(f"missionplan replan: {printable(text)}", file=sys.stderr)) as ledger:
        survey = ledger.survey
        missing = ledger.missing_cells()
        flights = len(ledger.flights())
    if out.resolve() in (plan_dir.resolve(), survey.root.resolve()):
        raise MapError(f"--out {out}: a re-plan goes into a new folder, not over the survey's own plan")
    check_out_folder(out)  # before a word is printed; write_plan_folder asks again, holding the folder
    stored = stored_settings(survey)
    if args.drones is not None and args.launch:
        raise MapError("give either --drones (the survey's drones, from their launch points) or --launch with --sysid")
    if args.drones is not None:
        if args.sysid:
            raise MapError("--sysid goes with --launch; --drones already names the vehicles by their system ids")
        cells, ids = launch_of_drones(survey, args.drones)
    elif args.launch:
        cells, ids = launch_at(survey, args.launch, args.sysid)
    else:
        raise MapError("say who flies the re-plan: --drones ID,... (the survey's drones, from their launch points) or "
                       "--launch LAT,LON once per drone with --sysid K=ID")
    targets = len(survey.targets)
    print(f"survey {printable(survey.root)}: {flights} flight{'' if flights == 1 else 's'} recorded, {targets - len(missing)} of "
          f"{targets} target cells "
          f"covered, {len(missing)} left")
    if not len(missing):
        print("nothing left to photograph: no re-plan written")
        return 0
    gmap = missing_map(survey.record, missing, cells)
    check_starts(gmap, cells)
    for k, (cell, sysid) in enumerate(zip(cells, ids), start=1):
        lat, lon = survey.frame.cell_to_latlon(np.array([cell[0]]), np.array([cell[1]]))
        print(f"  drone {k}: system id {sysid}, from {float(np.atleast_1d(lat)[0]):.7f},"
              f"{float(np.atleast_1d(lon)[0]):.7f} (cell {cell[0]},{cell[1]}) -> uav{sysid}.plan")
    pointer = SurveyPointer(os.path.relpath(survey.root.resolve(), out.resolve()), int(len(missing)),
                            os.path.relpath(plan_dir.resolve(), out.resolve()))
    options = PlanOptions(policy=args.policy or stored.policy, weights=args.weights, zones=stored.zones,
                          balance_zones=stored.balance_zones, open_ground=stored.open_ground, seed=args.seed,
                          progress=not args.quiet and sys.stderr.isatty(), drone_ids=ids, survey=pointer)
    folder = write_plan_folder(out, PlanGround(gmap, cells, survey.frame, stored.mission, stored.safety), options)
    print_plan(folder)
    return 0 if folder.success else EXIT_FAILED


def register(subparsers: Any) -> None:
    """Add `replan DIR --out NEW (--drones IDS | --launch LAT,LON ... --sysid K=ID ...) [--policy P] [--weights F]
    [--seed N] [--quiet]`."""
    p = subparsers.add_parser("replan", help="plan only the targets the survey's photos have not covered yet, "
                                             "for the vehicles given", allow_abbrev=False)
    p.add_argument("dir", help="a plan folder of the survey (the first plan or a re-plan of it)")
    p.add_argument("--out", required=True, type=Path, help="new plan folder (its flights add to the same survey)")
    p.add_argument("--drones", metavar="ID,ID", help="the survey's drones (system ids) that fly it, each from its "
                                                     "launch point in the survey's plan")
    p.add_argument("--launch", action="append", default=[], metavar="LAT,LON",
                   help="a launch point per drone of the re-plan, in degrees (with --sysid for each)")
    p.add_argument("--sysid", action="append", default=[], metavar="K=ID",
                   help="drone K (the K-th --launch) is flown by the vehicle with system id ID")
    p.add_argument("--policy", choices=POLICIES, default=None,
                   help="planning policy (default: the one the survey was planned with)")
    p.add_argument("--weights", type=Path, help="network weights for --policy nn (default: the shipped ones)")
    p.add_argument("--seed", type=int, default=0, help="seed for zones and deadlock breaking")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=cmd_replan)
