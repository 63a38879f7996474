"""`missionplan status DIR` (what the survey's photos have covered and what is left, from its ledger) and
`missionplan replan DIR --out NEW` (plan only what the survey still misses, for the vehicles given).

status reads only (flight/survey_status.py: the status, missing.geojson, status.png). replan plans as `plan`
does, with the settings the survey's root plan recorded (missionplan/planning/replan.py: who flies it, the stored
settings; plan_folder.write_plan_folder: the folder)."""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from missionplan.base.atomic import write_text_atomic
from missionplan.bridge.limits import SEED_MAX, check_integer
from missionplan.bridge.terminal_text import printable
from missionplan.geo.cells import cells_feature

from ..flight.ledger_repair import open_ledger
from ..flight.plan_report import missing_map
from ..flight.survey_status import draw_status, survey_status
from ..grid.world import check_starts
from ..maps.gridmap import MapError
from ..mission.plan_blocks import SurveyPointer
from ..planning.pipeline import POLICIES
from .plan_display import EXIT_FAILED, print_plan
from ..planning.plan_folder import PlanGround, PlanOptions, check_out_folder, write_plan_folder
from ..planning.terrain import checked_ground, folder_terrain
from ..planning.replan import launch_at, launch_of_drones, stored_settings
from .parsing import runs


@dataclass(frozen=True)
class StatusRequest:
    """`status`: a plan folder of the survey."""

    dir: str


@dataclass(frozen=True)
class ReplanRequest:
    """`replan`: the survey's folder, the new plan's folder, who flies it (the survey's drones, or launch
    points with the system id of each), and the planner's policy, weights and seed."""

    dir: str
    out: Path
    drones: str | None
    launch: tuple[str, ...]
    sysid: tuple[str, ...]
    policy: str | None
    weights: Path | None
    seed: int
    quiet: bool


def register(subparsers: Any) -> None:
    """Add `status DIR` and `replan DIR --out NEW (--drones IDS | --launch LAT,LON ... --sysid K=ID ...)
    [--policy P] [--weights F] [--seed N] [--quiet]`."""
    p = subparsers.add_parser("status", help="what the survey's photos have covered and what is left (from its "
                                             "ledger); writes missing.geojson and status.png", allow_abbrev=False)
    p.add_argument("dir", help="a plan folder of the survey (the first plan or a re-plan of it)")
    p.set_defaults(handler=runs(StatusRequest, cmd_status))

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
    p.set_defaults(handler=runs(ReplanRequest, cmd_replan))


def _say(text: str) -> None:
    print(f"missionplan status: {printable(text)}", file=sys.stderr)


def cmd_status(request: StatusRequest) -> int:
    """Print the survey's status; exit 1 when it could not write missing.geojson or status.png (the
    status printed is whole all the same), 2 when DIR is no plan."""
    plan_dir = Path(request.dir)
    with open_ledger(plan_dir, _say) as ledger:
        status = survey_status(ledger)
        flights = status["flights"]
        survey = ledger.survey
        print(f"survey {printable(survey.root)}: {len(flights)} flight{'' if len(flights) == 1 else 's'} recorded, "
              f"{sum(f['photos'] for f in flights)} photos")
        for f in flights:
            when = datetime.fromtimestamp(f["recorded"], timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
            print(f"  {printable(f['plan']):<16} flight {f['flight']} (sortie {f['sortie']}): {f['photos']} photos, recorded {when}")
        print(f"covered {status['covered']} of {status['targets']} target cells: {status['coverage']:.2f} %, "
              f"{status['covered_m2']:g} of {status['target_m2']:g} m²")
        box = status["extent"]
        if box is None:
            print("left: nothing")
        else:
            print(f"left: {status['missing']} cells, {status['missing_m2']:g} m², within {box['south']:.6f}.."
                  f"{box['north']:.6f} N, {box['west']:.6f}..{box['east']:.6f} E ({box['rows_m']:g} m x "
                  f"{box['cols_m']:g} m along the grid): `missionplan replan {printable(plan_dir)} --out NEW --drones ...` plans it")
        geojson, png = plan_dir / "missing.geojson", plan_dir / "status.png"
        doc = {"type": "FeatureCollection", "features": [cells_feature(survey.frame, status["missing_cells"], {
            "what": "survey target cells no photo has covered yet", "cells": status["missing"],
            "area_m2": status["missing_m2"], "coverage": status["coverage"]})]}
        failed: dict[str, str] = {}
        for path, write in ((geojson, lambda: write_text_atomic(geojson, json.dumps(doc) + "\n")),
                            (png, lambda: draw_status(png, ledger, status))):
            try:
                write()
            except OSError as err:  # a read-only folder, a full disk: the status above stands
                failed[path.name] = err.strerror or str(err)
    if failed:
        why = sorted(set(failed.values()))
        _say(f"{plan_dir}: {' and '.join(failed)} could not be written ({'; '.join(why)}); the status above is whole")
        return 1
    print(f"wrote {printable(geojson)} and {printable(png)}")
    return 0


def cmd_replan(request: ReplanRequest) -> int:
    check_integer(request.seed, "--seed", 0, SEED_MAX, error=MapError)
    plan_dir, out = Path(request.dir), Path(request.out)
    with open_ledger(plan_dir, lambda text: print(f"missionplan replan: {printable(text)}", file=sys.stderr)) as ledger:
        survey = ledger.survey
        missing = ledger.missing_cells()
        flights = len(ledger.flights())
    if out.resolve() in (plan_dir.resolve(), survey.root.resolve()):
        raise MapError(f"--out {out}: a re-plan goes into a new folder, not over the survey's own plan")
    check_out_folder(out)  # before a word is printed; write_plan_folder asks again, holding the folder
    stored = stored_settings(survey)
    if request.drones is not None and request.launch:
        raise MapError("give either --drones (the survey's drones, from their launch points) or --launch with --sysid")
    if request.drones is not None:
        if request.sysid:
            raise MapError("--sysid goes with --launch; --drones already names the vehicles by their system ids")
        cells, ids = launch_of_drones(survey, request.drones)
    elif request.launch:
        cells, ids = launch_at(survey, list(request.launch), list(request.sysid))
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
    options = PlanOptions(policy=request.policy or stored.policy, weights=request.weights, zones=stored.zones,
                          balance_zones=stored.balance_zones, open_ground=stored.open_ground,
                          lane_spacing_cells=stored.lane_spacing_cells, seed=request.seed,
                          progress=not request.quiet and sys.stderr.isatty(), drone_ids=ids, survey=pointer,
                          overlap_fill=stored.overlap_fill)
    roofs = survey.record.roofs  # a survey of roofs re-plans its roofs as such
    georef = survey.record.georeference  # a capture plan's camera block goes on into the re-plan
    ground = PlanGround(gmap, cells, survey.frame, stored.mission, stored.safety,
                        capture=georef.capture if georef is not None else None,
                        **({"targets": roofs.targets} if roofs is not None else {}))
    terrain = folder_terrain(survey.root, survey.record)  # over the survey's ground, when it was planned over a DEM
    if terrain is not None:
        ground.terrain = checked_ground(terrain, survey.frame, gmap, cells)
    folder = write_plan_folder(out, ground, options)
    print_plan(folder)
    return 0 if folder.success else EXIT_FAILED
