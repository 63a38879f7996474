"""MAVLink 2 signing end to end: a mock started with a key serves only ground stations with the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from missionplan.bridge import BridgeError
from missionplan.cli.app import build_parser
from missionplan.bridge.formats.mission_items import (
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    Mission,
    MissionItem,
)
from missionplan.bridge.formats.missionfile import PlanFile, write_plan
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.link.signing import SigningKey, new_key, write_key
from missionplan.bridge.transfer.uploader import open_backend, upload_plan

FAST = Timeouts(item_timeout=0.15, retries=3)


def survey(n: int, alt: float) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=45.07, y=7.68, z=alt)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.07 + i * 1e-4, y=7.68, z=alt)
              for i in range(n)]
    return Mission(items, home=(45.07, 7.68, 240.0))


@pytest.fixture()
def key() -> SigningKey:
    return new_key()


@pytest.mark.parametrize("backend", ["pymavlink", "mavsdk"])
def test_right_key_verifies_and_no_or_wrong_key_changes_nothing(key: SigningKey, backend: str) -> None:
    with MockAutopilot(flavour="px4", key=key, request_interval=0.02) as mock:
        with open_backend(backend, mock.client_url, 1, key=key, timeouts=FAST, connect_timeout=3) as b:
            assert b.vehicle.signed
            assert upload_plan(b, [survey(20, 30.0)]).verified
        before = mock.mission(1)
        assert len(before) == 21
        # No key: we hear the vehicle (its packets are signed, we do not check) but it ignores us.
        with pytest.raises(BridgeError) as err:
            with open_backend(backend, mock.client_url, 1, timeouts=FAST, connect_timeout=3) as b:
                upload_plan(b, [survey(5, 50.0)])
        assert "sign" in str(err.value)
        # Wrong key: its packets fail our check, so the vehicle is never heard.
        with pytest.raises(BridgeError) as err:
            with open_backend(backend, mock.client_url, 1, key=new_key(), timeouts=FAST, connect_timeout=1) as b:
                upload_plan(b, [survey(5, 50.0)])
        assert "no heartbeat from system 1" in str(err.value) and "signed with another key" in str(err.value)
        assert mock.mission(1) == before
        assert mock.stats["rejected"] > 0 and mock.vehicle(1).uploads_completed == 1


def test_cli_signing_key_end_to_end(tmp_path: Path, key: SigningKey, capsys: pytest.CaptureFixture[str]) -> None:
    key_path = tmp_path / "link.key"
    write_key(key_path, key)
    plan_path = tmp_path / "m.plan"
    write_plan(plan_path, PlanFile(mission=survey(10, 40.0)))
    parser = build_parser()

    def run(*argv: str) -> int:
        args = parser.parse_args(list(argv))
        return int(args.handler(args))

    fast = ["--timeout", "2", "--item-timeout", "0.15", "--retries", "3", "--quiet"]
    with MockAutopilot(key=key, request_interval=0.02) as mock:
        assert run("upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url,
                   "--signing-key", str(key_path), *fast) == 0
        assert run("upload", str(plan_path), "--sysid", "1", "--connect", mock.client_url, *fast) == 1
        assert mock.vehicle(1).uploads_completed == 1
    captured = capsys.readouterr()
    assert "verified by read-back" in captured.out
    assert "--signing-key" in captured.err and len(captured.err.strip().splitlines()) == 1
    assert key.secret.hex() not in captured.out + captured.err  # the key is never printed
