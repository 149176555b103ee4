"""The fast time loop against a plain form-assembly loop (no timing here: see benchmarks/bench_solver.py).

`simulate` assembles M, C, K once and builds each right-hand side from mat-vecs on preallocated
vectors. The loop below is what one would write first with dolfinx: the step's UFL form, its
`lhs`/`rhs`, reassembled every step with `apply_lifting` and `set_bc`, and the contact law
interpolated with `fem.Expression`. Both must give the same η to 1e-10.
"""

import dolfinx.fem.petsc  # noqa: F401 - not imported with dolfinx.fem on 0.9
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

import stringcontact as sc
from stringcontact.fem import compat
from stringcontact.model.interface import Model, Parameters


def forms_loop(scene, penalty="explicit", mass="lumped", model=sc.inelastic):
    """Reassemble the step form every step; return η at every step, ordered by x (serial)."""
    comm = MPI.COMM_SELF
    msh = mesh.create_interval(comm, scene.nx, [0.0, scene.length])
    V = compat.function_space(msh)
    p = Parameters(
        alpha=fem.Constant(msh, PETSc.ScalarType(scene.alpha)),
        eps=fem.Constant(msh, PETSc.ScalarType(scene.eps)),
        x=ufl.SpatialCoordinate(msh),
        length=scene.length,
    )
    dt = scene.dt
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    eta, eta_old, law_f = fem.Function(V), fem.Function(V), fem.Function(V)
    zero = fem.Constant(msh, PETSc.ScalarType(0.0))
    # Lumped mass and lumped force weights are row sums: ∫ w dx (P1), by definition of lumping.
    ones = fem.petsc.assemble_vector(fem.form(w * ufl.dx)).array.copy()
    if mass == "lumped":  # the mass term enters below, on the diagonal
        R = model.momentum_form(u, (u - eta) / dt, zero * u, zero, w, p)
    else:
        R = model.momentum_form(u, (u - eta) / dt, (u - 2 * eta + eta_old) / dt**2, zero, w, p)
    a_form, L_form = ufl.lhs(R), ufl.rhs(R)

    x = V.tabulate_dof_coordinates()[:, 0]
    ends = fem.locate_dofs_geometrical(V, lambda X: np.isclose(X[0], 0.0) | np.isclose(X[0], scene.length))
    g = fem.Function(V)
    g.x.array[:] = np.where(np.isclose(x, 0.0), scene.h_left, scene.h_right)
    bcs = [fem.dirichletbc(g, ends)]

    eta.x.array[:] = scene.initial_displacement(x)
    eta.x.array[ends] = g.x.array[ends]
    v0 = np.asarray(scene.initial_velocity(x), dtype=float)
    v0[ends] = 0.0
    eta_old.x.array[:] = eta.x.array - dt * v0

    law_ufl = (model.penalty if penalty == "explicit" else model.penalty_damping)(eta, (eta - eta_old) / dt, p)
    law_expr = fem.Expression(law_ufl, compat.interpolation_points(V))
    a_compiled, L_compiled = fem.form(a_form), fem.form(L_form)
    solver = PETSc.KSP().create(comm)
    solver.setType("preonly")
    solver.getPC().setType("lu")
    history = [eta.x.array.copy()]
    for _ in range(scene.nt):
        law_f.interpolate(law_expr)
        law = law_f.x.array
        A = fem.petsc.assemble_matrix(a_compiled, bcs=bcs)
        A.assemble()
        diag = np.zeros_like(law)
        if mass == "lumped":
            diag += ones / dt**2
        if penalty == "semi-implicit":
            diag += ones * law / dt
        interior = np.ones(law.size, dtype=bool)
        interior[ends] = False
        d = A.getDiagonal()
        d.array[interior] += diag[interior]
        A.setDiagonal(d)
        b = fem.petsc.assemble_vector(L_compiled)
        if mass == "lumped":
            b.array[:] += ones * (2 * eta.x.array - eta_old.x.array) / dt**2
        if penalty == "explicit":
            b.array[:] += ones * law
        else:
            b.array[:] += ones * law / dt * eta.x.array
        fem.petsc.apply_lifting(b, [a_compiled], bcs=[bcs])
        fem.petsc.set_bc(b, bcs)
        solver.setOperators(A)
        new = A.createVecRight()
        solver.solve(b, new)
        eta_old.x.array[:] = eta.x.array
        eta.x.array[:] = new.array
        history.append(eta.x.array.copy())
    order = np.argsort(x)
    return np.array(history)[:, order]


@pytest.fixture(scope="module")
def small():
    # r = dt/eps = 0.8 and an impact at t ≈ 0.02: the penalty is active in most steps
    return sc.load_scene("example1").replace(nx=60, nt=250, T=0.1, output_times=[])


@pytest.mark.parametrize(
    "penalty,mass", [("explicit", "lumped"), ("explicit", "consistent"), ("semi-implicit", "lumped")]
)
def test_fast_path_equals_form_assembly_every_step(small, penalty, mass):
    res = sc.simulate(small, penalty=penalty, mass=mass, storage=sc.Storage(max_rows=50))
    ref = forms_loop(small, penalty, mass)
    assert res.min_eta < -1e-3  # contact happened, so the penalty is part of the comparison
    assert np.max(np.abs(res.eta - ref[res.steps])) <= 1e-10
    v_ref = (ref[res.steps[1:]] - ref[res.steps[1:] - 1]) / small.dt
    assert np.max(np.abs(res.velocity[1:] - v_ref)) <= 1e-10 / small.dt


def test_semi_implicit_refactorises_only_when_the_active_set_changes(small):
    res = sc.simulate(small, penalty="semi-implicit")
    n = res.counters["refactorisations"]
    assert 0 < n < small.nt  # it does change, but not at every step


def test_energy_guard_still_fires_with_the_fast_diagnostics(small):
    # A (wrong) law that pushes along the velocity below the obstacle feeds energy in; the per-step
    # guard, computed from the stacked dot products, must name the step.
    def pushing(eta, v, p):
        return ufl.conditional(ufl.lt(eta, 0), v / p.eps, 0)

    model = Model(name="pushing", penalty=pushing)
    with pytest.raises(sc.InstabilityError, match=r"unstable at step \d+.*energy rose"):
        sc.simulate(small, model=model)


def test_storage_does_not_grow_with_the_number_of_steps(small):
    a = sc.simulate(small, storage=sc.Storage(max_rows=20))
    b = sc.simulate(small.replace(nt=1000, T=0.4), storage=sc.Storage(max_rows=20))
    assert len(b.t) <= 21 and len(a.t) <= 21
    assert b.eta.shape == a.eta.shape
