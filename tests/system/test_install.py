"""`pip install ".[dolfinx]"` into a fresh virtual environment that has nothing but what pip puts there: dolfinx 0.11
from PyPI's wheel, and this package from its source; then `make demo`'s run with its pictures (docs/tutorial/install.md).

Offline: pip takes every distribution from a wheelhouse (``STRINGCONTACT_WHEELHOUSE``; the image's wheel-test target
makes it with ``scripts/setup --wheel --wheelhouse``). Without one the test is skipped: on Debian's dolfinx the
package is installed by scripts/setup instead.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
WHEELHOUSE = os.environ.get("STRINGCONTACT_WHEELHOUSE")


@pytest.mark.slow
@pytest.mark.skipif(not WHEELHOUSE, reason="no wheelhouse (STRINGCONTACT_WHEELHOUSE): the wheel's image makes one")
def test_pip_install_with_the_dolfinx_extra_runs_example1(tmp_path):
    source = tmp_path / "source"  # a copy: pip builds in the source folder, which must stay as it is
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, source / name)
    shutil.copytree(ROOT / "src", source / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = subprocess.run([venv / "bin" / "python", "-m", "pip", "install", "-q", "--no-index", "--find-links",
                          WHEELHOUSE, f"{source}[dolfinx]"], capture_output=True, text=True, check=False)
    assert pip.returncode == 0, pip.stderr[-3000:]
    listed = subprocess.run([venv / "bin" / "python", "-m", "pip", "list", "--format", "json"], capture_output=True,
                            text=True, check=True).stdout
    names = {d["name"].lower() for d in json.loads(listed)}
    assert "dolfinx-solver-real" in names and "stringcontact" in names
    out = tmp_path / "ex1"
    run = subprocess.run([venv / "bin" / "stringcontact", "run", "example1", "--out", str(out), "--no-progress"],
                         capture_output=True, text=True, check=False, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete"
    for picture in ("contact_set.png", "energy.png", "space_time.png", "velocity_field.png", "snapshots.png"):
        assert (out / picture).stat().st_size > 10_000, picture
    assert (out / "solution.xdmf").is_file() and (out / "solution.h5").stat().st_size > 0
