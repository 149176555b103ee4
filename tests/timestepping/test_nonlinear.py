"""Nonlinear models: every scheme's Newton step (timestepping/newton.py), the shipped nonlinear variants.

No timing here: the speed figures are in benchmarks/bench_nonlinear.py.
"""

import dataclasses
import itertools
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import ufl
from conftest import run_problem
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

import stringcontact as sc
from stringcontact.fem.compat import trapezoid
from stringcontact.model import nonlinear as variants
from stringcontact.model import inelastic as paper
from stringcontact.timestepping import scheme_class

K3 = 10.0


def cubic_form(eta, eta_t, eta_tt, force, w, p):
    return paper.momentum_form(eta, eta_t, eta_tt, force, w, p) + K3 * eta**3 * w * ufl.dx


def cubic_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.25 * K3 * eta**4


CUBIC = dataclasses.replace(sc.inelastic, name="cubic", momentum_form=cubic_form, stored_energy=cubic_energy)


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


@pytest.fixture(scope="module")
def ex1():
    return sc.load_scene("example1").replace(nx=100, nt=600)


@pytest.mark.slow
@pytest.mark.parametrize("scheme,penalty", [("paper", "explicit"), ("paper", "semi-implicit"), ("projection", None),
                                            ("newmark", None)])
def test_the_newton_path_of_a_linear_model_is_the_linear_path(ex1, scheme, penalty):
    """Model.newton forces the Newton step on the paper's (linear) model: η equals the constant operators' to 1e-10."""
    linear = run(ex1, scheme=scheme, penalty=penalty)
    newton = run(ex1, scheme=scheme, penalty=penalty, model=dataclasses.replace(sc.inelastic, name="forced", newton=True))
    assert "newton iterations" in newton.counters and "newton iterations" not in linear.counters
    assert linear.contact.any()
    assert np.max(np.abs(newton.eta - linear.eta)) <= 1e-10
    assert np.max(np.abs(newton.contact_force - linear.contact_force)) <= 1e-10 * np.max(np.abs(linear.contact_force))
    assert newton.checks["energy_balance"]["closes"]


def _alive(kind) -> int:
    import gc

    gc.collect()
    return sum(isinstance(o, kind) for o in gc.get_objects())


@pytest.mark.parametrize("scheme,penalty", [("paper", "semi-implicit"), ("projection", None), ("newmark", None)])
def test_a_nonlinear_run_leaves_nothing_alive(scheme, penalty):
    """A finished run's Newton step and problem (its mesh, forms and SNES) are freed. petsc4py 3.25 (the dolfinx
    wheel's) keeps a SNES's callbacks out of the garbage collector's sight: a callback bound to the Newton step kept
    each run alive for ever, with its mesh's MPI communicators (8 a run; MPICH has 2,048, and a long session of runs
    aborted when they ran out)."""
    from stringcontact.timestepping.base import DiscreteProblem
    from stringcontact.timestepping.newton import NewtonStep

    scene = sc.load_scene("example1").replace(nx=20, nt=60)
    before = _alive(NewtonStep), _alive(DiscreteProblem)
    for _ in range(2):
        assert run(scene, scheme=scheme, penalty=penalty, model=CUBIC).counters["newton iterations"] > 0
    assert (_alive(NewtonStep), _alive(DiscreteProblem)) == before


def test_a_linear_model_does_not_pay_for_newton(ex1):
    problem = _problem(ex1, sc.inelastic, "paper")
    assert problem.ops.nonlinear is None
    assert type(scheme_class("paper")(problem)).__module__.endswith("timestepping.paper")


@pytest.mark.slow
def test_the_cubic_variant_runs_with_every_scheme(ex1):
    for scheme in ("paper", "projection", "newmark"):
        res = run(ex1, scheme=scheme, model=CUBIC)
        assert res.status == "complete", res.message
        assert res.counters["newton iterations"] >= ex1.nt
        linear = run(ex1, scheme=scheme)
        assert np.max(np.abs(res.eta - linear.eta)) > 1e-3  # the cubic term acts


# --- the Newton step driven directly: a manufactured solution, Newton's convergence ---------------------------


def _problem(scene, model, scheme, penalty=None):
    return run_problem(scene, scheme, penalty, model=model)[0]


class Manufactured:
    """η*(x, t) = 1 + ½ sin(πx) cos(2t) made exact by subtracting the model's own residual at η*: a load R(η*)."""

    def __init__(self, base):
        self.t = None
        self.base = base

    def exact(self, x, t):
        return 1 + 0.5 * np.sin(np.pi * x) * np.cos(2 * t)

    def model(self):
        def form(eta, eta_t, eta_tt, force, w, p):
            if self.t is None:
                self.t = fem.Constant(w.ufl_function_space().mesh, PETSc.ScalarType(0.0))
            s = ufl.sin(ufl.pi * p.x[0])
            ex, ex_t, ex_tt = 1 + 0.5 * s * ufl.cos(2 * self.t), -s * ufl.sin(2 * self.t), -2 * s * ufl.cos(2 * self.t)
            zero = fem.Constant(w.ufl_function_space().mesh, PETSc.ScalarType(0.0))
            return self.base.momentum_form(eta, eta_t, eta_tt, force, w, p) - self.base.momentum_form(ex, ex_t, ex_tt, zero, w, p)

        return dataclasses.replace(self.base, name="manufactured", momentum_form=form)


def _manufactured_error(base, scheme, n):
    mms = Manufactured(base)
    scene = sc.load_scene("example1").replace(nx=n, nt=n, T=0.5, eta0="1", v0="0", alpha=0.1, eps=1.0,
                                              output_times=[])
    problem = _problem(scene, mms.model(), scheme, penalty="explicit" if scheme == "paper" else None)
    stepper = scheme_class(scheme)(problem)
    stepper.start(mms.exact(problem.x, 0.0), 0 * problem.x)  # projection computes η¹ here, at t = 0
    # the residual's time: t^{n+1} (paper), the midpoint (newmark), t^n one step ahead (projection)
    shift = {"paper": 1.0, "newmark": 0.5, "projection": 1.0}[scheme]
    for k in range(scene.nt):
        mms.t.value = (k + shift) * scene.dt
        stepper.step()
    return np.max(np.abs(stepper.eta - mms.exact(problem.x, scene.T))), stepper.timings


@pytest.mark.slow
@pytest.mark.parametrize("base", [variants.cubic_foundation, variants.large_deflection], ids=lambda m: m.name)
@pytest.mark.parametrize("scheme", ["paper", "projection", "newmark"])
def test_a_manufactured_solution_converges_at_first_order_or_better(base, scheme):
    """Δt = Δx/2 halved twice: the paper's implicit Euler at first order (measured 0.81-0.99, pre-asymptotic on the
    cubic), projection at first (0.85-0.99: its implicit viscous term), newmark's midpoint at second (1.99-2.01)."""
    errors = [_manufactured_error(base, scheme, n)[0] for n in (32, 64, 128)]
    rates = [math.log2(a / b) for a, b in itertools.pairwise(errors)]
    assert errors[-1] < 2e-3, errors
    assert min(rates) >= {"paper": 0.8, "projection": 0.8, "newmark": 1.8}[scheme], (errors, rates)


@pytest.mark.slow
def test_newton_converges_quadratically():
    """A large slope (η_x up to 3) on the large-deflection string: with a fresh Jacobian at every iteration (no
    Jacobian kept from an earlier step), the residual norms of a step fall quadratically, r_{k+1} ≤ C r_k² with
    the same C at each iteration (measured: 8.8e1, 1.5e-1, 1.4e-6, then the round-off floor 9.7e-12;
    C = 1.9e-5 and 6.3e-5), not linearly (a constant ratio)."""
    scene = sc.load_scene("example1").replace(nx=200, nt=20, T=0.02, eta0="1 + sin(pi*x)", v0="-30",
                                              alpha=0.01, eps=1.0, output_times=[])
    problem = _problem(scene, variants.large_deflection, "paper", penalty="explicit")
    stepper = scheme_class("paper")(problem)
    stepper.newton.reuse_jacobian = False
    stepper.start(np.asarray(scene.initial_displacement(problem.x)), np.where(problem.interior, -30.0, 0.0))
    histories = []
    for _ in range(scene.nt):
        stepper.step()
        histories.append(stepper.newton.history)
    r = max(histories, key=len)[:3]  # above the round-off floor
    assert len(r) == 3 and r[2] < r[1] < r[0], histories
    assert r[2] / r[1] < 1e-2 * (r[1] / r[0])  # superlinear: the ratio itself falls by orders of magnitude
    assert r[2] / r[1] ** 2 < 1e2 * (r[1] / r[0] ** 2)  # quadratic: r_{k+1}/r_k² does not grow


@pytest.mark.slow
@pytest.mark.parametrize("model", ["cubic_foundation", "large_deflection"])
@pytest.mark.parametrize("scheme,penalty", [("paper", "explicit"), ("paper", "semi-implicit"), ("projection", None),
                                            ("newmark", None)])
def test_a_kept_jacobian_gives_the_fresh_jacobians_answer(ex1, scheme, penalty, model, monkeypatch):
    """The Jacobian kept across steps and iterations (the default: chord iterations) against a fresh one at every
    iteration: the same η to within Newton's tolerance (measured up to 1.0e-9, paper: a kept J stops just below the
    absolute tolerance, a fresh one far below; 0 on projection, whose Jacobian is constant), with fewer assemblies
    than steps."""
    from stringcontact.timestepping.newton import NewtonStep

    kept = run(ex1, scheme=scheme, penalty=penalty, model=getattr(variants, model))
    monkeypatch.setattr(NewtonStep, "reuse_jacobian", False)
    fresh = run(ex1, scheme=scheme, penalty=penalty, model=getattr(variants, model))
    assert kept.contact.any()
    assert np.max(np.abs(kept.eta - fresh.eta)) <= 1e-8
    assert fresh.counters["jacobian assemblies"] >= fresh.counters["newton iterations"] >= ex1.nt
    assert kept.counters["jacobian assemblies"] < ex1.nt


# --- contact and energy -------------------------------------------------------------------------------------


def test_projection_with_a_nonlinear_model_is_a_variational_inequality(ex1):
    res = run(ex1, scheme="projection", model=CUBIC)
    f, contact = res.contact_force, res.contact
    assert contact[1:].any()
    assert np.all(res.eta >= -1e-12)  # η ≥ ψ = 0
    assert np.all(f >= 0.0)
    assert np.all(f[~contact] == 0.0)  # no force off the contact set
    assert np.max(f) > 0


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["paper", "projection", "newmark"])
@pytest.mark.parametrize("name", ["example1", "flat"])
def test_the_energy_ledger_closes_for_the_cubic_variant(ex1, scheme, name):
    scene = ex1 if name == "example1" else ex1.replace(v0="0", eta0="1 + 0.5*sin(pi*x)")  # no contact
    res = run(scene, scheme=scheme, model=CUBIC)
    balance = res.checks["energy_balance"]
    assert balance["closes"], balance
    assert bool(res.contact[1:].any()) == (name == "example1")
    if name == "flat":
        assert balance["contact_dissipation"] == 0.0
    assert balance["viscous_dissipation"] > 0
    # E(0) is the model's energy: ½∫v² + ∫ ½η_x² + ¼ k3 η⁴ (the trapezoid on the nodes, against the scheme's quadrature)
    x = res.x
    eta0, v0 = np.asarray(scene.initial_displacement(x), float), np.asarray(scene.initial_velocity(x), float)
    v0[[0, -1]] = 0.0
    eta0_x = np.diff(eta0) / np.diff(x)
    expected = np.sum(0.5 * eta0_x**2 * np.diff(x)) + trapezoid(0.25 * K3 * eta0**4 + 0.5 * v0**2, x)
    if scheme != "projection":  # projection's energy sits at the half step
        assert res.total_energy[0] == pytest.approx(expected, rel=2e-2)


# --- the shipped variants from the command line ---------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cubic_foundation", "large_deflection"])
def test_a_shipped_nonlinear_variant_runs_from_the_command_line(tmp_path, name):
    import json

    from stringcontact.cli.main import main
    from stringcontact.io.readback import read_output
    from stringcontact.plot import charts

    out = tmp_path / "run"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["run", "example1", "--model", name, "--nx", "200", "--no-progress", "--no-pictures", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["model"] == name and summary["counters"]["newton iterations"] >= 1500
    res = read_output(out)
    fig, _ = charts.energy_figure(res)
    labels = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]  # the key under the panels
    assert sc.load_model(name).energy_label in labels and summary["energy_label"] == sc.load_model(name).energy_label
    assert any("model " + name in t.get_text() for t in fig.texts)  # the caption names the model


# --- several fields -------------------------------------------------------------------------------------------


def two_field_residual(U, U_t, U_tt, force, W, p):
    """The cubic foundation written with a second field q = η: k η + k3 q² η, and the equation (q − η) r."""
    (eta, q), (w, r) = U, W
    foundation = variants.FOUNDATION_K * eta + variants.FOUNDATION_K3 * q**2 * eta
    return paper.momentum_form(eta, U_t[0], U_tt[0], force, w, p) + foundation * w * ufl.dx + (q - eta) * r * ufl.dx


def two_field_energy(U, p):
    """The cubic foundation's stored energy, in η = U[0] (q = η stores none of its own)."""
    return variants.cubic_foundation.stored_energy(U[0], p)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["paper", "projection", "newmark"])
def test_a_second_field_gives_the_single_field_answer(ex1, scheme, monkeypatch):
    """A fresh Jacobian at every iteration on both: a kept one stops each at its own point below the tolerance
    (2.4e-9 apart on newmark)."""
    from stringcontact.timestepping.newton import NewtonStep

    monkeypatch.setattr(NewtonStep, "reuse_jacobian", False)
    two = dataclasses.replace(variants.cubic_foundation, name="two_fields", fields=("q",), residual=two_field_residual,
                              stored_energy=two_field_energy)
    single = run(ex1, scheme=scheme, model=variants.cubic_foundation)
    res = run(ex1, scheme=scheme, model=two)
    assert res.contact.any() and res.checks["energy_balance"]["closes"]
    assert np.max(np.abs(res.eta - single.eta)) <= 1e-9  # measured 1.7e-12 to 1.8e-11


def test_the_second_field_is_solved_not_lagged(ex1):
    two = dataclasses.replace(variants.cubic_foundation, name="two_fields", fields=("q",), residual=two_field_residual,
                              stored_energy=two_field_energy)
    problem = _problem(ex1, two, "paper", penalty="explicit")
    stepper = scheme_class("paper")(problem)
    stepper.start(np.asarray(ex1.initial_displacement(problem.x)), np.where(problem.interior, -50.0, 0.0))
    for _ in range(5):
        stepper.step()
    nw = stepper.newton
    assert np.max(np.abs(nw.field(0) - stepper.eta)) == 0.0
    assert np.max(np.abs(nw.field(1) - nw.field(0))) <= 1e-12  # q = η at the new level, not the old one
    assert np.max(np.abs(stepper.eta - stepper.old)) > 1e-3


@pytest.mark.slow
def test_a_scene_load_read_only_by_the_residual_counts_as_used():
    """`unused_fields` reads a model with fields through its residual: a load used there is not refused."""
    def residual(U, U_t, U_tt, force, W, p):
        return two_field_residual(U, U_t, U_tt, force, W, p) - p.extra["load"] * W[0] * ufl.dx

    loaded = dataclasses.replace(variants.cubic_foundation, name="loaded_two", fields=("q",), residual=residual,
                                 stored_energy=two_field_energy)
    scene = sc.load_scene("example1").replace(nx=50, nt=300, load="-1")
    assert run(scene, scheme="projection", model=loaded).status == "complete"
    with pytest.raises(ValueError, match="load"):  # the same scene with a model that ignores the load
        run(scene, scheme="projection", model=dataclasses.replace(loaded, residual=two_field_residual))


def test_a_model_with_fields_must_give_its_residual(ex1):
    from stringcontact.fem.operators import ModelError

    with pytest.raises(ModelError, match="residual"):
        run(ex1, model=dataclasses.replace(sc.inelastic, name="half", fields=("q",)))


# --- several ranks ---------------------------------------------------------------------------------------------


def _mpi_cases():
    return [("string", sc.load_scene("example1").replace(nx=100, nt=300)),
            ("membrane", sc.load_scene("drum").replace(load=None, mesh_size=0.15, T=0.25, output_times=[])),
            ("piston", sc.load_scene("piston").replace(nx=100, nt=125, T=0.5, output_times=[]))]


def _piston_model(name: str):
    """A shipped nonlinear model with `loaded_obstacle`'s laws, which read a moving obstacle's rate."""
    from stringcontact.model.variants import loaded_obstacle

    base = sc.load_model(name)
    return dataclasses.replace(loaded_obstacle, name=f"{name}_on_a_piston", momentum_form=base.momentum_form,
                               stored_energy=base.stored_energy)


def _mpi_run(scene, scheme, model, comm):
    model = _piston_model(model) if scene.obstacle_moves else model
    return run_on(scene, comm, scheme=scheme, model=model, storage=sc.Storage(max_rows=10),
                  penalty="semi-implicit" if scheme == "paper" else None)


def run_on(scene, comm, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, comm=comm, **kwargs)


MPI_RUNS = [(case, scheme, model) for case in ("string", "membrane") for scheme in ("paper", "projection", "newmark")
            for model in ("cubic_foundation", "large_deflection")]
MPI_RUNS += [("piston", scheme, "cubic_foundation") for scheme in ("paper", "projection", "newmark")]  # ψ(x, t)


@pytest.mark.slow
def test_two_ranks_give_the_serial_answer(tmp_path):
    """Measured 3.5e-12 at most (the membrane's projection), 1e-13 on the string; the piston (a moving obstacle)
    2e-14."""
    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve(), tmp_path], ranks=2, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    got = np.load(tmp_path / "nonlinear.npz")
    scenes = dict(_mpi_cases())
    for case, scheme, model in MPI_RUNS:
        serial = _mpi_run(scenes[case], scheme, model, MPI.COMM_SELF)
        assert serial.contact.any()
        assert np.max(np.abs(got[f"{case}-{scheme}-{model}"] - serial.eta)) <= 1e-8


def _worker(out: Path) -> None:
    scenes = dict(_mpi_cases())
    etas = {}
    for case, scheme, model in MPI_RUNS:
        res = _mpi_run(scenes[case], scheme, model, MPI.COMM_WORLD)
        assert res.checks["energy_balance"]["closes"]
        if MPI.COMM_WORLD.rank == 0:
            etas[f"{case}-{scheme}-{model}"] = res.eta
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out / "nonlinear.npz", **etas)


if __name__ == "__main__":
    _worker(Path(sys.argv[1]))
