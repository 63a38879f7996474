"""missionplan.bridge.link.signing: key files in both formats, and a key that never shows."""

from __future__ import annotations

from pathlib import Path

import pytest

from missionplan.bridge import BridgeUsageError
from missionplan.bridge.link.signing import load_key, new_key, write_key


def test_raw_and_hex_key_files(tmp_path: Path) -> None:
    secret = bytes(range(32))
    raw = tmp_path / "raw.key"
    raw.write_bytes(secret)
    assert load_key(raw).secret == secret
    hexfile = tmp_path / "hex.key"
    hexfile.write_text(secret.hex().upper() + "\n")
    assert load_key(hexfile).secret == secret
    key = new_key()
    written = tmp_path / "new.key"
    write_key(written, key)
    assert load_key(written) == key
    assert written.stat().st_mode & 0o077 == 0  # readable by its owner only


def test_key_never_shows(tmp_path: Path) -> None:
    key = load_key(_write(tmp_path, bytes(range(32))))
    text = repr(key) + str(key) + f"{key}"
    assert "hidden" in text and bytes(range(32)).hex() not in text and "\\x01" not in text


@pytest.mark.parametrize("content", [b"short", b"z" * 64, bytes(range(33))])
def test_bad_key_files(tmp_path: Path, content: bytes) -> None:
    path = _write(tmp_path, content)
    with pytest.raises(BridgeUsageError, match="expected a 32-byte key") as err:
        load_key(path)
    assert content.hex() not in str(err.value)
    with pytest.raises(BridgeUsageError, match="no such file"):
        load_key(tmp_path / "missing.key")


def _write(folder: Path, content: bytes) -> Path:
    path = folder / "k.key"
    path.write_bytes(content)
    return path


# ------------------------------------------------------------- signing after the vehicle has been up a while

def _survey(n: int = 5) -> "Mission":
    from missionplan.bridge.formats.mission_items import (
        CMD_NAV_TAKEOFF,
        CMD_NAV_WAYPOINT,
        FRAME_GLOBAL_RELATIVE_ALT,
        Mission,
        MissionItem,
    )

    return Mission([MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=30.0)]
                   + [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.07 + i * 1e-4, y=7.68, z=30.0)
                      for i in range(n)], home=(45.07, 7.68, 240.0))


class _Clock:
    """A settable wall clock: real time plus an offset the test moves."""

    def __init__(self, offset: float = 0.0) -> None:
        self.offset = offset

    def time(self) -> float:
        import time

        return time.time() + self.offset


@pytest.mark.parametrize("uptime_s", [61.0, 600.0])
def test_right_key_still_works_when_the_vehicle_has_been_up_for_minutes(monkeypatch: pytest.MonkeyPatch,
                                                                         uptime_s: float) -> None:
    """The mock used to sign with the timestamp of its start plus one tick per packet, so after 60 s
    with few packets a fresh ground station (whose timestamp is its clock) refused it as a replay
    and blamed the key. The vehicle boots at clock time T - uptime; the ground station comes at T."""
    import types

    import missionplan.bridge.link.signing as signing
    from missionplan.bridge.sim.mock import MockAutopilot
    from missionplan.bridge.transfer.protocol import Timeouts
    from missionplan.bridge.transfer.uploader import open_backend, upload_plan

    clock = _Clock(-uptime_s)
    monkeypatch.setattr(signing, "time", types.SimpleNamespace(time=clock.time))
    key = new_key()
    with MockAutopilot(key=key, request_interval=0.02) as mock:
        clock.offset = 0.0  # uptime_s later
        with open_backend("pymavlink", mock.client_url, 1, key=key, timeouts=Timeouts(item_timeout=0.2, retries=3),
                          connect_timeout=3) as backend:
            assert upload_plan(backend, [_survey()]).verified
        assert mock.vehicle(1).uploads_completed == 1 and mock.stats["rejected"] == 0


def test_a_vehicle_whose_signing_clock_lags_is_blamed_on_the_clock_not_the_key() -> None:
    """A vehicle signing with the right key but timestamps 5 minutes old is refused (MAVLink's replay
    rule for a new stream); the message must say so instead of suggesting a wrong key."""
    import time

    from missionplan.bridge import BridgeError
    from missionplan.bridge.sim.mock import MockAutopilot
    from missionplan.bridge.transfer.protocol import Timeouts
    from missionplan.bridge.transfer.uploader import open_backend

    key = new_key()
    with MockAutopilot(key=key, request_interval=0.02, clock=lambda: time.time() - 300) as mock:
        with pytest.raises(BridgeError) as err:
            open_backend("pymavlink", mock.client_url, 1, key=key, timeouts=Timeouts(item_timeout=0.2, retries=1),
                         connect_timeout=1.5)
    text = str(err.value)
    assert "right signature" in text and "60 s behind" in text and "wrong --signing-key" not in text


def test_a_forged_packet_does_not_lock_out_the_stream_it_imitates() -> None:
    """pymavlink records a packet's timestamp before checking its signature: one forged packet with a
    far-future timestamp made every later genuine packet of that stream look like a replay."""
    import os

    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from missionplan.bridge.link.signing import apply_key

    class Sink:
        def __init__(self) -> None:
            self.data = b""

        def write(self, buf: bytes) -> None:
            self.data += bytes(buf)

    key, other = new_key(), new_key()
    genuine, forger = Sink(), Sink()
    sender = mavlink.MAVLink(genuine, srcSystem=1, srcComponent=1)
    apply_key(sender, key)
    attacker = mavlink.MAVLink(forger, srcSystem=1, srcComponent=1)
    apply_key(attacker, other, clock=lambda: 4e9)  # the year 2096
    receiver = mavlink.MAVLink(None)
    receiver.robust_parsing = True
    apply_key(receiver, key)
    attacker.heartbeat_send(2, 3, 0, 0, 0)
    assert [m.get_type() for m in receiver.parse_buffer(forger.data) or []] == ["BAD_DATA"]
    sender.heartbeat_send(2, 3, 0, 0, 0)
    assert [m.get_type() for m in receiver.parse_buffer(genuine.data) or []] == ["HEARTBEAT"]
    assert receiver.signing.stale_count == 0 and receiver.signing.badsig_count == 1


def test_a_key_for_a_vehicle_that_does_not_sign_says_so() -> None:
    """Seen on ArduCopter SITL after a wipe: with --signing-key and an unsigned vehicle the message was
    "nothing was received at all" (pymavlink does not count unsigned packets it drops)."""
    from missionplan.bridge import BridgeError
    from missionplan.bridge.sim.mock import MockAutopilot
    from missionplan.bridge.transfer.uploader import open_backend

    with MockAutopilot(request_interval=0.02) as mock:
        with pytest.raises(BridgeError) as err:
            open_backend("pymavlink", mock.client_url, 1, key=new_key(), connect_timeout=1.0)
    text = str(err.value)
    assert "packets were refused because they were not signed: the vehicle does not sign" in text
    assert "nothing was received" not in text
