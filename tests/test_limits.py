"""Limits before work: what no mission, option or file may hold is refused in one line, before any work,
any file written or any packet sent; what a file says is printed escaped; the mock refuses what ArduCopter
cannot store and keeps serving.

Each refusal is checked as a crew meets it: the exit code (2), exactly one line on stderr, no traceback,
and nothing written (the output folder absent, a plan folder's files hashed before and after).

Memory of the item-count refusal, measured with bench/limits_bench.py (the child's own peak resident memory
above what importing the reader took, VmHWM): a .waypoints of 1,000,000 items (36 MiB) is refused at line 65,537
in +30 MB and about a second, where the old reader took +996 MB and 18 s to read it whole (then the upload
died of a struct.error); a .plan of 70,000 items in +43 MB;
a .plan over the 96 MiB size bound from its size alone, unread, in +0 MB; the largest compact .plan under the
bound (883,009 items) is parsed before its count refuses it: +550 MB and 6 s, the bound's price, stated in
docs/file-formats.md. Not timed here: the tests below check the answers, the bench the cost.
"""

from __future__ import annotations

import hashlib
import json
import math
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from missionplan import cli
from missionplan.cli import plan as plan_command
from missionplan.bridge.formats.mission_items import MissionType
from missionplan.bridge.limits import check_integer, check_range
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.sim.mission_server import MissionServer
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.terminal_text import printable
from missionplan.bridge.transfer.protocol import MissionTransferError, Timeouts
from missionplan.bridge.transfer.uploader import PymavlinkBackend
from missionplan.flight.display import progress_display
from missionplan.maps import catalog
from missionplan.maps.gridmap import MapError
from missionplan.testing.limit_cases import EXPECTED_ARDUCOPTER, EXPECTED_PX4, HOME, mock_answers
from missionplan.testing.plans import wire_item
from missionplan.testing.px4_mission_session import HOME as PX4_HOME

HOME_LINE = "0\t1\t0\t16\t0\t0\t0\t0\t45.07\t7.68\t240\t1\n"
HOSTILE = "\x1b[2J\x1b[31mred\x07bell\rover\u202eevil"  # clear screen, colour, bell, carriage return, RTL
# What a .map line can hold (its lines end at a CR): clear screen, colour, bell, backspace, C1 CSI, RTL override.
MAP_HOSTILE = "\x1b[2J\x1b[31mred\x07bell\x08\x9b2Jover\u202eevil"


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """The CLI in-process: (exit code, stdout, stderr); a traceback would fail the test by itself."""
    try:
        code = cli.main(argv)
    except SystemExit as stop:  # argparse's own errors
        code = int(stop.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The command must exit 2 with exactly one line on stderr and no traceback; returns the line."""
    code, _, err = run(argv, capsys)
    lines = err.splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, (code, err)
    return lines[0]


def waypoints(path: Path, rows: list[str]) -> Path:
    path.write_text("QGC WPL 110\n" + HOME_LINE + "".join(rows))
    return path


def row(index: int, frame: int, command: int, p1: float = 0, p2: float = 0, z: float = 30.0, x: float = 45.07,
        y: float = 7.68) -> str:
    return f"{index}\t0\t{frame}\t{command}\t{p1}\t{p2}\t0\t0\t{x}\t{y}\t{z}\t1\n"


def plan_doc(items: list[dict[str, Any]]) -> dict[str, Any]:
    return {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
            "mission": {"version": 2, "firmwareType": 3, "plannedHomePosition": [45.07, 7.68, 240], "items": items},
            "geoFence": {"version": 2, "circles": [], "polygons": []}, "rallyPoints": {"version": 2, "points": []}}


def simple(command: int, params: list[Any], jump_id: int, frame: int = 3) -> dict[str, Any]:
    return {"type": "SimpleItem", "command": command, "frame": frame, "doJumpId": jump_id, "autoContinue": True,
            "params": params}


def upload(path: Path) -> list[str]:
    """An upload of `path` to a port nobody serves: bad input must be refused before any connection."""
    return ["upload", str(path), "--sysid", "1", "--connect", "udpout:127.0.0.1:9", "--timeout", "1", "--quiet"]


def folder_hashes(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------------------------- item counts

def test_a_waypoints_file_beyond_the_mavlink_count_is_refused_while_it_is_read(tmp_path, capsys):
    # 70,000 items, then bytes that are not UTF-8: a reader that read the file whole would stumble on those
    # (or, before, on struct.error packing MISSION_COUNT); this one stops at the first item too many.
    path = tmp_path / "big.waypoints"
    with path.open("w") as out:
        out.write("QGC WPL 110\n" + HOME_LINE)
        out.writelines(row(i, 3, 16) for i in range(1, 70_001))
    with path.open("ab") as out:
        out.write(b"\xff\xfe not text")
    line = refused(upload(path), capsys)
    assert line.startswith(f"missionplan: {path}: line 65537: more than 65,534 mission items")
    assert "MISSION_COUNT counts 65,535 items at most" in line and "home item" in line


def test_a_plan_beyond_the_mavlink_count_is_refused(tmp_path, capsys):
    item = simple(16, [0, 0, 0, None, 45.07, 7.68, 30], 1)
    path = tmp_path / "big.plan"
    path.write_text(json.dumps(plan_doc([dict(item, doJumpId=i) for i in range(1, 70_001)])))
    line = refused(upload(path), capsys)
    assert line == (f"missionplan: {path}: 70,000 mission items: one upload carries at most 65,534 (MAVLink's "
                    "MISSION_COUNT counts 65,535 items at most, ArduPilot's home item one of them); split it")


def test_a_json_mission_larger_than_any_legal_one_is_refused_unread(tmp_path, capsys):
    path = tmp_path / "huge.plan"
    with path.open("wb") as out:
        out.truncate(97 * 2**20)  # sparse: 97 MiB of zeros, never written; not even valid JSON
    line = refused(upload(path), capsys)
    assert line.startswith(f"missionplan: {path}: 97 MiB, larger than any mission MAVLink can carry")


# ---------------------------------------------------------------------------------------- numbers

@pytest.mark.parametrize("z, message", [
    (-1e9, "altitude -1e+09: must be metres above home (frame 3), from -10,000 to 30,000 m"),
    (1e38, "altitude 1e+38: must be metres above home (frame 3), from -10,000 to 30,000 m"),
])
def test_absurd_waypoint_altitudes_are_refused(tmp_path, capsys, z, message):
    path = waypoints(tmp_path / "m.waypoints", [row(1, 3, 22, z=10), row(2, 3, 16, z=z)])
    assert refused(upload(path), capsys) == f"missionplan: {path}: line 4 (item 2): {message}"


def test_a_mountain_site_above_sea_level_is_a_mission(tmp_path):
    from missionplan.bridge.formats.missionfile import read_mission_file

    # Frame 0 (AMSL) at 4,800 m on a summit, and 8,000 m below a home on it in frame 3: both fly somewhere.
    path = waypoints(tmp_path / "m.waypoints", [row(1, 0, 16, z=4_800.0), row(2, 3, 16, z=-8_000.0)])
    assert [item.z for item in read_mission_file(path).mission.items] == [4_800.0, -8_000.0]


@pytest.mark.parametrize("command, params, message", [
    (16, [0, 0, 0, 1e30, 45.07, 7.68, 30], "param4 (yaw) 1e+30: must be from -360 to 360 degrees"),
    (16, [1e6, 0, 0, None, 45.07, 7.68, 30], "param1 (hold time) 1e+06: must be from 0 to 65,535 s"),
    (178, [1, 1e30, -1, 0, 0, 0, 0], "param2 (speed) 1e+30: must be from -2 to 300 m/s"),
])
def test_angles_speeds_and_times_of_items_are_checked(tmp_path, capsys, command, params, message):
    path = tmp_path / "m.plan"
    path.write_text(json.dumps(plan_doc([simple(command, params, 1)])))
    assert refused(upload(path), capsys) == f"missionplan: {path}: mission item 1: {message}"


@pytest.mark.parametrize("argv, message", [
    (["--rotation", "1e308"], "--rotation 1e+308: must be a grid angle, from -360 to 360 degrees"),
    (["--speed", "1e308"], "--speed 1e+308: must be a waypoint speed ArduCopter and PX4 fly, above 0 and at most 20 m/s"),
    (["--seed", "-1"], "--seed -1: must be an integer from 0 to 4,294,967,295"),
    (["--overlap", "nan"], "--overlap nan: must be a fraction, at least 0 and below 1"),
    (["--max-altitude", "1e9"], "--max-altitude 1e+09: must be above 0 and at most 5,000 m"),
    (["--endurance", "-5"], "--endurance -5: must be 0 (no limit) or minutes, from 0 to 1,440 minutes"),
    (["--clearance", "inf"], "--clearance inf: must be from 0 to 1,000 m"),
    (["--altitude-step", "1e9"], "--altitude-step 1e+09: must be from 0 to 5,000 m"),
    (["--min-separation", "0"], "--min-separation 0: must be above 0 and at most 1,000 m"),
    (["--reserve", "1"], "--reserve 1: must be a fraction, at least 0 and below 1"),
])
def test_plan_options_out_of_range_are_refused_before_anything(tmp_path, capsys, argv, message):
    out = tmp_path / "out"
    line = refused(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--quiet", *argv], capsys)
    assert line == f"missionplan: {message}"
    assert not out.exists()


@pytest.mark.parametrize("argv, message", [
    (["plan", "--map", "leonardo", "--uavs", "300", "--out", "OUT"], "--uavs 300: must be a number of drones"),
    (["fly", "DIR", "--timeout", "nan"], "--timeout nan: must be above 0 and at most 604,800 s"),
    (["fly", "DIR", "--telemetry-hz", "1e9"], "--telemetry-hz 1e+09: must be from 0.01 to 1,000 Hz"),
    (["fly", "DIR", "--time-scale", "0"], "--time-scale 0: must be above 0 and at most 1,000"),
    (["fly", "DIR", "--sortie", "0"], "--sortie 0: must be an integer from 1 to 10,000"),
    (["upload", "F.plan", "--sysid", "1", "--timeout", "1e308"], "--timeout 1e+308: must be above 0"),
    (["download", "--sysid", "1", "-o", "x.plan", "--item-timeout", "nan"], "--item-timeout nan: must be above 0"),
    (["clear", "--sysid", "1", "--retries", "-1"], "--retries -1: must be an integer from 0 to 1,000"),
    (["mock", "--speedup", "1e308"], "--speedup 1e+308: must be simulated seconds per second"),
    (["mock", "--duration", "-1"], "--duration -1: must be above 0"),
    (["mock", "--home", "45,7,1e9"], "--home 45,7,1e9: altitude 1e+09: must be metres above sea level"),
    (["demo", "--speedup", "inf"], "--speedup inf: must be simulated seconds per second"),
    (["train", "--out", "w.pt", "--workers", "0"], "--workers 0: must be a number of processes"),
    (["replan", "DIR", "--out", "NEW", "--seed", "-1"], "--seed -1: must be an integer from 0"),
])
def test_every_command_checks_its_numbers_first(tmp_path, capsys, argv, message):
    argv = [str(tmp_path / a) if a in ("OUT", "DIR", "NEW", "F.plan") else a for a in argv]
    if argv[0] == "fly":
        (tmp_path / "DIR").mkdir()
    line = refused(argv, capsys)
    assert line.startswith(f"missionplan: {message}"), line
    assert not (tmp_path / "OUT").exists() and not (tmp_path / "NEW").exists()
    assert not (tmp_path / "DIR").exists() or not any((tmp_path / "DIR").iterdir())


def test_the_check_names_the_value_and_raises_the_callers_error() -> None:
    assert check_range(5.0, "--x", 0.0, 10.0) == 5.0
    with pytest.raises(MapError, match=r"^--x nan: must be above 0 and below 1 m$"):
        check_range(math.nan, "--x", 0.0, 1.0, unit=" m", low_open=True, high_open=True, error=MapError)
    with pytest.raises(MapError, match=r"^--n 10\*\*400 \.\.\.|^--n 1000000"):
        check_integer(10**400, "--n", 0, 5, error=MapError)
    with pytest.raises(MapError, match="must be an integer"):
        check_integer(True, "--n", 0, 5, error=MapError)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------- DO_JUMP

def test_a_jump_to_itself_for_ever_is_refused(tmp_path, capsys):
    path = waypoints(tmp_path / "loop.waypoints", [row(1, 3, 22, z=10), row(2, 2, 177, p1=2, p2=-1, x=0, y=0, z=0)])
    assert refused(upload(path), capsys) == (
        f"missionplan: {path}: line 4 (item 2): DO_JUMP to itself repeats for ever (repeat -1) over no navigation "
        "command: the vehicle would stay where it is and never fly the rest of the mission")


def test_a_jump_back_over_a_waypoint_is_a_mission(tmp_path):
    from missionplan.bridge.formats.missionfile import read_mission_file

    path = waypoints(tmp_path / "laps.waypoints", [row(1, 3, 22, z=10), row(2, 3, 16),
                                                   row(3, 2, 177, p1=2, p2=-1, x=0, y=0, z=0)])
    assert len(read_mission_file(path).mission.items) == 3


@pytest.mark.parametrize("target", [0, 3, 99, -5])
def test_a_jump_outside_the_mission_is_refused(tmp_path, capsys, target):
    path = waypoints(tmp_path / "far.waypoints", [row(1, 3, 22, z=10), row(2, 2, 177, p1=target, p2=1, x=0, y=0,
                                                                            z=0)])
    assert refused(upload(path), capsys) == (
        f"missionplan: {path}: line 4 (item 2): DO_JUMP to item {target}, outside the mission's items 1..2")


def test_a_plan_jump_to_itself_for_ever_is_refused(tmp_path, capsys):
    path = tmp_path / "loop.plan"
    path.write_text(json.dumps(plan_doc([simple(22, [0, 0, 0, None, 45.07, 7.68, 10], 1),
                                         simple(177, [2, -1, 0, 0, 0, 0, 0], 2, frame=2)])))
    assert "mission item 2: DO_JUMP to itself repeats for ever" in refused(upload(path), capsys)


# ------------------------------------------------------------------------------------------ .map

def test_a_map_header_key_given_twice_is_refused_naming_both_lines(tmp_path, capsys):
    path = tmp_path / "twice.map"
    path.write_text("name: one\ncell_m: 1\nname: two\nlaunch: 1,1\ngrid:\n###\n#.#\n###\n")
    out = tmp_path / "out"
    line = refused(["plan", "--map", str(path), "--uavs", "1", "--out", str(out), "--quiet"], capsys)
    assert line == f"missionplan: {path}:3: header key 'name' given twice (lines 1 and 3); keep one"
    assert not out.exists()


# ------------------------------------------------------------------------------------------- fly

@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plan") / "leonardo"
    assert cli.main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--quiet"]) == 0
    return out


def test_fly_refuses_an_empty_mission_before_any_vehicle_hears_of_it(planned, tmp_path, capsys):
    folder = tmp_path / "plan"
    folder.mkdir()
    for path in planned.iterdir():
        if path.is_file():
            (folder / path.name).write_bytes(path.read_bytes())
    empty = folder / "uav2.plan"
    doc = json.loads(empty.read_text())
    doc["mission"]["items"] = []
    empty.write_text(json.dumps(doc))
    before = folder_hashes(folder)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as vehicle:  # where the vehicles would be
        vehicle.bind(("127.0.0.1", 0))
        vehicle.setblocking(False)
        line = refused(["fly", str(folder), "--connect", f"udpout:127.0.0.1:{vehicle.getsockname()[1]}", "--quiet"],
                       capsys)
        with pytest.raises(BlockingIOError):
            vehicle.recv(1024)  # not one packet was sent
    assert line == (f"missionplan: {empty}: the file holds no mission items; flying it would wipe vehicle 2's "
                    "mission (plan the folder again, or `missionplan clear` the vehicle to mean that)")
    assert folder_hashes(folder) == before


# ------------------------------------------------------------------------------------ escaping

def hostile_map(path: Path, name: str) -> Path:
    path.write_text(f"name: {name}\ntitle: {name}\nlaunch: 1,1\ngrid:\n#####\n#...#\n#...#\n#####\n")
    return path


def assert_clean(text: str) -> None:
    """No control character but the newlines that end lines, and no bidirectional override."""
    assert not any(ord(c) < 32 and c != "\n" or 0x7f <= ord(c) < 0xa0 or c == "\u202e" for c in text), repr(text)


def test_printable_escapes_every_control_character() -> None:
    assert printable(HOSTILE) == "\\x1b[2J\\x1b[31mred\\x07bell\\rover\\u202eevil"
    assert printable("a\nb\tc\x00d\x9be") == "a\\nb\\tc\\x00d\\x9be"
    assert printable("Torino, via Cernaia 1 — 中文 é") == "Torino, via Cernaia 1 — 中文 é"
    long = "x" * 100_000 + "\r"
    assert printable(long) == "x" * 100_000 + "\\r"


def test_plan_prints_a_hostile_map_name_escaped(tmp_path):
    name = MAP_HOSTILE + "y" * 5_000  # and a long line
    path = hostile_map(tmp_path / "evil.map", name)
    # A real process: what reaches its stderr includes warnings (plan.png's title once warned of each control
    # character's missing glyph, quoting it raw).
    done = subprocess.run([sys.executable, "-m", "missionplan", "plan", "--map", str(path), "--uavs", "1", "--out",
                           str(tmp_path / "o"), "--quiet"], capture_output=True, text=True, timeout=120)
    assert done.returncode in (0, 1), done.stderr
    assert_clean(done.stdout + done.stderr)
    assert f"map {printable(name)} (4 x 5)" in done.stdout.splitlines()[0]


def test_maps_prints_a_hostile_title_escaped(tmp_path, capsys, monkeypatch):
    hostile_map(tmp_path / "evil.map", MAP_HOSTILE)
    monkeypatch.setattr(catalog, "MAPS_DIR", tmp_path)
    monkeypatch.setattr(plan_command, "shipped_map_names", catalog.shipped_map_names)
    code, out, err = run(["maps"], capsys)
    assert code == 0 and out.splitlines()[1].endswith(printable(MAP_HOSTILE))
    assert_clean(out + err)


def test_an_error_quoting_a_file_is_one_escaped_line(tmp_path, capsys):
    path = tmp_path / "evil.map"
    path.write_text(f"{MAP_HOSTILE}: 1\n{MAP_HOSTILE}: 2\nlaunch: 1,1\ngrid:\n###\n#.#\n###\n")
    line = refused(["plan", "--map", str(path), "--uavs", "1", "--out", str(tmp_path / "o")], capsys)
    assert_clean(line)
    assert "given twice (lines 1 and 2)" in line and "\\x1b[2J" in line
    # A file whose very name moves the cursor back (CR) and rings the bell: named, escaped, on one line.
    named = tmp_path / "mission\r\x07.waypoints"
    named.write_text("not a mission\n")
    line = refused(upload(named), capsys)
    assert_clean(line)
    assert line.startswith(f"missionplan: {tmp_path}/mission\\r\\x07.waypoints: not a waypoints file")


def test_fly_says_a_vehicles_text_escaped(capsys):
    _, say, alert = progress_display({1: "uav1"}, progress=True)
    alert("uav1: says: " + HOSTILE)
    err = capsys.readouterr().err
    assert err == "uav1: says: " + printable(HOSTILE) + "\n"


# -------------------------------------------------------------------------------------------- mock

LAT, LON = 450700000, 76800000


def _upload(mock: MockAutopilot, items: list[Any], mission_type: int = MissionType.MISSION) -> int:
    """The MISSION_ACK result of a raw upload (no file, no checks of ours): 0 when accepted."""
    with PymavlinkBackend(mock.client_url, 1, timeouts=Timeouts(item_timeout=0.3, retries=2)) as backend:
        try:
            backend.upload(mission_type, items)
        except MissionTransferError as err:
            return int(err.result)
    return 0


def _mission(z: float) -> list[Any]:
    return [wire_item(0, 0, 16, x=LAT, y=LON), wire_item(1, 3, 22, x=LAT, y=LON, z=10.0),
            wire_item(2, 3, 16, x=LAT + 100, y=LON, z=z)]


@pytest.mark.parametrize("z, result", [(1e38, mavlink.MAV_MISSION_INVALID_PARAM7),
                                       (-1e9, mavlink.MAV_MISSION_INVALID_PARAM7),
                                       (83_000.0, mavlink.MAV_MISSION_INVALID_PARAM7),
                                       (82_999.0, mavlink.MAV_MISSION_ACCEPTED)])
def test_the_mock_answers_an_altitude_it_cannot_store_as_arducopter(z, result):
    with MockAutopilot("udpin:127.0.0.1:0") as mock:
        assert _upload(mock, _mission(z)) == result
        assert _upload(mock, _mission(30.0)) == 0  # and serves on
        assert mock.vehicle(1).handler_errors == 0


def test_the_mock_survives_a_handler_that_raises(monkeypatch, caplog):
    def broken(self: MissionServer, item: Any) -> Any:
        raise OverflowError("float too large \x1b[31m")

    monkeypatch.setattr(MissionServer, "_stored", broken)
    with MockAutopilot("udpin:127.0.0.1:0") as mock:
        with caplog.at_level("ERROR", logger="missionplan.bridge.sim"):
            assert _upload(mock, _mission(30.0)) == mavlink.MAV_MISSION_ERROR
        monkeypatch.undo()
        assert _upload(mock, _mission(30.0)) == 0
        assert mock.serving
        assert mock.vehicle(1).handler_errors == 1
    assert [r.getMessage() for r in caplog.records] == [
        "mock vehicle 1: OverflowError answering MISSION_ITEM_INT: float too large \\x1b[31m"]


def test_the_mock_answers_out_of_range_items_as_the_autopilots_did() -> None:
    """Without SITL: each flavour of the mock gives the answers measured on the real autopilots."""
    ardupilot = mock_answers("ardupilot", HOME, 7)
    assert {name: result for name, (result, _) in ardupilot.items()} == EXPECTED_ARDUCOPTER
    assert ardupilot["waypoint hold 1e6 s"][1][5] == 16_960.0  # param1 of the stored item, as SITL holds it
    px4_mock = mock_answers("px4", PX4_HOME, 11)
    assert {name: result for name, (result, _) in px4_mock.items()} == EXPECTED_PX4
    assert px4_mock["DO_JUMP to itself for ever"][1][6] == 65_535.0  # param2: PX4's uint16 repeat count
