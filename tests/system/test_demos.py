"""Every demo in demos/ runs as a plain script at reduced resolution and writes only under its output folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

DEMOS = sorted((Path(__file__).resolve().parents[2] / "demos").glob("*.py"))
TIMEOUT = 900  # seconds per demo: generous, the machine is shared; a timing threshold is not the point
# What the paper's demos must report (the observations of Section 6, measured at reduced resolution;
# the full-resolution numbers are in docs/explanation/visualisation.md), and the files they must leave.
EXPECTED = {
    "demo_example1.py": ["largest contact fraction", "mirror node: 0", "contact fraction never grows after its peak: True"],
    "demo_example2.py": ["most components at one time", "two or more components"],
    "demo_membrane.py": ["the contact patch is a disk at every stored time: True", "two patches that join into one: True",
                         "the inelastic skin stays down longer: True", "the spring loses under 1% of E(0) in contact: True"],
    "demo_stiff_string.py": ["dispersion relation: largest relative error", "the landing stays above the obstacle: True",
                             "the contact force is >= 0 and 0 off the contact set: True", "energy ledger closes: True"],
}
PAPER_FILES = ("solution.xdmf", "solution.h5", "contact_set.png", "velocity_field.png", "snapshots.png", "energy.png")
FILES = {
    "demo_example1.py": PAPER_FILES,
    "demo_example2.py": PAPER_FILES,
    "demo_membrane.py": ("solution.xdmf", "solution.h5", "membrane.png", "contact_area.png", "energy.png", "membrane.gif",
                         "drum_variants.png"),
    "demo_stiff_string.py": ("stiff_string_modes.png", "stiff_string_landing.png"),
}


def test_there_are_demos():
    names = {d.name for d in DEMOS}
    assert {"demo_example1.py", "demo_example2.py"} <= names


@pytest.mark.slow  # each demo is a script of several whole runs with pictures, in its own process
@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demo_runs(demo, tmp_path):
    out = tmp_path / "out"
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    env = dict(os.environ, STRINGCONTACT_DEMO_FAST="1", STRINGCONTACT_DEMO_OUT=str(out), MPLBACKEND="Agg")
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    proc = subprocess.run(
        [sys.executable, str(demo)], cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT
    )
    assert proc.returncode == 0, f"{demo.name} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    written = [p for p in out.rglob("*") if p.is_file()]
    assert written, f"{demo.name} wrote nothing under STRINGCONTACT_DEMO_OUT"
    assert not any(cwd.iterdir()), f"{demo.name} wrote outside STRINGCONTACT_DEMO_OUT: {sorted(cwd.iterdir())}"
    assert "Traceback" not in proc.stderr
    for words in EXPECTED.get(demo.name, []):
        assert words in proc.stdout, f"{demo.name}: {words!r} not in its output:\n{proc.stdout}"
    for name in FILES.get(demo.name, ()):
        assert list(out.rglob(name)), f"{demo.name}: no {name}"
