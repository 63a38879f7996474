"""`missionplan geotag SURVEY_DIR IMAGES_DIR... [--out DIR]`: the crew's camera cards geotagged from the survey's
capture records, into copies (missionplan/flight/exif_geotag.py places each card and writes the copies;
image_match.py finds each camera clock's offset and pairs images with records)."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.bridge.terminal_text import printable

from ..flight.exif_geotag import DEFAULT_OUT, geotag_cards
from .parsing import runs

EXIT_NONE_PLACED = 1


@dataclass(frozen=True)
class GeotagRequest:
    """`geotag`: a plan folder of the survey, the cards (one folder of images per camera), where the copies go."""

    survey_dir: Path
    images_dirs: tuple[Path, ...]
    out: Path | None


def register(subparsers: Any) -> None:
    """Add `geotag SURVEY_DIR IMAGES_DIR... [--out DIR]`."""
    p = subparsers.add_parser("geotag", help="write GPS position, altitude and gimbal angles from the survey's "
                                             "capture records into copies of the crew's images", allow_abbrev=False)
    p.add_argument("survey_dir", type=Path, help="a plan folder of the flown survey (the first plan or a re-plan)")
    p.add_argument("images_dirs", type=Path, nargs="+", metavar="IMAGES_DIR",
                   help="one camera's card: a folder of its JPEGs (subfolders too)")
    p.add_argument("--out", type=Path, default=None,
                   help=f"where the copies go, one folder per card (default SURVEY_DIR/{DEFAULT_OUT})")
    p.set_defaults(handler=runs(GeotagRequest, cmd_geotag))


def cmd_geotag(request: GeotagRequest) -> int:
    """One line per card; exit 1 when no card could be placed, 2 for bad input (said by main)."""
    run = geotag_cards(request.survey_dir, request.images_dirs, request.out)
    for line in run.lines:
        print(printable(line))
    if not run.placed:
        print("missionplan geotag: no card could be placed on a drone of the survey: nothing written",
              file=sys.stderr)
        return EXIT_NONE_PLACED
    copies = sum(len(p.written) for p in run.placed)
    print(f"wrote {copies} geotagged cop{'y' if copies == 1 else 'ies'} into {printable(run.out)}")
    return 0
