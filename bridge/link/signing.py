"""MAVLink 2 message signing keys: reading a key file and applying it to a pymavlink MAVLink object.

A key is a 32-byte secret. The key file holds either the 32 raw bytes or 64 hexadecimal digits
(whitespace ignored). The key is never printed, logged or put in an exception message; SigningKey's
repr hides it. A link set up with a key signs what it sends and rejects unsigned or wrongly signed
packets (no allow_unsigned_callback), so a vehicle with a key ignores anyone without it.

Timestamps. A signature carries a 48-bit timestamp (10 us units since 2015-01-01) that must grow on
each stream (link id, system, component); a receiver refuses a *new* stream whose timestamp is more
than 60 s behind its own. pymavlink 2.4 sets its timestamp once (at setup) and then only adds 1 per
packet sent, so a link that has been up for minutes sends timestamps minutes old, and every newcomer
refuses it as a replay (signing that "breaks after 60 s"). apply_key therefore brings
the timestamp up to the wall clock before every send (never backwards: max with the last one used),
and checks incoming signatures itself: the signature first, and only a good signature may advance a
stream's timestamp (pymavlink records the timestamp of a forged packet before checking it, so one
bad packet could lock a stream out). A right-key packet refused for its timestamp is counted apart
(`stale_count`), so the message can blame the clock rather than the key.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import string
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missionplan.base.naming import Named

from ..errors import BridgeUsageError

KEY_BYTES = 32
_SIGNING_EPOCH = 1420070400  # MAVLink signing timestamps count 10 us units from 2015-01-01
NEW_STREAM_WINDOW = 60 * 100_000  # a new stream may start at most 60 s behind our timestamp (10 us units)


@dataclass(frozen=True)
class SigningKey:
    """A 32-byte MAVLink 2 signing secret whose value never shows in a repr or a log."""

    secret: bytes = field(repr=False)

    def __post_init__(self) -> None:
        if len(self.secret) != KEY_BYTES:
            raise BridgeUsageError(f"a signing key must be {KEY_BYTES} bytes, got {len(self.secret)}")

    def __repr__(self) -> str:
        return "SigningKey(<hidden>)"

    __str__ = __repr__


def load_key(path: str | os.PathLike[str]) -> SigningKey:
    """Read a key file: 32 raw bytes or 64 hex digits. Errors name the file, never the content."""
    path = Path(path)
    if not path.is_file():
        raise BridgeUsageError(Named("{signing_key} {0}: no such file", path))
    try:
        data = path.read_bytes()
    except OSError as err:
        raise BridgeUsageError(Named("{signing_key} {0}: cannot read ({1})", path, err.strerror)) from None
    if len(data) == KEY_BYTES:
        return SigningKey(data)
    text = "".join(chr(b) for b in data if not chr(b).isspace()) if data.isascii() else ""
    if len(text) == 2 * KEY_BYTES and all(c in string.hexdigits for c in text):
        return SigningKey(bytes.fromhex(text))
    raise BridgeUsageError(Named("{signing_key} {0}: expected a {1}-byte key ({1} raw bytes or {2} hex digits), "
                                 "got {3} bytes", path, KEY_BYTES, 2 * KEY_BYTES, len(data)))


def write_key(path: str | os.PathLike[str], key: SigningKey) -> None:
    """Write a key as 64 hex digits, readable by its owner only."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as handle:
        handle.write(key.secret.hex() + "\n")


def new_key() -> SigningKey:
    return SigningKey(os.urandom(KEY_BYTES))


def wall_clock() -> float:
    """Seconds since 1970 (time.time); a vehicle simulator or a test may pass another clock."""
    return time.time()


def signing_timestamp(now: float | None = None) -> int:
    """The MAVLink signing timestamp (10 us units since 2015) at wall-clock time `now` (default: now)."""
    now = wall_clock() if now is None else now
    return int(max(now - _SIGNING_EPOCH, 0) * 100_000)


def apply_key(mav: Any, key: SigningKey | None, link_id: int = 0, clock: Callable[[], float] | None = None) -> None:
    """Sign what this pymavlink MAVLink object sends and accept only packets signed with the key.

    mav is a pymavlink MAVLink (connection.mav). With key None the object neither signs nor checks.
    clock: the wall clock (seconds since 1970) the signing timestamps follow; default time.time.
    """
    state = mav.signing
    for name in ("send", "check_signature"):  # undo an earlier apply_key: back to pymavlink's own
        mav.__dict__.pop(name, None)
    if key is None:
        state.secret_key = None
        state.sign_outgoing = False
        state.allow_unsigned_callback = None
        return
    now: Callable[[], int] = (lambda: signing_timestamp(clock())) if clock is not None else signing_timestamp
    state.secret_key = key.secret
    state.sign_outgoing = True
    # Unsigned or badly signed packets are refused. pymavlink counts a refusal only when a callback
    # said no, so say no here: then reject_count - badsig_count is the number of unsigned packets.
    state.allow_unsigned_callback = _refuse
    state.link_id = link_id
    state.timestamp = max(state.timestamp, now())
    state.stale_count = 0
    plain_send = type(mav).send

    def send(msg: Any, force_mavlink1: bool = False) -> None:
        # pymavlink signs with state.timestamp and then adds 1: keep it at the clock, never going back.
        state.timestamp = max(state.timestamp, now())
        plain_send(mav, msg, force_mavlink1=force_mavlink1)

    def check_signature(msgbuf: bytearray, src_system: int, src_component: int) -> bool:
        return _check_signature(state, now, msgbuf, src_system, src_component)

    mav.send = send
    mav.check_signature = check_signature


def _refuse(mav: Any, msg_id: int) -> bool:
    return False


def _check_signature(state: Any, now: Callable[[], int], msgbuf: bytearray, src_system: int,
                     src_component: int) -> bool:
    """pymavlink's MAVLink.check_signature, with the signature checked before the timestamp is trusted
    and timestamp refusals counted in state.stale_count. msgbuf ends with link id (1 byte), timestamp
    (6 bytes, little-endian) and signature (6 bytes)."""
    expected = hashlib.sha256(state.secret_key + bytes(msgbuf[:-6])).digest()[:6]
    if not hmac.compare_digest(expected, bytes(msgbuf[-6:])):
        return False  # another key (or none): pymavlink counts it in badsig_count
    timestamp = int.from_bytes(bytes(msgbuf[-12:-6]), "little")
    stream = (msgbuf[-13], src_system, src_component)
    last = state.stream_timestamps.get(stream)
    if last is not None:
        stale = timestamp <= last  # a replay, or a duplicate
    else:
        stale = timestamp + NEW_STREAM_WINDOW < max(state.timestamp, now())
    if stale:
        state.stale_count += 1  # the right key, but a replay or a sender whose clock is far behind
        return False
    state.stream_timestamps[stream] = timestamp
    state.timestamp = max(state.timestamp, timestamp)
    return True


def stale_signatures(mav: Any) -> int:
    """Packets with the right signature refused for their timestamp (replayed, or a clock far behind)."""
    return int(getattr(mav.signing, "stale_count", 0))


def refused_packets(mav: Any) -> tuple[int, int, int]:
    """(signed with another key, not signed at all, right key but stale timestamp) since apply_key."""
    state = mav.signing
    stale = stale_signatures(mav)
    return (int(state.badsig_count) - stale, int(state.reject_count) - int(state.badsig_count), stale)
