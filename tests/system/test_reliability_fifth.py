"""A hostile user's fifth round (docs/explanation/reliability_promises.md): code planted in the working folder,
studies that refused only after computing, user models that crashed, exited 0 or ran to garbage marked
"complete", arrays read back unchecked, messages that blamed the wrong thing. Each is one line and exit 2 (or
a run that stops at the step that failed), nothing written."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import leftovers, one_error_line, plot_refusal

QUICK = ["--no-progress", "--no-pictures"]
SMALL = ["--nx", "50", "--nt", "40", "--eps", "0.01"]


def stringcontact(*argv, python=(), cwd=None, env=None, timeout=300) -> subprocess.CompletedProcess:
    """`python [PYTHON] -m stringcontact ARGV` in a fresh process; a hang fails the test."""
    try:
        return subprocess.run([sys.executable, *python, "-m", "stringcontact", *map(str, argv)], capture_output=True,
                              text=True, cwd=cwd, env=env, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail(f"stringcontact {' '.join(map(str, argv))} did not end within {timeout} s")


# --- code in the working folder ----------------------------------------------------------------------------------

PLANTED = "import pathlib\npathlib.Path('imported-{name}').write_text('x')\n"


def _plant(folder: Path, *names: str) -> None:
    for name in names:
        (folder / f"{name}.py").write_text(PLANTED.format(name=name))


@pytest.mark.slow
def test_python_m_stringcontact_imports_nothing_from_the_working_folder(tmp_path):
    """`python -m stringcontact` puts the current folder first on sys.path: a ufl.py there was imported by the run.
    The run draws its pictures itself: a pyvista.py or matplotlib.py there must not be imported for them either."""
    _plant(tmp_path, "ufl", "pyvista", "matplotlib")
    proc = stringcontact("run", "example1", *SMALL, "--no-progress", "--out", tmp_path / "o", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.glob("imported-*")) == []


# --- study and check take their folder before they compute ---------------------------------------------------------

@pytest.mark.parametrize(("argv", "module", "name"), [
    (["study", "film", "--quick"], "stringcontact.analysis.film", "film_study"),
    (["check", "example1", "--levels", "1"], "stringcontact.cli.check", "run_checks"),
])
def test_study_and_check_hold_their_folder_while_they_compute(tmp_path, monkeypatch, argv, module, name):
    """They took the lock only when they wrote: two `study film --out out/s` at once both computed, and the second
    was refused at the end, its result lost. While computing, the folder's lock is held."""
    import importlib

    from stringcontact.cli.main import main
    from stringcontact.io.publish import TargetLock

    out = tmp_path / "s"
    held = []

    def computing(*args, **kwargs):
        held.append(TargetLock.busy(out))
        raise KeyboardInterrupt  # enough: what matters is who holds the folder now

    monkeypatch.setattr(importlib.import_module(module), name, computing)
    assert main([*argv, "--out", str(out)]) == 130
    assert len(held) == 1 and f"`stringcontact {argv[0]}` (pid {os.getpid()}) is writing to this folder" in held[0]
    assert not out.exists() and leftovers(tmp_path) == []


@pytest.mark.parametrize(("argv", "module", "name"), [
    (["study", "film", "--quick"], "stringcontact.analysis.film", "film_study"),
    (["check", "example1", "--levels", "1"], "stringcontact.cli.check", "run_checks"),
])
def test_study_and_check_refuse_a_folder_they_cannot_make_before_computing(capsys, monkeypatch, argv, module, name):
    """`--out /proc/x` passed the checks, ran the whole study (7-12 s), then was refused."""
    import importlib

    from stringcontact.cli.main import main

    computed = []
    monkeypatch.setattr(importlib.import_module(module), name, lambda *a, **k: computed.append(1))
    assert main([*argv, "--out", "/proc/x"]) == 2
    one_error_line(capsys.readouterr().err, "--out /proc/x")
    assert computed == []


# --- a user's form, checked before anything is compiled ----------------------------------------------------------

FORMS = '''
import dataclasses
import ufl
from stringcontact.model.interface import inelastic
from stringcontact.model.inelastic import momentum_form
from stringcontact.model.stiff_string import stiff_string

def model(name, form):
    return dataclasses.replace(inelastic, name=name, momentum_form=form)

def paper(eta, eta_t, eta_tt, force, w, p):
    return momentum_form(eta, eta_t, eta_tt, force, w, p)

def _trial(w):
    return ufl.TrialFunction(w.ufl_function_space())

bilinear = model("bilinear", lambda eta, eta_t, eta_tt, force, w, p: _trial(w) * w * ufl.dx)
negative = model("negative", lambda *a: paper(*a) - 3 * a[2] * a[4] * ufl.dx)
massless = model("massless", lambda *a: paper(*a) - a[2] * a[4] * ufl.dx)
no_dx = model("no_dx", lambda eta, eta_t, eta_tt, force, w, p: eta_tt * w + ufl.inner(ufl.grad(eta), ufl.grad(w)))
boundary_only = model("boundary_only", lambda eta, eta_t, eta_tt, force, w, p: eta_tt * w * ufl.ds)
functional = model("functional", lambda eta, eta_t, eta_tt, force, w, p: eta_tt * eta * ufl.dx)
root_of_negative = model("root_of_negative", lambda *a: paper(*a) + ufl.sqrt(a[0] - 5) * a[4] * ufl.dx)
overflowing = model("overflowing", lambda *a: paper(*a) + ufl.exp(1000 * a[0]) * a[4] * ufl.dx)
held_unknown = dataclasses.replace(stiff_string, name="held_unknown", held_fields=("zz",))
quadratic = model("quadratic", lambda eta, eta_t, eta_tt, force, w, p: paper(eta, eta_t, eta_tt, force, w, p)
                  + w * w * ufl.dx)
'''


@pytest.mark.parametrize(("name", "scheme", "fragment"), [
    ("bilinear", "paper", "momentum_form is bilinear (rank 2: a TrialFunction in it)"),  # SIGABRT in the assembler
    ("negative", "paper", "momentum_form's mass (the coefficient of eta_tt) is -2 at x = (0)"),  # eta to 1e30, complete
    ("negative", "newmark", "momentum_form's mass (the coefficient of eta_tt) is -2"),
    ("massless", "projection", "momentum_form's mass (the coefficient of eta_tt) is 0"),
    ("no_dx", "paper", "momentum_form returned a Sum, not a form"),  # internal error AttributeError
    ("boundary_only", "paper", "momentum_form has no term integrated over the domain (ufl.dx)"),  # "smaller dt"
    ("functional", "paper", "momentum_form is a functional (rank 0: no test function w)"),  # internal error
    ("quadratic", "paper", "momentum_form is not linear in the test function w"),  # internal error
    ("held_unknown", "paper", "held_fields names 'zz', not a field of the model"),  # internal error KeyError
])
@pytest.mark.slow
def test_a_form_that_is_no_residual_is_refused_before_it_is_compiled(tmp_path, name, scheme, fragment):
    (tmp_path / "forms.py").write_text(FORMS)
    grid = SMALL if scheme != "projection" else SMALL[:4]  # projection has no eps
    proc = stringcontact("run", "example1", *grid, *QUICK, "--scheme", scheme, "--model", f"forms:{name}", "--out",
                         tmp_path / "o", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, f"model '{name}': ", fragment, "allowed: ")
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- a plugin that ends the process -------------------------------------------------------------------------------

PLUGIN = '''
import dataclasses, sys
from stringcontact.model.interface import inelastic

def _exits(*args):
    sys.exit(0)

def _interrupts(*args):
    raise KeyboardInterrupt

exits = dataclasses.replace(inelastic, name="exits", momentum_form=_exits)
interrupts = dataclasses.replace(inelastic, name="interrupts", momentum_form=_interrupts)
'''


@pytest.mark.parametrize(("module", "spec", "fragment"), [
    ("import sys\nsys.exit(0)\n", "plugin:model", "model: importing module 'plugin' for 'plugin:model' called sys.exit(0)"),
    ("raise KeyboardInterrupt\n", "plugin:model", "'plugin:model' raised KeyboardInterrupt itself"),
    (PLUGIN, "plugin:exits", "model 'exits' called sys.exit(0)"),
    (PLUGIN, "plugin:interrupts", "model 'interrupts' raised KeyboardInterrupt itself"),
])
@pytest.mark.slow
def test_a_plugin_that_exits_is_one_line_and_exit_2(tmp_path, module, spec, fragment):
    """Only `Exception` was caught: a plugin's sys.exit(0) on import or in a model function ended the run with exit 0,
    nothing done and nothing said; its own KeyboardInterrupt was reported as a Ctrl-C (130)."""
    (tmp_path / "plugin.py").write_text(module)
    proc = stringcontact("run", "example1", *SMALL, *QUICK, "--model", spec, "--out", tmp_path / "o", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- Newton's options ----------------------------------------------------------------------------------------------

FILM_CAVITATING = """
name = "film_cavitating"
length = 1.0
T = 0.1
dt = 0.00025
nx = 100
alpha = 0.01
eta0 = "1 + 0.5*sin(10*pi*x)**2"
v0 = "-50"
h = 1.0
model = "film"

[scheme]
name = "paper"
eps = 0.0005

[parameters]
mu = 0.001
p_cav = 0
"""


@pytest.mark.parametrize(("scene", "option", "fragment"), [
    # 0 Newton iterations: η = −2, the energy up 30 %, "complete"
    ("cubic", "snes_atol=1e300", "snes_atol = 1e+300 is out of range; allowed: a number in [0, 1e-06]"),
    ("cubic", "snes_rtol=0.5", "snes_rtol = 0.5 is out of range; allowed: a number in [0, 0.01]"),
    ("cubic", "snes_max_it=0", "snes_max_it = 0 is out of range; allowed: an integer in [1, 1000]"),
    ("cubic", "snes_linesearch_type=shell", "snes_linesearch_type = 'shell' is not a line search"),  # error code 83
    # error code 60, "Nonconforming object sizes", once the film cavitates (a VI)
    ("film", "snes_linesearch_type=nleqerr", "snes_linesearch_type = 'nleqerr' does not take the bounds"),
])
@pytest.mark.slow
def test_newton_options_that_make_its_test_vacuous_or_fail_are_refused(tmp_path, scene, option, fragment):
    if scene == "film":
        (tmp_path / "film.toml").write_text(FILM_CAVITATING)
        argv = [tmp_path / "film.toml"]
    else:
        argv = ["example1", *SMALL, "--model", "cubic_foundation"]
    proc = stringcontact("run", *argv, *QUICK, "--petsc-option", option, "--out", tmp_path / "o")
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "petsc_options", fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- a model's field read back -------------------------------------------------------------------------------------

FILM_SMALL = FILM_CAVITATING.replace("T = 0.1", "T = 0.01").replace("p_cav = 0\n", "").replace("nx = 100", "nx = 40")


@pytest.fixture(scope="module")
def a_film_result(tmp_path_factory):
    """A complete film run folder (its pressure in rows.npz and solution.h5; no pictures)."""
    from stringcontact.cli.main import main

    folder = tmp_path_factory.mktemp("film")
    (folder / "film.toml").write_text(FILM_SMALL)
    assert main(["run", str(folder / "film.toml"), *QUICK, "--out", str(folder / "run")]) == 0
    return folder / "run"


@pytest.mark.parametrize(("values", "fragment"), [
    (lambda p: np.where(p == p.max(), np.inf, p), "its field 'pressure' holds a value that is not finite"),  # drawn
    (lambda p: np.full_like(p, np.nan), "its field 'pressure' holds a value that is not finite"),  # "Invalid vmin"
    (lambda p: p.astype("U8"), "its array 'pressure' holds <U8 values; allowed: real numbers"),
    (lambda p: p.astype(complex), "its array 'pressure' holds complex128 values; allowed: real numbers"),
], ids=["inf", "nan", "strings", "complex"])
def test_a_model_field_in_rows_is_checked_like_eta(tmp_path, a_film_result, capsys, values, fragment):
    def damage(copy):
        with np.load(copy / "rows.npz") as npz:
            arrays = {name: npz[name] for name in npz.files}
        arrays["pressure"] = values(arrays["pressure"])
        np.savez(copy / "rows.npz", **arrays)

    _, err = plot_refusal(a_film_result, damage, tmp_path, capsys)
    assert fragment in err and "allowed: " in err, err


# --- resource figures ----------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_the_memory_estimate_covers_a_model_with_two_unknowns_per_node(tmp_path):
    """The film at cells = [1000, 1000] took 5.5 GB, 1.8 times the 3.1 KB per node the scene's cap assumes: its own
    cost per node (`SolverHints.setup_bytes_per_node`) is counted, and the run refused before the mesh."""
    import stringcontact as sc

    scene_file = Path(sc.__file__).parent / "scenes" / "film_drum.toml"
    lines = [("cells = [1000, 1000]" if line.startswith("cells") else line)
             for line in scene_file.read_text().splitlines()]
    (tmp_path / "big.toml").write_text("\n".join(lines) + "\n")
    proc = stringcontact("run", tmp_path / "big.toml", *QUICK, "--out", tmp_path / "o", timeout=120)
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, "cells: [1000, 1000] gives 1002001 nodes, about 5.51 GB to set up with model 'film'",
                   "allowed: at most 564764 nodes with this model")
    assert not (tmp_path / "o").exists()


def test_a_run_over_an_hour_says_so_at_its_start():
    """nx = 1e5 with nt = 1e8 (about 65 hours) was accepted without a word."""
    import stringcontact as sc

    scene = sc.load_scene("example1").replace(nx=100_000, nt=100_000_000)
    Stepper = sc.Stepper  # imported first: dolfinx's import hands warnings to logging, past pytest.warns
    with pytest.warns(UserWarning, match=r"nt = 100000000 steps of 100001 nodes: this run will take about 69\.4 hours"):
        stepper = Stepper(scene)
    assert stepper.step == 0


# --- the obstacle, checked at every step -------------------------------------------------------------------------

MOVING = """
name = "moving"
length = 1.0
T = 0.2
nt = 400
nx = 50
alpha = 0.01
eta0 = "1 + x*(1 - x)"
v0 = "0"
h = 1.0
model = "loaded_obstacle"
obstacle = "{obstacle}"

[scheme]
name = "projection"
eps = 0.01
"""


@pytest.mark.parametrize(("obstacle", "fragment"), [
    # 0 at t = 0, T/2 and T, where the scene's check samples it; 1.9e7 between them: the run completed
    ("5e6*sin(pi*t/0.2)**2 - 1",
     "obstacle: at t = 0.03 it is 1.031e+06 at x = (0); allowed: finite values in [-1e+06, 1e+06] at every node"),
    # NaN at t = 0.05 only: exit 1, "step failed", no time named
    ("-1 + sqrt(abs(t - 0.05) - 1e-6)", "obstacle at t = 0.05: '-1 + sqrt(abs(t - 0.05) - 1e-6)' is not finite"),
])
@pytest.mark.slow
def test_a_moving_obstacle_is_checked_at_every_step(tmp_path, obstacle, fragment):
    (tmp_path / "moving.toml").write_text(MOVING.format(obstacle=obstacle))
    proc = stringcontact("run", tmp_path / "moving.toml", *QUICK, "--out", tmp_path / "o")
    assert proc.returncode == 2, proc.stderr[-3000:]
    one_error_line(proc.stderr, fragment)
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


def test_frames_is_named_as_the_flag(tmp_path, capsys):
    """--frames 100000000 was refused as "max_frames: ...", the API's argument, which the user never typed."""
    from stringcontact.cli.main import main

    assert main(["run", "example1", *SMALL, *QUICK, "--frames", "100000000", "--out", str(tmp_path / "o")]) == 2
    line = one_error_line(capsys.readouterr().err, "--frames: 100000000 is out of range; allowed: a whole number in [1, ")
    assert "max_frames" not in line
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize(("name", "value"), [("root_of_negative", "nan"), ("overflowing", "inf")])
def test_a_form_that_is_not_finite_is_named_not_the_step_size(tmp_path, name, value):
    """sqrt(eta - 5) or exp(1000 eta) in a form was reported as "Newton did not converge (SNES reason -4) ... use a
    smaller dt", after 16 sub-steps that could not help."""
    (tmp_path / "forms.py").write_text(FORMS)
    proc = stringcontact("run", "example1", *SMALL, *QUICK, "--model", f"forms:{name}", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr[-3000:]
    line = one_error_line(proc.stderr, f"step 1, t = 0.0075: model '{name}': its momentum_form is {value} (not "
                          "finite)", "a smaller dt does not change it")
    assert "sub-steps" not in line and "use a smaller dt" not in line


# --- a form singular at eta = 0, on a string that stays above it -------------------------------------------------

SINGULAR = '''
import dataclasses
import ufl
from stringcontact.model.interface import inelastic
from stringcontact.model.inelastic import momentum_form

def _repelled(eta, eta_t, eta_tt, force, w, p):
    return momentum_form(eta, eta_t, eta_tt, force, w, p) - 0.01 / eta * w * ufl.dx

def _repelled_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) - 0.01 * ufl.ln(eta)

def _rooted(eta, eta_t, eta_tt, force, w, p):
    return momentum_form(eta, eta_t, eta_tt, force, w, p) + ufl.sqrt(eta) * w * ufl.dx

repelled = dataclasses.replace(inelastic, name="repelled", momentum_form=_repelled, stored_energy=_repelled_energy)
undeclared = dataclasses.replace(inelastic, name="undeclared", momentum_form=_repelled)
rooted = dataclasses.replace(inelastic, name="rooted", momentum_form=_rooted)
'''

#: example1 thrown down slowly: eta stays above 0.7, where k/eta and sqrt(eta) are smooth
HELD_HIGH = """
name = "held_high"
length = 1.0
T = 0.3
nt = 40
nx = 50
alpha = 0.01
eta0 = "1 + 0.5*sin(10*pi*x)**2"
v0 = "-1"
h = 1.0

[scheme]
eps = 0.01
"""


def _singular(tmp_path):
    (tmp_path / "singular.py").write_text(SINGULAR)
    sys.path.insert(0, str(tmp_path))
    try:
        import importlib

        return importlib.import_module("singular")
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("singular", None)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["paper", "newmark", "projection"])
def test_a_form_singular_at_zero_runs_on_a_string_that_stays_above_it(tmp_path, scheme):
    """k/eta in the form, with its stored energy declared, on a string that never comes near eta = 0: the operators
    were its tangent and load at eta = 0 (inf), and the run stopped at step 1 with "a value is not finite ... use a
    smaller dt". They are taken at the initial state, and the load is what the declared energy leaves of the form
    there (0 to round-off: the energy is the form's)."""
    import stringcontact as sc

    (tmp_path / "high.toml").write_text(HELD_HIGH)
    stepper = sc.Stepper(sc.load_scene(tmp_path / "high.toml"), scheme, model=_singular(tmp_path).repelled)
    while stepper.step < stepper.nt:
        stepper.advance()  # InstabilityError at step 1
    result = stepper.result()
    assert result.eta.min() > 0.7
    assert np.abs(result.balance_residual).max() < 1e-10 * result.total_energy[0]
    assert stepper.discrete.ops.linearised_at == "the state"
    assert np.abs(stepper.discrete.ops.load).max() < 1e-15


@pytest.mark.slow
def test_a_form_whose_tangent_is_infinite_at_zero_keeps_its_guards(tmp_path):
    """sqrt(eta) (no stored energy declared: its potential is finite) has an infinite tangent at eta = 0: the energy
    guard's round-off floor was inf and projection's stable dt_max nan, so neither could ever refuse."""
    import stringcontact as sc

    (tmp_path / "high.toml").write_text(HELD_HIGH)
    stepper = sc.Stepper(sc.load_scene(tmp_path / "high.toml"), "projection", model=_singular(tmp_path).rooted)
    assert 0 < stepper.scheme.dt_max < 1
    assert np.isfinite(stepper.ledger.tol)


@pytest.mark.slow
def test_a_form_singular_at_zero_without_a_stored_energy_is_named(tmp_path):
    """Without a declared energy the load -R(0) and the potential's zero are taken at eta = 0, where k/eta is inf
    (it is finite at the initial state): the run stopped at step 1 with "unstable ... use a smaller dt" (exit 3).
    One line naming the cause, exit 2, nothing written."""
    (tmp_path / "singular.py").write_text(SINGULAR)
    (tmp_path / "scene.toml").write_text(HELD_HIGH)
    proc = stringcontact("run", "scene.toml", *QUICK, "--model", "singular:undeclared", "--out", tmp_path / "o",
                         cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    line = one_error_line(proc.stderr, "model 'undeclared': momentum_form is evaluated at eta = 0 for its load",
                          "its load -R(0) is not finite (a term singular at eta = 0)", "stored_energy(eta, p)")
    assert "smaller dt" not in line
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- plot redrawing a run's folder holds it --------------------------------------------------------------------------

@pytest.fixture
def a_run_folder(tmp_path):
    """A complete run folder (no pictures: the tests stand in for their drawing)."""
    from stringcontact.cli.main import main

    assert main(["run", "example1", *SMALL, *QUICK, "--out", str(tmp_path / "r")]) == 0
    return tmp_path / "r"


def test_run_force_is_refused_while_plot_redraws_the_folder(a_run_folder, capsys, monkeypatch):
    """`run --out DIR --force` while `plot DIR` drew was refused naming plot's temporary picture
    (".energy.png.tmp-92mjtdy1.png is not a file stringcontact wrote there"), or, a moment later, replaced the
    folder under plot, which then wrote the old run's pictures into the new result. `plot` holds the folder's lock."""
    import stringcontact.cli.plot as plot_command
    from stringcontact.cli.main import main

    folder, seen = a_run_folder, []

    def drawing(result, into, look=None):
        (into / ".energy.png.tmp-92mjtdy1.png").write_bytes(b"")  # what atomic_path has there while it draws
        seen.append(main(["run", "example1", *SMALL, *QUICK, "--out", str(folder), "--force"]))
        seen.append(capsys.readouterr().err)
        (into / ".energy.png.tmp-92mjtdy1.png").unlink()
        return []

    monkeypatch.setattr(plot_command, "write_pictures", drawing)
    assert main(["plot", str(folder)]) == 0
    code, err = seen
    assert code == 2
    line = one_error_line(err, f"--out {folder}: `stringcontact plot` (pid {os.getpid()}) is drawing its pictures in "
                          "this folder; wait for it to finish")
    assert ".png" not in line
    assert leftovers(folder.parent) == []


def test_plot_refuses_a_folder_a_run_is_writing(a_run_folder, capsys, monkeypatch):
    """`plot DIR` while `run --out DIR --force` ran drew into the folder the run was about to replace."""
    import stringcontact.cli.plot as plot_command
    from stringcontact.cli.main import main
    from stringcontact.io.publish import TargetLock

    drawn = []
    monkeypatch.setattr(plot_command, "write_pictures", lambda *args, **kwargs: drawn.append(1) or [])
    lock = TargetLock(a_run_folder)  # as a run writing there holds it
    try:
        assert main(["plot", str(a_run_folder)]) == 2
    finally:
        lock.release()
    one_error_line(capsys.readouterr().err, f"{a_run_folder}: another stringcontact run (pid {os.getpid()}) is writing "
                   "to this folder")
    assert drawn == []
