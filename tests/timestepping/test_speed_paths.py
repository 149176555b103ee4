"""The shortcuts a step takes for speed give the numbers of the long way, bit for bit: projection's contact
step with a diagonal step matrix (α = 0, lumped mass) is the nodal maximum, no linear solve, and equals the
active-set method on A's LU."""

import warnings

import numpy as np
import pytest
from mpi4py import MPI

import stringcontact as sc
from stringcontact.timestepping import complementarity


def _run(scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, scheme="projection", comm=MPI.COMM_SELF)


@pytest.mark.parametrize("name", ["example1", "example2"])
def test_diagonal_contact_step_is_the_active_set_answer_without_a_solve(name, monkeypatch):
    scene = sc.load_scene(name).replace(nx=300, nt=600, alpha=0.0)  # A = M/Δt²: diagonal
    nodal = _run(scene)
    assert nodal.solver["linear solver"].startswith("none")
    assert nodal.solver["contact step"].startswith("nodal maximum")
    assert nodal.contact.any()
    monkeypatch.setattr(complementarity, "inverse_diagonal", lambda A, comm: None)  # the active-set method on LU
    active_set = _run(scene)
    assert active_set.solver["linear solver"].startswith("LU")
    for field in ("eta", "velocity", "contact", "contact_force"):
        assert np.array_equal(getattr(nodal, field), getattr(active_set, field)), field
    for key, values in nodal.energy.items():
        assert np.array_equal(values, active_set.energy[key]), key


def test_with_viscosity_the_step_matrix_is_not_diagonal():
    res = _run(sc.load_scene("example1").replace(nx=300, nt=600))
    assert res.solver["linear solver"].startswith("LU")
