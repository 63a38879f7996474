"""MAVLink 2 message signing keys: reading a key file and applying it to a pymavlink MAVLink object.

A key is a 32-byte secret. The key file holds either the 32 raw bytes or 64 hexadecimal digits
(whitespace ignored). The key is never printed, logged or put in an exception message; SigningKey's
repr hides it. A link set up with a key signs what it sends and rejects unsigned or wrongly signed
packets (no allow_unsigned_callback), so a vehicle with a key ignores anyone without it.
"""

from __future__ import annotations

import os
import string
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import BridgeUsageError

KEY_BYTES = 32
_SIGNING_EPOCH = 1420070400  # MAVLink signing timestamps count 10 us units from 2015-01-01


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
        raise BridgeUsageError(f"--signing-key {path}: no such file")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise BridgeUsageError(f"--signing-key {path}: cannot read ({err.strerror})") from None
    if len(data) == KEY_BYTES:
        return SigningKey(data)
    text = "".join(chr(b) for b in data if not chr(b).isspace()) if data.isascii() else ""
    if len(text) == 2 * KEY_BYTES and all(c in string.hexdigits for c in text):
        return SigningKey(bytes.fromhex(text))
    raise BridgeUsageError(f"--signing-key {path}: expected a {KEY_BYTES}-byte key "
                           f"({KEY_BYTES} raw bytes or {2 * KEY_BYTES} hex digits), got {len(data)} bytes")


def write_key(path: str | os.PathLike[str], key: SigningKey) -> None:
    """Write a key as 64 hex digits, readable by its owner only."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as handle:
        handle.write(key.secret.hex() + "\n")


def new_key() -> SigningKey:
    return SigningKey(os.urandom(KEY_BYTES))


def signing_timestamp(now: float | None = None) -> int:
    """The current MAVLink signing timestamp (10 us units since 2015)."""
    now = time.time() if now is None else now
    return int(max(now - _SIGNING_EPOCH, 0) * 100_000)


def apply_key(mav: Any, key: SigningKey | None, link_id: int = 0) -> None:
    """Sign what this pymavlink MAVLink object sends and accept only packets signed with the key.

    mav is a pymavlink MAVLink (connection.mav). With key None the object neither signs nor checks.
    """
    if key is None:
        mav.signing.secret_key = None
        mav.signing.sign_outgoing = False
        mav.signing.allow_unsigned_callback = None
        return
    mav.signing.secret_key = key.secret
    mav.signing.sign_outgoing = True
    mav.signing.allow_unsigned_callback = None  # unsigned or badly signed packets are refused
    mav.signing.link_id = link_id
    mav.signing.timestamp = max(mav.signing.timestamp, signing_timestamp())
