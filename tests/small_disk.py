"""Disks that do not play along, for the tests of a full disk and of a read-only folder.

`small_disk`: a tmpfs of the size asked, mounted where the machine allows it (root, as on CI and on
the development machine), filled with a filler file and freed again on demand. Where the mount is
refused, a stand-in: the flight journal's SQLite connections (missionplan.flight.journal_db) fail their
writes with SQLite's "database or disk is full" while the disk is "full"; it says so with a warning,
so a run without a real small disk is never mistaken for one with it.

`read_only`: the folder made read-only, by a read-only bind mount over itself (root: file modes do not
stop root), else by taking the write bits away.
"""

from __future__ import annotations

import errno
import os
import sqlite3
import stat
import subprocess
import types
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest


def _mount(*args: str) -> bool:
    try:
        return subprocess.run(["mount", *args], capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def _umount(path: Path) -> None:
    # Lazily: a file a failed test left open (its journal) must not keep the disk mounted.
    subprocess.run(["umount", "--lazy", str(path)], capture_output=True, timeout=30)


class SmallDisk:
    """A folder on a small disk (`mounted`: a real tmpfs) that can be filled to the last byte and freed."""

    def __init__(self, path: Path, mounted: bool) -> None:
        self.path, self.mounted = path, mounted
        self.full = False
        self._filler = path / "filler.bin"

    def fill(self) -> int:
        """Fill the disk; the bytes the filler took."""
        self.full = True
        if not self.mounted:
            return 0
        written = 0
        chunk = b"\0" * 65536
        with open(self._filler, "ab", buffering=0) as f:
            for size in (65536, 4096, 512, 1):
                while True:
                    try:
                        written += f.write(chunk[:size])
                    except OSError as err:
                        if err.errno != errno.ENOSPC:
                            raise
                        break
        return written

    def free(self) -> None:
        self.full = False
        self._filler.unlink(missing_ok=True)


class _FullDiskConnection:
    """A journal connection whose writes fail as on a full disk while `disk.full` (the stand-in)."""

    WRITES = ("INSERT", "UPDATE", "COMMIT", "CREATE", "ALTER")

    def __init__(self, db: sqlite3.Connection, disk: SmallDisk) -> None:
        self._db, self._disk = db, disk

    def execute(self, sql: str, *args: Any) -> Any:
        if self._disk.full and sql.lstrip().upper().startswith(self.WRITES):
            err = sqlite3.OperationalError("database or disk is full")
            err.sqlite_errorcode = sqlite3.SQLITE_FULL  # type: ignore[attr-defined]
            raise err
        return self._db.execute(sql, *args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._db, name)

    def __enter__(self) -> Any:
        return self._db.__enter__()

    def __exit__(self, *exc: Any) -> Any:
        return self._db.__exit__(*exc)


@contextmanager
def small_disk(where: Path, size_kb: int, monkeypatch: pytest.MonkeyPatch) -> Iterator[SmallDisk]:
    where.mkdir(parents=True, exist_ok=True)
    if _mount("-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs", str(where)):
        try:
            yield SmallDisk(where, mounted=True)
        finally:
            _umount(where)
        return
    warnings.warn(f"tmpfs refused at {where}: the full disk is a stand-in (the journal's writes fail as on a full "
                  "disk; the other files are written)", stacklevel=3)
    disk = SmallDisk(where, mounted=False)
    import missionplan.flight.journal_db as journal

    real_connect = sqlite3.connect
    shim = types.SimpleNamespace(**{name: getattr(sqlite3, name) for name in dir(sqlite3) if not name.startswith("__")})
    shim.connect = lambda *a, **k: _FullDiskConnection(real_connect(*a, **k), disk)
    monkeypatch.setattr(journal, "sqlite3", shim)
    yield disk


@contextmanager
def read_only(folder: Path) -> Iterator[None]:
    """`folder` and everything in it cannot be written until the end of the block."""
    if _mount("--bind", str(folder), str(folder)):
        try:
            if not _mount("-o", "remount,ro,bind", str(folder)):
                raise RuntimeError(f"{folder}: bound but not remounted read-only")
            yield
        finally:
            _umount(folder)
        return
    modes = {path: path.stat().st_mode for path in [folder, *folder.rglob("*")]}
    for path, mode in modes.items():
        path.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    try:
        yield
    finally:
        for path, mode in modes.items():
            os.chmod(path, mode)
