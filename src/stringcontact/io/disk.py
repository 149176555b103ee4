"""The device under an output folder: the files written to it (fsync, and `sync_soon` to start that early), and
what a failed write means, in one line (`describe_os_error`: a full disk, a read-only file system, no
permission) or as a failing device that no output can be kept on (`disk_failure`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from pathlib import Path

from ..errors import one_line

#: below this many free bytes a failed write is reported as a full disk.
NEARLY_FULL_BYTES = 1 << 20


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _fsync_tree(folder: Path) -> None:
    for p in folder.iterdir():
        if p.is_file():
            _fsync_file(p)
    _fsync_dir(folder)


def _fsync_file(path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def sync_soon(paths) -> threading.Thread:
    """Start writing the files `paths` to the device now, in a thread (returned), while the caller goes on.

    A run's data (solution.h5, rows.npz, diagnostics.csv: Example 1's 48 MB) then reach the disk while the
    pictures are drawn, and publishing, whose fsync of every file is what guarantees them, finds them written:
    Example 1's publishing fsyncs took 0.003 s against 0.030-0.035 s (six runs each; docs/explanation/performance.md). A
    failure here is left to that later fsync to report."""

    def sync():
        for path in paths:
            with contextlib.suppress(OSError):
                _fsync_file(path)

    thread = threading.Thread(target=sync, name="sync_soon", daemon=True)
    thread.start()
    return thread


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):  # some file systems cannot fsync a directory
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)



def describe_os_error(exc: BaseException, folder, probe=None) -> str:
    """One line for an I/O failure in `folder`: disk full, read-only, permission denied, or the error itself.

    `probe` is the path whose device is examined when the error has no errno (default: `folder`).
    """
    err = getattr(exc, "errno", None)
    if err == errno.ENOSPC:
        return f"the disk is full (no space left on the device of {folder})"
    if err == errno.EDQUOT:
        return f"the disk quota is exceeded on {folder}"
    if err == errno.EROFS:
        return f"{folder} is on a read-only file system"
    if err in (errno.EACCES, errno.EPERM):
        return f"permission denied in {folder}"
    if err is not None:
        return f"{getattr(exc, 'strerror', None) or exc} ({folder})"
    # dolfinx/HDF5 raise RuntimeError without an errno: look at the device.
    probe = Path(probe if probe is not None else folder)
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    try:
        st = os.statvfs(probe)
    except OSError:
        return f"{one_line(exc, 300)} ({folder})"
    free = st.f_bavail * st.f_frsize
    if free < NEARLY_FULL_BYTES:
        return f"the disk is full ({free // 1024} KiB left on the device of {folder})"
    if st.f_flag & os.ST_RDONLY:
        return f"{folder} is on a read-only file system"
    if not os.access(probe, os.W_OK):
        return f"permission denied in {folder}"
    return f"{one_line(exc, 300)} ({folder})"


#: errno values that mean the device failed, not the data: the output folder cannot be kept.
DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS)


def disk_failure(exc: BaseException) -> OSError | None:
    """The OSError of a full or failing device that `exc` is, or was raised from or during; else None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in DISK_ERRNOS:
            return exc
        exc = exc.__cause__ or exc.__context__
    return None
