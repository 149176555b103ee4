"""Steps that do not give up: landings whose Newton contact step failed at Δt run to T with a few steps taken as
halved sub-steps, the constraint and the contact force intact, the energy balance closing. No clock: the solver's
own counts are asserted."""

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


@pytest.mark.parametrize("nx", [500, 1000])
def test_a_stiff_cubic_landing_runs_under_projection(nx):
    """η0 = 1 + 0.3 sin πx thrown down by v0 = −3 sin 2πx, α = 0.02, Δt = Δx: Newton's VI fails on one contact step
    at Δt (measured: at nx = 500 and 1000); that step is taken in sub-steps and the run completes."""
    scene = sc.load_scene("example1").replace(nx=nx, alpha=0.02, eta0="1 + 0.3*sin(pi*x)", v0="-3*sin(2*pi*x)",
                                              h=1.0, T=1.0, dt=1.0 / nx, output_times=[])
    r = run(scene, scheme="projection", model=CUBIC)
    assert r.status == "complete" and r.checks["energy_balance"]["closes"], r.message
    assert r.eta.min() >= -1e-12 and r.contact.any()
    assert r.contact_force.min() >= 0.0 and np.all(r.contact_force[~r.contact] == 0.0)
    assert 1 <= r.counters["sub-stepped steps"] <= 3
    assert r.counters["newton iterations"] <= 3 * scene.nt  # Newton converges in a few iterations a step


def test_film_landing_runs_at_600_steps():
    """The film thrown onto the obstacle with Δt = 5e-4: Newton failed on the landing's step at Δt; it is taken in
    sub-steps, the pressure stays finite and the ledger closes."""
    scene = sc.load_scene("film_landing").replace(nt=600)
    r = run(scene)
    assert r.status == "complete" and r.checks["energy_balance"]["closes"], r.message
    assert 1 <= r.counters["sub-stepped steps"] <= 3
    assert r.counters["newton iterations"] <= 10 * scene.nt
    assert np.all(np.isfinite(r.fields["pressure"])) and r.fields["pressure"].max() > 0
