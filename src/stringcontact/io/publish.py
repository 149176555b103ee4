"""An output folder is absent, complete, or marked in its summary.json, never half-written: a command locks it, writes
into a hidden ``.NAME.partial-*`` beside it, fsyncs and renames that into place. With ``--force`` a complete result
replaces one of ours through ``.NAME.old-*``; any other goes beside it (``NAME.interrupted``, ...). The next run to
take the lock removes what killed runs left."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import tempfile
import time
import warnings
from pathlib import Path

from ..errors import OutputError
from .disk import _umask, describe_os_error, fsync
from .lock import TargetLock
from .manifest import MANIFEST, foreign_file, small_regular_file, write_manifest
from .signals import signals_held
from .target import check_target

#: The marker file of a run's hidden folders ("partial" while written, "old" when moved aside by a --force swap): a
#: later run removes only folders so marked.
MARKER = ".stringcontact-marker"


def _recover_stale(target: Path) -> None:
    """Under the lock: remove the marked hidden folders of killed runs into `target`, put back a result an interrupted
    --force swap left aside."""
    name, removed = re.escape(target.name), []
    with contextlib.suppress(OSError):
        for p in sorted(target.parent.iterdir()):
            kind = ("partial" if re.fullmatch(rf"\.{name}\.partial-\d+-[a-z0-9_]+", p.name)
                    else "old" if re.fullmatch(rf"\.{name}\.old-\d+-\d+", p.name) else None)
            if kind is None or not p.is_dir() or p.is_symlink() or TargetLock.holder(p) is not None:
                continue
            if kind == "old" and not target.exists():  # the swap stopped between its two renames
                (p / MARKER).unlink(missing_ok=True)
                os.rename(p, target)
                warnings.warn(f"--out {target}: restored the previous result from {p.name}", stacklevel=4)
            elif (small_regular_file(p / MARKER, 64) or b"").strip() == kind.encode():  # never a user's folder so named
                shutil.rmtree(p, ignore_errors=True)
                removed += [p.name] if kind == "partial" else []
    if removed:
        warnings.warn(f"--out {target}: removed {len(removed)} unfinished folder(s) left by a run that was killed "
                      f"({', '.join(removed)})", stacklevel=4)


def move_into_place(partial: Path, target: Path, force: bool, status: str = "complete") -> Path:
    """Rename the finished folder `partial` to `target` (occupied: only a complete one with `force`, else beside it as
    ``NAME.new``/``NAME.<status>``); returns where it went."""
    try:
        os.replace(partial, target)  # target absent or an empty folder
        return target
    except OSError as exc:
        if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
            raise
    # occupied, looked at again: a run into a folder inside it may have started meanwhile, or a user put a file there
    if status != "complete" or not force or foreign_file(target) is not None:  # beside it: NAME.new, NAME.new-2, ...
        label = "new" if status == "complete" else status
        for i in range(1, 1000):
            dest = target.with_name(f"{target.name}.{label}" + (f"-{i}" if i > 1 else ""))
            if not dest.exists():
                os.rename(partial, dest)
                return dest
        raise OutputError(f"--out {target}: no free name {target.name}.{label}-N beside it")  # pragma: no cover
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


def open_partial(path, force: bool, command: str = "run") -> tuple[Path, TargetLock, Path]:
    """Check, lock and check again `path`, clear what killed runs left, make the hidden partial folder:
    ``(target, lock, partial)``; on failure (OutputError) nothing is held or left."""
    target = Path(path).resolve()
    lock = partial = None
    try:
        # checked before the lock too: a file or a non-empty folder is refused as such even where no lock can be made
        check_target(path, force, parents=True, command=command)
        target.parent.mkdir(parents=True, exist_ok=True)
        lock = TargetLock(target, command)
        check_target(target, force, locked=True, parents=True, command=command)  # a run may have just finished there
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
    """Drop the marker, write the manifest, fsync, rename into place, fsync the parent; returns where it went (call
    it with the signals held)."""
    (partial / MARKER).unlink(missing_ok=True)
    files = [p for p in partial.iterdir() if p.is_file() and not p.is_symlink() and p.name != MANIFEST]
    write_manifest(partial, {p.name: p.stat().st_size for p in files})
    for p in partial.iterdir():
        if p.is_file():
            fsync(p)
    fsync(partial, folder=True)
    dest = move_into_place(partial, target, force, status)
    fsync(target.parent, folder=True)
    return dest


@contextlib.contextmanager
def staged_folder(path, force: bool = False, command: str = "run"):
    """``with staged_folder(out, force) as tmp: write files into tmp``: the whole folder published, or (any error,
    Ctrl-C too) nothing; serial. `command`'s `--force` never replaces a run."""
    target, lock, partial = open_partial(path, force, command)
    try:
        try:
            yield partial
            with signals_held():
                dest = publish_partial(partial, target, force)
                partial = None
        except OSError as exc:
            raise OutputError(f"--out {target}: {describe_os_error(exc, target.parent, probe=partial)}; nothing was "
                              "written there") from None
        if dest != target:
            warnings.warn(f"--out {target} already holds a result; the new one is in {dest}", stacklevel=3)
    finally:
        if partial is not None:
            shutil.rmtree(partial, ignore_errors=True)
        lock.release()
