"""The output folder's lock: ``.NAME.lock`` beside the target, so that a second run into the same folder is refused.

The lock is filelock's `FileLock` (an ``flock`` on the file, tried once: ``timeout=0``; no fall-back to a soft
lock, which a killed run would leave held). What this module adds: the holder's pid and command in the file
(the refusal names them: `plot` redraws a run's folder under the same lock), the file removed on release (no ``.NAME.lock`` stays behind; a killed run's lock file is
not held by anyone and is taken over by the next run), and `TargetLock.holder`, a probe that never creates
the file. Measured with filelock 4.2.12: it opens the lock file with ``O_NOFOLLOW`` (a symlink there is
refused: ELOOP), ``O_NONBLOCK`` (a FIFO never blocks the open) and without ``O_TRUNC`` (a contender never
empties the holder's pid); a folder there gives IsADirectoryError. It does lock a FIFO, so `_write_pid`
refuses any non-regular file (EINVAL). Each reaches the caller as an OSError: one line, nothing held.
"""

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

#: How often a lock whose file its holder removed just then (an inode nobody guards any more) is tried again.
_ATTEMPTS = 100


def lock_path(target) -> Path:
    """The lock file of an output folder: ``.NAME.lock`` beside it."""
    target = Path(target)
    return target.parent / f".{target.name}.lock"


def _write_pid(path: Path, command: str, fd: int) -> None:
    """filelock's `on_acquired`: refuse a lock "file" that is not a regular file, then write our pid and the
    command that holds the folder into it (``PID\nCOMMAND\n``).

    If the pid cannot be written (a full disk), the file is removed again while still held, as `release`
    does: a refused run leaves no ``.NAME.lock`` behind.
    """
    mine = os.fstat(fd)
    if not stat.S_ISREG(mine.st_mode):  # filelock itself locks a FIFO (opened O_RDWR | O_NONBLOCK)
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
    """An exclusive, non-blocking lock on ``.NAME.lock`` beside the target (filelock's `FileLock`).

    Raises :class:`OutputError` naming the other command and its pid if the lock is held (`busy`). `command` is
    what this process does with the folder (``run``, ``study``, ``check``, ``plot``), recorded for such a refusal;
    `label` names the folder in messages (``--out DIR`` by default). The file is removed on release, while still
    held: a run that opened it meanwhile finds it unlinked (filelock checks the link count after its ``flock``)
    and tries the new file.
    """

    def __init__(self, target, command: str = "run", label: str | None = None):
        self.path = lock_path(target)
        self.target = Path(target)
        label = label or f"--out {self.target}"
        self._lock = filelock.FileLock(self.path, timeout=0, thread_local=False, fallback_to_soft=False,
                                       on_acquired=functools.partial(_write_pid, self.path, command))
        for _ in range(_ATTEMPTS):
            try:
                self._lock.acquire()
                return
            except filelock.Timeout:
                message = self.busy(self.target, label)
                if message is None:  # released between our open and our flock: try the new file
                    continue
                raise OutputError(message) from None
            except OSError:
                odd = _not_a_lock_file(self.path)
                if odd is None:
                    raise
                raise OutputError(f"{label}: its lock file {self.path.name} is {odd}, which no stringcontact "
                                  "run makes; remove it (nothing was written there)") from None
        raise OutputError(f"--out {self.target}: cannot take the lock {self.path}")  # pragma: no cover

    def release(self) -> None:
        if not self._lock.is_locked:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)  # while still holding it: nobody can have locked this inode meanwhile
        self._lock.release()

    @staticmethod
    def holder(target) -> int | None:
        """The pid of the run holding the lock of `target` (0 if unknown), or None if nobody holds it."""
        held = _probe(target)
        return None if held is None else held[0]

    @staticmethod
    def busy(target, label: str | None = None) -> str | None:
        """The refusal of a folder whose lock another command holds, naming the command and its pid (one line,
        the folder as `label`, ``--out DIR`` by default), or None if nobody holds it."""
        held = _probe(target)
        if held is None:
            return None
        pid, command = held
        label = label or f"--out {target}"
        who = f" (pid {pid})" if pid else ""
        if command in (None, "run"):
            return (f"{label}: another stringcontact run{who} is writing to this folder; wait for it to finish or "
                    "choose another folder")
        doing = "is drawing its pictures in this folder" if command == "plot" else "is writing to this folder"
        return f"{label}: `stringcontact {command}`{who} {doing}; wait for it to finish or choose another folder"


def _probe(target) -> tuple[int, str | None] | None:
    """(pid, command) of the process holding the lock of `target` (pid 0 and command None where the file does not
    say), or None if nobody holds it. Hand-written: filelock has no probe that leaves a missing lock file missing
    (it creates the file)."""
    try:
        fd = os.open(lock_path(target), os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return None
    except BlockingIOError:
        return _read_holder(fd)
    except OSError:  # not a file flock works on (a FIFO, a device): no run of ours holds it
        return None
    finally:
        os.close(fd)


def _not_a_lock_file(path: Path) -> str | None:
    """What stands at `path` if it is not a regular file (a planted link or FIFO), else None."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISDIR(mode):
        return "a folder"
    return None if stat.S_ISREG(mode) else "not a regular file"


def _read_holder(fd) -> tuple[int, str | None]:
    """The pid (0 if unreadable) and command (None if not given) in a held lock file."""
    try:
        lines = os.pread(fd, 64, 0).decode().split("\n")
    except (OSError, ValueError):
        return 0, None
    pid = int(lines[0]) if lines[0].strip().isdigit() else 0
    command = lines[1].strip() if len(lines) > 1 and lines[1].strip().isalpha() else None
    return pid, command
