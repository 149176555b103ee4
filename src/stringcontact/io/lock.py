"""The output folder's lock ``.NAME.lock`` beside it: filelock's `FileLock` tried once, the file holding the holder's
pid and command (a refusal names them), removed on release; anything but a regular file is refused (filelock locks a
FIFO)."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import functools
import os
import stat
from pathlib import Path

import filelock

from ..errors import OutputError

__all__ = ["TargetLock", "lock_path"]


def lock_path(target) -> Path:
    """The lock file of an output folder: ``.NAME.lock`` beside it."""
    target = Path(target)
    return target.parent / f".{target.name}.lock"


def _write_pid(path: Path, command: str, fd: int) -> None:
    """filelock's `on_acquired`: refuse a lock that is no regular file, write ``PID\\nCOMMAND\\n`` (failing: unlink)."""
    mine = os.fstat(fd)
    if not stat.S_ISREG(mine.st_mode):
        raise OSError(errno.EINVAL, "the lock file is not a regular file")
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n{command}\n".encode())
    except OSError:
        with contextlib.suppress(OSError):
            if os.path.samestat(os.lstat(path), mine):
                os.unlink(path)
        raise


class TargetLock:
    """An exclusive, non-blocking lock on `target`'s ``.NAME.lock`` for `command`; `label` names the folder in
    messages. Held by another: `OutputError` naming it."""

    def __init__(self, target, command: str = "run", label: str | None = None):
        self.path, self.target = lock_path(target), Path(target)
        label = label or f"--out {self.target}"
        self._lock = filelock.FileLock(self.path, timeout=0, thread_local=False, fallback_to_soft=False,
                                       on_acquired=functools.partial(_write_pid, self.path, command))
        for _ in range(100):  # a holder that releases (unlinks) between our open and our flock: try the new file
            try:
                self._lock.acquire()
                return
            except filelock.Timeout:
                message = self.busy(self.target, label)
                if message is not None:
                    raise OutputError(message) from None
            except OSError:
                odd = _not_a_lock_file(self.path)
                if odd is None:
                    raise
                raise OutputError(f"{label}: its lock file {self.path.name} is {odd}, which no stringcontact "
                                  "run makes; remove it (nothing was written there)") from None
        raise OutputError(f"--out {self.target}: cannot take the lock {self.path}")  # pragma: no cover

    def release(self) -> None:
        """Remove the lock file while still holding it, then unlock."""
        if self._lock.is_locked:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
            self._lock.release()

    @staticmethod
    def holder(target) -> int | None:
        """The pid of the process holding the lock of `target` (0 if unknown), or None if nobody holds it."""
        held = _probe(target)
        return None if held is None else held[0]

    @staticmethod
    def busy(target, label: str | None = None) -> str | None:
        """The one-line refusal of a folder another command holds, naming it and its pid; else None."""
        held = _probe(target)
        if held is None:
            return None
        (pid, command), label = held, label or f"--out {target}"
        who = f" (pid {pid})" if pid else ""
        if command in (None, "run"):
            return (f"{label}: another stringcontact run{who} is writing to this folder; wait for it to finish or "
                    "choose another folder")
        doing = "is drawing its pictures in this folder" if command == "plot" else "is writing to this folder"
        return f"{label}: `stringcontact {command}`{who} {doing}; wait for it to finish or choose another folder"


def _probe(target) -> tuple[int, str | None] | None:
    """(pid, command) of the holder of `target`'s lock (0, None where unsaid), or None. Hand-written: filelock has no
    probe that leaves a missing lock file missing."""
    try:
        fd = os.open(lock_path(target), os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return None
    except BlockingIOError:
        try:
            lines = os.pread(fd, 64, 0).decode().split("\n")
        except (OSError, ValueError):
            return 0, None
        command = lines[1].strip() if len(lines) > 1 and lines[1].strip().isalpha() else None
        return (int(lines[0]) if lines[0].strip().isdigit() else 0), command
    except OSError:  # not a file flock works on (a FIFO, a device): no run of ours holds it
        return None
    finally:
        os.close(fd)


def _not_a_lock_file(path: Path) -> str | None:
    """What stands at `path` if it is not a regular file (a planted link, FIFO or folder), else None."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    kinds = {stat.S_IFLNK: "a symbolic link", stat.S_IFIFO: "a FIFO", stat.S_IFDIR: "a folder", stat.S_IFREG: None}
    return kinds.get(stat.S_IFMT(mode), "not a regular file")
