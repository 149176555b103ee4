"""A hostile user's fifth round (docs/explanation/reliability_promises.md): code planted in the working folder,
studies that refused only after computing, user models that crashed, exited 0 or ran to garbage marked
"complete", arrays read back unchecked, messages that blamed the wrong thing. Each is one line and exit 2 (or
a run that stops at the step that failed), nothing written."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import leftovers

QUICK = ["--no-progress", "--no-pictures"]
SMALL = ["--nx", "50", "--nt", "40", "--eps", "0.01"]


def stringcontact(*argv, python=(), cwd=None, env=None, timeout=300) -> subprocess.CompletedProcess:
    """`python [PYTHON] -m stringcontact ARGV` in a fresh process; a hang fails the test."""
    try:
        return subprocess.run([sys.executable, *python, "-m", "stringcontact", *map(str, argv)], capture_output=True,
                              text=True, cwd=cwd, env=env, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail(f"stringcontact {' '.join(map(str, argv))} did not end within {timeout} s")


def one_error_line(stderr: str, *fragments) -> str:
    lines = [line for line in stderr.splitlines() if not line.startswith("stringcontact: warning:")]
    assert len(lines) == 1 and lines[0].startswith("stringcontact: error: "), stderr[-3000:]
    assert "internal error" not in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


# --- code in the working folder ----------------------------------------------------------------------------------

PLANTED = "import pathlib\npathlib.Path('imported-{name}').write_text('x')\n"


def _plant(folder: Path, *names: str) -> None:
    for name in names:
        (folder / f"{name}.py").write_text(PLANTED.format(name=name))


def test_the_picture_process_imports_nothing_from_the_working_folder(tmp_path):
    """The picture process was started with `python -c`, which puts the current folder first on sys.path: a
    stringcontact.py or pyvista.py there ran. `-P` (as the installed `stringcontact` command) keeps the run's own
    process from the folder; the picture process must keep itself from it too."""
    _plant(tmp_path, "stringcontact", "pyvista", "matplotlib")
    proc = stringcontact("run", "example1", *SMALL, "--no-progress", "--out", tmp_path / "o", python=("-P",),
                         cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "o" / "energy.png").is_file()
    assert sorted(p.name for p in tmp_path.glob("imported-*")) == []


def test_python_m_stringcontact_imports_nothing_from_the_working_folder(tmp_path):
    """`python -m stringcontact` puts the current folder first on sys.path: a ufl.py there was imported by the run."""
    _plant(tmp_path, "ufl", "pyvista", "matplotlib")
    proc = stringcontact("run", "example1", *SMALL, "--no-progress", "--out", tmp_path / "o", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.glob("imported-*")) == []
