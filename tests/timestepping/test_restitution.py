"""Scheme projection with a restitution coefficient e (Paoli-Schatzman): the step for the weighted position
z = (η^{n+1} + e η^{n−1})/(1 + e), its e = 0 case bit for bit, the rebound, the ledger, and the refusals."""

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import run_problem
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis.problems import flat_landing_scene
from stringcontact.run.checks import energy_balance
from stringcontact.timestepping import projection
from stringcontact.verification import exact

H, V, L = 0.2, 1.0, 1.0  # the flat landing's data (analysis.problems)


class _TruthyZero(float):
    """0.0 in every operation, but true: sends the step down the weighted (e > 0) path with e = 0."""

    def __bool__(self):
        return True


def _march(scene, restitution):
    """η, the centred velocity, the contact force and the energy terms of every step of projection on `scene`,
    from the scheme's own object (as the driver makes it) with `DiscreteProblem.restitution` = `restitution`."""
    problem, eta0, v0 = run_problem(scene, "projection", mass="lumped")
    stepper = projection.ProjectionScheme(dataclasses.replace(problem, restitution=restitution))
    terms = [stepper.start(eta0, v0)]
    rows = []
    for _ in range(scene.nt):
        terms.append(stepper.step())
        rows.append((stepper.eta.copy(), np.array(stepper.velocity), stepper.contact_force.copy()))
    return rows, terms


@pytest.mark.parametrize("alpha", [0.0, 0.01])  # the nodal maximum, and the active set on LU
def test_e0_takes_the_weighted_path_bit_for_bit(alpha):
    scene = sc.load_scene("example1").replace(nx=200, nt=120, alpha=alpha)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain, plain_terms = _march(scene, 0.0)
        weighted, weighted_terms = _march(scene, _TruthyZero(0.0))
    assert any(row[2].any() for row in plain)  # the string lands
    for a, b in zip(plain, weighted):
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
    assert plain_terms == weighted_terms


def test_the_weighted_step_is_paoli_schatzman_written_out():
    """α = 0: z = max(z̃, ψ) node by node, η^{n+1} = (1 + e) z − e η^{n−1}, with NumPy alone."""
    e = 0.5
    scene = sc.load_scene("example1").replace(nx=100, nt=60, alpha=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(scene, scheme="projection", restitution=e, storage=sc.Storage(max_rows=scene.nt),
                          comm=MPI.COMM_SELF)
        problem, eta, v = run_problem(scene, "projection", mass="lumped")
    ops = problem.ops
    K = ops.K.convert("dense").getDenseArray()
    m, dt, inner = ops.m, scene.dt, problem.interior
    old, now = eta - dt * v, eta.copy()
    rows = [now]
    for _ in range(scene.nt):
        free = 2 * now - old - dt**2 * (K @ now) / m
        z = np.maximum((free + e * old) / (1 + e), 0.0)
        new = np.where(inner, (1 + e) * z - e * old, now)
        old, now = now, new
        rows.append(now)
    order = np.argsort(problem.x)
    assert np.abs(res.contact_force).max() > 0
    assert np.max(np.abs(res.eta - np.array(rows)[:, order])) < 1e-12


@pytest.mark.parametrize("e", [0.25, 0.5, 1.0])
def test_flat_landing_rebounds_at_e_V_and_converges_to_the_exact_solution(e):
    t_check = 1.0  # inside the window t* < t <= l + 3t* = 1.6
    assert H / V < t_check <= exact.flat_landing_rebound_end(H, V, L)
    errors = []
    for n in (100, 200, 400):
        scene = flat_landing_scene(n, round(1.25 * n * t_check), T=t_check)
        res = sc.simulate(scene, scheme="projection", restitution=e, storage=sc.Storage(max_rows=scene.nt))
        assert res.status == "complete"
        middle = np.abs(res.x - 0.5) < 0.1
        k = np.argmin(np.abs(res.t - 0.3))  # after the landing, before the kinks' waves reach the middle
        assert np.allclose(res.velocity[k, middle], e * V, atol=1e-9)
        eta, _ = exact.flat_landing(res.t[-1], res.x, h=H, V=V, length=L, restitution=e)
        errors.append(float(np.sqrt(np.mean((res.eta[-1] - eta) ** 2))))
        # the ledger: the landing takes (1 − e²) of the landing part's kinetic energy, O(Δx) for the kinks
        loss = (1 - e * e) * exact.flat_landing_energy_loss(H, V, L)
        assert abs(res.energy["contact_dissipation"][-1] - loss) < 2.0 / n
        assert energy_balance(res)["relative_residual"] < 1e-9
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < errors[0] / 4**0.7  # order 0.7 or better (measured 0.85 to 0.95)
    assert errors[2] < 3e-3


def test_viscous_rebound_closes_the_ledger():
    scene = flat_landing_scene(200, 400, T=1.6, alpha=0.01)
    res = sc.simulate(scene, scheme="projection", restitution=1.0, storage=sc.Storage(max_rows=scene.nt))
    b = energy_balance(res)
    assert res.status == "complete" and b["relative_residual"] < 1e-9
    middle = np.argmin(np.abs(res.x - 0.5))
    k = np.argmin(np.abs(res.t - 0.21))
    # the nodal law v⁺ = e v⁻ whatever α, but for the nodes whose account the viscous pull would overdraw
    assert res.velocity[k, middle] == pytest.approx(V, abs=1e-5)
    assert b["viscous_dissipation"] > 0
    assert res.energy["contact_dissipation"].min() >= 0.0  # the rebound never gives back more than the landing took
    # the contact work is the landing's and the rebound's: at e = 1 the rebound gives back most of what the landing
    # took, less what the neighbours' viscous pull would have had the contact give on top (a negative D_con)
    loss = exact.flat_landing_energy_loss(H, V, L)
    assert 0.0 <= res.energy["contact_dissipation"][-1] < 0.15 * loss


@pytest.mark.parametrize("scheme", ["paper", "newmark"])
def test_other_schemes_refuse_a_restitution(scheme):
    scene = flat_landing_scene(20, 24, r=0.4)
    with pytest.raises(ValueError, match=r"^restitution: scheme .* only scheme .*'projection' does") as info:
        sc.simulate(scene, scheme=scheme, restitution=0.5)
    assert "\n" not in str(info.value)
    sc.simulate(scene, scheme=scheme, restitution=0.0)  # e = 0 is every scheme's contact


def test_simulate_records_the_restitution_in_the_result():
    res = sc.simulate(flat_landing_scene(20, 24), scheme="projection", restitution=0.75)
    assert res.scene.restitution == 0.75
    with pytest.raises(sc.SceneError, match=r"restitution: 2 is out of range; allowed: a number in \[0, 1\]"):
        sc.simulate(flat_landing_scene(20, 24), scheme="projection", restitution=2)


@pytest.mark.parametrize("alpha", [0.0, 0.01])
def test_the_newton_path_takes_the_restitution(alpha):
    """The Newton step of `projection` (forced on the paper's linear model) bounds the weighted position too: it
    gives the linear path's rebound to round-off, not the inelastic landing."""
    scene = flat_landing_scene(50, 80, T=0.8, alpha=alpha)
    forced = dataclasses.replace(sc.inelastic, name="forced", newton=True)
    linear = sc.simulate(scene, scheme="projection", restitution=0.5, comm=MPI.COMM_SELF)
    newton = sc.simulate(scene, scheme="projection", restitution=0.5, model=forced, comm=MPI.COMM_SELF)
    inelastic = sc.simulate(scene, scheme="projection", model=forced, comm=MPI.COMM_SELF)
    assert newton.status == linear.status == "complete"
    assert np.max(np.abs(newton.eta - linear.eta)) < 1e-9
    assert np.max(np.abs(newton.eta - inelastic.eta)) > 1e-2  # e was not dropped
    assert energy_balance(newton)["relative_residual"] < 1e-9
