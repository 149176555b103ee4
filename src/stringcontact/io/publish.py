"""An output folder is absent, complete, or marked in its summary.json, never half-written: `check_target` refuses an
--out that cannot or must not take a result, `TargetLock` locks it, a command writes into a hidden
``.NAME.partial-*`` beside it, fsyncs and renames that into place (`staged_folder`). With ``--force`` a complete
result replaces one of ours through ``.NAME.old-*``; any other goes beside it (``NAME.interrupted``, ...). The next
run to take the lock removes what killed runs left. Each file is written whole (`atomic_path`) and listed with its size
in the folder's ``manifest.json``: all that ``--force`` may replace (`foreign_file`). A failed write is one line
(`describe_os_error`)."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import functools
import itertools
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

import filelock

from ..errors import OutputError, one_line
from ..signals import signals_held

#: The marker file of a run's hidden folders ("partial" while written, "old" when moved aside by a --force swap): a
#: later run removes only folders so marked.
MARKER = ".stringcontact-marker"
#: below this many free bytes a failed write is reported as a full disk.
NEARLY_FULL_BYTES = 1 << 20
#: errno values that mean the device failed, not the data: the output folder cannot be kept.
DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS)
#: Files that Docker (/.dockerenv) and podman (/run/.containerenv) put in every container.
CONTAINER_MARKERS = ("/.dockerenv", "/run/.containerenv")
#: The list of the files a stringcontact command wrote into a folder, with their sizes: what `--force` may replace.
MANIFEST = "manifest.json"
#: The largest manifest read: a folder's few dozen names and sizes take a few kB.
MAX_MANIFEST_BYTES = 1 << 20


# --- the device: a failed write in one line, fsync ---------------------------------------------------------------

def describe_os_error(exc: BaseException, folder, probe=None) -> str:
    """One line for an I/O failure in `folder`; without an errno (a RuntimeError) the device of `probe` is examined."""
    err = getattr(exc, "errno", None)
    reasons = {errno.ENOSPC: f"the disk is full (no space left on the device of {folder})",
               errno.EDQUOT: f"the disk quota is exceeded on {folder}", errno.EROFS: f"{folder} is on a read-only file system",
               errno.EACCES: f"permission denied in {folder}", errno.EPERM: f"permission denied in {folder}"}
    if err is not None:
        return reasons.get(err) or f"{getattr(exc, 'strerror', None) or exc} ({folder})"
    probe = _existing(Path(probe if probe is not None else folder))
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


def _existing(path: Path) -> Path:
    """`path` or its nearest existing parent."""
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


# --- a file written whole, the manifest listing the files ----------------------------------------------------------

def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def small_regular_file(path: Path, limit: int) -> bytes | None:
    """The bytes of `path` if it is a regular file (no link, FIFO or device) of at most `limit` bytes, else None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        data = os.read(fd, limit + 1) if stat.S_ISREG(st.st_mode) and st.st_size <= limit else None
    except OSError:
        data = None
    finally:
        os.close(fd)
    return data if data is not None and len(data) <= limit else None


def read_manifest(folder: Path) -> dict[str, int] | None:
    """{file name: size} from the folder's manifest, or None if it has none that a stringcontact command wrote."""
    text = small_regular_file(Path(folder) / MANIFEST, MAX_MANIFEST_BYTES)
    try:
        data = json.loads(text) if text is not None else None
    except (ValueError, RecursionError, MemoryError):
        return None
    files = data.get("files") if isinstance(data, dict) and data.get("written_by") == "stringcontact" else None
    if not isinstance(files, dict) or not all(isinstance(v, int) and not isinstance(v, bool) for v in files.values()):
        return None
    return files


def write_manifest(folder: Path, files: dict[str, int]) -> None:
    """Write `folder`'s manifest whole: {name: size} of the files a command wrote there."""
    with atomic_path(Path(folder) / MANIFEST, record=False) as tmp:
        tmp.write_text(json.dumps({"written_by": "stringcontact", "files": dict(sorted(files.items()))}, indent=1) + "\n")


def foreign_file(folder: Path, depth: int = 3) -> str | None:
    """Why `--force` may not replace `folder` (its first file the manifest does not list with that size), or None; a
    folder in it that a command published counts, `depth` levels down."""
    files = read_manifest(folder)
    if files is None:
        return f"this folder has no {MANIFEST} of a stringcontact command"
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


@contextlib.contextmanager
def atomic_path(path, record: bool = True):
    """One file whole or not at all: ``with atomic_path(path) as tmp: write to tmp``, a hidden sibling renamed onto
    `path`, or removed on any error. With `record`, the file joins the folder's manifest if it has one."""
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
        files = read_manifest(path.parent) if record else None
        if files is not None and path.name != MANIFEST:
            write_manifest(path.parent, files | {path.name: path.stat().st_size})
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# --- whether an --out may take a result ----------------------------------------------------------------------------

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
        _check_parent(target, resolved.parent, parents)
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


def _check_parent(target: Path, parent: Path, parents: bool) -> None:
    """Refuse a missing parent outside the current folder (``--out /nonexistent/x``: a typo; unless `parents`) and a
    nearest existing parent that is a file or cannot be written."""
    existing = _existing(parent)
    missing = next((p for p in [parent, *parent.parents] if p.parent == existing), existing)
    with contextlib.suppress(OSError):
        parents = parents or Path.cwd() in missing.parents
    if missing != existing and not parents:
        raise OutputError(f"--out {target}: the folder {missing} does not exist; create it first (mkdir -p {parent}) "
                          "or correct the path")
    if existing.exists() and not existing.is_dir():
        raise OutputError(f"--out {target}: cannot create the output folder: {existing} is a file, not a folder; "
                          "choose a path inside a folder")
    reason = None
    with contextlib.suppress(OSError):
        if os.statvfs(existing).f_flag & os.ST_RDONLY:
            reason = errno.EROFS
    if reason is None and not os.access(existing, os.W_OK | os.X_OK):
        reason = errno.EACCES
    if reason is not None:
        why = describe_os_error(OSError(reason, os.strerror(reason)), existing)
        raise OutputError(f"--out {target}: cannot create the output folder: {why}"
                          + (permission_fix(existing) if reason == errno.EACCES else ""))


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


# --- the lock -----------------------------------------------------------------------------------------------------

def _lock_path(target) -> Path:
    return Path(target).parent / f".{Path(target).name}.lock"


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
    """An exclusive, non-blocking lock on ``.NAME.lock`` beside `target` (filelock's `FileLock` tried once; the file
    holds the holder's pid and `command`, which a refusal names; removed on release); `label` names the folder in
    messages. Held by another: `OutputError` naming it; anything but a regular file is refused (filelock locks a
    FIFO)."""

    def __init__(self, target, command: str = "run", label: str | None = None):
        self.path, self.target = _lock_path(target), Path(target)
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
                kind = stat.S_IFMT(os.lstat(self.path).st_mode) if os.path.lexists(self.path) else stat.S_IFREG
                if kind == stat.S_IFREG:
                    raise
                odd = {stat.S_IFLNK: "a symbolic link", stat.S_IFIFO: "a FIFO", stat.S_IFDIR: "a folder"}
                raise OutputError(f"{label}: its lock file {self.path.name} is {odd.get(kind, 'not a regular file')}, "
                                  "which no stringcontact run makes; remove it (nothing was written there)") from None
        raise OutputError(f"--out {self.target}: cannot take the lock {self.path}")  # pragma: no cover

    def release(self) -> None:
        """Remove the lock file while still holding it, then unlock."""
        if self._lock.is_locked:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
            self._lock.release()

    @staticmethod
    def busy(target, label: str | None = None) -> str | None:
        """The one-line refusal of a folder another command holds, naming it and the pid and command in its lock file;
        else None. Hand-written: filelock has no probe that leaves a missing lock file missing."""
        try:
            fd = os.open(_lock_path(target), os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return None
        except BlockingIOError:
            text = ""
            with contextlib.suppress(OSError):
                text = os.pread(fd, 64, 0).decode(errors="replace")
        except OSError:  # not a file flock works on (a FIFO, a device): no run of ours holds it
            return None
        finally:
            os.close(fd)
        pid, command = (line.strip() for line in [*text.split("\n"), ""][:2])
        who, label = f" (pid {int(pid)})" if pid.isdigit() and int(pid) else "", label or f"--out {target}"
        if command in ("", "run") or not command.isalpha():
            return (f"{label}: another stringcontact run{who} is writing to this folder; wait for it to finish or "
                    "choose another folder")
        doing = "is drawing its pictures in this folder" if command == "plot" else "is writing to this folder"
        return f"{label}: `stringcontact {command}`{who} {doing}; wait for it to finish or choose another folder"


# --- the hidden folder, published whole ---------------------------------------------------------------------------

def _recover_stale(target: Path) -> None:
    """Under the lock: remove the marked hidden folders of killed runs into `target`, put back a result an interrupted
    --force swap left aside."""
    name, removed = re.escape(target.name), []
    with contextlib.suppress(OSError):
        for p in sorted(target.parent.iterdir()):
            kind = ("partial" if re.fullmatch(rf"\.{name}\.partial-\d+-[a-z0-9_]+", p.name)
                    else "old" if re.fullmatch(rf"\.{name}\.old-\d+-\d+", p.name) else None)
            if kind is None or not p.is_dir() or p.is_symlink() or TargetLock.busy(p) is not None:
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


def _move_into_place(partial: Path, target: Path, force: bool, status: str) -> Path:
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
        names = (target.with_name(f"{target.name}.{label}" + (f"-{i}" if i > 1 else "")) for i in itertools.count(1))
        dest = next(name for name in names if not name.exists())
        os.rename(partial, dest)
        return dest
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
    dest = _move_into_place(partial, target, force, status)
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
