"""The dolfinx solver against the paper's finite differences, exact solutions and its own energy identity."""

import numpy as np
import pytest
from conftest import sine_mode

import stringcontact as sc
from stringcontact.fem import compat
from stringcontact.verification import exact, reference


@pytest.fixture(scope="module")
def ex1_small():
    # dt = 4e-4 keeps r = dt/eps = 0.8 < 1, the paper's inelastic regime, at a tenth of the cost.
    return sc.load_scene("example1").replace(nx=500, nt=750)


def fd_reference(scene, penalty="explicit"):
    x = scene.x()
    return reference.fd_solve(
        scene.initial_displacement(x),
        scene.initial_velocity(x),
        length=scene.length,
        T=scene.T,
        nt=scene.nt,
        alpha=scene.alpha,
        eps=scene.eps,
        h_left=scene.h_left,
        h_right=scene.h_right,
        penalty=penalty,
    )


@pytest.mark.parametrize("penalty", ["explicit", "semi-implicit"])
def test_lumped_fem_is_the_papers_finite_difference_scheme(ex1_small, penalty):
    res = sc.simulate(ex1_small, penalty=penalty)
    _, eta, vel = fd_reference(ex1_small, penalty)
    assert res.min_eta < 0  # contact happened, so the penalty is part of the comparison
    assert np.max(np.abs(res.eta - eta[res.steps])) <= 1e-10
    assert np.max(np.abs(res.velocity - vel[res.steps])) <= 1e-10 / ex1_small.dt


def test_energy_identity_closes_and_energy_never_rises(ex1_small):
    res = sc.simulate(ex1_small)
    E = res.total_energy
    assert np.all(np.diff(E) <= 1e-9 * E[0])
    assert np.max(np.abs(res.balance_residual)) <= 1e-9 * E[0]
    e = res.energy
    assert e["contact_dissipation"][-1] > 0.1 * E[0]  # contact really dissipates
    assert np.all(np.diff(e["viscous_dissipation"]) >= 0)


def test_example1_contact_set_is_mirror_symmetric(ex1_small):
    res = sc.simulate(ex1_small)
    assert res.contact.any()
    assert np.array_equal(res.contact, res.contact[:, ::-1])
    assert np.allclose(res.eta, res.eta[:, ::-1], atol=1e-9)


def test_stored_rows_include_output_times_and_ends(ex1_small):
    res = sc.simulate(ex1_small, storage=sc.Storage(max_rows=20))
    for t in ex1_small.output_times:
        assert np.min(np.abs(res.t - t)) < 1e-12
    assert res.t[0] == 0 and res.t[-1] == pytest.approx(ex1_small.T)
    assert len(res.t) <= 20 + len(ex1_small.output_times) + 1
    assert res.eta.shape == (len(res.t), ex1_small.nx + 1)
    assert np.all(np.diff(res.x) > 0)


def test_explicit_penalty_beyond_r2_is_refused(ex1_small):
    with pytest.raises(sc.InstabilityError, match=r"r = dt/eps = 4"):
        sc.simulate(ex1_small.replace(eps=ex1_small.dt / 4))


def test_explicit_penalty_between_r1_and_r2_warns(ex1_small):
    with pytest.warns(sc.InstabilityWarning, match="restitution"):
        sc.simulate(ex1_small.replace(eps=ex1_small.dt / 1.5, T=0.06, nt=150, output_times=[]))


def test_semi_implicit_is_stable_far_beyond_r2(ex1_small):
    res = sc.simulate(ex1_small.replace(eps=ex1_small.dt / 100), penalty="semi-implicit")
    E = res.total_energy
    assert np.all(np.diff(E) <= 1e-9 * E[0])
    assert res.min_eta > -ex1_small.dt * 50 * 1.01  # one step of penetration at most


@pytest.mark.parametrize("k,alpha", [(1, 0.0), (3, 0.05)])
def test_sine_mode_without_contact_converges_at_first_order(k, alpha):
    base = sc.load_scene("example1")
    errors = []
    for n in (100, 200, 400):
        scene = base.replace(
            eta0=f"2 + 0.1*sin({k}*pi*x)", v0="0", alpha=alpha, eps=1.0, T=0.5, nx=n, nt=n // 2, output_times=[]
        )
        res = sc.simulate(scene)
        ex, _ = sine_mode(res.t, res.x, k=k, a0=0.1, a1=0.0, alpha=alpha, length=1.0, h=2.0)
        errors.append(np.max(np.abs(res.eta - ex)))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > 0.8), (errors, rates)


def test_semi_implicit_converges_to_the_exact_flat_landing():
    base = sc.load_scene("example1")
    errors = []
    for n in (100, 200, 400):
        scene = base.replace(eta0="0.2", v0="-1", alpha=0.0, eps=1e-8, T=0.6, nx=n, nt=n, output_times=[])
        res = sc.simulate(scene, penalty="semi-implicit")
        ex, _ = exact.flat_landing(res.t[-1], res.x, h=0.2, V=1.0, length=1.0)
        errors.append(np.sqrt(compat.trapezoid((res.eta[-1] - ex) ** 2, res.x)))
    assert errors[-1] < 0.01
    assert errors[0] > errors[1] > errors[2]


def test_consistent_mass_runs_and_agrees_with_lumped_to_discretisation_error(ex1_small):
    a = sc.simulate(ex1_small, mass="lumped")
    b = sc.simulate(ex1_small, mass="consistent")
    assert np.max(np.abs(b.balance_residual)) <= 1e-9 * b.total_energy[0]
    diff = np.max(np.abs(a.eta - b.eta))
    assert 0 < diff < 0.2
