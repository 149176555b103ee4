"""Scheme `fitted`: the blended mass (row sums, positive definite, θ from each edge's Courant number), a fourth-order
phase at every Courant number, no Δt_max (a string, a membrane on a gmsh disk, the stiff string), the ledger."""

import warnings

import numpy as np
import pytest
from conftest import run_problem
from mpi4py import MPI

import stringcontact as sc
from stringcontact.run.checks import energy_balance
from stringcontact.timestepping import fitted

AMPLITUDE, HEIGHT = 0.1, 1.0  # a mode high above the obstacle: no contact


def _mode(nx: int, dt_over_h: float, periods: float = 1.0):
    """sin(πx) on a unit string (period 2), high above the obstacle, α = 0."""
    nt = round(2.0 * periods * nx / dt_over_h)
    return sc.Scene.from_dict({"name": "mode", "length": 1.0, "T": 2.0 * periods, "nt": nt, "nx": nx, "alpha": 0.0,
                               "scheme": {"eps": 1e-3}, "h": HEIGHT,
                               "eta0": f"{HEIGHT} + {AMPLITUDE}*sin(pi*x)", "v0": "0"})


def _run(scene, scheme="fitted", **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, scheme=scheme, comm=MPI.COMM_SELF, **kwargs)


def _phase_error(res) -> float:
    """max |η − exact| at the last row, over the amplitude (exact: the mode's cos(πt))."""
    exact = HEIGHT + AMPLITUDE * np.sin(np.pi * res.x) * np.cos(np.pi * res.t[-1])
    return float(np.max(np.abs(res.eta[-1] - exact)) / AMPLITUDE)


@pytest.mark.parametrize("name", ["example1", "drum"])
def test_the_blended_mass_keeps_the_row_sums_and_is_positive_definite(name):
    scene = sc.load_scene(name).replace(T=0.01, nt=2, output_times=None)
    problem, _, _ = run_problem(scene, "fitted", model=sc.inelastic if name == "example1" else None)
    ops = problem.ops
    M_theta, theta = fitted.blended_mass(ops.M, ops.K, ops.m, problem.dt, problem.x.ndim)
    ones, out = M_theta.createVecRight(), M_theta.createVecLeft()
    ones.set(1.0)
    M_theta.mult(ones, out)
    assert np.allclose(out.array, ops.m, rtol=1e-12, atol=0)  # the total mass is the lumped one
    assert theta.min() >= 0.5 and theta.max() < fitted.THETA_BOUND[problem.x.ndim]
    dense = M_theta.convert("dense").getDenseArray()
    assert np.linalg.eigvalsh(0.5 * (dense + dense.T)).min() > 0


def test_theta_is_a_half_plus_the_courant_number_squared():
    """On a uniform string θ = ½ + ν² on every edge up to ν = 1, then ½ + 1/ν²."""
    for dt_over_h, expected in ((0.5, 0.75), (0.8, 1.14), (2.0, 0.75)):
        problem, _, _ = run_problem(_mode(20, dt_over_h), "fitted")
        ops = problem.ops
        _, theta = fitted.blended_mass(ops.M, ops.K, ops.m, problem.dt, 1)
        assert np.allclose(theta, expected, rtol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("dt_over_h", [0.25, 0.5, 0.75])
def test_a_mode_keeps_its_phase_to_fourth_order(dt_over_h):
    """One period of sin(πx): the error falls like h⁴, and at nx = 20 it is 20 times below projection's (the lumped
    leapfrog's phase error is second order)."""
    errors = {s: [_phase_error(_run(_mode(nx, dt_over_h), s)) for nx in (10, 20)] for s in ("fitted", "projection")}
    assert errors["fitted"][0] / errors["fitted"][1] > 2**3.5
    assert errors["fitted"][1] < errors["projection"][1] / 20


def test_any_dt_is_stable_and_conserves_the_energy_without_contact():
    scene = _mode(20, 4.0, periods=20)  # Δt = 4h: projection refuses it
    with pytest.raises(sc.InstabilityError, match="dt_max"):
        _run(scene, "projection")
    res = _run(scene)
    E = res.total_energy
    assert res.status == "complete" and not res.contact.any()
    assert np.max(np.abs(E / E[0] - 1)) < 1e-12
    assert energy_balance(res)["relative_residual"] < 1e-12


@pytest.mark.slow
def test_a_membrane_on_an_unstructured_disk_above_projection_s_dt_max():
    scene = sc.load_scene("drum").replace(dt=0.05, output_times=None)  # projection: dt_max = 0.026
    res = _run(scene)
    assert res.status == "complete" and res.contact.any()
    assert energy_balance(res)["relative_residual"] < 1e-10
    F = res.contact_force
    assert np.all(F >= 0) and np.all(F[~res.contact] == 0)
    assert res.min_eta >= -1e-12


@pytest.mark.slow
def test_the_stiff_string_lands_at_nine_times_projection_s_dt_max():
    scene = sc.Scene.from_dict({"name": "stiff", "length": 1.0, "T": 0.2, "dt": 1e-3, "nx": 200, "alpha": 0.0,
                                "scheme": {"eps": 1e-3},
                                "h": 0.2, "eta0": "0.2", "v0": "-1", "model": "stiff_string",
                                "parameters": {"beta": 4e-3}})
    with pytest.raises(sc.InstabilityError, match=r"dt_max = 0\.000114"):
        _run(scene, "projection")
    res = _run(scene)
    E0 = res.total_energy[0]
    assert res.status == "complete" and res.contact.any()
    assert energy_balance(res)["relative_residual"] < 1e-9
    assert res.energy["contact_dissipation"].min() >= 0.0
    # the ledger books the mean of the two levels' stored energies; the β-average conserves the midpoint's: the
    # difference, ⅛|η^{n+1} − η^n|²_K, is the numerical dissipation's (of either sign)
    assert np.max(np.abs(res.energy["numerical_dissipation"])) < 0.02 * E0
