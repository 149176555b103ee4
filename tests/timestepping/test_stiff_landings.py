"""Stiff landings converge at Δt: the nonlinear contact step (SNES VI) on a cubic foundation thrown onto the obstacle,
and the film's landing (plain Newton), run to T without sub-steps, the constraint and the contact force intact, the
energy balance closing. No clock: the solver's own counts are asserted."""

import dataclasses
import warnings

import numpy as np
import pytest
import ufl

import stringcontact as sc

K3 = 20.0


def cubic_form(eta, eta_t, eta_tt, force, w, p):
    """A user's cubic foundation k3 η³ on the paper's string."""
    return sc.inelastic.momentum_form(eta, eta_t, eta_tt, force, w, p) + K3 * eta**3 * w * ufl.dx


def cubic_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + K3 / 4 * eta**4


CUBIC = dataclasses.replace(sc.inelastic, name="cubic20", momentum_form=cubic_form, stored_energy=cubic_energy)


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, storage=sc.Storage(max_rows=scene.nt), **kwargs)


@pytest.mark.slow
@pytest.mark.parametrize("nx", [500, 1000])
def test_a_stiff_cubic_landing_converges_at_dt_under_projection(nx):
    """η0 = 1 + 0.3 sin πx thrown down by v0 = −3 sin 2πx, α = 0.02, Δt = Δx: every contact step converges at Δt, in a
    few Newton iterations. (With PETSc's zero tolerance of the VI, 1e-8, nodes within 1e-8 above the obstacle were
    held active off their bound and one step cycled: a sub-stepped step and 1.4 iterations a step at nx = 500.)"""
    scene = sc.load_scene("example1").replace(
        nx=nx, alpha=0.02, eta0="1 + 0.3*sin(pi*x)", v0="-3*sin(2*pi*x)", h=1.0, T=1.0, dt=1.0 / nx, output_times=[]
    )
    r = run(scene, scheme="projection", model=CUBIC)
    assert r.status == "complete" and r.checks["energy_balance"]["closes"], r.message
    assert r.eta.min() >= -1e-12 and r.contact.any()
    assert r.contact_force.min() >= 0.0 and np.all(r.contact_force[~r.contact] == 0.0)
    assert r.counters.get("sub-stepped steps", 0) == 0
    assert r.counters.get("line search rescues", 0) == 0  # no SNES solve failed
    assert r.counters["newton iterations"] <= 1.25 * (scene.nt + 1)  # measured 1.13 (nx = 500), 1.17 (nx = 1000)


@pytest.mark.slow
def test_film_landing_converges_at_600_steps():
    """The film thrown onto the obstacle with Δt = 5e-4: the landing's step, where the film's line search (l2) lets
    the residual rise until it diverges, is tried again with bt from the same guess and converges at Δt; the
    pressure stays finite and the ledger closes."""
    scene = sc.load_scene("film_landing").replace(nt=600)
    r = run(scene)
    assert r.status == "complete" and r.checks["energy_balance"]["closes"], r.message
    assert r.counters.get("sub-stepped steps", 0) == 0
    assert 1 <= r.counters["line search rescues"] <= 3
    assert r.counters["newton iterations"] <= 4 * scene.nt  # measured 2.96 a step
    assert np.all(np.isfinite(r.fields["pressure"])) and r.fields["pressure"].max() > 0
