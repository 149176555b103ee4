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
