"""bridge.signing: key files in both formats, and a key that never shows."""

from __future__ import annotations

from pathlib import Path

import pytest

from bridge import BridgeUsageError
from bridge.signing import load_key, new_key, write_key


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
