"""Flight that survives what goes wrong, against real ArduCopter SITL (the mock-based versions are
tests/test_fly_faults.py): a `fly` killed mid-flight, a link that drops for 30 s, a battery failsafe on
one vehicle, and Ctrl-C.

Each test starts its own fleet of three ArduCopter SITL vehicles (system ids 1-3, `--speedup`, each in
its own temp folder, killed in teardown: the `fleet` fixture of sitl_tests/conftest.py, built by
missionplan/testing/sitl_fleet.py), each at its plan's launch point and sending to a loopback relay
(missionplan/testing/relay.py UdpRelay, `--serial0 udpclient:127.0.0.1:P`) that forwards to the port
`fly --connect udpin:127.0.0.1:Q` listens on. The relay breaks the link on purpose and is the ground
truth of what fly sent to the vehicles (`commands_sent`) and of what the vehicles did (`state`: armed,
mode, mission item, photos taken, arming count), whatever fly says. The team's one-time set-up (camera:
CAM1_TYPE = 1 and a reboot; the battery failsafe parameters) goes over the same relay before fly runs.
`fly` runs as a child process (the `fly_runs` fixture: SIGKILL as a crash, SIGINT as Ctrl-C), its output
read line by line with the time each line came. The plan (a block in Milan, 3 drones) is made once per
module.

Required: a fly SIGKILLed mid-flight leaves its journal; a plain fly then exits non-zero with one line
per armed vehicle and commands nothing (no upload, mode, arming, mission start or parameter); fly --resume
exits 0, re-arms nothing, re-flies nothing and judges the whole flight (>= 99 %) with both runs' photos and
the logs'. A 30 s link drop: "link lost" / "link back" said for every drone, all finish, >= 99 %, the
gap's photos read from the logs. A battery failsafe (RTL) on one vehicle: its flight ended within 10 s of
its own time after it disarmed, the reason named on the terminal and in flight.json's ended_early, exit
1, the others finish, no wait for the time-out. Ctrl-C: exit within the 5 s window plus the record,
flight.json from the journal, "fly on" said, the vehicles still armed in AUTO and nothing commanded.

Skipped with a reason when ../shared/sitl/arducopter is absent.
"""

from __future__ import annotations

import json
import signal
import time

import pytest

from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.link.readiness import ARDUPILOT_AUTO
from missionplan.flight.journal_read import read_flight
from missionplan.testing.loopback import wait_until
from missionplan.testing.relay import UdpRelay
from missionplan.testing.sitl_fleet import (BATTERY_LOW_V, BATTERY_SIM_V, FLY_TIMEOUT_S, LINK_DROP_S, SPEEDUP, SYSIDS,
                                            Fleet, configure, flight_doc, in_flight, landed, set_param_on_serial1,
                                            summary)

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out

# What fly must never send to a vehicle it did not start, or after Ctrl-C: an upload, a mode, arming,
# a mission start, a parameter (commands as the relay records them: "COMMAND_LONG <MAV_CMD number>").
COMMANDING = ("MISSION_COUNT", "MISSION_ITEM", "MISSION_ITEM_INT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
              "SET_MODE", "PARAM_SET",
              *(f"{kind} {command}" for kind in ("COMMAND_LONG", "COMMAND_INT")
                for command in (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_CMD_DO_SET_MODE,
                                mavlink.MAV_CMD_MISSION_START, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                mavlink.MAV_CMD_NAV_LAND)),
              f"COMMAND_LONG {mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN}")
LOW_BATTERY_SYSID = 2


def _commanding(relay: UdpRelay) -> list[str]:
    return [kind for kind in relay.commands_sent() if kind in COMMANDING]


def _onboard_logs(fleet: Fleet) -> str:
    """For assertion messages about photos read back from the logs: each vehicle's DataFlash files as
    ArduCopter left them (name and size; LASTLOG.TXT names the log it writes), and what its console
    said about logging (AP_Logger prints there when it cannot open, write or keep a log), so a
    vehicle that did not log its flight can be told from a log fly failed to read."""
    lines = []
    for vehicle in fleet.vehicles:
        folder = vehicle.workdir / "logs" if vehicle.workdir is not None else None
        console = [line.strip() for line in vehicle.log_bytes().decode(errors="replace").splitlines()
                   if "log" in line.lower() or "stuck" in line.lower()]
        said = f"; console: {' | '.join(console[-8:])}" if console else ""
        if folder is None or not folder.is_dir():
            lines.append(f"uav{vehicle.sysid}: no logs folder{said}")
            continue
        files = ", ".join(f"{f.name} {f.stat().st_size} B" for f in sorted(folder.glob("*.BIN")))
        last = (folder / "LASTLOG.TXT").read_text().strip() if (folder / "LASTLOG.TXT").exists() else "-"
        lines.append(f"uav{vehicle.sysid}: {files or 'no .BIN'} (LASTLOG {last}){said}")
    return "onboard logs: " + "; ".join(lines)


# ------------------------------------------------------------------------------ the tests
def test_a_killed_fly_leaves_the_fleet_flying_a_plain_fly_commands_nothing_and_resume_judges_it_all(
        fleet: Fleet, fly_runs) -> None:
    configure(fleet)
    relay, plan_dir = fleet.relay, fleet.plan_dir
    crashed = fly_runs(plan_dir, fleet.url)
    assert in_flight(relay, 8), summary(fleet, crashed)
    crashed.kill()  # SIGKILL: a laptop crash, nothing written at exit
    _, _, kept = read_flight(plan_dir)  # what was journaled before the crash is all there
    assert all(rec.started for rec in kept) and not (plan_dir / "flight.json").exists()
    relay.forget()

    # A plain fly finds them armed and flying: one line each, non-zero exit, nothing commanded.
    plain = fly_runs(plan_dir, fleet.url)
    code = plain.finish(60.0)
    assert code != 0, plain.out
    armed_lines = [text for _, text in plain.lines if "is ARMED" in text and "nothing was sent to it" in text]
    assert sorted(text.split("uav")[1].split(":")[0] for text in armed_lines) == [str(k) for k in SYSIDS], plain.out
    assert _commanding(relay) == [], (relay.commands_sent(), plain.out)

    # fly --resume re-attaches, commands nothing, and judges the whole flight with both runs' photos.
    relay.forget()
    resumed = fly_runs(plan_dir, fleet.url, "--resume")
    code = resumed.finish(FLY_TIMEOUT_S)
    doc, rows = flight_doc(plan_dir)
    print(resumed.out, {k: (rows[k]["photos"], rows[k]["photos_from_log"], relay.state(k)) for k in SYSIDS})
    assert code == 0, (resumed.out, doc["problems"], _onboard_logs(fleet))
    assert _commanding(relay) == [], relay.commands_sent()
    assert landed(relay, timeout=10.0), summary(fleet)
    assert all(relay.state(k)["arms"] == 1 for k in SYSIDS), summary(fleet)  # nobody re-armed, nothing re-flown
    planned = {int(d["id"]): int(d["photos"]) for d in json.loads((plan_dir / "report.json").read_text())["drones"]}
    assert all(relay.state(k)["photos"] <= planned[k] + 5 for k in SYSIDS), (planned, summary(fleet))
    assert all(rows[k]["finished"] for k in SYSIDS), doc["problems"]
    # Photos not doubled: at most the vehicle's own count (img_idx from 1), from both runs and its log.
    assert all(0 < rows[k]["photos"] <= relay.state(k)["photos"] for k in SYSIDS), \
        {k: (rows[k]["photos"], relay.state(k)) for k in SYSIDS}
    assert sum(rows[k]["photos_from_log"] for k in SYSIDS) > 0
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])
    assert any("re-attached" in text for d in doc["drones"] for _, text in d["events"])


def test_a_30_s_link_drop_is_a_gap_and_its_photos_come_from_the_logs(fleet: Fleet, fly_runs) -> None:
    configure(fleet)
    relay, plan_dir = fleet.relay, fleet.plan_dir
    run = fly_runs(plan_dir, fleet.url)
    assert in_flight(relay, 3), summary(fleet, run)
    relay.drop()  # both ways
    dropped_at = time.monotonic()
    lost = wait_until(lambda: all(run.first(f"uav{k}", "link lost") for k in SYSIDS), 20.0)
    # The fault is a gap of LINK_DROP_S on our clock: polled (with its bound), then the link is back.
    wait_until(lambda: time.monotonic() - dropped_at >= LINK_DROP_S, LINK_DROP_S + 1.0)
    relay.restore()
    code = run.finish(FLY_TIMEOUT_S)
    doc, rows = flight_doc(plan_dir)
    print(run.out, {k: (rows[k]["photos"], rows[k]["photos_from_log"], relay.state(k)) for k in SYSIDS})
    assert lost, run.out
    assert all(run.first(f"uav{k}", "link back") for k in SYSIDS), run.out
    assert code == 0, (run.out, doc["problems"])
    assert all(rows[k]["finished"] for k in SYSIDS), doc["problems"]
    assert sum(rows[k]["photos_from_log"] for k in SYSIDS) > 0
    assert all(rows[k]["photos"] <= relay.state(k)["photos"] for k in SYSIDS)
    assert doc["coverage"] >= 99.0, (doc["coverage"], doc["problems"])


def test_a_battery_failsafe_on_one_vehicle_ends_its_flight_at_once_with_the_reason(fleet: Fleet, fly_runs) -> None:
    # Every vehicle returns home (RTL) when its battery reads under BATT_LOW_VOLT for BATT_LOW_TIMER.
    configure(fleet, {"BATT_FS_LOW_ACT": 2.0, "BATT_LOW_VOLT": BATTERY_LOW_V})
    relay, plan_dir = fleet.relay, fleet.plan_dir
    run = fly_runs(plan_dir, fleet.url)
    assert in_flight(relay, 5), summary(fleet, run)
    set_param_on_serial1(fleet.vehicle(LOW_BATTERY_SYSID), "SIM_BATT_VOLTAGE", BATTERY_SIM_V)
    code = run.finish(FLY_TIMEOUT_S)
    finished_at = time.monotonic()
    doc, rows = flight_doc(plan_dir)
    low = rows[LOW_BATTERY_SYSID]
    print(run.out, {k: (rows[k]["finished"], rows[k]["ended_early"], relay.state(k)) for k in SYSIDS})
    assert code == 1, (run.out, doc["problems"])  # coverage short
    assert not low["finished"] and low["ended_early"], low
    assert any(word in low["ended_early"].lower() for word in ("battery", "failsafe")), low["ended_early"]
    said = run.first(f"uav{LOW_BATTERY_SYSID}", "before the end of its mission")
    assert said is not None, run.out
    line = next(text for t, text in run.lines if t == said)
    assert any(word in line.lower() for word in ("battery", "failsafe")), line
    # Ended as soon as it was down and disarmed: within 10 s of its own time.
    disarmed_at = relay.state(LOW_BATTERY_SYSID).get("disarmed_at")
    print(f"uav{LOW_BATTERY_SYSID} ended by fly {said - disarmed_at if disarmed_at else None} s after it disarmed")
    assert disarmed_at is not None and 0.0 <= said - disarmed_at <= 10.0 / SPEEDUP + 0.5, \
        (said - disarmed_at if disarmed_at else None, summary(fleet))
    assert all(rows[k]["finished"] for k in SYSIDS if k != LOW_BATTERY_SYSID), doc["problems"]
    assert doc["coverage"] < 99.0
    assert finished_at - run.started < FLY_TIMEOUT_S / 2  # not waiting for the time-out


def test_ctrl_c_stops_following_writes_the_record_and_the_vehicles_fly_on(fleet: Fleet, fly_runs) -> None:
    configure(fleet)
    relay, plan_dir = fleet.relay, fleet.plan_dir
    run = fly_runs(plan_dir, fleet.url)
    assert in_flight(relay, 3), summary(fleet, run)
    relay.forget()
    interrupted = time.monotonic()
    run.proc.send_signal(signal.SIGINT)
    code = run.finish(30.0)
    took = time.monotonic() - interrupted
    states = {k: relay.state(k) for k in SYSIDS}
    print(run.out, f"exited {took:.1f} s after Ctrl-C", states)
    assert code == 1, run.out
    assert "stopped following: uav1, uav2, uav3 fly on with their missions" in run.out, run.out
    assert "Traceback" not in run.out
    assert took < 5.0 + 10.0  # the window for a second Ctrl-C, and the record
    assert all(s["armed"] == 1 and s["custom_mode"] == ARDUPILOT_AUTO for s in states.values()), states
    assert _commanding(relay) == [], relay.commands_sent()
    doc, rows = flight_doc(plan_dir)
    assert not any(rows[k]["finished"] for k in SYSIDS)
    assert all("fly --resume" in p for p in doc["problems"] if "not followed to the end" in p)
    _, _, records = read_flight(plan_dir)  # flight.json is the journal's view
    assert [len(rec.samples) for rec in records] == [rows[k]["samples"] for k in SYSIDS]
