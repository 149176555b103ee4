"""3-D axes with the venv's matplotlib, beside Debian's python3-matplotlib (which python3-paraview pulls in):
Debian's matplotlib-*-nspkg.pth made `mpl_toolkits` its own package before any import, so a matplotlib that pip
put into the venv found Debian's mplot3d ("Unable to import Axes3D", "Unknown projection '3d'").
scripts/setup installs scripts/mpl_toolkits.pth into the venv, which registers the venv's own first."""

from __future__ import annotations

import glob
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PTH = REPO / "scripts" / "mpl_toolkits.pth"

DRAW = """
import sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import mpl_toolkits.mplot3d
fig = plt.figure()
ax = fig.add_subplot(projection="3d")
ax.plot([0, 1], [0, 1], [0, 1])
fig.savefig(sys.argv[1])
print(matplotlib.__file__)
print(mpl_toolkits.mplot3d.__file__)
"""


def test_the_venvs_python_draws_a_3d_plot_with_its_own_matplotlibs_mplot3d(tmp_path):
    png = tmp_path / "axes3d.png"
    proc = subprocess.run([sys.executable, "-W", "error::UserWarning", "-c", DRAW, str(png)], capture_output=True,
                          text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]  # no "Unable to import Axes3D", no "Unknown projection '3d'"
    assert png.stat().st_size > 5000
    matplotlib_file, mplot3d_file = proc.stdout.split()
    # mplot3d from the folder that holds this matplotlib (the venv's, or Debian's when the venv has none)
    assert Path(mplot3d_file).parents[2] == Path(matplotlib_file).parents[1], (matplotlib_file, mplot3d_file)


def test_setup_installed_the_pth_into_this_venv():
    if sys.prefix == sys.base_prefix:
        pytest.skip("not run from a venv")
    installed = Path(sysconfig.get_paths()["purelib"]) / "mpl_toolkits.pth"
    assert installed.is_file(), f"{installed} missing: run scripts/setup"
    assert installed.read_text() == PTH.read_text()
    assert "mpl_toolkits.pth" in (REPO / "scripts" / "setup").read_text()


@pytest.mark.parametrize("with_pth", [True, False])
def test_a_venvs_own_mpl_toolkits_comes_before_debians(tmp_path, with_pth):
    """A venv (system site packages) holding an mpl_toolkits of its own, as pip's matplotlib installs it: with
    the .pth its mplot3d is imported, without it Debian's (the failure this guards against)."""
    debian = glob.glob("/usr/lib/python3/dist-packages/matplotlib-*-nspkg.pth")
    if not debian:
        pytest.skip("Debian's python3-matplotlib (its nspkg .pth) is not installed")
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    own = site / "mpl_toolkits" / "mplot3d"
    own.mkdir(parents=True)
    (own / "__init__.py").write_text("WHOSE = 'the venv'\n")
    if with_pth:
        (site / "mpl_toolkits.pth").write_text(PTH.read_text())
    proc = subprocess.run([str(python), "-c", "import mpl_toolkits.mplot3d as m; print(getattr(m, 'WHOSE', m.__file__))"],
                          capture_output=True, text=True, check=False)
    whose = proc.stdout.strip()
    assert (whose == "the venv") is with_pth, (whose, proc.stderr[-1000:])
