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
that writes a few files.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import stat
import tempfile
import threading
import time
import warnings
from pathlib import Path

from ..errors import OutputError, one_line
from .lock import TargetLock
from .signals import signals_held

#: below this many free bytes a failed write is reported as a full disk.
NEARLY_FULL_BYTES = 1 << 20



def _occupied(path: Path) -> bool:
    """A file, or a folder with something in it."""
    if not path.exists():
        return False
    return not path.is_dir() or any(path.iterdir())



#: The statuses a run writes into its summary.json.
STATUSES = ("complete", "interrupted", "unstable", "unbalanced")


def check_target(path, force: bool, *, locked: bool = False, parents: bool = False, command: str = "run") -> Path:
    """Refuse an --out that cannot or must not take a result, before any work is done.

    Refused: the root folder, the current folder or one containing it, a mount point, a file, a parent that
    cannot be written, a missing parent outside the current folder (unless `parents`: the Python API's
    ``output_dir`` makes them, as asked), a non-empty folder (unless `force`, and then only a folder holding
    nothing but what its manifest lists and, for a `command` other than ``run``, not a run's result), and a
    folder another run writes to. `locked`: the caller holds the folder's lock itself (so the lock is not probed).
    """
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
    if target.is_dir() and any(target.iterdir()):
        if not force:
            raise OutputError(f"--out {target}: folder is not empty; choose another or pass --force to replace it")
        blocker = foreign_file(target)
        if blocker is not None:
            raise OutputError(f"--out {target}: --force replaces only a stringcontact result (the files its {MANIFEST} "
                              f"lists), and {blocker}; move it away or choose another folder")
        if command != "run" and is_run_result(target):
            raise OutputError(f"--out {target}: holds the result of a run (summary.json, solution.xdmf), which "
                              f"`{command} --force` does not replace; choose another folder")
    holder = None if locked else TargetLock.holder(target)
    if holder is not None:
        who = f" (pid {holder})" if holder else ""
        raise OutputError(
            f"--out {target}: another stringcontact run{who} is writing to this folder; "
            "wait for it to finish or choose another folder"
        )
    return target


def is_run_result(folder: Path) -> bool:
    """`folder` holds the result of `stringcontact run` (its manifest lists summary.json and solution.xdmf)."""
    files = read_manifest(folder) or {}
    return "summary.json" in files and "solution.xdmf" in files


def _check_parents(target: Path, parent: Path) -> None:
    """Refuse missing parent folders outside the current folder: ``--out /nonexistent/x`` is more likely a typo
    than a wish for a new top-level folder. Below the current folder they are made (``--out out/ex1``)."""
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
    """Refuse a target whose nearest existing parent folder cannot be written (read-only or no permission), or
    whose nearest existing parent is not a folder (``--out afile/x``)."""
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
        fix = permission_fix(parent) if reason == errno.EACCES else ""
        raise OutputError(f"--out {target}: cannot create the output folder: {why}{fix}")


# Files that Docker (/.dockerenv) and podman (/run/.containerenv) put in every container.
CONTAINER_MARKERS = ("/.dockerenv", "/run/.containerenv")


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


#: The list of the files a stringcontact command wrote into a folder, with their sizes: what `--force` may replace.
MANIFEST = "manifest.json"
#: The marker file of a run's hidden folders: "partial" while one is written (removed before it is renamed into
#: place), "old" in a result that a --force swap moved aside. A later run removes only folders so marked.
MARKER = ".stringcontact-marker"


#: The largest manifest read: a folder's few dozen names and sizes take a few kB.
MAX_MANIFEST_BYTES = 1 << 20


def read_manifest(folder: Path) -> dict[str, int] | None:
    """{file name: size} from the folder's manifest, or None if it has none that a stringcontact command wrote.

    Only a regular file of at most MAX_MANIFEST_BYTES counts: it is opened with O_NONBLOCK and O_NOFOLLOW, so a
    FIFO or a link to /dev/zero planted there is neither waited on nor read without end."""
    text = small_regular_file(Path(folder) / MANIFEST, MAX_MANIFEST_BYTES)
    try:
        data = json.loads(text) if text is not None else None
    except (ValueError, RecursionError, MemoryError):
        return None
    files = data.get("files") if isinstance(data, dict) and data.get("written_by") == "stringcontact" else None
    if not isinstance(files, dict) or not all(isinstance(v, int) and not isinstance(v, bool) for v in files.values()):
        return None
    return files


def small_regular_file(path: Path, limit: int) -> bytes | None:
    """The bytes of `path` if it is a regular file (not a link to one) of at most `limit` bytes, else None.

    Opened with O_NONBLOCK and O_NOFOLLOW: a FIFO is never waited on, a link to a device never followed."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
            return None
        data = os.read(fd, limit + 1)
        return data if len(data) <= limit else None
    except OSError:
        return None
    finally:
        os.close(fd)


def write_manifest(folder: Path, files: dict[str, int]) -> None:
    """Write `folder`'s manifest, whole (`atomic_path`): {name: size} of the files a command wrote there."""
    with atomic_path(Path(folder) / MANIFEST, record=False) as tmp:
        tmp.write_text(json.dumps({"written_by": "stringcontact", "files": dict(sorted(files.items()))}, indent=1) + "\n")


def foreign_file(folder: Path, depth: int = 3) -> str | None:
    """Why `--force` may not replace `folder`: the first file in it that its manifest does not list as written,
    with that size, by a stringcontact command (a file the user added or changed); None if it may.

    A folder inside it that a command published there, whole (``plot RUN --out RUN/pictures``, as
    ``make docs`` does), counts as written by stringcontact too (`depth` levels down).
    """
    files = read_manifest(folder)
    if files is None:
        return (f"this folder has no {MANIFEST} of a stringcontact command (results written before "
                "stringcontact kept one have none: delete such a folder yourself once)")
    for p in sorted(Path(folder).iterdir()):
        if p.name == MANIFEST:
            continue
        if p.name not in files and depth > 0 and p.is_dir() and not p.is_symlink() and foreign_file(p, depth - 1) is None:
            continue
        if p.name not in files or p.is_symlink() or not p.is_file():
            return f"{p.name} is not a file stringcontact wrote there"
        if p.stat().st_size != files[p.name]:
            return f"{p.name} was changed after stringcontact wrote it ({p.stat().st_size} bytes, not {files[p.name]})"
    return None


def _record(path: Path) -> None:
    """Add `path` (just written whole) to its folder's manifest, if the folder has one: ``plot FOLDER``
    redraws the pictures of a result, which stays replaceable by `--force`."""
    files = read_manifest(path.parent)
    if files is not None and path.name != MANIFEST:
        write_manifest(path.parent, files | {path.name: path.stat().st_size})


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


@contextlib.contextmanager
def atomic_path(path, record: bool = True):
    """Write one file whole or not at all: ``with atomic_path(path) as tmp: write the file to tmp``.

    `tmp` is a hidden sibling ``.NAME.tmp-<random>.SUFFIX`` (the suffix kept, so matplotlib and pyvista pick
    the format from it), made by `tempfile.mkstemp` (O_CREAT|O_EXCL|O_NOFOLLOW, an unpredictable name: a
    symbolic link planted in the folder is never written through); on success it is renamed onto `path`
    (``os.replace``), on any exception, Ctrl-C included, it is removed and the exception goes on. With
    `record`, the file is added to the folder's manifest if it has one (a published result: ``plot FOLDER``).
    """
    path = Path(path)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.tmp-", suffix=path.suffix, dir=path.parent)
    tmp = Path(name)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes it private; a picture is an ordinary file
    finally:
        os.close(fd)
    try:
        yield tmp
        os.replace(tmp, path)
        if record:
            _record(path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


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
        lock = TargetLock(target)
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


