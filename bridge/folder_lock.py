"""One owner per folder: an OS lock that `fly`, `plan --out` and `replan --out` hold on their folder for
the whole run.

`hold_folder(folder)` takes an exclusive, non-blocking `fcntl.flock` on FOLDER/.missionplan.lock and
writes the holder into it (pid, host, command line, start time) so that a second process is told who
has the folder: `FolderBusy` (a BridgeUsageError: one line, exit 2). The OS releases the lock when its
holder ends however it ends, so a holder killed with SIGKILL leaves a file that names it but holds
no lock: the next process takes it over and says so in one line (`say`, stderr by default). A holder
that ends normally removes the file.

Within one process the lock is re-entrant for the thread that holds it (`replan` holds its --out
folder and calls write_plan_folder, which holds it too; `demo` plans, then flies, one after the
other); another thread of the same process is refused like another process.

flock is advisory and local: it keeps missionplan processes on one machine apart, not other programs,
nor two machines sharing the folder over a network. Lives in bridge, below flight/ and the top level, so
both share it.
"""

from __future__ import annotations

import errno
import fcntl
import functools
import json
import os
import shlex
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from .errors import BridgeUsageError
from .terminal_text import printable

LOCK_NAME = ".missionplan.lock"


class FolderBusy(BridgeUsageError):
    """The folder is held by another process (or another thread of this one): one line naming it."""


@dataclass(frozen=True)
class Holder:
    """Who holds (or last held) a folder, as its lock file says."""

    pid: int | None
    host: str
    command: str
    started: str  # local time, ISO 8601 to the second

    def describe(self) -> str:
        who = f"pid {self.pid}" if self.pid is not None else "a process"
        return f"{who} on {self.host or 'an unknown host'} (`{self.command or '?'}`, started {self.started or '?'})"

    @classmethod
    def read(cls, text: str) -> Holder | None:
        """The holder a lock file's text names; None when it names none (empty, or not ours)."""
        try:
            doc: Any = json.loads(text)
        except ValueError:
            return None
        if not isinstance(doc, dict):
            return None
        pid = doc.get("pid")
        host, command, started = (_printable(doc.get(key, "")) for key in ("host", "command", "started"))
        return cls(pid if isinstance(pid, int) and not isinstance(pid, bool) else None, host, command, started)

    @classmethod
    def this_process(cls) -> Holder:
        return cls(os.getpid(), socket.gethostname(), _command_line(), time.strftime("%Y-%m-%dT%H:%M:%S%z"))


MAX_FIELD = 300  # characters of a holder's field shown: the message stays one readable line


def _printable(value: Any) -> str:
    """A field of a lock file as it may be printed: control characters escaped (terminal_text) and at most
    MAX_FIELD characters."""
    text = printable(value)
    return text if len(text) <= MAX_FIELD else text[:MAX_FIELD] + "..."


def _command_line() -> str:
    """This process's command line as a crew typed it: `missionplan fly DIR ...` (argv[0] by its name; for
    `python -m missionplan`, whose argv[0] is the package's __main__.py, the package's name)."""
    program = Path(sys.argv[0]) if sys.argv and sys.argv[0] else Path("python")
    name = program.parent.name if program.name == "__main__.py" else program.name
    return " ".join(shlex.quote(a) for a in [name, *sys.argv[1:]])


def _say_on_stderr(text: str) -> None:
    print(f"missionplan: {text}", file=sys.stderr)


class _Held:
    """One folder this process holds: the locked file's descriptor, which thread holds it, how often."""

    def __init__(self, fd: int, path: Path, holder: Holder) -> None:
        self.fd, self.path, self.holder = fd, path, holder
        self.thread, self.depth = threading.get_ident(), 1


_held: dict[Path, _Held] = {}  # the folders this process holds, by resolved path
_held_guard = threading.Lock()


def _read_fd(fd: int) -> str:
    os.lseek(fd, 0, os.SEEK_SET)
    chunks = []
    while chunk := os.read(fd, 4096):
        chunks.append(chunk)
    return b"".join(chunks).decode("utf-8", "replace")


def _write_holder(fd: int, holder: Holder) -> None:
    """Name the holder in the lock file. Best effort: on a full disk the (empty) file still holds the lock,
    and a second process is told only that the folder is in use."""
    text = json.dumps({"pid": holder.pid, "host": holder.host, "command": holder.command,
                       "started": holder.started}).encode()
    try:
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, text)
    except OSError:
        pass


def _lock(folder: Path, holder: Holder, say: Callable[[str], None]) -> int:
    """flock FOLDER/LOCK_NAME; the locked descriptor. A file replaced or removed between open and flock
    (its holder released it meanwhile) is opened again, so that two processes never hold two files."""
    path = folder / LOCK_NAME
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        except FileNotFoundError:
            raise BridgeUsageError(f"{folder}: no such folder") from None
        except OSError as err:
            if err.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
                raise BridgeUsageError(f"{folder}: cannot write in this folder ({err.strerror}): a run of fly, plan "
                                       "or replan keeps its record there; copy the folder to a writable disk and "
                                       "run it there") from None
            raise BridgeUsageError(f"{path}: cannot create the folder's lock file ({err.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = Holder.read(_read_fd(fd))
            os.close(fd)
            who = holder.describe() if holder is not None else "another process (it has not said who yet)"
            raise FolderBusy(f"{folder} is in use by {who}: one process at a time flies or plans in a "
                             f"folder; wait for it to end, or use another folder") from None
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # released and removed while we waited for flock: take the file that is there now
    stale = Holder.read(_read_fd(fd))
    if stale is not None:
        say(f"{folder}: took over the lock left by {stale.describe()}, which no longer runs")
    _write_holder(fd, holder)
    return fd


def _release(held: _Held) -> None:
    # Removed while still locked: a process that opened this file meanwhile finds it gone and opens anew.
    try:
        held.path.unlink()
    except OSError:
        pass  # a folder made read-only or removed meanwhile: the OS lock goes with the descriptor anyway
    os.close(held.fd)


@contextmanager
def hold_folder(folder: str | os.PathLike[str], say: Callable[[str], None] = _say_on_stderr) -> Iterator[Path]:
    """Hold `folder` (which must exist) for the duration of the block: FolderBusy when another process,
    or another thread of this one, holds it. A lock left by a process that no longer runs is taken over,
    told through `say`. Yields the folder."""
    folder = Path(folder)
    key = folder.resolve()
    with _held_guard:
        held = _held.get(key)
        if held is not None and held.thread == threading.get_ident():
            held.depth += 1
        elif held is not None:
            raise FolderBusy(f"{folder} is in use by another thread of this process, {held.holder.describe()}")
        else:
            holder = Holder.this_process()
            held = _held[key] = _Held(_lock(folder, holder, say), key / LOCK_NAME, holder)
    try:
        yield folder
    finally:
        with _held_guard:
            held.depth -= 1
            if held.depth == 0:
                del _held[key]
                _release(held)


F = TypeVar("F", bound=Callable[..., Any])


def holding_folder(func: F) -> F:
    """Decorate a function whose first argument is a folder: it runs holding that folder (hold_folder)."""

    @functools.wraps(func)
    def held(folder: str | os.PathLike[str], *args: Any, **kwargs: Any) -> Any:
        with hold_folder(folder):
            return func(folder, *args, **kwargs)

    return held  # type: ignore[return-value]
