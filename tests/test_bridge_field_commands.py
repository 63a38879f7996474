"""Field faults at the command line: bad numbers, empty files, `clear`, other file names, -o.

Each test drives the real `upload` / `download` / `clear` handlers against a mock autopilot on
loopback and checks the one-line message, the exit code and what the vehicle holds afterwards.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from missionplan.bridge import BridgeUsageError
from missionplan.bridge.formats.mission_items import (
    CMD_FENCE_POLYGON_VERTEX_INCLUSION,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    CMD_RALLY_POINT,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Mission,
    MissionItem,
    MissionType,
)
from missionplan.bridge.formats.missionfile import PlanFile, write_plan, write_waypoints
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.cli import main

from test_bridge_commands import FAST, run  # tests/: pyproject.toml's pytest pythonpath


def _mission(n: int = 8) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=25.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param1=1.0, x=45.07 + i * 1e-4, y=7.68,
                          z=25.0) for i in range(n)]
    return Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=(45.07, 7.68, 240.0))


def _fenced(n: int = 8) -> PlanFile:
    plan = PlanFile(mission=_mission(n))
    plan.fence = Mission([MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.0, y=7.0),
                          MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.0),
                          MissionItem(CMD_FENCE_POLYGON_VERTEX_INCLUSION, FRAME_GLOBAL, param1=3, x=45.1, y=7.1)],
                         MissionType.FENCE)
    plan.rally = Mission([MissionItem(CMD_RALLY_POINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.02, y=7.03, z=20)],
                         MissionType.RALLY)
    return plan


@pytest.fixture()
def mock() -> MockAutopilot:
    with MockAutopilot(sysids=[1], request_interval=0.02, upload_timeout=1.0) as m:
        yield m


def test_nan_latitude_is_bad_input_and_nothing_is_uploaded(tmp_path: Path, mock: MockAutopilot,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """Item 5: a JSON NaN latitude used to go up as 0.0 and read back "verified"."""
    good = tmp_path / "good.plan"
    write_plan(good, PlanFile(mission=_mission()))
    assert run(["upload", str(good), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    before = mock.mission(1)
    doc = json.loads(good.read_text())
    doc["mission"]["items"][3]["params"][4] = math.nan  # json writes the literal NaN
    bad = tmp_path / "nan.plan"
    bad.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["upload", str(bad), "--sysid", "1", "--connect", mock.client_url] + FAST) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "mission item 4: latitude is NaN" in err[0]
    assert mock.mission(1) == before and mock.vehicle(1).uploads_completed == 1


@pytest.mark.parametrize("kind", ["plan", "waypoints"])
def test_empty_file_needs_allow_empty(tmp_path: Path, mock: MockAutopilot, kind: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """Item 9: a 0-item .plan or a header-only .waypoints used to wipe the vehicle silently."""
    good = tmp_path / "good.plan"
    write_plan(good, PlanFile(mission=_mission()))
    assert run(["upload", str(good), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    before = mock.mission(1)
    empty = tmp_path / f"empty.{kind}"
    if kind == "plan":
        write_plan(empty, PlanFile(mission=Mission(home=(45.07, 7.68, 240.0))))
    else:
        empty.write_text("QGC WPL 110\n")
    with pytest.raises(BridgeUsageError, match="holds no mission items.*--allow-empty") as err:
        run(["upload", str(empty), "--sysid", "1", "--connect", mock.client_url] + FAST)
    assert str(empty) in str(err.value)
    assert mock.mission(1) == before and mock.vehicle(1).uploads_completed == 1
    capsys.readouterr()
    assert run(["upload", str(empty), "--sysid", "1", "--connect", mock.client_url, "--allow-empty"] + FAST) == 0
    assert "uploaded 0 items" in capsys.readouterr().out
    assert len(mock.mission(1)) == 1  # ArduPilot keeps only its home item


def test_clear_empties_mission_fence_and_rally(tmp_path: Path, mock: MockAutopilot,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "fenced.plan"
    write_plan(path, _fenced())
    assert run(["upload", str(path), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    assert len(mock.mission(1, 1)) == 3 and len(mock.mission(1, 2)) == 1
    capsys.readouterr()
    assert run(["clear", "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("cleared the mission, fence and rally of vehicle 1 (ardupilot); verified empty by read-back")
    assert len(mock.mission(1)) == 1 and mock.mission(1, 1) == [] and mock.mission(1, 2) == []


def test_clear_of_an_absent_vehicle_exits_1(mock: MockAutopilot, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["clear", "--sysid", "9", "--connect", mock.client_url, "--timeout", "0.5", "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("missionplan clear: no heartbeat from system 9")


def test_mission_planner_txt_file_uploads(tmp_path: Path, mock: MockAutopilot) -> None:
    """Item 9: Mission Planner's `.waypoints.txt` is read by its QGC WPL 110 header."""
    path = tmp_path / "survey.waypoints.txt"
    write_waypoints(tmp_path / "m.waypoints", _mission(5))
    path.write_bytes((tmp_path / "m.waypoints").read_bytes())
    assert run(["upload", str(path), "--sysid", "1", "--connect", mock.client_url] + FAST) == 0
    assert len(mock.mission(1)) == 1 + 7
    out = tmp_path / "back.txt"
    assert run(["download", "--sysid", "1", "--connect", mock.client_url, "-o", str(out)] + FAST) == 0
    assert out.read_text().startswith("QGC WPL 110\n")


@pytest.mark.parametrize("target", ["/proc/self/mission.plan", "FOLDER", "MISSING/m.plan"])
def test_download_into_an_unwritable_place_is_one_line_and_leaves_nothing(
        tmp_path: Path, mock: MockAutopilot, capsys: pytest.CaptureFixture[str], target: str) -> None:
    """Item 9: `download -o` into a place that cannot take the file used to end in a traceback.

    /proc/self refuses new files even to root (tests here may run as root, who passes chmod checks).
    """
    out = {"FOLDER": str(tmp_path), "MISSING/m.plan": str(tmp_path / "missing" / "m.plan")}.get(target, target)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["download", "--sysid", "1", "--connect", mock.client_url, "-o", out] + FAST)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"missionplan: -o {out}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert not Path(out).is_file()


def test_download_whose_write_fails_late_is_one_line_exit_1(tmp_path: Path, mock: MockAutopilot,
                                                             monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The folder took the probe but the write itself fails (disk full): one line, exit 1, no file."""
    import errno

    import missionplan.bridge.formats.file_text

    def full(path: object, text: str) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(missionplan.bridge.formats.file_text, "write_text_atomic", full)
    out = tmp_path / "m.plan"
    assert main(["download", "--sysid", "1", "--connect", mock.client_url, "-o", str(out)] + FAST) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"missionplan download: cannot write {out}: No space left on device; nothing was written"]
    assert list(tmp_path.iterdir()) == []
