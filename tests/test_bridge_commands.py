"""The upload / download / mock subcommands, through the CLI's parser, their handlers called as main() calls them."""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path

import pytest

from missionplan.bridge import BridgeUsageError
from missionplan.cli.app import build_parser
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
from missionplan.bridge.formats.missionfile import PlanFile, read_plan, write_plan, write_waypoints
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.testing.loopback import udp_port_free, wait_until


def run(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    return int(args.handler(args))


def _mission(n: int = 12) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.07, y=7.68, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, param4=math.nan, x=45.07 + i * 1e-4,
                          y=7.68, z=25.0) for i in range(n)]
    return Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=(45.07, 7.68, 240.0))


FAST = ["--timeout", "2", "--item-timeout", "0.2", "--retries", "3", "--quiet"]


@pytest.fixture()
def mock() -> MockAutopilot:
    with MockAutopilot(sysids=[1, 2], request_interval=0.02, upload_timeout=1.0) as m:
        yield m


def test_upload_plan_and_waypoints_then_download(tmp_path: Path, mock: MockAutopilot,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission()))
    assert run(["upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1].startswith("uploaded 14 items (14 mission, no fence, no rally) to vehicle 1 (ardupilot, pymavlink); "
                              "verified by read-back (pymavlink); set WPNAV_RADIUS = 100 cm (was 200): the plan's "
                              "acceptance radius (ArduCopter ignores the waypoints' param2)")
    assert mock.vehicle(1).params["WPNAV_RADIUS"] == 100.0
    wp_path = tmp_path / "m.waypoints"
    write_waypoints(wp_path, _mission(5))
    assert run(["upload", str(wp_path), "--sysid", "2", "--connect", mock.client_url] + FAST) == 0
    assert len(mock.mission(2)) == 8 and len(mock.mission(1)) == 15
    assert run(["upload", str(wp_path), "--sysid", "2", "--connect", mock.client_url, "--no-verify"] + FAST) == 0
    assert "not verified (--no-verify)" in capsys.readouterr().out
    out_plan = tmp_path / "down.plan"
    assert run(["download", "--sysid", "1", "--connect", mock.client_url, "-o", str(out_plan)] + FAST) == 0
    assert "downloaded 14 mission items from vehicle 1" in capsys.readouterr().out
    back = read_plan(out_plan)
    assert [i.command for i in back.mission.items] == [i.command for i in _mission().items]
    assert back.mission.home is not None and math.isclose(back.mission.home[0], 45.0703)  # the mock's home
    assert json.loads(out_plan.read_text())["mission"]["firmwareType"] == 3


@pytest.mark.parametrize("argv, message", [
    (["upload", "MISSING.plan", "--sysid", "1"], "no such file"),
    (["upload", "FILE", "--sysid", "0"], "system ids run from 1 to 254"),
    (["upload", "FILE", "--sysid", "one"], "not a system id"),
    (["upload", "FILE", "--sysid", "1", "--connect", "http://127.0.0.1:80"], "not a connection string"),
    (["upload", "FILE", "--sysid", "1", "--connect", "udpout:127.0.0.1"], "expected udpout:HOST:PORT"),
    (["upload", "FILE", "--sysid", "1", "--signing-key", "NOKEY"], "no such file"),
    (["download", "--sysid", "1", "--connect", "udpout:127.0.0.1:9", "-o", "x.kml"], "unknown mission file type"),
    (["mock", "--sysid", "1,1"], "appears twice"),
    (["mock", "--listen", "tcp:127.0.0.1:5760"], "udpin:, udpout: or tcpin:"),
    (["mock", "--loss", "1.5", "--listen", "udpin:127.0.0.1:0"], "--loss 1.5: must be a probability, from 0 to 1"),
])
def test_bad_input_raises_a_one_line_usage_error(tmp_path: Path, argv: list[str], message: str) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission()))
    argv = [str(plan_path) if a == "FILE" else str(tmp_path / a) if a in ("MISSING.plan", "NOKEY") else a for a in argv]
    with pytest.raises(BridgeUsageError) as err:
        run(argv)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_reboot_mid_upload_exits_1_and_the_next_upload_succeeds(tmp_path: Path, mock: MockAutopilot,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission(60)))
    mock.reboot_after_items(1, 20, offline=0.3)
    assert run(["upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url] + FAST) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("missionplan upload: vehicle 1 rebooted during the mission upload")
    assert run(["upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    assert len(mock.mission(1)) == 63


def test_unreachable_sysid_exits_1_within_the_timeout(tmp_path: Path, mock: MockAutopilot,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=_mission()))
    start = time.monotonic()
    code = run(["upload", str(plan_path), "--sysid", "7", "--connect", mock.client_url, "--timeout", "1", "--quiet"])
    assert code == 1 and time.monotonic() - start < 6  # --timeout 1, not the default 10 s (busy machines are slow)
    err = capsys.readouterr().err.strip()
    assert err.startswith("missionplan upload: no heartbeat from system 7") and "within 1 s" in err


def test_mock_command_serves_until_its_duration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Find a free port, then let the command listen there.
    probe = MockAutopilot(listen="udpin:127.0.0.1:0")
    port = probe.port
    probe.close_sockets()
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(run(
        ["mock", "--sysid", "4,5", "--listen", f"udpin:127.0.0.1:{port}", "--flavour", "px4", "--speedup", "10",
         "--request-interval", "0.02", "--duration", "4"])))
    thread.start()
    try:
        plan_path = tmp_path / "m.plan"
        write_plan(plan_path, PlanFile(mission=_mission(), firmware=Flavour.PX4))
        assert wait_until(lambda: not udp_port_free(port), 3.0), "the mock command never bound its port"
        assert run(["upload", str(plan_path), "--sysid", "5", "--connect", f"udpout:127.0.0.1:{port}"] + FAST) == 0
        assert "vehicle 5 (px4, pymavlink)" in capsys.readouterr().out
    finally:
        thread.join(10)
    assert codes == [0]
    assert "mock autopilot stopped: 1 uploads completed" in capsys.readouterr().out


def test_mock_command_configures_the_cameras_of_a_sitl_like_fleet(monkeypatch: pytest.MonkeyPatch) -> None:
    configured: list[int] = []
    original = MockAutopilot.configure_camera

    def recording(self: MockAutopilot, sysid: int, offline: float = 0.05) -> None:
        original(self, sysid, offline)
        configured.append(sysid)
        assert self.vehicles[sysid].params["CAM1_TYPE"] == 1.0

    monkeypatch.setattr(MockAutopilot, "configure_camera", recording)
    assert run(["mock", "--sysid", "2,3", "--listen", "udpin:127.0.0.1:0", "--sitl-like", "--camera-configured",
                "--duration", "0.3"]) == 0
    assert configured == [2, 3]
    with pytest.raises(BridgeUsageError, match="--camera-configured needs --sitl-like"):
        run(["mock", "--sysid", "2", "--listen", "udpin:127.0.0.1:0", "--camera-configured", "--duration", "0.3"])
