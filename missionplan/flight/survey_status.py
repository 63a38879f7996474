"""What `missionplan status DIR` says (missionplan/cli/survey.py): what the survey's photos have covered and
what is left, from its ledger.

survey_status: the flights recorded (each folder's, each day's), the covered and missing target cells with
their area, and the missing area's extent on the Earth (`extent`); draw_status: DIR/status.png (the survey's
grid: covered, missing, out of reach, and every photo's position). The command also writes DIR/missing.geojson
(the missing cells as polygons, RFC 7946). Reads only: nothing is flown or planned. A missing or damaged
ledger is rebuilt from the survey's journals first (ledger_repair), said in one line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from missionplan.base.atomic import atomic_path

from .ledger import Ledger, Survey
from .plan_report import planned_grid


def extent(survey: Survey, cells: np.ndarray) -> dict[str, Any] | None:
    """The cells' bounding box in degrees (cell squares, not centres) and its size in metres along the grid."""
    if not len(cells):
        return None
    r0, c0 = cells.min(axis=0) - 0.5
    r1, c1 = cells.max(axis=0) + 0.5
    corners_r, corners_c = np.array([r0, r0, r1, r1]), np.array([c0, c1, c0, c1])
    lat, lon = survey.frame.grid_to_latlon(corners_r, corners_c)
    cell = survey.frame.cell_m
    return {"south": round(float(np.min(lat)), 7), "north": round(float(np.max(lat)), 7),
            "west": round(float(np.min(lon)), 7), "east": round(float(np.max(lon)), 7),
            "rows_m": round(float(r1 - r0) * cell, 1), "cols_m": round(float(c1 - c0) * cell, 1)}


def survey_status(ledger: Ledger) -> dict[str, Any]:
    survey = ledger.survey
    targets, missing = survey.targets, ledger.missing_cells()
    area = survey.frame.cell_m ** 2
    done = len(targets) - len(missing)
    return {"root": str(survey.root), "flights": ledger.flights(), "targets": int(len(targets)), "covered": int(done),
            "coverage": round(100.0 * done / len(targets), 2) if len(targets) else 100.0,
            "missing": int(len(missing)), "covered_m2": round(done * area, 1), "target_m2": round(len(targets) * area, 1),
            "missing_m2": round(len(missing) * area, 1), "extent": extent(survey, missing), "missing_cells": missing}


def draw_status(path: Path, ledger: Ledger, status: dict[str, Any]) -> None:
    """status.png: the survey grid in metres, covered targets green, missing red, photos as dots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    survey = ledger.survey
    gmap = planned_grid(survey.record)
    rows, cols = gmap.shape
    img = np.ones((rows, cols, 3))
    img[gmap.obstacle] = (0.25, 0.25, 0.25)
    img[gmap.target] = (0.85, 0.85, 0.85)  # out of reach: grey
    covered = ledger.covered_mask()
    img[covered] = (0.62, 0.87, 0.62)
    missing = status["missing_cells"]
    if len(missing):
        img[missing[:, 0], missing[:, 1]] = (0.95, 0.35, 0.35)
    cell = survey.frame.cell_m
    fig, ax = plt.subplots(figsize=(10, max(4.0, 10 * rows / cols + 1)))
    ax.imshow(img, interpolation="nearest", origin="upper", extent=(-0.5 * cell, (cols - 0.5) * cell,
                                                                     (rows - 0.5) * cell, -0.5 * cell))
    photos = ledger.photos()
    if photos:
        r, c = survey.frame.latlon_to_grid(np.array([p.lat for p in photos]), np.array([p.lon for p in photos]))
        ax.plot(np.atleast_1d(c) * cell, np.atleast_1d(r) * cell, ".", ms=1.5, color="tab:blue", label="photo")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_xlabel("metres along the grid's columns")
    ax.set_ylabel("metres along the grid's rows")
    ax.set_title(f"survey {status['coverage']:.2f} % covered over {len(status['flights'])} flights "
                 f"(green covered, red left, grey out of reach)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
