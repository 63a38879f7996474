"""Live re-tasking measured: how ArduCopter SITL and PX4 SIH take a mission replaced while they fly it.

Run by hand: `.venv/bin/python bench/retask_bench.py [--autopilots arducopter,px4] [--strategies
a,b/short] [--write-doc docs/live-retasking.md]` (about 30 minutes: PX4 SIH runs in real time, about 3
minutes a row). Needs ../shared/sitl/arducopter and ../shared/px4/bin/px4 (or MISSIONPLAN_SIMULATORS: see
missionplan/testing/simulators.py). Under each row, on stderr, what the vehicle said and did around the
change (its timeline). The harness (the survey, flying to mid-leg, watching, judging) is
missionplan/testing/retask_harness.py, which the tests use too; the strategies are this script's.

Each row is one fresh vehicle (a free instance, killed afterwards; one at a time): it flies a survey
(take-off to 20 m, the eight waypoints A1..A8 of a 60 x 60 m lawnmower north of home, RTL) in AUTO /
mission mode. Mid-leg from A5 to A6 (flying north, 15 m past A5) its mission is replaced. The new mission
keeps the items already flown and puts, at the item it flies to (resume_seq = that seq), three new
waypoints B1..B3 (a lost drone's, west of it and behind it) and the RTL: the same item count, so the
partial write can carry the change too. `/short`: the new mission is take-off, B1..B3, RTL (flown items
dropped, as fly's re-plans are), so B1 (resume_seq) gets another seq than the item flown, which is past
the new mission's end. Strategies:

- `upload-only`: the whole new mission uploaded in AUTO (MISSION_COUNT + items), items as
  missionplan.bridge.formats.mission_items.to_wire makes them (`current` = 1 on seq 0), and nothing more: what the
  autopilot does with the upload alone;
- `full`: the same, then MISSION_SET_CURRENT resume_seq (strategy a);
- `full-cmd`: the same, then MAV_CMD_DO_SET_MISSION_CURRENT (224) instead of the message;
- `full-flag` (PX4): the whole new mission with `current` = 1 on resume_seq instead, then
  MISSION_SET_CURRENT;
- `partial`: MISSION_WRITE_PARTIAL_LIST of the changed items (first changed seq to the end), answered as
  asked, then MISSION_SET_CURRENT (strategy b);
- `abort`: an upload that stops after its first 3 items (a link lost halfway), until the vehicle gives it
  up;
- `pause-guided`, `pause-brake` (ArduCopter), `pause-hold` (PX4): that mode first, the full replace,
  MISSION_SET_CURRENT, then AUTO / mission mode again (strategy c); `pause-guided-noset`: without
  MISSION_SET_CURRENT;
- `product`: missionplan.bridge.transfer.retask.replace_mission_in_flight, what the product does (timed from its call).

Columns: `ack` the upload's answer (MISSION_ACK result; `none`: no answer within 3 s); `heading path`
where the vehicle flew from the upload's start until B1 (or the end of the watch), as what its velocity
pointed at (within 30 degrees, the nearest in direction), each for at least 1.5 vehicle seconds: A6 (its
target when re-tasked), B1 (the new one), TO (the take-off point, home: where a mission restarted from its
first item goes), `stop` (under 1 m/s), `turn` (none of them); `seq path` MISSION_CURRENT
from the upload's start until B1 was reached; `upload s` from MISSION_COUNT (WRITE_PARTIAL_LIST) to the
final ACK, wall seconds, and `veh` the vehicle's; `to B1 s` from the upload's start until the vehicle
headed for B1 for good (the start of the run of samples pointing at B1 that took it there), vehicle
seconds; `min m/s` its lowest horizontal speed in between; `reached` the B waypoints it reported reached
(MISSION_ITEM_REACHED) where it was (within 10 m), of 3; `armed` whether it stayed armed and above 5 m
until B1 (or the end); `holds` what a read-back after the strategy found: `new`, `old`, or `mixed N:a+b`
(N items, a only the new mission's, b only the old one's); `says` its STATUSTEXT from the upload's start
on, each once. ArduCopter SITL runs at --speedup 10, PX4 SIH in real time; vehicle seconds are its own
clock (GLOBAL_POSITION_INT time_boot_ms, 10 per vehicle second).
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import doctable  # bench/doctable.py: --write-doc

from missionplan.bridge.formats.mission_items import Flavour, WireItem
from missionplan.bridge.link.connection import AUTOPILOT_COMPONENT_ID, Link, mavlink
from missionplan.bridge.link.readiness import (ARDUPILOT_AUTO, ARDUPILOT_GUIDED, PX4_AUTO_MAIN, PX4_LOITER_SUB,
                                               PX4_MISSION_SUB, mode_params)
from missionplan.bridge.transfer.protocol import RESULT_TEXT, MissionTransferError
from missionplan.bridge.transfer.retask import RetaskError, replace_mission_in_flight
from missionplan.testing.retask_harness import (AFTER_S, ARDUCOPTER_SPEEDUP, HEADER, LOST, Flight, Outcome, Row,
                                                holds, judge, line, listen_for, start_flying, timeline)

PARTIAL_WAIT_S = 3.0
ABORT_AFTER = 3  # items answered before an aborted upload goes silent
ARDUPILOT_BRAKE = 17  # ArduCopter's custom_mode number (its own, not a MAVLink enum)
RESULT_NAMES = {k: v.split("(MAV_MISSION_")[-1].rstrip(")") if "(MAV_MISSION_" in v else v
                for k, v in RESULT_TEXT.items()}
RESULT_NAMES[0] = "ACCEPTED"
RESULT_NAMES[15] = "CANCELLED"  # OPERATION_CANCELLED, short for the table
STRATEGIES = {
    Flavour.ARDUPILOT: ("upload-only", "upload-only/short", "full", "full/short", "full-cmd", "partial",
                        "abort/short", "pause-guided", "pause-guided/short", "pause-guided-noset/short", "pause-brake",
                        "product/short"),
    Flavour.PX4: ("upload-only", "full", "full-flag", "full-flag/short", "partial", "abort/short", "pause-hold",
                  "product/short"),
}


# ------------------------------------------------------------------------------ the strategies
def _mode(flight: Flight, name: str, deadline: float) -> int | None:
    f = flight
    if f.flavour is Flavour.ARDUPILOT:
        custom = {"AUTO": ARDUPILOT_AUTO, "GUIDED": ARDUPILOT_GUIDED, "BRAKE": ARDUPILOT_BRAKE}[name]
        return f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(custom), deadline)
    sub = {"MISSION": PX4_MISSION_SUB, "HOLD": PX4_LOITER_SUB}[name]
    return f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MODE, mode_params(PX4_AUTO_MAIN, sub), deadline)


def _upload(flight: Flight, items: list[WireItem], out: Outcome) -> bool:
    start = time.monotonic()
    try:
        flight.backend.upload(0, items)
        out.ack = "ACCEPTED"
        ok = True
    except MissionTransferError as err:
        out.ack = RESULT_NAMES.get(err.result, "none") if err.result is not None else "none"
        out.note = str(err)
        ok = False
    out.upload_wall = (start, time.monotonic())
    return ok


def _set_current(flight: Flight, out: Outcome, how: str = "message") -> None:
    f = flight
    if how == "command":
        result = f.link.command_long(f.sysid, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, [float(f.resume)],
                                     time.monotonic() + 5.0)
        out.note += f" DO_SET_MISSION_CURRENT result {result}"
        return
    try:
        f.backend.set_current(f.resume)
    except MissionTransferError as err:
        out.note += f" set_current: {err}"


def full(flight: Flight, how: str = "message", flag_resume: bool = False) -> Outcome:
    """The whole new mission in AUTO, then the current item set (how: "message", "command" or "none")."""
    out = Outcome()
    items = flight.new
    if flag_resume:
        items = [replace(it, current=int(it.seq == flight.resume)) for it in items]
    if _upload(flight, items, out) and how != "none":
        _set_current(flight, out, how)
    return out


def partial(flight: Flight) -> Outcome:
    """MISSION_WRITE_PARTIAL_LIST of the changed items, answered item by item as asked."""
    f, out = flight, Outcome()
    first = next(k for k, (a, b) in enumerate(zip(f.old, f.new)) if a != b)
    last = len(f.new) - 1
    mav = f.link.mav
    start = time.monotonic()
    mav.mission_write_partial_list_send(f.sysid, AUTOPILOT_COMPONENT_ID, first, last, mavlink.MAV_MISSION_TYPE_MISSION)
    until = start + PARTIAL_WAIT_S
    answer = "none"
    while (msg := f.link.recv(until)) is not None:
        if msg.get_srcSystem() != f.sysid:
            continue
        kind = msg.get_type()
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and first <= int(msg.seq) <= last:
            mav.mission_item_int_send(f.sysid, AUTOPILOT_COMPONENT_ID, **f.new[int(msg.seq)].fields())
            until = time.monotonic() + PARTIAL_WAIT_S
        elif kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mavlink.MAV_MISSION_TYPE_MISSION:
            answer = RESULT_NAMES.get(int(msg.type), str(msg.type))
            break
    out.upload_wall = (start, time.monotonic())
    out.ack = answer
    out.note = f"items {first}..{last}"
    if answer == "ACCEPTED":
        _set_current(f, out)
    return out


def abort(flight: Flight) -> Outcome:
    """An upload that stops halfway (a link lost): MISSION_COUNT, the first ABORT_AFTER items as asked,
    then silence until the vehicle gives the transfer up (ArduPilot after 8 vehicle s, PX4 after 5 s)."""
    f, out = flight, Outcome()
    mav = f.link.mav
    start = time.monotonic()
    mav.mission_count_send(f.sysid, AUTOPILOT_COMPONENT_ID, len(f.new), mavlink.MAV_MISSION_TYPE_MISSION)
    until = start + 8.0 / f.speedup + 5.0
    answer = "none"
    while (msg := f.link.recv(until)) is not None:
        if msg.get_srcSystem() != f.sysid:
            continue
        kind = msg.get_type()
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and int(msg.seq) < ABORT_AFTER:
            mav.mission_item_int_send(f.sysid, AUTOPILOT_COMPONENT_ID, **f.new[int(msg.seq)].fields())
        elif kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mavlink.MAV_MISSION_TYPE_MISSION:
            answer = RESULT_NAMES.get(int(msg.type), str(msg.type))
            break
    out.upload_wall = (start, time.monotonic())
    out.ack = answer
    out.note = f"answered items 0..{ABORT_AFTER - 1} of {len(f.new)}"
    return out


def paused(flight: Flight, mode: str, set_current: bool = True) -> Outcome:
    """`mode` first, the full replace, the current item set (unless not set_current), AUTO / mission mode."""
    f = flight
    deadline = time.monotonic() + 10.0
    result = _mode(f, mode, deadline)
    out = Outcome(note=f"{mode} result {result}")
    if _upload(f, f.new, out) and set_current:
        _set_current(f, out)
    back = _mode(f, "AUTO" if f.flavour is Flavour.ARDUPILOT else "MISSION", deadline)
    out.note += f"; back result {back}"
    # the upload's start counts from the pause: it is part of the strategy
    return out


def product(flight: Flight) -> Outcome:
    """missionplan.bridge.transfer.retask.replace_mission_in_flight; timed from its call (its HEARTBEAT wait and mode
    change included), its upload seconds its own."""
    f = flight
    start = time.monotonic()
    try:
        report = replace_mission_in_flight(f.backend, f.link, f.sysid, f.flavour, f.new, f.resume, start + 30.0)
    except RetaskError as err:
        report = err.report
    out = Outcome(ack="ACCEPTED" if report.accepted else "refused", note=report.summary())
    out.upload_wall = (start, start + report.upload_s)
    return out


def run_strategy(flight: Flight, name: str) -> Outcome:
    if name == "upload-only":
        return full(flight, how="none")
    if name == "full":
        return full(flight)
    if name == "full-cmd":
        return full(flight, how="command")
    if name == "full-flag":
        return full(flight, flag_resume=True)
    if name == "partial":
        return partial(flight)
    if name == "abort":
        return abort(flight)
    if name.startswith("pause-"):
        mode, _, noset = name.split("-", 1)[1].partition("-")
        return paused(flight, mode.upper(), set_current=noset != "noset")
    if name == "product":
        return product(flight)
    raise ValueError(name)


# ------------------------------------------------------------------------------ running
def fly_one(flavour: Flavour, row_name: str, say: Callable[[str], None]) -> Row:
    """A fresh vehicle, flown to mid-leg, re-tasked by strategy `name`, watched until B1..B3."""
    if flavour is Flavour.ARDUPILOT:
        from missionplan.testing.arducopter import ArduCopter

        vehicle: Any = ArduCopter(sysid=1, speedup=ARDUCOPTER_SPEEDUP)
        vehicle.start()
        home, url, speedup = vehicle.home[:3], vehicle.url, float(ARDUCOPTER_SPEEDUP)
    else:
        from missionplan.testing.px4_sih import PX4

        vehicle = PX4()
        vehicle.start()
        home, url, speedup = vehicle.home, vehicle.gcs_url, 1.0
    try:
        with Link(url) as link:
            name, _, scenario = row_name.partition("/")
            flight = start_flying(link, vehicle.sysid, flavour, home, speedup, scenario == "short", say)
            out = run_strategy(flight, name)
            b_last = flight.b1 + len(LOST) - 1
            until = time.monotonic() + AFTER_S[flavour] / speedup
            since = out.upload_wall[0]
            listen_for(flight.link, lambda: any(seq == b_last and t >= since for t, seq in flight.observer.reached)
                       or (flight.observer.beats and not flight.observer.beats[-1][1]), until)
            try:
                held = holds(flight, flight.backend.download(0))
            except MissionTransferError as err:
                held = f"? ({err})"
            row = judge(flight, row_name, out, time.monotonic(), held)
            row.note += "\n" + timeline(flight, out)
            return row
    finally:
        vehicle.stop()


def main() -> None:
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # killed: still stop the simulator (finally)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilots", default="arducopter,px4", help="arducopter, px4 (comma-separated)")
    parser.add_argument("--strategies", default="", help="only these (comma-separated; default: all of each)")
    doctable.add_option(parser)
    args = parser.parse_args()
    flavours = {"arducopter": Flavour.ARDUPILOT, "px4": Flavour.PX4}
    wanted = [flavours[name.strip()] for name in args.autopilots.split(",") if name.strip()]
    only = {s.strip() for s in args.strategies.split(",") if s.strip()}
    with doctable.Recorder(args.write_doc, __file__):
        print(HEADER)
        print("-" * len(HEADER))
        for flavour in wanted:
            for name in STRATEGIES[flavour]:
                if only and name not in only:
                    continue
                row = fly_one(flavour, name, lambda text: print(text, file=sys.stderr))
                print(line(row), flush=True)
                print(f"    {row.note}", file=sys.stderr, flush=True)  # the timeline: stderr, not the table


if __name__ == "__main__":
    main()
