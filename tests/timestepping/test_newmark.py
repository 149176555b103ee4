"""`newmark`: the trapezoidal rule conserves energy without contact, lands inelastically with ε → 0."""

import numpy as np
import pytest
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study
from stringcontact.model import variants


def run(scene, **kwargs):
    return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


@pytest.fixture(scope="module")
def ex1():
    return sc.load_scene("example1").replace(nx=400, nt=600)


@pytest.mark.parametrize("mass", ["lumped", "consistent"])
def test_newmark_conserves_energy_without_contact_and_viscosity(mass):
    # a sine mode well above the obstacle, α = 0, and Δt = 4Δx: beyond any explicit scheme's limit
    scene = study.flat_landing_scene(100, T=1.0, nt=25).replace(eta0="1 + 0.5*sin(pi*x)", v0="0", h=1)
    res = run(scene, scheme="newmark", mass=mass)
    E = res.total_energy
    assert not res.contact[:, 1:-1].any()
    assert np.max(np.abs(E - E[0])) <= 1e-12 * E[0]
    assert np.max(np.abs(res.energy["numerical_dissipation"])) == 0.0
    # the paper's scheme loses energy on the same run: the implicit Euler's numerical dissipation
    paper = run(scene, scheme="paper", penalty="semi-implicit", mass=mass)
    assert paper.energy["numerical_dissipation"][-1] > 0.1 * E[0]


def test_newmark_lands_inelastically_with_eps_to_zero():
    # ε = 1e-8: the ledger's round-off grows like 1/ε (2e-9 E0 at ε = 1e-10, docs/explanation/study.md)
    scene = study.flat_landing_scene(200, T=0.6, eps=1e-8)
    res = run(scene, scheme="newmark")
    e, E = res.energy, res.total_energy
    loss = E[0] - E[-1]  # α = 0: all of it is the landing's
    assert res.min_eta >= -2 * scene.dt * study.FLAT_V  # the active set needs η^n < 0: one step's travel
    assert loss > 0.5 * E[0]
    assert e["contact_dissipation"][-1] == pytest.approx(loss, rel=1e-6)  # all of it: no numerical dissipation
    assert np.max(np.abs(res.balance_residual)) <= 1e-9 * E[0]


def test_newmark_refuses_a_law_with_no_damping_form(ex1):
    with pytest.raises(ValueError, match=r"scheme 'newmark': model 'elastic' has no penalty_damping.*scheme paper"):
        run(ex1, scheme="newmark", model=variants.elastic)
    with pytest.raises(ValueError, match="scheme 'newmark' accepts penalty semi-implicit, not penalty 'explicit'"):
        run(ex1, scheme="newmark", penalty="explicit")
