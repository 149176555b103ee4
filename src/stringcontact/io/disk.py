"""The device under an output folder: fsync (`sync_soon` starts it early), a failed write in one line
(`describe_os_error`), a failing device (`disk_failure`)."""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from pathlib import Path

from ..errors import one_line

#: below this many free bytes a failed write is reported as a full disk.
NEARLY_FULL_BYTES = 1 << 20
#: errno values that mean the device failed, not the data: the output folder cannot be kept.
DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def fsync(path, folder: bool = False) -> None:
    """fsync the file `path` (a failure raised), or the folder `path` (some file systems cannot: left)."""
    try:
        fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if folder else 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        if not folder:
            raise


def sync_soon(paths) -> threading.Thread:
    """fsync the files `paths` in a thread (returned) while the pictures are drawn: publishing's fsync then takes
    0.003 s for Example 1, not 0.030-0.035 s (docs/explanation/performance.md)."""

    def sync():
        for path in paths:
            with contextlib.suppress(OSError):
                fsync(path)

    thread = threading.Thread(target=sync, name="sync_soon", daemon=True)
    thread.start()
    return thread


def describe_os_error(exc: BaseException, folder, probe=None) -> str:
    """One line for an I/O failure in `folder`; without an errno (a RuntimeError) the device of `probe` is examined."""
    err = getattr(exc, "errno", None)
    reasons = {errno.ENOSPC: f"the disk is full (no space left on the device of {folder})",
               errno.EDQUOT: f"the disk quota is exceeded on {folder}", errno.EROFS: f"{folder} is on a read-only file system",
               errno.EACCES: f"permission denied in {folder}", errno.EPERM: f"permission denied in {folder}"}
    if err is not None:
        return reasons.get(err) or f"{getattr(exc, 'strerror', None) or exc} ({folder})"
    probe = Path(probe if probe is not None else folder)
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    with contextlib.suppress(OSError):
        st = os.statvfs(probe)
        if st.f_bavail * st.f_frsize < NEARLY_FULL_BYTES:
            return f"the disk is full ({st.f_bavail * st.f_frsize // 1024} KiB left on the device of {folder})"
        if st.f_flag & os.ST_RDONLY:
            return reasons[errno.EROFS]
        if not os.access(probe, os.W_OK):
            return reasons[errno.EACCES]
    return f"{one_line(exc, 300)} ({folder})"


def disk_failure(exc: BaseException) -> OSError | None:
    """The OSError of a full or failing device that `exc` is, or was raised from or during; else None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in DISK_ERRNOS:
            return exc
        exc = exc.__cause__ or exc.__context__
    return None
