"""Hostile input to the command line, the output folders and the API: PETSc options that crashed or hung,
planted manifests and temporary names, `--force` onto the data it would delete, crafted rows and HDF5
files, misleading messages (docs/explanation/reliability_promises.md). Each is one line and exit 2, nothing
written, and never a hang: runs that used to hang or crash are fresh processes with a hang guard."""

import json
import os
import shutil
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import CTRL_C_AT_IMPORT, leftovers, mpirun, one_error_line, plot_refusal

from stringcontact.cli.main import main
from stringcontact.io.publish import TargetLock, atomic_path, staged_folder

QUICK = ["--no-progress", "--no-pictures"]
SMALL = ["--nx", "50", "--nt", "40", "--eps", "0.01", *QUICK]


def stringcontact(*argv, cwd=None, env=None, timeout=300) -> subprocess.CompletedProcess:
    """`python -m stringcontact ARGV` in a fresh process; a hang (or a crash's silence) fails the test."""
    try:
        return subprocess.run([sys.executable, "-m", "stringcontact", *map(str, argv)], capture_output=True, text=True,
                              cwd=cwd, env=env, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail(f"stringcontact {' '.join(map(str, argv))} did not end within {timeout} s")


# --- PETSc options that crashed (exit 59), hung, or exited 1 ---------------------------------------------------

@pytest.mark.parametrize(("options", "fragment"), [
    (["pc_mg_levels=100", "ksp_type=gmres"], "pc_mg_levels = 100 is out of range"),
    (["pc_type=mg", "ksp_type=gmres"], "pc_type = 'mg' needs code or data"),
    (["ksp_type=gmres", "ksp_gmres_restart=100000000"], "ksp_gmres_restart = 100000000 is out of range"),
    (["ksp_type=cg", "pc_type=hypre", "pc_hypre_boomeramg_max_iter=2147483647"],
     "pc_hypre_boomeramg_max_iter = 2147483647 is out of range; allowed: an integer in [1, 100]"),
    (["pc_type=shell"], "pc_type = 'shell' needs code or data"),
    (["pc_type=fieldsplit"], "pc_type = 'fieldsplit' needs code or data"),
    (["ksp_type=cg", "pc_type=ilu", "pc_factor_levels=-1"], "pc_factor_levels = -1 is out of range"),
])
@pytest.mark.slow
def test_petsc_options_that_crashed_or_hung_are_refused_in_one_line(tmp_path, options, fragment):
    argv = [a for option in options for a in ("--petsc-option", option)]
    proc = stringcontact("run", "example1", *SMALL, *argv, "--out", tmp_path / "o")
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "petsc_options", fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


@pytest.mark.slow
def test_petsc_factorisations_of_one_rank_are_refused_under_mpi(tmp_path):
    """ILU (and LU, ICC with PETSc's own factorisation) on 2 ranks exited 1, "internal error Error: error code 92"."""
    proc = mpirun([sys.executable, "-m", "stringcontact", "run", "example1", *SMALL, "--petsc-option", "ksp_type=cg",
                   "--petsc-option", "pc_type=ilu", "--out", tmp_path / "o"], timeout=300)
    assert proc.returncode == 2, proc.stderr[-3000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("stringcontact: error:")]
    assert len(errors) == 2 and all("runs on one rank only, not on 2" in line for line in errors), proc.stderr[-3000:]
    assert "internal error" not in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- manifest.json that is a FIFO or a link to /dev/zero ---------------------------------------------------------

@pytest.fixture(scope="module")
def a_result(tmp_path_factory):
    """A complete 1D run folder (no pictures)."""
    folder = tmp_path_factory.mktemp("result") / "run"
    assert main(["run", "example1", *SMALL, "--out", str(folder)]) == 0
    return folder


def copy_of(a_result, tmp_path, name="run") -> Path:
    copy = tmp_path / name
    shutil.copytree(a_result, copy)
    return copy


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero"])
def test_a_planted_manifest_never_blocks_or_fills_memory(tmp_path, a_result, kind):
    """A FIFO manifest hung every --force; one linked to /dev/zero was read until memory ran out."""
    run = copy_of(a_result, tmp_path)
    (run / "manifest.json").unlink()
    if kind == "FIFO":
        os.mkfifo(run / "manifest.json")
    else:
        (run / "manifest.json").symlink_to("/dev/zero")
    proc = stringcontact("run", "example1", *SMALL, "--out", run, "--force")
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "no manifest.json of a stringcontact command")
    assert (run / "summary.json").is_file() and leftovers(tmp_path) == []


# --- --force onto the data being plotted, a run's result, a live run inside ----------------------------------------

def test_plot_out_onto_the_folder_it_plots_is_refused(tmp_path, a_result, capsys):
    """`plot RUN --out RUN --force` deleted solution.*, diagnostics.csv, summary.json and rows.npz."""
    run = copy_of(a_result, tmp_path)
    before = sorted(p.name for p in run.iterdir())
    for out in (run, tmp_path):
        assert main(["plot", str(run), "--out", str(out), "--force"]) == 2
        one_error_line(capsys.readouterr().err, f"--out {out}: is the folder being plotted")
    assert sorted(p.name for p in run.iterdir()) == before


@pytest.mark.parametrize("argv", [
    ["check", "example1", "--nx", "20", "--nt", "20", "--levels", "1", "--force", "--out", "{run}"],
    ["study", "stability", "--quick", "--force", "--out", "{run}"],
    ["plot", "{other}", "--force", "--out", "{run}"],
])
def test_check_study_and_plot_force_never_replace_a_run_result(tmp_path, a_result, capsys, argv):
    run = copy_of(a_result, tmp_path)
    other = copy_of(a_result, tmp_path, "other")
    before = sorted(p.name for p in run.iterdir())
    assert main([a.format(run=run, other=other) for a in argv]) == 2
    one_error_line(capsys.readouterr().err, "holds the result of a run", f"`{argv[0]} --force` does not replace")
    assert sorted(p.name for p in run.iterdir()) == before


def test_force_keeps_the_partial_folder_of_a_live_run_inside_the_target(tmp_path):
    """A --force replacement of X deleted the partial folder of a run into X/sub that started meanwhile."""
    target = tmp_path / "x"
    with staged_folder(target) as folder:
        (folder / "a.txt").write_text("old")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with staged_folder(target, force=True) as folder:
            (folder / "a.txt").write_text("new")
            lock = TargetLock(target / "sub")  # a run into x/sub starts while this one writes
            partial = target / ".sub.partial-1-abcdefgh"
            partial.mkdir()
    assert any("already holds a result" in str(w.message) for w in caught)
    try:
        assert partial.is_dir() and (target / "a.txt").read_text() == "old"
        assert (tmp_path / "x.new" / "a.txt").read_text() == "new"
    finally:
        lock.release()


# --- in-place plot: unpredictable temporary names, never through a planted link ---------------------------------

def test_atomic_path_never_writes_through_a_planted_link(tmp_path):
    """The temporary name was `.NAME.tmp-<pid>.png`: 400 links planted for the next pids overwrote a file outside."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    folder = tmp_path / "run"
    folder.mkdir()
    for pid in (os.getpid(), *range(os.getpid() + 1, os.getpid() + 50)):
        (folder / f".a.png.tmp-{pid}.png").symlink_to(victim)
    with atomic_path(folder / "a.png", record=False) as tmp:
        assert not tmp.is_symlink() and tmp.parent == folder and tmp.suffix == ".png"
        tmp.write_bytes(b"picture")
    assert victim.read_text() == "precious\n"
    assert (folder / "a.png").read_bytes() == b"picture" and not (folder / "a.png").is_symlink()


# --- crafted files: sizes and types checked before reading -----------------------------------------------------

def _rewrite_rows(folder: Path, **changes) -> None:
    path = folder / "rows.npz"
    with np.load(path) as npz:
        arrays = {name: npz[name] for name in npz.files}
    arrays.update(changes)
    np.savez(path, **arrays)


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda a: {"eta": a["eta"].astype("U8")}, "'eta' holds <U8 values; allowed: real numbers"),
    (lambda a: {"eta": a["eta"].astype(complex)}, "'eta' holds complex128 values"),
    (lambda a: {"eta": np.zeros(a["eta"].shape, dtype=[("a", "f8")])}, "'eta' holds"),
    (lambda a: {"x": np.zeros_like(a["x"])}, "its nodes x are not increasing"),
    (lambda a: {"eta": np.where(a["eta"] > 0, np.nan, a["eta"])}, "'eta' holds a value that is not finite"),
], ids=["strings", "complex", "structured", "all-equal x", "nan eta"])
def test_crafted_rows_are_refused_in_one_line(tmp_path, a_result, capsys, change, fragment):
    def damage(copy):
        with np.load(copy / "rows.npz") as npz:
            arrays = {name: npz[name] for name in npz.files}
        _rewrite_rows(copy, **change(arrays))

    _, err = plot_refusal(a_result, damage, tmp_path, capsys)
    assert fragment in err, err


def test_nan_rows_leave_an_in_place_plot_folder_untouched(tmp_path, a_result, capsys):
    """NaN in eta failed after two pictures and the manifest had been rewritten."""
    run = copy_of(a_result, tmp_path)
    with np.load(run / "rows.npz") as npz:
        eta = npz["eta"].copy()
    eta[3, 5] = np.nan
    _rewrite_rows(run, eta=eta)
    before = {p.name: p.read_bytes() for p in run.iterdir()}
    assert main(["plot", str(run)]) == 2
    one_error_line(capsys.readouterr().err, "not finite")
    assert {p.name: p.read_bytes() for p in run.iterdir()} == before


@pytest.mark.slow
def test_a_zip_bomb_rows_file_is_refused_from_its_header(tmp_path, a_result, capsys):
    """A 1.9 MB rows.npz declaring 1.9 GB drove `plot` to 1.9 GB: the declared shape is refused unread."""
    from numpy.lib import format as npy

    def damage(copy):
        path = copy / "rows.npz"
        with np.load(path) as npz:
            arrays = {name: npz[name] for name in npz.files}
        k = arrays["eta"].shape[0]
        shape = (k, 3_000_000)  # 1 GB of zeros, about 1 MB deflated
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
            for name, values in arrays.items():
                if name != "eta":
                    archive.writestr(f"{name}.npy", _npy_bytes(values))
            with archive.open("eta.npy", "w", force_zip64=True) as f:
                npy.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": shape})
                zeros = bytes(8 * shape[1])
                for _ in range(k):
                    f.write(zeros)

    _, err = plot_refusal(a_result, damage, tmp_path, capsys)
    assert "'eta' declares the shape" in err, err


def _npy_bytes(values) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, values)
    return buffer.getvalue()


_HUGE_H5 = """
import sys
import h5py
with h5py.File(sys.argv[1], "a") as f:
    del f["eta_0"]
    f.create_dataset("eta_0", shape=(500_000_000,), dtype="f8", chunks=(1_000_000,), compression="gzip")
"""


def test_a_crafted_solution_h5_is_never_read(tmp_path, a_result, capsys):
    """A 134 kB solution.h5 declaring 4 GB drove `plot` to 3.85 GB when it read the XDMF's frames: `plot` draws from
    rows.npz alone, and without it refuses the folder in one line rather than fall back on solution.h5."""
    def damage(copy):
        (copy / "rows.npz").unlink()
        subprocess.run([sys.executable, "-c", _HUGE_H5, str(copy / "solution.h5")], check=True, timeout=120)

    copy, err = plot_refusal(a_result, damage, tmp_path, capsys)
    assert f"{copy} is not a stringcontact output folder (missing rows.npz)" in err, err


def test_deeply_nested_json_is_not_called_a_large_problem(tmp_path, a_result, capsys):
    def damage(copy):
        (copy / "summary.json").write_text("[" * 100_000 + "]" * 100_000)

    _, err = plot_refusal(a_result, damage, tmp_path, capsys)
    assert "nested too deeply" in err and "reduce nx" not in err, err


# --- messages and values silently accepted ---------------------------------------------------------------------

@pytest.mark.parametrize(("argv", "fragment"), [
    (["check", "flat-landing", "--nx", "-5"], "--nx: -5 is out of range"),
    (["check", "flat-landing", "--nx", "0"], "--nx: 0 is out of range"),
    (["check", "example1", "--nt", "0"], "--nt: 0 is out of range"),
    (["check", "example1", "--scheme", "projection", "--eps", "0.001"], "--eps: scheme 'projection' uses no penalty"),
    (["study", "work-precision", "--quick", "--repeat", "1000000000", "--out", "{tmp}/s"], "--repeat: 1000000000"),
    (["run", "example1", *SMALL, "--out", "{tmp}/afile/x"], "afile is a file, not a folder"),
])
def test_flags_are_checked_and_named(tmp_path, capsys, argv, fragment):
    (tmp_path / "afile").write_text("a file\n")
    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    line = one_error_line(capsys.readouterr().err, fragment)
    assert "example1" not in line or "example1" in argv and "docker" not in line


def test_a_list_as_domain_is_one_line(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('domain = ["disk"]\nT = 0.1\nnt = 10\nalpha = 0\nscheme = { eps = 0.01 }\neta0 = "1"\nv0 = -1\n'
                     'nx = 10\n')
    assert main(["run", str(scene), *QUICK]) == 2
    one_error_line(capsys.readouterr().err, "domain: invalid value")


def test_environment_that_stops_petsc_or_mpi_is_one_line(tmp_path):
    """`PETSC_OPTIONS='-options_file /nonexistent'` gave a 35-line traceback, `TMPDIR=/proc` 45 lines of MPI abort."""
    for name, value, fragment in (("PETSC_OPTIONS", f"-options_file {tmp_path}/nonexistent", "PETSC_OPTIONS: -options_file"),
                                  ("TMPDIR", "/proc", "TMPDIR=/proc: cannot make a folder there")):
        proc = stringcontact("run", "example1", *SMALL, env=dict(os.environ, **{name: value}), cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr[-3000:]
        one_error_line(proc.stderr, fragment)


def test_show_writes_the_mesh_path_that_works_anywhere(tmp_path, capsys, monkeypatch):
    """`show sub/s.toml` wrote mesh = "sub/m.xdmf": relative to the current folder, wrong beside the scene file."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "m.xdmf").write_text("<Xdmf/>")
    (tmp_path / "sub" / "s.toml").write_text('mesh = "m.xdmf"\nT = 0.1\nnt = 10\nalpha = 0\nscheme = { eps = 0.01 }\n'
                                             'eta0 = "1"\nv0 = -1\nh = 1\n')
    monkeypatch.chdir(tmp_path)
    assert main(["show", "sub/s.toml"]) == 0
    assert f'mesh = "{tmp_path / "sub" / "m.xdmf"}"' in capsys.readouterr().out


def test_api_values_are_checked():
    import stringcontact as sc
    from stringcontact.run.options import Output

    for bad in ({"force": "no"}, {"max_frames": 0}, {"max_frames": -5}, {"max_frames": float("nan")}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            Output("out", **bad)
    assert sc.load_scene(b"example1").name == sc.load_scene(Path("example1")).name == "example1"


@pytest.mark.parametrize(("argv", "written"), [
    (["plot", "{run}", "--out", "{out}"], "pictures.json"),
    (["check", "flat-landing", "--nx", "40", "--nt", "48", "--levels", "1", "--out", "{out}"], "checks.json"),
])
@pytest.mark.slow
def test_mpi_check_and_plot_out_write_once(tmp_path, a_result, argv, written):
    """`mpirun -n 2 check|plot --out` raced for the folder: one rank exited 2."""
    out = tmp_path / "out"
    proc = mpirun([sys.executable, "-m", "stringcontact", *(a.format(run=a_result, out=out) for a in argv)], timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (out / written).is_file() and leftovers(tmp_path) == []


# --- a VTK window that needs a display; Ctrl-C inside VTK ----------------------------------------------------------

def _no_display(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(extra)
    return env


@pytest.mark.slow
def test_an_x_window_without_a_display_is_a_warning_and_the_run_completes(tmp_path):
    """`VTK_DEFAULT_OPENGL_WINDOW=vtkXOpenGLRenderWindow` without a display: exit 59, 19 lines, .lock and .partial left."""
    env = _no_display(VTK_DEFAULT_OPENGL_WINDOW="vtkXOpenGLRenderWindow")
    proc = stringcontact("run", "example1", "--nx", "50", "--nt", "40", "--eps", "0.01", "--no-progress", "--out", "o",
                         cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr.splitlines() == [proc.stderr.strip()] and "VTK_DEFAULT_OPENGL_WINDOW" in proc.stderr, proc.stderr
    assert proc.stderr.startswith("stringcontact: warning: ")
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "complete"
    assert (tmp_path / "o" / "energy.png").is_file() and leftovers(tmp_path) == []


@pytest.mark.slow
def test_plot_with_an_x_window_without_a_display_is_one_line(tmp_path, a_result):
    """`plot` exited 139 (a segfault)."""
    proc = stringcontact("plot", a_result, "--out", tmp_path / "p",
                         env=_no_display(VTK_DEFAULT_OPENGL_WINDOW="vtkXOpenGLRenderWindow"))
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "VTK_DEFAULT_OPENGL_WINDOW=vtkXOpenGLRenderWindow needs an X display")
    assert not (tmp_path / "p").exists() and leftovers(tmp_path) == []


@pytest.mark.slow
@pytest.mark.parametrize("module", ["pyvista", "vtkmodules.util.numpy_support"])
@pytest.mark.parametrize("in_place", [False, True], ids=["--out", "in place"])
def test_ctrl_c_inside_vtk_during_plot_is_exit_130_and_one_line(tmp_path, a_result, module, in_place):
    """Ctrl-C during `plot` gave a segfault (139), "internal error ImportError: Failed to load vtkCommonMath", or
    exit 0 with a traceback."""
    run = copy_of(a_result, tmp_path)
    before = sorted(p.name for p in run.iterdir())
    argv = ["plot", str(run)] + ([] if in_place else ["--out", str(tmp_path / "p")])
    proc = subprocess.run([sys.executable, "-c", CTRL_C_AT_IMPORT, module, *argv], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert proc.stderr == "stringcontact: error: interrupted by SIGINT (Ctrl-C)\n"
    assert not (tmp_path / "p").exists() and leftovers(tmp_path) == []
    assert not [p.name for p in run.iterdir() if p.name.startswith(".")]  # no temporary picture left
    assert set(before) <= {p.name for p in run.iterdir()}


# --- MPI: one rank failing alone ends the job -------------------------------------------------------------------

@pytest.mark.slow
def test_a_rank_failing_alone_ends_the_whole_mpi_job_with_its_code(tmp_path):
    """`mpirun -n 1 ... : -n 1 ... nonexistent.toml` hung: rank 1 waited in MPI's finalize for rank 0, which
    waited in the run's first collective call for rank 1. The failing rank now aborts the job after a grace
    period, with its exit code."""
    import shutil as sh

    exe = sh.which("mpirun")
    if exe is None:
        pytest.skip("mpirun not found")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    good = ["run", "example1", "--nx", "50", "--nt", "4000", *SMALL[4:], "--out", "o"]
    bad = ["run", "nonexistent.toml", "--out", "o"]
    # Different arguments per rank from one program, not `mpirun -n 1 A : -n 1 B`: Open MPI 5.0's mpirun (Debian
    # trixie, the image) segfaults on that syntax before starting anything, whatever the programs.
    per_rank = tmp_path / "per_rank.py"
    per_rank.write_text(
        "import os, runpy, sys\n"
        "rank = int(os.environ.get('OMPI_COMM_WORLD_RANK', os.environ.get('PMIX_RANK', os.environ.get('PMI_RANK', '0'))))\n"
        f"sys.argv = ['stringcontact', *({good!r} if rank == 0 else {bad!r})]\n"
        "runpy.run_module('stringcontact', run_name='__main__', alter_sys=True)\n")
    from conftest import MPIRUN_FLAGS, mpi_flavour

    proc = subprocess.Popen([exe, "-n", "2", *MPIRUN_FLAGS[mpi_flavour(exe)], sys.executable, str(per_rank)], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=300)  # a hang guard: the grace period is 10 s
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.communicate()
        pytest.fail("the MPI job with one failing rank did not end")
    assert proc.returncode == 2, err[-3000:]
    assert "scene 'nonexistent.toml': no built-in scene" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".o.")]


@pytest.mark.slow
def test_a_scene_name_with_dollars_is_drawn_as_written(tmp_path):
    """A scene named `$x^{$` broke matplotlib's titles (mathtext), without naming the key."""
    scene = tmp_path / "s.toml"
    scene.write_text('name = "$x^{$"\nT = 0.3\nnt = 40\nnx = 50\nalpha = 0.01\nscheme = { eps = 0.01 }\n'
                     'eta0 = "1 + 0.5*sin(10*pi*x)**2"\nv0 = -5\n')
    proc = stringcontact("run", scene, "--no-progress", "--out", tmp_path / "o")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr == "", proc.stderr
    assert all((tmp_path / "o" / name).is_file() for name in ("snapshots.png", "energy.png", "contact_set.png"))


SIGTERM_AT_IMPORT = CTRL_C_AT_IMPORT.replace("SIGINT", "SIGTERM")


@pytest.mark.slow
def test_sigterm_during_rank_0s_pictures_marks_the_folder_interrupted_on_every_rank(tmp_path):
    """Under MPI, a SIGTERM during rank 0's pictures left a folder marked complete without its pictures (and rank 1
    read rank 0's clean-up as its own outcome). Rank 0 sends it to itself at its import of pyvista; rank 1 never
    imports pyvista."""
    proc = mpirun([sys.executable, "-c", SIGTERM_AT_IMPORT, "pyvista", "run", "example1", *SMALL[:6], "--no-progress",
                   "--out", tmp_path / "o"], timeout=300)
    assert proc.returncode == 143, proc.stderr[-3000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("stringcontact: error:")]
    assert errors == ["stringcontact: error: interrupted by SIGTERM"] * 2, proc.stderr[-3000:]
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["status"] == "interrupted", summary["status"]
    assert leftovers(tmp_path) == []


# One rank fails on its own: rank 0 runs out of memory in the set-up, or rank 1 gets SIGTERM as the scheme (the
# registered `paper` class) is handed its discrete problem, the set-up's last part. Before, the other rank waited in
# the set-up's next collective call for ever (a hang); the job now ends with the failing rank's exit code after the
# grace period.
ONE_RANK_FAILS = r"""
import os, signal, sys
from mpi4py import MPI
import stringcontact.run.adapter as adapter
from stringcontact.timestepping import scheme_class
rank = MPI.COMM_WORLD.rank
if sys.argv[1] == "memory" and rank == 0:
    def no_memory(*args, **kwargs):
        raise MemoryError()
    adapter.scene_problem = no_memory
if sys.argv[1] == "sigterm" and rank == 1:
    Paper = scheme_class("paper")
    set_up = Paper.__init__
    def set_up_then_signal(self, problem):
        os.kill(os.getpid(), signal.SIGTERM)
        set_up(self, problem)
    Paper.__init__ = set_up_then_signal
from stringcontact.cli.main import main
sys.argv = ["stringcontact", *sys.argv[2:]]
sys.exit(main())
"""


@pytest.mark.slow
@pytest.mark.parametrize(("how", "code", "fragment"), [("memory", 2, "MemoryError"),
                                                       ("sigterm", 143, "interrupted by SIGTERM")])
def test_one_rank_failing_or_signalled_ends_the_job(tmp_path, how, code, fragment):
    proc = mpirun([sys.executable, "-c", ONE_RANK_FAILS, how, "run", "example1", "--nx", "50", "--nt", "4000",
                   *SMALL[4:], "--out", tmp_path / "o"], timeout=300)
    assert proc.returncode == code, proc.stderr[-3000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("stringcontact: error:")]
    assert len(errors) == 1 and fragment in errors[0] and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert not (tmp_path / "o").exists()


# SIGTERM to rank 1 only, in the middle of the time loop: sent by rank 1 to itself when it stores its first row
# after t = 0 (no clock).
SIGTERM_TO_RANK_1_MID_RUN = r"""
import os, signal, sys
from mpi4py import MPI
from stringcontact.run.rows import RowObserver
if MPI.COMM_WORLD.rank == 1:
    store = RowObserver._store
    def store_then_signal(self, stepper, n):
        store(self, stepper, n)
        if n > 0:
            os.kill(os.getpid(), signal.SIGTERM)
    RowObserver._store = store_then_signal
from stringcontact.cli.main import main
sys.argv = ["stringcontact", *sys.argv[1:]]
sys.exit(main())
"""


@pytest.mark.slow
def test_sigterm_to_one_rank_mid_run_stops_every_rank_and_marks_the_folder(tmp_path):
    """`kill -TERM` to one rank's pid hung silently, and killing the job then left .lock and .partial. Every rank
    now leaves the time loop at the same step: the folder is marked interrupted, each rank prints its line."""
    proc = mpirun([sys.executable, "-c", SIGTERM_TO_RANK_1_MID_RUN, "run", "example1", "--nx", "200", "--nt", "20000",
                   "--eps", "0.001", *QUICK, "--out", tmp_path / "o"], timeout=300)
    assert proc.returncode == 143, proc.stderr[-3000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("stringcontact: error:")]
    assert errors == ["stringcontact: error: interrupted by SIGTERM"] * 2, proc.stderr[-3000:]
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "interrupted"
    assert leftovers(tmp_path) == []
