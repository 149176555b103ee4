"""Input checks that must hold under MPI and before any set-up (issue 27: items 5 and 9, and the also-fix list:
MUMPS' refused ICNTLs, a membrane too large for memory, r >= 2 before the mesh).

Under `mpirun -n 2` a check that fails on one rank only used to leave the other rank waiting in a collective
call forever; each such run is a bounded subprocess (conftest.mpirun), whose expiry fails the test.
"""

import sys
from pathlib import Path

import pytest
from conftest import mpirun

from stringcontact.cli.main import main


def error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("stringcontact: error:")]


def assert_one_line_error(err: str, *fragments):
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("stringcontact: warning:")]
    assert "Traceback" not in err and len(lines) == 1 and lines[0].startswith("stringcontact: error: "), err
    assert all(f in lines[0] for f in fragments), lines[0]


@pytest.fixture(scope="module")
def long_strip(tmp_path_factory) -> Path:
    """An XDMF triangle mesh of [-4, 4] x [0, 1]: two ranks split it across x."""
    from dolfinx import mesh
    from dolfinx.io import XDMFFile
    from mpi4py import MPI

    path = tmp_path_factory.mktemp("mesh") / "strip.xdmf"
    msh = mesh.create_rectangle(MPI.COMM_SELF, [[-4.0, 0.0], [4.0, 1.0]], [32, 4], mesh.CellType.triangle)
    with XDMFFile(MPI.COMM_SELF, str(path), "w") as f:
        f.write_mesh(msh)
    return path


def strip_scene(folder: Path, mesh: Path, **keys) -> Path:
    values = {"T": 0.01, "alpha": 0.01, "scheme": "{ eps = 0.001 }", "nt": 10, "eta0": "'1'", "v0": "0"} | keys
    path = folder / "strip.toml"
    path.write_text(f"mesh = '{mesh}'\n" + "".join(f"{k} = {v}\n" for k, v in values.items()))
    return path


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("key, value", [("eta0", "'1 + sqrt(x + 2)'"), ("v0", "'sqrt(x + 2) - sqrt(x + 2)'"),
                                        ("obstacle", "'-1 + sqrt(x + 2)'")])
def test_an_expression_failing_on_one_rank_ends_every_rank_with_one_line(tmp_path, long_strip, key, value):
    """Not finite at x < -2 only, where one rank's nodes lie (the scene's checks cannot see a mesh file's nodes)."""
    scene = strip_scene(tmp_path, long_strip, **{key: value}, **({"model": "'loaded_obstacle'"} if key == "obstacle" else {}))
    proc = mpirun([sys.executable, "-m", "stringcontact", "run", scene, "--no-progress",
                   "--out", tmp_path / "never"], timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    lines = error_lines(proc.stderr)
    assert len(lines) == 2 and lines[0] == lines[1] and key in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "never").exists()


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("option", ["ksp_type=bogus", "pc_factor_mat_ordering_type=external"])
def test_a_bad_petsc_value_ends_every_rank_with_one_line(tmp_path, option):
    proc = mpirun([sys.executable, "-m", "stringcontact", "run", "example1", "--nx", "40", "--nt", "600",
                   "--no-progress", "--petsc-option", option], timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    lines = error_lines(proc.stderr)
    assert len(lines) == 2 and lines[0] == lines[1] and option.split("=")[0] in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr and "PETSC ERROR" not in proc.stderr


# --- PETSc option values (item 9) -----------------------------------------------------------------------


@pytest.mark.parametrize("option, allowed", [
    ("ksp_type=bogus", "cg, "), ("pc_type=bogus", "jacobi"), ("pc_factor_mat_ordering_type=external", "nd, "),
    ("pc_factor_mat_solver_type=bogus", "mumps"), ("ksp_rtol=tight", "a number"), ("ksp_max_it=2.5", "an integer"),
    ("ksp_initial_guess_nonzero=3", "true or false"), ("pc_type=7", "a word"),
])
def test_a_bad_petsc_option_value_is_one_line_naming_it_and_exit_2(capfd, tmp_path, option, allowed):
    out = tmp_path / "never"
    assert main(["run", "example1", "--nx", "20", "--nt", "600", "--no-progress", "--out", str(out),
                 "--petsc-option", option]) == 2
    assert_one_line_error(capfd.readouterr().err, option.split("=")[0], "allowed:", allowed)
    assert not out.exists()


def test_a_scene_petsc_option_of_the_wrong_type_is_one_line(capfd, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('T = 0.3\nalpha = 0.01\nscheme = { eps = 5e-4 }\nnx = 20\nnt = 600\neta0 = "1"\nv0 = -5\n'
                     "petsc_options = {ksp_type = true}\n")
    assert main(["run", str(scene), "--no-progress"]) == 2
    assert_one_line_error(capfd.readouterr().err, "ksp_type = true", "allowed: a word")


def test_a_value_only_petsc_knows_is_refused_in_one_line(capfd):
    """pc_hypre_type has no petsc4py list: PETSc's own refusal, in one line, exit 2 (where PETSc has hypre: without
    it, hypre's options are left out with BoomerAMG itself, `linear.without_hypre`)."""
    from stringcontact.timestepping import linear

    if not linear.has_hypre():
        pytest.skip("this PETSc has no hypre (the dolfinx wheel's): its options are left out, not refused")
    assert main(["run", "example1", "--nx", "20", "--nt", "600", "--no-progress", "--petsc-option", "pc_type=hypre",
                 "--petsc-option", "pc_hypre_type=bogus"]) == 2
    assert_one_line_error(capfd.readouterr().err, "pc_hypre_type", "boomeramg")


def test_mumps_output_units_are_refused_saying_why(capfd):
    assert main(["run", "example1", "--nx", "20", "--nt", "600", "--petsc-option", "mat_mumps_icntl_4=1"]) == 2
    err = capfd.readouterr().err
    assert_one_line_error(err, "mat_mumps_icntl_4", "not mat_mumps_icntl_1, mat_mumps_icntl_2, mat_mumps_icntl_3, "
                          "mat_mumps_icntl_4, mat_mumps_icntl_22")


# --- cheap checks first, memory estimated up front ------------------------------------------------------


@pytest.mark.parametrize("geometry, key", [('domain = "rectangle"\ncells = [2000, 2000]\n', "cells"),
                                           ('domain = "disk"\nradius = 1\nmesh_size = 0.0015\n', "mesh_size")])
def test_a_membrane_too_large_for_memory_is_refused_from_an_estimate(capfd, tmp_path, geometry, key):
    scene = tmp_path / "big.toml"
    scene.write_text(geometry + 'T = 0.3\nalpha = 0.01\nscheme = { eps = 5e-4 }\nnt = 600\neta0 = "1"\nv0 = -5\n')
    from stringcontact.errors import SceneError
    from stringcontact.scene import load_scene

    with pytest.raises(SceneError):  # when the scene is loaded: nothing is built (it used to take 7 GB and more)
        load_scene(str(scene))
    assert main(["run", str(scene), "--no-progress"]) == 2
    assert_one_line_error(capfd.readouterr().err, f"{key}:", "GB to set up", "allowed: at most 1002001 nodes")


def test_r_at_least_2_is_refused_before_the_mesh_is_built(capfd, monkeypatch):
    from stringcontact.fem import domains

    def no_mesh(*args):
        pytest.fail("the mesh was built before the r >= 2 check")

    monkeypatch.setattr(domains, "create", no_mesh)
    assert main(["run", "drum", "--scheme", "paper", "--nt", "2", "--no-progress"]) == 2
    assert_one_line_error(capfd.readouterr().err, "r = dt/eps", ">= 2")


def test_a_bad_petsc_value_is_refused_before_the_mesh_is_built(capfd, monkeypatch):
    from stringcontact.fem import domains

    monkeypatch.setattr(domains, "create", lambda *a: pytest.fail("the mesh was built before the option check"))
    assert main(["run", "drum", "--no-progress", "--petsc-option", "ksp_type=bogus"]) == 2
    assert_one_line_error(capfd.readouterr().err, "ksp_type")
