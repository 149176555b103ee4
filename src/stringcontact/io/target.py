"""Whether an output folder (`--out`) may take a result, checked before any work is done: `check_target`."""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

from ..errors import OutputError
from .disk import describe_os_error
from .lock import TargetLock
from .manifest import MANIFEST, foreign_file, read_manifest

#: Files that Docker (/.dockerenv) and podman (/run/.containerenv) put in every container.
CONTAINER_MARKERS = ("/.dockerenv", "/run/.containerenv")


def check_target(path, force: bool, *, locked: bool = False, parents: bool = False, command: str = "run") -> Path:
    """Refuse in one line (`OutputError`) an --out that cannot or must not take a result: the root or current folder
    (or one containing it), a mount point, a file, an unwritable parent, a missing parent outside the current folder
    (unless `parents`), a non-empty folder (with `force`: one not ours, or a run's for another `command`), a folder
    another command holds (unless `locked`)."""
    target = Path(path)
    resolved = target.resolve()
    if not resolved.name:
        raise OutputError(f"--out {target}: is the root folder; choose a new folder")
    with contextlib.suppress(OSError):
        if Path.cwd() == resolved or resolved in Path.cwd().parents:
            raise OutputError(f"--out {target}: is the current folder or contains it; choose a new folder")
    if target.exists() and not target.is_dir():
        raise OutputError(f"--out {target}: exists and is not a folder")
    if target.is_dir() and os.path.ismount(target):  # the finished folder is renamed onto it: EBUSY
        raise OutputError(f"--out {target}: is a mount point, which a finished folder cannot be renamed onto; "
                          f"choose a new folder inside it (e.g. {target / 'run1'})")
    if not target.exists():
        if not parents:
            _check_parents(target, resolved.parent)
        _check_writable(target, resolved.parent)
    busy = None if locked else TargetLock.busy(target)  # before the files: a holder's own temporary ones
    if target.is_dir() and any(target.iterdir()):
        if not force:
            raise OutputError(f"--out {target}: folder is not empty; choose another or pass --force to replace it")
        if busy is not None:
            raise OutputError(busy)
        blocker = foreign_file(target)
        if blocker is not None:
            raise OutputError(f"--out {target}: --force replaces only a stringcontact result (the files its {MANIFEST} "
                              f"lists), and {blocker}; move it away or choose another folder")
        if command != "run" and {"summary.json", "solution.xdmf"} <= set(read_manifest(target) or {}):  # a run's
            raise OutputError(f"--out {target}: holds the result of a run (summary.json, solution.xdmf), which "
                              f"`{command} --force` does not replace; choose another folder")
    if busy is not None:
        raise OutputError(busy)
    return target


def _check_parents(target: Path, parent: Path) -> None:
    """Missing parents are made below the current folder; elsewhere (``--out /nonexistent/x``) a typo: refused."""
    missing = parent
    while not missing.parent.exists() and missing != missing.parent:
        missing = missing.parent
    if missing.exists():
        return
    with contextlib.suppress(OSError):
        if Path.cwd() in missing.parents:
            return
    raise OutputError(f"--out {target}: the folder {missing} does not exist; create it first (mkdir -p {parent}) "
                      "or correct the path")


def _check_writable(target: Path, parent: Path) -> None:
    """Refuse a target whose nearest existing parent is a file or cannot be written."""
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if parent.exists() and not parent.is_dir():
        raise OutputError(f"--out {target}: cannot create the output folder: {parent} is a file, not a folder; "
                          "choose a path inside a folder")
    reason = None
    with contextlib.suppress(OSError):
        if os.statvfs(parent).f_flag & os.ST_RDONLY:
            reason = errno.EROFS
    if reason is None and not os.access(parent, os.W_OK | os.X_OK):
        reason = errno.EACCES
    if reason is not None:
        why = describe_os_error(OSError(reason, os.strerror(reason)), parent)
        raise OutputError(f"--out {target}: cannot create the output folder: {why}"
                          + (permission_fix(parent) if reason == errno.EACCES else ""))


def permission_fix(folder: Path) -> str:
    """The way out of a permission denied in `folder`: in a container, run it as the folder's owner."""
    try:
        owner = folder.stat().st_uid
    except OSError:
        return ""
    me = os.geteuid()
    if any(os.path.exists(m) for m in CONTAINER_MARKERS):
        return (f" (it belongs to uid {owner}, this container runs as uid {me}); run the container as the folder's "
                'owner: docker run --user "$(id -u):$(id -g)" ...')
    return f" (it belongs to uid {owner}, you are uid {me}); choose a folder of yours"
