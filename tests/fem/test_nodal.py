"""`nodal`: a pointwise UFL law walked into NumPy gives what dolfinx's own evaluation gives."""

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

import stringcontact as sc
from stringcontact.fem import compat, nodal
from stringcontact.model.interface import Parameters


def test_nodal_evaluation_matches_dolfinx_interpolation():
    msh = mesh.create_interval(MPI.COMM_WORLD, 40, [0.0, 1.0])
    V = compat.function_space(msh)
    eta, eta_old = fem.Function(V), fem.Function(V)
    eta.interpolate(lambda x: np.sin(7 * x[0]) - 0.3)
    eta_old.interpolate(lambda x: np.sin(7 * x[0]) - 0.3 + 0.01 * np.cos(3 * x[0]))
    p = Parameters(alpha=fem.Constant(msh, 0.01), eps=fem.Constant(msh, 5e-4), x=ufl.SpatialCoordinate(msh), length=1.0)
    dt = fem.Constant(msh, 2e-4)
    expr = sc.inelastic.penalty(eta, (eta - eta_old) / dt, p) + ufl.exp(p.x[0]) * abs(eta)
    ref = fem.Function(V)
    ref.interpolate(fem.Expression(expr, compat.interpolation_points(V)))
    x = V.tabulate_dof_coordinates()[:, 0]
    got = nodal.evaluate(expr, {eta: eta.x.array, eta_old: eta_old.x.array}, x)
    assert np.max(np.abs(ref.x.array)) > 1  # the penalty is active somewhere
    assert np.allclose(got, ref.x.array, rtol=1e-12, atol=1e-9)


def test_nodal_subtraction_is_bit_identical_to_ufl_sum():
    msh = mesh.create_interval(MPI.COMM_WORLD, 30, [0.0, 1.0])
    V = compat.function_space(msh)
    f, g = fem.Function(V), fem.Function(V)
    rng = np.random.default_rng(1)
    fa, ga = rng.standard_normal(31), rng.standard_normal(31)
    x = np.linspace(0, 1, 31)
    got = nodal.evaluate((f - g) + (-1 * f + g * 2), {f: fa, g: ga}, x)
    assert np.array_equal(got, (fa - ga) + (ga * 2 - fa))
