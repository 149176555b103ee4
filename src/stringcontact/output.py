"""Results on disk: `solution.xdmf`/`.h5`, `diagnostics.csv` and `summary.json`.

A run writes into a hidden folder of its own beside the target (``.NAME.partial-<pid>-<random>``) and
renames it into place at the end, so the target is always absent, complete, or explicitly marked
``"status": "interrupted"``, ``"unstable"`` or ``"unbalanced"`` in its `summary.json`. Never half-written:

* a lock file ``.NAME.lock`` (``fcntl.flock``) keeps a second run from writing to the same target;
* each stored time is written with SIGINT/SIGTERM held back, so the XDMF holds whole time levels;
* the XDMF is closed (and read back) before the rename; files are fsync'ed, then the folder is renamed;
* with ``--force`` only a *complete* run replaces an existing target, and only one holding a result of ours
  (`check_target`); an interrupted, unstable or unbalanced one goes to ``NAME.interrupted`` / ``.unstable`` /
  ``.unbalanced`` beside it, so a finished result is never lost;
* a disk-full or permission error (in a picture too) removes the partial folder and raises
  :class:`OutputError` with one line, on every MPI rank;
* the partial folders of runs that were killed (SIGKILL, power loss) are removed by the next run that
  takes the lock: exact names only, never one a live run holds.

`energy_balance` and `penetration_check` are the two numbers checks of every run (summary.json and the
command line's last lines); see docs/reliability.md.
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import errno
import fcntl
import json
import math
import os
import re
import shutil
import signal
import tempfile
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from .errors import OutputError  # noqa: F401 - re-exported: `from stringcontact.output import OutputError`
from .errors import one_line
from .result import FIELDS  # the XDMF's attributes (also read as output.FIELDS)
from .xdmf import XdmfTimeSeries, hdf5_library, mesh_arrays, read_xdmf, xdmf_series  # noqa: F401 - re-exported

#: max |balance residual| / energy scale above which the energy balance is reported as not closing.
BALANCE_RTOL = 1e-8
#: the penetration bound is PENETRATION_FACTOR·(ε + Δt)·max|v| below the lowest initial value (docs/reliability.md).
PENETRATION_FACTOR = 2.0
#: below this many free bytes a failed write is reported as a full disk.
NEARLY_FULL_BYTES = 1 << 20
#: the entry-point group of the function `pictures=True` calls, `(result, folder)`: `stringcontact.viz:write_pictures`.
PICTURES_ENTRY_POINT = "stringcontact.pictures"


# --- the target folder and its lock ---------------------------------------------------------------


def _occupied(path: Path) -> bool:
    """A file, or a folder with something in it."""
    if not path.exists():
        return False
    return not path.is_dir() or any(path.iterdir())


def lock_path(target) -> Path:
    """The lock file of an output folder: ``.NAME.lock`` beside it."""
    target = Path(target)
    return target.parent / f".{target.name}.lock"


class TargetLock:
    """An exclusive, non-blocking ``flock`` on ``.NAME.lock`` beside the target.

    Raises :class:`OutputError` naming the other run's pid if the lock is held. The file is removed on
    release; after taking the lock we check it is still the file at that path (another run may have
    removed it in between), the usual way to combine flock with unlinking.
    """

    def __init__(self, target):
        self.path = lock_path(target)
        self.target = Path(target)
        self.fd = None
        for _ in range(100):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_pid(fd)
                os.close(fd)
                who = f" (pid {holder})" if holder else ""
                raise OutputError(
                    f"--out {self.target}: another stringcontact run{who} is writing to this folder; "
                    "wait for it to finish or choose another folder"
                ) from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self.fd = fd
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                return
            os.close(fd)  # the file was unlinked by its previous holder: try again with a fresh one
        raise OutputError(f"--out {self.target}: cannot take the lock {self.path}")  # pragma: no cover

    def release(self) -> None:
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)  # while still holding it: nobody can have locked this inode meanwhile
        os.close(self.fd)
        self.fd = None

    @staticmethod
    def holder(target) -> int | None:
        """The pid of the run holding the lock of `target` (0 if unknown), or None if nobody holds it."""
        try:
            fd = os.open(lock_path(target), os.O_RDONLY | os.O_CLOEXEC)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return None
        except BlockingIOError:
            return _read_pid(fd) or 0
        finally:
            os.close(fd)


def _read_pid(fd) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode().strip()
        return int(text) if text.isdigit() else None
    except (OSError, ValueError):
        return None


#: The statuses a run writes into its summary.json; `--force` replaces only a folder holding one of them.
STATUSES = ("complete", "interrupted", "unstable", "unbalanced")
#: What marks a folder as ours: a run's summary.json, or the checks.json of `stringcontact check --out`.
RESULT_MARKERS = {"summary.json": "status", "checks.json": "checks"}


def check_target(path, force: bool, *, locked: bool = False) -> Path:
    """Refuse an --out that cannot or must not take a result, before any work is done.

    Refused: the root folder, the current folder or one containing it, a file, a parent that cannot be written,
    a non-empty folder (unless `force`, and then only a folder holding a result of ours), and a folder another
    run writes to. `locked`: the caller holds the folder's lock itself (so the lock is not probed).
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
    if not target.exists():
        _check_writable(target, resolved.parent)
    if target.is_dir() and any(target.iterdir()):
        if not force:
            raise OutputError(f"--out {target}: folder is not empty; choose another or pass --force to replace it")
        if not _holds_our_result(target):
            raise OutputError(
                f"--out {target}: --force replaces only a stringcontact result (a folder with its summary.json), "
                "and this folder holds other files; choose another folder"
            )
    holder = None if locked else TargetLock.holder(target)
    if holder is not None:
        who = f" (pid {holder})" if holder else ""
        raise OutputError(
            f"--out {target}: another stringcontact run{who} is writing to this folder; "
            "wait for it to finish or choose another folder"
        )
    return target


def _check_writable(target: Path, parent: Path) -> None:
    """Refuse a target whose nearest existing parent folder cannot be written (read-only or no permission)."""
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    reason = None
    with contextlib.suppress(OSError):
        if os.statvfs(parent).f_flag & os.ST_RDONLY:
            reason = errno.EROFS
    if reason is None and not os.access(parent, os.W_OK | os.X_OK):
        reason = errno.EACCES
    if reason is not None:
        why = describe_os_error(OSError(reason, os.strerror(reason)), parent)
        fix = _permission_fix(parent) if reason == errno.EACCES else ""
        raise OutputError(f"--out {target}: cannot create the output folder: {why}{fix}")


# Files that Docker (/.dockerenv) and podman (/run/.containerenv) put in every container.
CONTAINER_MARKERS = ("/.dockerenv", "/run/.containerenv")


def _permission_fix(folder: Path) -> str:
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


def _holds_our_result(folder: Path) -> bool:
    """A folder with a summary.json (or checks.json) written by stringcontact."""
    for name, key in RESULT_MARKERS.items():
        try:
            data = json.loads((folder / name).read_text())
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and key in data and (key != "status" or data[key] in STATUSES):
            return True
    return False


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
        if kind == "partial":
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p.name)
        elif not target.exists():  # the swap stopped between its two renames: the old result comes back
            os.rename(p, target)
            warnings.warn(f"--out {target}: restored the previous result from {p.name}", stacklevel=4)
        else:
            shutil.rmtree(p, ignore_errors=True)
    if removed:
        warnings.warn(
            f"--out {target}: removed {len(removed)} unfinished folder(s) left by a run that was killed "
            f"({', '.join(removed)})",
            stacklevel=4,
        )


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _fsync_tree(folder: Path) -> None:
    for p in folder.iterdir():
        if p.is_file():
            fd = os.open(p, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
    _fsync_dir(folder)


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):  # some file systems cannot fsync a directory
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_path(path):
    """Write one file whole or not at all: ``with atomic_path(path) as tmp: write the file to tmp``.

    `tmp` is a hidden sibling ``.NAME.tmp-<pid>.SUFFIX`` (the suffix kept, so matplotlib and pyvista pick
    the format from it); on success it is renamed onto `path` (``os.replace``), on any exception, Ctrl-C
    included, it is removed and the exception goes on.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
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
        if status != "complete" or not force:
            dest = _free_sibling(target, label)
            os.rename(partial, dest)
            return dest
        # --force and complete: swap, so that a crash in between leaves the old result under .NAME.old-*
        old = target.with_name(f".{target.name}.old-{os.getpid()}-{time.monotonic_ns()}")
        os.rename(target, old)
        try:
            os.rename(partial, target)
        except OSError:
            os.rename(old, target)
            raise
        shutil.rmtree(old, ignore_errors=True)
        return target
    try:
        os.replace(partial, target)  # target absent or an empty folder
    except OSError as exc:
        if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR, errno.EBUSY):
            raise
        dest = _free_sibling(target, label)
        os.rename(partial, dest)
        return dest
    return target


def _open_partial(path, force: bool) -> tuple[Path, TargetLock, Path]:
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
        check_target(path, force)
        target.parent.mkdir(parents=True, exist_ok=True)
        lock = TargetLock(target)
        check_target(target, force, locked=True)  # again under the lock: a run may have just finished there
        _recover_stale(target)
        partial = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-{os.getpid()}-", dir=target.parent))
        os.chmod(partial, 0o777 & ~_umask())  # mkdtemp makes it private; the result is an ordinary folder
        return target, lock, partial
    except BaseException as exc:
        if partial is not None:
            shutil.rmtree(partial, ignore_errors=True)
        if lock is not None:
            lock.release()
        if isinstance(exc, OSError):
            raise OutputError(f"--out {target}: cannot create the output folder: {describe_os_error(exc, target.parent)}") from None
        raise


def _publish_partial(partial: Path, target: Path, force: bool, status: str = "complete") -> Path:
    """fsync the finished folder `partial`, rename it into place (`move_into_place`), fsync the parent.

    Returns where the folder went. Call it with the signals held.
    """
    _fsync_tree(partial)
    dest = move_into_place(partial, target, force, status)
    _fsync_dir(target.parent)
    return dest


@contextlib.contextmanager
def staged_folder(path, force: bool = False):
    """Write a whole output folder, or nothing: ``with staged_folder(out, force) as tmp: write files into tmp``.

    The same protocol as a run's output (for commands such as ``check --out`` that write files, not a time
    series): the lock, a unique hidden folder beside the target, fsync and rename at the end; on any error,
    including Ctrl-C, the hidden folder is removed and the target is left as it was. Serial (one process).
    """
    target, lock, partial = _open_partial(path, force)
    try:
        yield partial
        with signals_held():
            try:
                dest = _publish_partial(partial, target, force)
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


# --- signals and HDF5's error printing -----------------------------------------------------------------


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT, SIGTERM and SIGHUP back for a short critical section; they take effect right after it.

    The Python handlers are swapped for a recorder (blocking the signals in the OS would not do: a signal
    that arrived just before still runs its Python handler at the next bytecode, inside the section).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    saved = {s: h for s, h in saved.items() if h is not None}  # a C handler (PETSc's) cannot be put back: leave it
    for s in saved:
        signal.signal(s, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
        for signum in received[:1]:
            handler = saved[signum]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)


class _Hdf5Quiet:
    """Turns HDF5's automatic error printing off while the writer runs.

    On a full disk, HDF5 prints a 60-line error stack to stderr before PETSc turns it into an error (a RuntimeError);
    we report one line instead (`describe_os_error`). The switch is HDF5's own H5Eset_auto2 on the libhdf5
    that dolfinx and PETSc loaded (not h5py's bundled copy); where it cannot be found nothing changes.
    """

    @classmethod
    def _library(cls):
        return hdf5_library()

    def __init__(self):
        self.saved = None

    def __enter__(self):
        lib = self._library()
        if lib is not None:
            func, data = ctypes.c_void_p(), ctypes.c_void_p()
            if lib.H5Eget_auto2(0, ctypes.byref(func), ctypes.byref(data)) >= 0:  # 0 is H5E_DEFAULT
                self.saved = (func, data)
                lib.H5Eset_auto2(0, None, None)
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            self._library().H5Eset_auto2(0, self.saved[0], self.saved[1])
            self.saved = None
        return False


# --- the writer ------------------------------------------------------------------------------------------


def xdmf_frames(steps, keep_steps, max_frames: int) -> np.ndarray:
    """Which stored rows become XDMF frames: at most `max_frames` (at least 2) of them. The first and the last
    always; then the rows at `keep_steps` (the scene's output times), evenly thinned if they do not fit;
    then evenly spaced rows up to `max_frames`.

    dolfinx 0.5's XDMFFile rewrites its whole XML on every write, so writing costs O(frames²): 376 rows of
    Example 1 take 3.5 s, 100 take 0.4 s; 3000 output times took over 600 s. The bound is therefore on
    every frame, output times included. The Result and diagnostics.csv keep every stored row.
    """
    steps = np.asarray(steps)
    mask = np.zeros(steps.size, dtype=bool)
    if not steps.size:
        return mask
    budget = max(2, int(max_frames))
    mask[[0, -1]] = True
    keep = np.flatnonzero(np.isin(steps, np.asarray(sorted(keep_steps), dtype=steps.dtype)) & ~mask)
    _add_evenly(mask, keep, budget)
    if keep.size and not mask[keep].all():
        warnings.warn(
            f"the scene's {keep.size} output times do not fit in {budget} XDMF frames (--frames): solution.xdmf "
            f"holds {int(mask[keep].sum())} of them; all are stored rows (diagnostics.csv, the pictures)",
            stacklevel=2,
        )
    _add_evenly(mask, np.flatnonzero(~mask), budget)
    return mask


def _add_evenly(mask: np.ndarray, candidates: np.ndarray, budget: int) -> None:
    """Set up to ``budget - mask.sum()`` of the rows `candidates` (sorted, unset) in `mask`, evenly spaced."""
    room = budget - int(mask.sum())
    if room <= 0 or not candidates.size:
        return
    if candidates.size > room:
        candidates = candidates[((np.arange(room) + 0.5) * (candidates.size / room)).astype(int)]  # centred picks
    mask[candidates] = True


def registered_pictures():
    """The picture function registered under the entry point PICTURES_ENTRY_POINT ("default").

    Looked up by name, not imported: the picture code (viz) imports this module.
    """
    from importlib.metadata import entry_points

    for entry in entry_points(group=PICTURES_ENTRY_POINT, name="default"):
        return entry.load()
    raise RuntimeError(f"no picture function registered as entry point {PICTURES_ENTRY_POINT}:default (reinstall: make setup)")


class OutputWriter:
    """Streams the stored rows to XDMF during the run and writes the tables at the end.

    The solver calls ``write(t, fields)`` at each stored time, then ``finish(result)`` or, on
    InstabilityError or KeyboardInterrupt, ``abort(status, message[, result])``. `path` is where the
    folder ended up (the target, or ``NAME.interrupted``/``NAME.unstable`` beside an existing result).
    """

    def __init__(self, path, scene, V, comm, force: bool = False, pictures=True, frames=None):
        self.comm = comm
        self.frames = None if frames is None else np.asarray(frames, dtype=bool)  # which stored rows go to XDMF
        self._row = 0
        self._skipped = None  # the time of the last stored row not written to XDMF, if the latest row was one
        self._kept = None  # that row's fields: flushed if the run stops there
        self._spare = None  # the buffers the next skipped row is copied into before it replaces the kept one
        self.pictures = pictures  # False, True (the registered picture function) or a function (result, folder)
        self.scene = scene
        self.force = force
        self.write_time = 0.0
        self.times: list[float] = []
        self.lock = None
        self.partial = None
        self.xdmf = None
        self.path = None
        self._quiet = _Hdf5Quiet()
        # Only rank 0 looks at the folder: another rank would find rank 0's own lock and refuse.
        self.target = Path(path).resolve()
        failure = None
        if comm.rank == 0:
            try:
                self.target, self.lock, self.partial = _open_partial(path, force)
            except OutputError as exc:
                failure = str(exc)
        failure, partial = comm.bcast((failure, self.partial), root=0) if comm.size > 1 else (failure, self.partial)
        if failure is not None:
            raise OutputError(failure)
        self.partial = partial
        try:
            self._quiet.__enter__()
            self.xdmf = XdmfTimeSeries(self.partial, mesh_arrays(V, comm), comm)
        except (RuntimeError, OSError) as exc:  # petsc4py's Error is a RuntimeError
            self._fail("cannot write solution.xdmf", exc)
        except BaseException:  # Ctrl-C while opening: leave nothing behind
            self._discard()
            raise

    # -- during the run

    def write(self, t: float, fields: dict) -> None:
        """One stored row: all four fields as one XDMF frame, or (interrupted) none of them.

        Rows that are not among `frames` are not written; the latest of them is kept, so that a run that
        stops there still ends its XDMF with its last stored row.
        """
        row, self._row = self._row, self._row + 1
        if self.frames is not None and row < self.frames.size and not self.frames[row]:
            if self._spare is None:
                self._spare = {name: np.empty(np.shape(values)) for name, values in fields.items()}
            for name, values in fields.items():  # into the spare buffers: a Ctrl-C here leaves the kept row whole
                np.copyto(self._spare[name], values)
            self._kept, self._spare = self._spare, self._kept
            self._skipped = t
            return
        self._skipped = None
        self._write_frame(t, fields)

    def _write_frame(self, t: float, fields: dict) -> None:
        t0 = time.perf_counter()
        try:
            with signals_held():
                self.xdmf.write(t, fields)
                self.times.append(float(t))
        except (RuntimeError, OSError) as exc:
            self._fail(f"cannot write solution.h5 at t = {t:.6g}", exc)
        self.write_time += time.perf_counter() - t0

    # -- the end of a run

    def finish(self, result) -> None:
        """Close the XDMF, write diagnostics, pictures and summary, and rename the folder into place.

        A run whose energy balance does not close is kept, marked "unbalanced" (result.status too), never
        "complete". A write that fails on the device (disk full, I/O error), pictures included, removes the
        folder and raises OutputError on every rank.
        """
        try:
            self._close_xdmf()
            unbalanced = unbalanced_message(result)
            if unbalanced is not None:
                result.status, result.message = "unbalanced", unbalanced
            summary = summary_dict(result)
            failure = None
            if self.comm.rank == 0:
                try:
                    self._write_tables_and_pictures(result, summary)
                except Exception as exc:  # noqa: BLE001 - sorted below
                    if not isinstance(exc, (OSError, RuntimeError)) and disk_failure(exc) is None:
                        raise
                    failure = describe_os_error(disk_failure(exc) or exc, self.target.parent, probe=self.partial)
            if self.comm.size > 1:
                failure = self.comm.bcast(failure, root=0)
            if failure is not None:
                self._discard()
                raise OutputError(f"--out {self.target}: cannot write the output files: {failure}; nothing was written there")
            self._publish(summary)
        except KeyboardInterrupt as exc:
            # Ctrl-C while drawing: the data are whole, and the folder says it was interrupted. If it came
            # after the folder was published (held back until then), the folder is complete and stays so.
            self.abort("interrupted", f"{str(exc) or 'interrupted'} while writing the output files", result=result)
            raise
        except OutputError:
            raise
        except (OSError, RuntimeError) as exc:
            self._fail("cannot write the output files", exc)

    def abort(self, status: str, message: str, result=None, error=None) -> None:
        """Keep what was written so far, marked `status` ("interrupted" or "unstable").

        `result` (optional) holds the rows stored so far, for diagnostics.csv and the energy balance.
        `error` (default: the exception being handled) gives the step, time and r of an InstabilityError.
        Never raises an I/O error: the caller is already handling the run's own exception.
        """
        if self.partial is None and self.xdmf is None:
            return  # already finished, failed or aborted
        if error is None:
            import sys

            error = sys.exc_info()[1]
        try:
            with signals_held():
                if self._skipped is not None and self.xdmf is not None:  # end the XDMF with the last stored row
                    self._write_frame(self._skipped, self._kept)
                    self._skipped = None
                self._close_xdmf()
                summary = summary_dict(result) if result is not None and len(result.t) else self._bare_summary()
                summary["status"] = status
                summary["message"] = message or str(error or "") or status
                if error is not None and getattr(error, "step", None) is not None:
                    summary["instability"] = {"message": str(error), "step": error.step, "time": error.time, "r": error.r}
                if self.comm.rank == 0 and result is not None and len(result.t):
                    write_diagnostics(self.partial / "diagnostics.csv", result)
                self._publish(summary)
        except Exception as exc:  # noqa: BLE001 - never hide the run's own exception behind ours
            self._discard()
            warnings.warn(f"--out {self.target}: the partial output could not be kept: {describe_os_error(exc, self.target)}", stacklevel=2)

    def discard(self) -> None:
        """Remove everything this run wrote (for a caller that stops on an unexpected error)."""
        self._discard()

    # -- internals

    def _write_tables_and_pictures(self, result, summary: dict) -> None:
        """Rank 0: diagnostics.csv and the pictures. A picture that fails on the device raises (`disk_failure`)."""
        write_diagnostics(self.partial / "diagnostics.csv", result)
        if self.pictures:
            t0 = time.perf_counter()
            self._pictures(result)
            summary.setdefault("timings", {})["pictures"] = time.perf_counter() - t0

    def _pictures(self, result) -> None:
        try:  # on rank 0 only
            draw = self.pictures if callable(self.pictures) else registered_pictures()
            draw(result, self.partial)
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001 - pictures are optional; the data must still be kept
            if disk_failure(exc) is not None:  # ...but not on a device that fails: then nothing is kept (finish)
                raise
            warnings.warn(f"pictures not written ({type(exc).__name__}: {one_line(exc, 300)})", stacklevel=3)

    def _bare_summary(self) -> dict:
        import dolfinx

        scene = self.scene
        return {
            "status": None,
            "message": "",
            "scene": scene.as_dict(),
            "r": scene.dt / scene.eps,
            "dolfinx": dolfinx.__version__,
            "stored_rows": self._row,
            "xdmf_frames": len(self.times),
        }

    def _close_xdmf(self, discard: bool = False) -> None:
        if self.xdmf is not None:
            xdmf, self.xdmf = self.xdmf, None
            try:
                xdmf.close(discard=discard)
            except BaseException:
                self.xdmf = xdmf  # still open: a discard closes it (XdmfTimeSeries.close)
                raise
            finally:
                self._quiet.__exit__()

    def _publish(self, summary: dict) -> None:
        """Check the XDMF, write summary.json, fsync, and rename the partial folder into place.

        SIGINT/SIGTERM are held back throughout, so the folder is either still partial or fully in place.
        """
        status = summary.get("status") or "complete"
        failure, dest = None, None
        with signals_held():
            if self.comm.rank == 0:
                try:
                    series = xdmf_series(self.partial / "solution.xdmf")
                    counts = {name: len(series.get(name, ())) for name in FIELDS}
                    if any(c != len(self.times) for c in counts.values()):
                        raise OutputError(f"solution.xdmf holds {counts} time levels, expected {len(self.times)}")
                    summary["xdmf_frames"] = len(self.times)
                    summary["last_time"] = self.times[-1] if self.times else None
                    with open(self.partial / "summary.json", "w") as f:
                        f.write(json.dumps(_clean_json(summary), indent=2, allow_nan=False))
                    dest = _publish_partial(self.partial, self.target, self.force, status)
                except (OSError, OutputError) as exc:
                    failure = describe_os_error(exc, self.target) if isinstance(exc, OSError) else str(exc)
            if self.comm.size > 1:
                failure, dest = self.comm.bcast((failure, dest), root=0)
            if failure is not None:
                self._discard()
                raise OutputError(f"--out {self.target}: {failure}; nothing was written there")
            self.path, self.partial = dest, None
            self._release()
        if dest != self.target and self.comm.rank == 0:
            warnings.warn(f"--out {self.target} already holds a result; this run's {status} output is in {dest}", stacklevel=3)

    def _fail(self, what: str, exc: BaseException):
        reason = describe_os_error(exc, self.target.parent, probe=self.partial)  # before the partial folder frees the disk
        self._discard()
        raise OutputError(f"--out {self.target}: {what}: {reason}; nothing was written there") from None

    def _discard(self) -> None:
        if self.xdmf is not None:
            with contextlib.suppress(Exception):
                self._close_xdmf(discard=True)
        self._quiet.__exit__()
        if self.comm.rank == 0 and self.partial is not None:
            shutil.rmtree(self.partial, ignore_errors=True)
        self.partial = None
        self._release()

    def _release(self) -> None:
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def __del__(self):  # an unexpected error in the solver: no half-written folder, no stale lock
        with contextlib.suppress(Exception):
            if self.partial is not None:
                self._discard()


# --- tables and numbers ----------------------------------------------------------------------------


def _clean_json(o):
    """JSON without NaN/Infinity (not JSON): non-finite numbers become the strings "nan", "inf", "-inf"."""
    if isinstance(o, dict):
        return {str(k): _clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean_json(o.tolist())
    if isinstance(o, (np.bool_, bool)):
        return bool(o)
    if isinstance(o, (np.integer, int)):
        return int(o)
    if isinstance(o, (np.floating, float)):
        v = float(o)
        return v if math.isfinite(v) else str(v)
    if o is None or isinstance(o, str):
        return o
    return str(o)


DIAGNOSTIC_COLUMNS = (
    "step",
    "t",
    "kinetic",
    "elastic",
    "viscous_dissipation",
    "contact_dissipation",
    "numerical_dissipation",
    "external_work",
    "balance_residual",
    "min_eta",
    "contact_length",
    "max_contact_force",
)


def write_diagnostics(path: Path, result) -> None:
    cols = {
        "step": result.steps,
        "t": result.t,
        **result.energy,
        "balance_residual": result.balance_residual,
        "min_eta": result.eta.min(axis=1),
        "contact_length": result.contact_length,
        "max_contact_force": result.contact_force.max(axis=1),
    }
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(DIAGNOSTIC_COLUMNS)
        for i in range(len(result.t)):
            w.writerow([int(cols[c][i]) if c == "step" else repr(float(cols[c][i])) for c in DIAGNOSTIC_COLUMNS])


def energy_balance(result) -> dict:
    """The discrete energy balance at the last stored time, with a verdict.

    E(0) + W_ext = E(t) + D_visc + D_con + D_num, where D_num is the scheme's own consistency term
    (see `Result`). The residual is the largest |E(0) + W_ext − [E(t) + D]| over the stored times,
    relative to the largest term; the balance "closes" when it is below BALANCE_RTOL.
    """
    e = result.energy
    total = result.total_energy
    residual = np.asarray(result.balance_residual, dtype=float)
    terms = {
        "initial": float(total[0]),
        "final": float(total[-1]),
        "viscous_dissipation": float(e["viscous_dissipation"][-1]),
        "contact_dissipation": float(e["contact_dissipation"][-1]),
        "numerical_dissipation": float(e["numerical_dissipation"][-1]),
        "external_work": float(e["external_work"][-1]),
    }
    scale = max([abs(v) for v in terms.values()] + [np.finfo(float).tiny])
    worst = float(np.max(np.abs(residual))) if residual.size else 0.0
    relative = worst / scale if math.isfinite(worst) else math.inf
    return {
        **terms,
        "residual": float(residual[-1]),
        "max_abs_residual": worst,
        "relative_residual": relative,
        "tolerance": BALANCE_RTOL,
        "closes": bool(relative <= BALANCE_RTOL),
    }


def penetration_check(result) -> dict:
    """How far the string went below the obstacle, against the bound of its contact law.

    The velocity penalty F = (1/ε)(v)⁻ brakes a node falling at speed V within a depth ε·V (exactly, for
    the explicit scheme: Σ Δt·V·(1 − r)^k = ε·V), plus at most one step Δt·V travelled before the force
    switches on. The bound allows twice that, for the elastic and viscous forces acting meanwhile, below
    the deepest initial value:

        depth ≤ max(0, max(ψ − η0)) + PENETRATION_FACTOR·(ε + Δt)·V,   V = max |v| over the stored rows,

    with ψ the scene's obstacle (0 unless it gives one). For the `elastic` variant (a spring of stiffness
    1/ε) ε·V becomes √ε·V. A run beyond the bound holds the string down by something the penalty cannot
    stop (a static load, a model variant, an r > 1 rebound): see docs/reliability.md.
    """
    scene = result.scene
    if getattr(result, "has_rows", True):
        eta = np.asarray(result.eta, dtype=float)
        velocity = np.asarray(result.velocity, dtype=float)
        v_max = float(np.max(np.abs(velocity))) if velocity.size else 0.0
        if scene.obstacle is None:  # min_eta covers every step, not only the stored ones
            depth = max(0.0, -float(result.min_eta))
            start_depth = max(0.0, -float(np.min(eta[0]))) if eta.size else 0.0
        else:
            obstacle = scene.obstacle_values(np.asarray(result.x, dtype=float))
            depth = max(0.0, float(np.max(obstacle - eta))) if eta.size else 0.0
            start_depth = max(0.0, float(np.max(obstacle - eta[0]))) if eta.size else 0.0
    else:  # an MPI rank without the rows: the same numbers from the series the ranks summed (Result.series)
        v_max, depth, start_depth = _penetration_from_series(result)
    braking = math.sqrt(scene.eps) if result.model == "elastic" else scene.eps
    bound = start_depth + PENETRATION_FACTOR * (braking + scene.dt) * v_max
    return {
        "depth": depth,
        "bound": bound,
        "initial_depth": start_depth,
        "max_speed": v_max,
        "eps_times_speed": braking * v_max,
        "law": "spring (sqrt(eps))" if result.model == "elastic" else "velocity penalty (eps)",
        "within_bound": bool(depth <= bound * (1 + 1e-12)),
    }


def _penetration_from_series(result) -> tuple[float, float, float]:
    """max |v|, the depth and the initial depth from Result.series ("max_speed", "depth" = max(ψ − η))."""
    speed, below = result.series["max_speed"], result.series["depth"]
    if not len(below):
        return 0.0, max(0.0, -float(result.min_eta)), 0.0
    depth = -float(result.min_eta) if result.scene.obstacle is None else float(np.max(below))
    return float(np.max(speed)), max(0.0, depth), max(0.0, float(below[0]))


def unbalanced_message(result) -> str | None:
    """Why a run whose energy balance does not close cannot be called complete; None if it closes."""
    if not len(result.t):
        return None
    b = energy_balance(result)
    if b["closes"]:
        return None
    return (
        f"the energy balance does not close (relative residual {b['relative_residual']:.2g} > {b['tolerance']:.0e}): "
        "the numbers are not trustworthy; see docs/reliability.md"
    )


def summary_dict(result) -> dict:
    import dolfinx

    scene = result.scene
    return {
        "status": result.status,
        "message": result.message,
        "scene": scene.as_dict(),
        "scheme": result.scheme,
        "penalty": result.penalty,
        "mass": result.mass,
        "model": result.model,
        "r": scene.dt / scene.eps,
        "dolfinx": dolfinx.__version__,
        "timings": result.timings,
        "min_eta": result.min_eta,
        "stored_rows": len(result.t),
        "final_energy": {k: float(v[-1]) for k, v in result.energy.items()},
        "initial_energy": float(result.total_energy[0]),
        "max_abs_balance_residual": float(np.max(np.abs(result.balance_residual))),
        "energy_balance": energy_balance(result),
        "penetration": penetration_check(result),
    }
