"""The repository holds text and the docs' PNG figures: no wheels, archives or executables (tools come from registries)."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PNG = b"\x89PNG\r\n\x1a\n"


def _tracked() -> list[Path]:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    return [ROOT / name for name in out.decode().split("\0") if name]


def test_no_binaries_in_the_tree():
    binaries = []
    for path in _tracked():
        if not path.is_file():  # deleted in the work tree, not yet committed
            continue
        head = path.read_bytes()[:8192]
        figure = path.suffix == ".png" and path.parent == ROOT / "docs" and head.startswith(PNG)
        if b"\0" in head and not figure:
            binaries.append(str(path.relative_to(ROOT)))
    assert binaries == []


def test_no_two_test_files_share_a_name():
    """The test folders have no __init__.py, so pytest imports each file by its name alone: two test_x.py in two
    folders stop the collection ("import file mismatch")."""
    seen: dict[str, list[str]] = {}
    for path in (ROOT / "tests").rglob("test_*.py"):
        seen.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    assert {name: paths for name, paths in seen.items() if len(paths) > 1} == {}
