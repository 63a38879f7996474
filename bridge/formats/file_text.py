"""A mission file's text, read and written: what every mission file format shares of the file itself.

Reading: a missing file, a folder, a file that is no UTF-8 text or cannot be read is one BridgeUsageError
naming the file. Writing: into an existing folder only, atomically (temp file, then rename: a reader never
sees half a file, a failed write leaves nothing), with LF line endings.
"""

from __future__ import annotations

from pathlib import Path

from missionplan.base.atomic import write_text_atomic

from ..errors import BridgeUsageError


def write_text(path: Path, text: str) -> None:
    """Temp file beside the target then rename (atomic): a reader never sees half a file."""
    if not path.parent.is_dir():
        raise BridgeUsageError(f"{path}: folder {path.parent} does not exist")
    write_text_atomic(path, text)


def check_file(path: Path) -> None:
    if not path.exists():
        raise BridgeUsageError(f"{path}: no such file")
    if not path.is_file():
        raise BridgeUsageError(f"{path}: not a file")


def read_text(path: Path, limit: int | None = None) -> str:
    """The file's text (its first `limit` characters when given); one-line BridgeUsageError otherwise."""
    check_file(path)
    try:
        with path.open(encoding="utf-8-sig") as stream:
            return stream.read() if limit is None else stream.read(limit)
    except UnicodeDecodeError:
        raise BridgeUsageError(f"{path}: not a text file (expected a .plan or .waypoints mission)") from None
    except OSError as err:
        raise BridgeUsageError(f"{path}: cannot read ({err.strerror})") from None

