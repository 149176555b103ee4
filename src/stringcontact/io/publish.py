"""File-system safety of an output folder: check the target, lock it, write into a hidden folder beside it,
and rename that into place.

A run writes into a hidden folder of its own beside the target (``.NAME.partial-<pid>-<random>``) and
renames it into place at the end, so the target is always absent, complete, or explicitly marked
``"status": "interrupted"``, ``"unstable"`` or ``"unbalanced"`` in its `summary.json`. Never half-written:

* a lock file ``.NAME.lock`` (`lock.TargetLock`) keeps a second run from writing to the same target;
* files are fsync'ed, then the folder is renamed (`publish_partial`);
* with ``--force`` only a *complete* run replaces an existing target, and only one holding a result of ours
  (`check_target`); an interrupted, unstable or unbalanced one goes to ``NAME.interrupted`` / ``.unstable`` /
  ``.unbalanced`` beside it, so a finished result is never lost;
* an I/O failure is one line (`describe_os_error`) in an :class:`OutputError`;
* the partial folders of runs that were killed (SIGKILL, power loss) are removed by the next run that
  takes the lock: exact names only, never one a live run holds.

No numbers, no XDMF, no pictures: `folder.OutputWriter` uses this for a run, `staged_folder` for a command
that writes a few files. The target's checks are `target.py`'s, the manifest and `atomic_path` `manifest.py`'s,
fsync and the one-line I/O errors `disk.py`'s.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import stat
import tempfile
import time
import warnings
from pathlib import Path

from ..errors import OutputError
from .disk import _fsync_dir, _fsync_tree, _umask, describe_os_error
from .lock import TargetLock
from .manifest import MANIFEST, foreign_file, write_manifest
from .signals import signals_held
from .target import check_target


def _occupied(path: Path) -> bool:
    """A file, or a folder with something in it."""
    if not path.exists():
        return False
    return not path.is_dir() or any(path.iterdir())


#: The statuses a run writes into its summary.json.
STATUSES = ("complete", "interrupted", "unstable", "unbalanced")

#: The marker file of a run's hidden folders: "partial" while one is written (removed before it is renamed into
#: place), "old" in a result that a --force swap moved aside. A later run removes only folders so marked.
MARKER = ".stringcontact-marker"


def _free_sibling(target: Path, label: str) -> Path:
    for i in range(1, 1000):
        candidate = target.with_name(f"{target.name}.{label}" + (f"-{i}" if i > 1 else ""))
        if not candidate.exists():
            return candidate
    raise OutputError(f"--out {target}: no free name {target.name}.{label}-N beside it")  # pragma: no cover


def _stale_kind(name: str, entry: str) -> str | None:
    """'partial' or 'old' if `entry` is exactly a hidden folder that a run into `name` makes, else None.

    Exact names only: ``.ex.old-1.partial-…`` belongs to a run into ``ex.old-1``, not to one into ``ex``.
    """
    partial = rf"\.{re.escape(name)}\.partial-\d+-[a-z0-9_]+"  # tempfile.mkdtemp's suffix
    old = rf"\.{re.escape(name)}\.old-\d+-\d+"  # move_into_place's swap
    if re.fullmatch(partial, entry):
        return "partial"
    if re.fullmatch(old, entry):
        return "old"
    return None


def _recover_stale(target: Path) -> None:
    """Under the lock: remove the partial folders of killed runs; finish an interrupted --force swap.

    Only folders named exactly as a run into `target` names them, and none that is itself the target of a
    live run (a user's ``--out .ex.partial-1-x``): its lock would be held.
    """
    parent, name = target.parent, target.name
    try:
        entries = list(parent.iterdir())
    except OSError:
        return
    removed = []
    for p in sorted(entries):
        kind = _stale_kind(name, p.name)
        if kind is None or not p.is_dir() or p.is_symlink() or TargetLock.holder(p) is not None:
            continue
        if kind == "old" and not target.exists():  # the swap stopped between its two renames: the old result comes back
            (p / MARKER).unlink(missing_ok=True)
            os.rename(p, target)
            warnings.warn(f"--out {target}: restored the previous result from {p.name}", stacklevel=4)
        elif _marker(p) == kind:  # never a folder a user merely named so (a result saved as .ex.partial-1-x)
            shutil.rmtree(p, ignore_errors=True)
            if kind == "partial":
                removed.append(p.name)
    if removed:
        warnings.warn(
            f"--out {target}: removed {len(removed)} unfinished folder(s) left by a run that was killed "
            f"({', '.join(removed)})",
            stacklevel=4,
        )


def _marker(folder: Path) -> str | None:
    """What the marker of a run's hidden folder says ("partial" or "old"); None without one (or if it is not a
    regular file: O_NOFOLLOW and O_NONBLOCK, so a link or a FIFO planted there is neither followed nor waited on)."""
    try:
        fd = os.open(folder / MARKER, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        return os.read(fd, 64).decode(errors="replace").strip() if stat.S_ISREG(os.fstat(fd).st_mode) else None
    except OSError:
        return None
    finally:
        os.close(fd)


def move_into_place(partial: Path, target: Path, force: bool, status: str = "complete") -> Path:
    """Rename the finished folder `partial` to `target`; returns where it went.

    A complete folder replaces an occupied target only with `force` (swapping through ``.NAME.old-*``);
    otherwise, and always for an interrupted or unstable one, it goes to ``NAME.<status>`` (or ``NAME.new``)
    beside the target, so a finished result is never lost.
    """
    label = status if status != "complete" else "new"
    if _occupied(target):
        # Checked again now: since the run started, another run may have begun writing inside the target
        # (its lock and partial folder there), or a user may have put a file there; they are not replaced.
        if status != "complete" or not force or foreign_file(target) is not None:
            dest = _free_sibling(target, label)
            os.rename(partial, dest)
            return dest
        # --force and complete: swap, so that a crash in between leaves the old result under .NAME.old-*
        old = target.with_name(f".{target.name}.old-{os.getpid()}-{time.monotonic_ns()}")
        os.rename(target, old)
        with contextlib.suppress(OSError):
            (old / MARKER).write_text("old\n")  # a later run may remove it (`_recover_stale`)
        try:
            os.rename(partial, target)
        except OSError:
            (old / MARKER).unlink(missing_ok=True)
            os.rename(old, target)
            raise
        shutil.rmtree(old, ignore_errors=True)
        return target
    try:
        os.replace(partial, target)  # target absent or an empty folder
    except OSError as exc:
        if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
            raise
        dest = _free_sibling(target, label)
        os.rename(partial, dest)
        return dest
    return target


def open_partial(path, force: bool, command: str = "run") -> tuple[Path, TargetLock, Path]:
    """Take the output folder `path`: check it, lock it, check it again, clear what killed runs left there,
    and make the hidden partial folder beside it. Returns ``(target, lock, partial)``, target resolved.

    On failure nothing is held or left behind, and OutputError is raised (an OSError as "cannot create the
    output folder").
    """
    target = Path(path).resolve()
    lock = partial = None
    try:
        # Checked before the lock as well: a file or a non-empty folder is refused as such, named as given,
        # even where the lock file cannot be made (a read-only parent) or another run holds the lock.
        check_target(path, force, parents=True, command=command)  # the command line refused missing parents before
        target.parent.mkdir(parents=True, exist_ok=True)
        lock = TargetLock(target, command)
        check_target(target, force, locked=True, parents=True, command=command)  # again under the lock: a run may have just finished there
        _recover_stale(target)
        partial = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-{os.getpid()}-", dir=target.parent))
        os.chmod(partial, 0o777 & ~_umask())  # mkdtemp makes it private; the result is an ordinary folder
        (partial / MARKER).write_text("partial\n")  # what lets a later run remove it if this one is killed
        return target, lock, partial
    except BaseException as exc:
        if partial is not None:
            shutil.rmtree(partial, ignore_errors=True)
        if lock is not None:
            lock.release()
        if isinstance(exc, OSError):
            raise OutputError(f"--out {target}: cannot create the output folder: {describe_os_error(exc, target.parent)}") from None
        raise


def publish_partial(partial: Path, target: Path, force: bool, status: str = "complete") -> Path:
    """fsync the finished folder `partial`, rename it into place (`move_into_place`), fsync the parent.

    Before that, the partial marker is removed and the manifest written: the names and sizes of the files
    in `partial`, what a later `--force` may replace. Returns where the folder went. Call it with the signals held.
    """
    (partial / MARKER).unlink(missing_ok=True)
    write_manifest(partial, {p.name: p.stat().st_size for p in partial.iterdir()
                             if p.is_file() and not p.is_symlink() and p.name != MANIFEST})
    _fsync_tree(partial)
    dest = move_into_place(partial, target, force, status)
    _fsync_dir(target.parent)
    return dest


@contextlib.contextmanager
def staged_folder(path, force: bool = False, command: str = "run"):
    """Write a whole output folder, or nothing: ``with staged_folder(out, force) as tmp: write files into tmp``.

    The same protocol as a run's output (for commands such as ``check --out`` that write files, not a time
    series): the lock, a unique hidden folder beside the target, fsync and rename at the end; on any error,
    including Ctrl-C, the hidden folder is removed and the target is left as it was. Serial (one process).
    `command` (``check``, ``study``, ``plot``): its `--force` never replaces a run's result (`check_target`).
    """
    target, lock, partial = open_partial(path, force, command)
    try:
        yield partial
        with signals_held():
            try:
                dest = publish_partial(partial, target, force)
            except OSError as exc:
                raise OutputError(f"--out {target}: {describe_os_error(exc, target.parent, probe=partial)}; nothing was written there") from None
            partial = None
        if dest != target:
            warnings.warn(f"--out {target} already holds a result; the new one is in {dest}", stacklevel=3)
    except OSError as exc:  # writing into the folder failed
        raise OutputError(f"--out {target}: {describe_os_error(exc, target.parent, probe=partial)}; nothing was written there") from None
    finally:
        if partial is not None:
            shutil.rmtree(partial, ignore_errors=True)
        lock.release()


