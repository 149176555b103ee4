"""Files written whole or not at all (`atomic_path`), and a folder's ``manifest.json`` listing them with their sizes:
all that `--force` may replace (`foreign_file`)."""

from __future__ import annotations

import contextlib
import json
import os
import stat
import tempfile
from pathlib import Path

#: The list of the files a stringcontact command wrote into a folder, with their sizes: what `--force` may replace.
MANIFEST = "manifest.json"
#: The largest manifest read: a folder's few dozen names and sizes take a few kB.
MAX_MANIFEST_BYTES = 1 << 20


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
