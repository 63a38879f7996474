"""Command-line habits every command shares: no abbreviated options, `--version`, one --connect default,
the ground-station identity and signing options, progress that suits where stderr goes, and signing
named when it is why a vehicle does not answer.

Vehicles are in-process mock autopilots on 127.0.0.1 at ports the system picks (missionplan.bridge.sim.mock); every
command is given an explicit loopback --connect (never the 14550 default); every wait is bounded.
"""

from __future__ import annotations

import argparse
import io
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from missionplan.bridge.link.connection import Link, VehicleInfo, wait_vehicle
from missionplan.bridge.formats.mission_items import (
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
)
from missionplan.bridge.formats.missionfile import PlanFile, write_plan
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.link.signing import SigningKey, new_key, write_key
from missionplan import cli
from missionplan.cli import fly as fly_module
from missionplan.cli.app import build_parser
from missionplan.cli.parsing import package_version
from missionplan.cli.vehicle import CONNECT_HELP, DEFAULT_CONNECT, register
from missionplan.flight.display import progress_display
from missionplan.flight.mock_fleet import start_mock_fleet

SIGNS_UNSIGNED = "the vehicle signs its MAVLink (MAVLink 2 signing) and this link sends unsigned"
FAST = ["--timeout", "3", "--item-timeout", "0.2", "--retries", "2", "--quiet"]


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that nobody holds right now (the system picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def one_line_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run the CLI; it must exit 2 with exactly one line on stderr, which is returned."""
    try:
        code = cli.main(argv)
    except SystemExit as stop:  # argparse's own errors
        code = int(stop.code or 0)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, (code, err)
    return err[0]


def survey_plan(path: Path) -> Path:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.07, y=7.68, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, x=45.07 + i * 1e-4, y=7.68,
                          z=25.0) for i in range(6)]
    write_plan(path, PlanFile(mission=Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)],
                                              home=(45.07, 7.68, 240.0))))
    return path


def record_senders(mock: MockAutopilot) -> set[tuple[int, int]]:
    """(system, component) of every packet the mock's vehicles take from now on."""
    seen: set[tuple[int, int]] = set()
    for vehicle in mock.vehicles.values():
        plain = vehicle.handle

        def handle(msg: Any, now: float, plain: Any = plain) -> None:
            seen.add((msg.get_srcSystem(), msg.get_srcComponent()))
            plain(msg, now)

        vehicle.handle = handle  # type: ignore[method-assign]
    return seen


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Leonardo for 2 drones (the expert: fast), georeferenced: what `fly` flies."""
    out = tmp_path_factory.mktemp("plan")
    assert cli.main(["plan", "--map", "leonardo", "--uavs", "2", "--out", str(out), "--quiet"]) == 0
    return out


@pytest.fixture()
def plan_copy(planned: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(planned, tmp_path / "plan"))


@pytest.fixture()
def key_file(tmp_path: Path) -> tuple[SigningKey, Path]:
    key = new_key()
    path = tmp_path / "fleet.key"
    write_key(path, key)
    return key, path


# ------------------------------------------------------------------------------------ abbreviations

def test_no_parser_in_the_tree_accepts_abbreviations() -> None:
    top = build_parser()
    assert not top.allow_abbrev
    subs = subparsers(top)
    assert {"maps", "plan", "train", "upload", "download", "clear", "mock", "fly", "demo"} <= set(subs)
    assert [name for name, parser in subs.items() if parser.allow_abbrev] == []


@pytest.mark.parametrize("argv, abbreviated", [
    (["plan", "--map", "leonardo", "--uav", "3", "--out", "o"], "--uav"),
    (["train", "--out", "w.pt", "--work", "2"], "--work"),
    (["upload", "m.plan", "--sysid", "1", "--conn", "udpout:127.0.0.1:9"], "--conn"),
    (["download", "--sysid", "1", "-o", "x.plan", "--gcs-sys", "254"], "--gcs-sys"),
    (["clear", "--sysid", "1", "--signing", "k.key"], "--signing"),
    (["mock", "--speed", "2"], "--speed"),
    (["fly", "dir", "--connec", "udpout:127.0.0.1:9"], "--connec"),
    (["demo", "--uav", "2"], "--uav"),
])
def test_an_abbreviated_option_is_refused_in_one_line(argv: list[str], abbreviated: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(argv)  # parsing only: nothing runs, whatever happens
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 2 and len(err) == 1 and f"unrecognized arguments: {abbreviated}" in err[0], err


def test_bridge_subcommands_refuse_abbreviations_under_any_parser(capsys: pytest.CaptureFixture[str]) -> None:
    """vehicle.register() sets it on its own parsers, so a plain argparse parent refuses them too."""
    parser = argparse.ArgumentParser(prog="missionplan")
    register(parser.add_subparsers(dest="command", required=True))
    with pytest.raises(SystemExit):
        parser.parse_args(["upload", "m.plan", "--sysid", "1", "--keep", "--conn", "udpout:127.0.0.1:9"])
    assert "unrecognized arguments: --keep --conn" in capsys.readouterr().err


# ----------------------------------------------------------------------------------------- version

def test_version_prints_the_installed_version_and_exits_0() -> None:
    from importlib import metadata

    out = subprocess.run([sys.executable, "-m", "missionplan", "--version"], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout == f"missionplan {metadata.version('missionplan')}\n"


def test_version_without_package_metadata_comes_from_the_source_tree(monkeypatch: pytest.MonkeyPatch) -> None:
    import tomllib
    from importlib import metadata

    import missionplan

    def not_installed(name: str) -> str:
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "version", not_installed)
    pyproject = Path(cli.__file__).resolve().parents[2] / "pyproject.toml"
    assert package_version() == tomllib.loads(pyproject.read_text())["project"]["version"]

    def unreadable(text: str) -> Any:
        raise tomllib.TOMLDecodeError("broken")

    monkeypatch.setattr(tomllib, "loads", unreadable)
    assert package_version() == missionplan.__version__


# --------------------------------------------------------------------------------------- --connect

def test_connect_has_one_default_and_one_help_in_every_command() -> None:
    subs = subparsers(build_parser())
    for name in ("upload", "download", "clear", "fly"):
        (action,) = [a for a in subs[name]._actions if "--connect" in a.option_strings]
        assert action.help.startswith(CONNECT_HELP) and not action.required, name
        assert action.default == (None if name == "fly" else DEFAULT_CONNECT), name  # fly: see below
    for name in ("download", "clear"):  # once required: now the same default as upload
        args = build_parser().parse_args([name, "--sysid", "1", "-o", "x.plan"] if name == "download"
                                              else [name, "--sysid", "1"])
        assert args.connect == DEFAULT_CONNECT == "udpin:0.0.0.0:14550"


def test_fly_takes_the_default_only_when_no_connect_is_given(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """An argparse append with a default list appends to that list (and keeps it between parses):
    fly's default is applied after parsing, when no --connect came. No socket is opened here."""
    from missionplan.bridge.errors import BridgeError

    (tmp_path / "report.json").write_text("{}")
    asked: list[Any] = []

    def fake_fly(plan_dir: Path, connect: Any, **options: Any) -> Any:
        asked.append(connect)
        raise BridgeError("stop here")

    monkeypatch.setattr(fly_module, "fly", fake_fly)
    a, b = f"udpout:127.0.0.1:{free_udp_port()}", f"1=udpout:127.0.0.1:{free_udp_port()}"
    assert cli.main(["fly", str(tmp_path)]) == 1
    assert cli.main(["fly", str(tmp_path), "--connect", a, "--connect", b]) == 1
    assert cli.main(["fly", str(tmp_path)]) == 1
    assert asked == [[DEFAULT_CONNECT], [a, b], [DEFAULT_CONNECT]]
    assert capsys.readouterr().err.count("missionplan fly: stop here") == 3


# ----------------------------------------------------------------------------- ground-station ids

@pytest.mark.parametrize("extra, message", [
    (["--gcs-sysid", "0"], "--gcs-sysid 0: system ids run from 1 to 255"),
    (["--gcs-sysid", "256"], "--gcs-sysid 256: system ids run from 1 to 255"),
    (["--gcs-sysid", "me"], "--gcs-sysid 'me': not a system id"),
    (["--gcs-sysid", "1"], "--gcs-sysid 1: that is a vehicle's system id"),
    (["--gcs-compid", "0"], "--gcs-compid 0: component ids run from 1 to 255"),
    (["--gcs-compid", "x"], "--gcs-compid 'x': not a component id"),
])
@pytest.mark.parametrize("command", ["upload", "download", "clear", "fly"])
def test_bad_gcs_ids_are_one_line_and_exit_2(command: str, extra: list[str], message: str, planned: Path,
                                             tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    url = f"udpout:127.0.0.1:{free_udp_port()}"  # never opened: the ids are checked first
    argv = {"upload": ["upload", str(survey_plan(tmp_path / "m.plan")), "--sysid", "1"],
            "download": ["download", "--sysid", "1", "-o", str(tmp_path / "d.plan")],
            "clear": ["clear", "--sysid", "1"],
            "fly": ["fly", str(planned)]}[command]
    line = one_line_exit_2(argv + ["--connect", url] + extra, capsys)
    assert line.startswith("missionplan: ") and message in line


def test_upload_with_mavsdk_refuses_another_gcs_identity(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = one_line_exit_2(["upload", str(survey_plan(tmp_path / "m.plan")), "--sysid", "1", "--backend", "mavsdk",
                            "--connect", f"udpout:127.0.0.1:{free_udp_port()}", "--gcs-sysid", "254"], capsys)
    assert "--backend mavsdk" in line and "system 245" in line


def test_upload_download_clear_speak_as_the_gcs_ids_given(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = survey_plan(tmp_path / "m.plan")
    ids = ["--gcs-sysid", "254", "--gcs-compid", "191"]
    with MockAutopilot(request_interval=0.02) as mock:
        seen = record_senders(mock)
        url = ["--connect", mock.client_url]
        assert cli.main(["upload", str(plan), "--sysid", "1", *url, *ids, *FAST]) == 0
        assert cli.main(["download", "--sysid", "1", "-o", str(tmp_path / "d.plan"), *url, *ids, *FAST]) == 0
        assert cli.main(["clear", "--sysid", "1", *url, *ids, *FAST]) == 0
        assert mock.vehicle(1).uploads_completed == 1 and mock.vehicle(1).params["WPNAV_RADIUS"] == 100.0
    assert seen == {(254, 191)}
    out = capsys.readouterr().out
    assert "uploaded 8 items" in out and "downloaded 8 mission items" in out and "cleared the mission" in out


# --------------------------------------------------------------------------- signing named as the cause

def test_unsigned_upload_to_a_signing_vehicle_names_signing(tmp_path: Path, key_file: tuple[SigningKey, Path],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The report: "parameter WPNAV_RADIUS did not answer", signing never named."""
    plan = survey_plan(tmp_path / "m.plan")
    with MockAutopilot(key=key_file[0], request_interval=0.02) as mock:
        url = ["--connect", mock.client_url]
        assert cli.main(["upload", str(plan), "--sysid", "1", *url, *FAST]) == 1
        first = capsys.readouterr().err.strip().splitlines()
        assert cli.main(["upload", str(plan), "--sysid", "1", "--keep-params", *url, *FAST]) == 1
        second = capsys.readouterr().err.strip().splitlines()
        assert cli.main(["download", "--sysid", "1", "-o", str(tmp_path / "d.plan"), *url, *FAST]) == 1
        third = capsys.readouterr().err.strip().splitlines()
        assert cli.main(["clear", "--sysid", "1", *url, *FAST]) == 1
        fourth = capsys.readouterr().err.strip().splitlines()
        assert mock.vehicle(1).uploads_completed == 0
    for lines, start in ((first, "missionplan upload: vehicle 1 did not answer for parameter WPNAV_RADIUS"),
                         (second, "missionplan upload: vehicle 1 answered nothing"),
                         (third, "missionplan download: vehicle 1 did not send the mission count"),
                         (fourth, "missionplan clear: vehicle 1 did not send an answer to clearing")):
        assert len(lines) == 1 and lines[0].startswith(start), lines
        assert lines[0].endswith(f"{SIGNS_UNSIGNED}, so it likely ignores us; give --signing-key"), lines


def test_no_signing_hint_when_the_vehicle_does_not_sign() -> None:
    with MockAutopilot(request_interval=0.02) as mock, Link(mock.client_url) as link:
        info = wait_vehicle(link, 1, timeout=3.0)
        assert not info.signed and link.signing_hint(1) == ""
        with pytest.raises(Exception) as err:  # a parameter the mock does not have: no answer
            ParamClient(link, info).get("NO_SUCH_PARAM", tries=1, wait_s=0.2)
        assert str(err.value) == "vehicle 1 did not answer for parameter NO_SUCH_PARAM (1 tries, 0.2 s each)"


def test_a_wrong_key_is_named_when_the_vehicle_does_not_answer(key_file: tuple[SigningKey, Path]) -> None:
    """We sign with another key: the vehicle's packets fail our check, and what it does not answer says so."""
    from missionplan.bridge.errors import BridgeError

    with MockAutopilot(key=key_file[0], request_interval=0.02) as mock, Link(mock.client_url, new_key()) as link:
        deadline = time.monotonic() + 3.0
        while link.bad_signatures == 0 and time.monotonic() < deadline:  # its heartbeats, refused
            link.recv(min(deadline, time.monotonic() + 0.1))
        assert link.bad_signatures > 0
        info = VehicleInfo(sysid=1, compid=1, autopilot=3, mav_type=2, flavour=Flavour.ARDUPILOT, signed=True)
        with pytest.raises(BridgeError) as err:
            ParamClient(link, info).set("WPNAV_RADIUS", 100.0, tries=1, wait_s=0.2)
    assert "did not answer for parameter WPNAV_RADIUS" in str(err.value)
    assert "packets were refused because they were signed with another key (wrong --signing-key?)" in str(err.value)


# ------------------------------------------------------------------------------------------------ fly

@pytest.mark.flight
def test_fly_signs_speaks_as_the_gcs_ids_and_logs_plain_lines(plan_copy: Path, key_file: tuple[SigningKey, Path],
                                                             tmp_path: Path) -> None:
    """`fly` in its own process with stderr to a file (not a terminal): a signed fleet flies, every packet
    it took came from --gcs-sysid / --gcs-compid, and the log holds plain lines, no cursor codes."""
    key, path = key_file
    mock = start_mock_fleet(plan_copy, speedup=10.0, key=key)
    try:
        seen = record_senders(mock)
        log = tmp_path / "fly.log"
        with log.open("w") as stderr:
            done = subprocess.run([sys.executable, "-m", "missionplan", "fly", str(plan_copy), "--connect",
                                   mock.client_url, "--signing-key", str(path), "--gcs-sysid", "254",
                                   "--gcs-compid", "191", "--time-scale", "10", "--timeout", "120"],
                                  stdout=subprocess.PIPE, stderr=stderr, text=True, timeout=180)
        rejected = mock.stats["rejected"]
    finally:
        mock.stop()
    text = log.read_text()
    assert done.returncode == 0, done.stdout + text
    assert "flown coverage" in done.stdout and rejected == 0 and seen == {(254, 191)}
    assert "\x1b" not in text and "\r" not in text and "it/s" not in text and "item/s" not in text
    lines = text.splitlines()
    for uav in ("uav1", "uav2"):
        assert f"{uav}: mission started" in lines and any(line.startswith(f"{uav}: at item ") for line in lines)


@pytest.mark.flight
def test_fly_without_the_key_names_signing(plan_copy: Path, key_file: tuple[SigningKey, Path],
                                           capsys: pytest.CaptureFixture[str]) -> None:
    mock = start_mock_fleet(plan_copy, speedup=10.0, key=key_file[0])
    try:
        code = cli.main(["fly", str(plan_copy), "--connect", mock.client_url, "--timeout", "8", "--ready-timeout", "5",
                         "--quiet"])
    finally:
        mock.stop()
    out = capsys.readouterr().out
    problems = [line for line in out.splitlines() if line.startswith("  problem: ")]
    assert code == 1 and len(problems) == 2, out
    assert all(SIGNS_UNSIGNED in line and line.endswith("give --signing-key") for line in problems), out


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bars_only_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    for stream, bars_expected in ((_Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        bars, say, _ = progress_display({1: "uav1"}, progress=True)
        bars[1].n = 1
        bars[1].refresh()  # readiness, before the mission: a log says nothing
        bars[1].reset(total=8)
        for item in range(1, 9):
            bars[1].n = item
            bars[1].refresh()
        say("uav1: ready after 1.0 s")
        bars[1].close()
        text = stream.getvalue()
        assert ("\r" in text) is bars_expected and "uav1: ready after 1.0 s" in text
        if not bars_expected:
            assert text.splitlines() == ["uav1: mission started", "uav1: at item 2 of 8", "uav1: at item 4 of 8",
                                         "uav1: at item 6 of 8", "uav1: at item 8 of 8", "uav1: ready after 1.0 s"]
    monkeypatch.setattr(sys, "stderr", _Terminal())
    assert progress_display({1: "uav1"}, progress=False)[0] == {}  # --quiet: no bars (alerts are said)
