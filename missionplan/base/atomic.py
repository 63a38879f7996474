"""Atomic file output: write to a temp file beside the target, then rename.

A reader never sees a half-written file and a failed write leaves nothing behind. The
temp file gets the permissions a plain open() would give (mkstemp makes 0600 files).
Lives in base, below every layer, so that every layer that writes a file (geo, maps, learn, bridge and
the ones above) shares it.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temp path to write; on success it replaces `path`, on error it is removed."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as err:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(err, OSError) and err.filename is None:  # a failed write names no file: say which
            err.filename = str(path)
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="\n")  # LF on every platform


def probe_writable(folder: str | os.PathLike[str]) -> None:
    """Create and remove a temp file in `folder`; OSError when outputs could not be written there.

    Asked before a long planning run: an existing folder may still refuse files (permissions,
    a read-only mount), and finding out only at the first output would waste the run.
    """
    fd, tmp = tempfile.mkstemp(prefix=".write-probe.", dir=folder)
    os.close(fd)
    os.unlink(tmp)
