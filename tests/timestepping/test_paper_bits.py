"""The paper's step, with its rotating rows, kept law and flags set once (for speed), gives the η and v of the
scheme written out plainly (temporaries, one mat-vec (C/Δt)η per step, the law evaluated on every node every
step), bit for bit, at every stored row."""

import warnings

import numpy as np
import pytest
from conftest import run_problem
from mpi4py import MPI
from petsc4py import PETSc

import stringcontact as sc
from stringcontact.fem import nodal
from stringcontact.fem.operators import step_matrices
from stringcontact.timestepping.linear import dirichlet_rows


def _plain(scene, steps):
    """A η^{n+1} = (M/Δt²)((η^n − η^{n−1}) + η^n) + (C/Δt) η^n + m_F∘F(η^n, v^n), ends held; η, v at `steps`."""
    problem, eta, v = run_problem(scene, "paper", "explicit", "lumped")
    ops, model, params = problem.ops, problem.laws.model, problem.laws.params
    A, _, C_dt = step_matrices(ops, scene.dt, "lumped")
    dirichlet_rows(A, problem.bc)
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    law = nodal.NodalExpression(model.penalty(problem.laws.eta, problem.laws.quotient, params))
    eta_old, dt = eta - scene.dt * v, scene.dt
    rows = {0: (eta, v)}
    b, x, c_eta = A.createVecLeft(), A.createVecRight(), A.createVecLeft()
    for n in range(1, scene.nt + 1):
        problem.laws.set(eta=eta, eta_old=eta_old)
        with np.errstate(all="ignore"):
            F = np.where(True, law._f(problem.laws.env), 0.0)  # the whole UFL graph on every node
        x.array[:] = eta
        C_dt.mult(x, c_eta)
        b.array[:] = ((eta - eta_old) + eta) * (ops.m / dt**2) + c_eta.array + ops.m_force * F
        b.array[problem.bc] = problem.g
        ksp.solve(b, x)
        eta_old, eta = eta, x.array.copy()
        rows[n] = (eta, (eta - eta_old) * (1.0 / dt))
    return np.array([rows[n][0] for n in steps]), np.array([rows[n][1] for n in steps])


@pytest.mark.parametrize("nx, nt", [(200, 400), (121, 1500)])
def test_the_paper_step_is_the_plain_scheme_bit_for_bit(nx, nt):
    scene = sc.load_scene("example1").replace(nx=nx, nt=nt)  # the landing and the spreading contact set
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sc.simulate(scene, comm=MPI.COMM_SELF)
    assert res.contact.any()
    eta, v = _plain(scene, res.steps)
    assert np.array_equal(res.eta, eta)
    assert np.array_equal(res.velocity[1:], v[1:])  # row 0 is the given v⁰
