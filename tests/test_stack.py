"""The FEniCS stack: the package loads it in the order it needs (the dolfinx wheel's MPI first) and refuses a
dolfinx it does not support in one line, exit code 2."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import pytest

from stringcontact import stack
from stringcontact.errors import StackError

WHEEL = importlib.util.find_spec("dolfinx_solver") is not None


@pytest.mark.parametrize("found", ["0.5.2", "0.9.0", "0.10.0", "0.11.0.post0", "0.11.1"])
def test_the_supported_versions_pass(found):
    stack.check_version(found)


@pytest.mark.parametrize("found", ["0.4.1", "0.12.0", "1.0.0", "0.13.0.dev0", "unknown"])
def test_another_version_is_refused_naming_the_found_and_the_supported(found):
    with pytest.raises(StackError) as info:
        stack.check_version(found)
    message = str(info.value)
    assert "\n" not in message and f"dolfinx {found} is not supported" in message
    assert "0.5 to 0.11" in message and stack.WHEEL in message


def test_a_program_that_imports_only_stringcontact_runs():
    """A user's script names neither dolfinx_solver nor the import order; on the wheel, `import dolfinx` first fails
    (libmpi.so.12), so the package must load the stack itself."""
    script = ("import stringcontact as sc\n"
              "r = sc.simulate(sc.load_scene('example1').replace(nx=20, nt=600))\n"
              "print(r.status)\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and proc.stdout.strip() == "complete", proc.stderr[-2000:]


@pytest.mark.skipif(not WHEEL, reason="the import-order rule is the dolfinx wheel's")
def test_on_the_wheel_dolfinx_alone_does_not_import():
    """What the package's `stack.load` is for: without it, dolfinx from the wheel cannot be imported."""
    proc = subprocess.run([sys.executable, "-c", "import dolfinx"], capture_output=True, text=True, check=False)
    assert proc.returncode != 0 and "libmpi" in proc.stderr


@pytest.mark.skipif(not WHEEL, reason="the import-order rule is the dolfinx wheel's")
def test_on_the_wheel_importing_stringcontact_starts_no_mpi_and_the_users_dolfinx_then_imports():
    """`import stringcontact` leaves MPI unloaded (the command line sets its streams, signals and MPI settings first);
    the user's own `import dolfinx` after it brings the wheel's MPI first."""
    code = ("import sys, stringcontact\nbefore = 'mpi4py.MPI' in sys.modules or 'dolfinx_solver' in sys.modules\n"
            "import dolfinx.mesh\nprint(before, 'dolfinx_solver' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and proc.stdout.split() == ["False", "True"], proc.stderr[-2000:]


@pytest.mark.slow
def test_the_command_refuses_a_dolfinx_too_new_in_one_line(tmp_path):
    """A dolfinx release outside `SUPPORTED` (here a stand-in that says 0.12.0): one line naming it and the
    supported ones, exit 2, nothing written."""
    fake = tmp_path / "site" / "dolfinx"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('__version__ = "0.12.0"\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(fake.parent), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "run", "example1", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, env=env, check=False)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1 and "dolfinx 0.12.0 is not supported" in proc.stderr
    assert "0.5 to 0.11" in proc.stderr and not (tmp_path / "out").exists()
