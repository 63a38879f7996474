"""What `fly` and `demo` say on the terminal: progress per drone, the lines said as things happen, and
the summary of a judged flight.

Bars only when stderr is a terminal (as `plan` and `upload` do); in a log, plain lines at the start and
every quarter of each mission (LineProgress), so a log gets no cursor codes. Alerts (a link lost, a
failsafe, a mode changed by someone else) are said even with --quiet: they are not progress. Every line said
and every problem printed goes through printable(): a vehicle's STATUSTEXT or a file's name never moves the
cursor or splits a line.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import Any

from missionplan.bridge.terminal_text import printable

from .flight_report import FlightResult
from .phases import slow_phase

Say = Callable[[str], None]


class LineProgress:
    """A drone's progress where no bar can be drawn (stderr is a file or a pipe): the few attributes
    of a tqdm bar that the drone's flight uses, said as plain lines, at the mission's start and at each
    quarter of it."""

    def __init__(self, label: str, say: Say) -> None:
        self.label, self.say = label, say
        self.n, self.total = 0, 1
        self._quarter = 4  # nothing to say before the mission starts (reset)

    def reset(self, total: int) -> None:
        self.n, self.total, self._quarter = 0, total, 0
        self.say(f"{self.label}: mission started")

    def refresh(self) -> None:
        quarter = 4 * self.n // max(self.total, 1)
        if quarter > self._quarter:
            self._quarter = quarter
            self.say(f"{self.label}: at item {self.n} of {self.total}")

    def close(self) -> None:
        pass


def _plain_say() -> Say:
    lock = threading.Lock()

    def say(text: str) -> None:
        with lock:  # one write per line: the drones' threads say things at once
            sys.stderr.write(printable(text) + "\n")
            sys.stderr.flush()
    return say


def progress_display(labels: dict[int, str], progress: bool) -> tuple[dict[int, Any], Say, Say]:
    """(one progress display per drone, how to say a progress line, how to say an alert). progress
    False: no displays and no progress lines, alerts still said."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        def above_bars(text: str) -> None:
            tqdm.write(printable(text), file=sys.stderr)  # above the bars, not through them

        if not progress:
            return {}, lambda text: None, above_bars
        bars = {sysid: tqdm(total=1, desc=label, position=pos, unit="item", leave=True, file=sys.stderr)
                for pos, (sysid, label) in enumerate(labels.items())}
        return bars, above_bars, above_bars
    say = _plain_say()
    if not progress:
        return {}, lambda text: None, say
    return {sysid: LineProgress(label, say) for sysid, label in labels.items()}, say, say


def print_flight(result: FlightResult) -> None:
    """The lines `fly` and `demo` print about a judged flight."""
    sep = result.separation
    unconfirmed = sum(d.get("photos_placed_on_track", 0) for d in result.drones)
    print(f"flown coverage {result.coverage:.2f} % of {result.targets} target cells "
          f"(photos from {result.photo_source}); {len(result.drones)} drones, {result.wall_s:.1f} s wall")
    for name, block in (result.doc.get("coverage_by_class") or {}).items():
        print(f"  {name}: {block['coverage_pct']:.2f} % of {block['targets']} target cells")
    if unconfirmed:
        print(f"  {unconfirmed} photos not confirmed by the vehicles (placed on the track between their "
              f"neighbours): with them, {result.coverage_with_unconfirmed:.2f} %")
    if result.overlap is not None and result.overlap.photos:  # from the confirmed photos' positions
        print(f"  overlaps as flown: {result.overlap.summary()}")
    if sep["kept"] is None:
        print(f"separation not measured: {sep.get('tracks', 0)} drone(s) flew, it takes two"
              + (f" (the plan promised {sep['planned_3d']} m 3-D)" if sep["planned_3d"] is not None else ""))
    else:
        print(f"closest approach {sep['horizontal']} m horizontal / {sep['3d']} m 3-D; "
              f"the plan promised {sep['planned_3d']} m 3-D (tolerance {sep['tolerance']} m): "
              f"{'kept' if sep['kept'] else 'BROKEN'}")
    for d in result.drones:
        state = "finished" if d["finished"] else ("ended early" if d.get("ended_early") else "NOT finished")
        held = {True: "holds the uploaded mission", False: "LOST its mission", None: "mission not re-read"}
        retimed = d.get("planned_flight_s_vehicle")
        vehicle = (f"; {retimed:.1f} s with the vehicle's parameters"
                   if retimed is not None and abs(retimed - d["planned_flight_s"]) >= 0.05 else "")
        recovered = d.get("photos_from_log", 0)
        print(f"  uav{d['id']}: {state}, {d['flight_s']:.1f} s flown (planned {d['planned_flight_s']:.1f} s{vehicle}), "
              f"{d['photos']} photos" + (f" ({recovered} read from its log)" if recovered else "")
              + f", {held[d['held_after_flight']]}"
              + "".join(f"; {printable(note)}" for note in d.get("notes", []) if note.startswith("left "))
              + (f"; {slow}" if (slow := slow_phase(d.get("phases") or [])) else ""))
    for problem in result.problems:
        print(f"  problem: {printable(problem)}")
    survey = result.survey
    if survey is not None and survey["flights"] > 1:
        print(f"survey {survey['root']}: {survey['coverage']:.2f} % of {survey['targets']} target cells over "
              f"{survey['flights']} flights, {survey['missing_cells']} left (`missionplan status {survey['root']}`)")
    names = [result.json_path.name, result.png_path.name, *(p.name for p in result.map_paths), result.missed_path.name]
    if survey is not None:  # a judged flight of the journal: its photos' geotags too
        names += ["photos.csv", "photos.geojson", "geo.txt"]
    unwritten = {name for names_ in result.unwritten for name in names_.split(", ")}  # said on stderr by fly
    names = [name for name in names if name not in unwritten]
    print(f"wrote {printable(result.json_path.parent)}: {', '.join(names) or 'nothing'}")
