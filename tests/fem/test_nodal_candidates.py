"""A pointwise law evaluated only where it can act (`nodal.NodalExpression`'s candidate subset) is the full
evaluation bit for bit, on every pattern of candidates: none, all, one interval, scattered nodes."""

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from stringcontact.fem import compat, nodal
from stringcontact.model import inelastic as paper, interface
from stringcontact.model.variants import elastic

N = 400


@pytest.fixture(scope="module")
def space():
    msh = mesh.create_interval(MPI.COMM_SELF, N, [0.0, 1.0])
    V = compat.function_space(msh, "Lagrange", 1)
    params = interface.Parameters(alpha=fem.Constant(msh, PETSc.ScalarType(0.1)),
                              eps=fem.Constant(msh, PETSc.ScalarType(5e-4)), x=ufl.SpatialCoordinate(msh), length=1.0)
    eta, eta_old = fem.Function(V), fem.Function(V)
    v = (eta - eta_old) / fem.Constant(msh, PETSc.ScalarType(2e-4))
    return eta, eta_old, v, params, V.tabulate_dof_coordinates()[:, 0]


def _laws(eta, v, params):
    x = params.x[0]
    return {
        "penalty": paper.penalty(eta, v, params),
        "penalty_damping": paper.penalty_damping(eta, v, params),  # conditional(η < 0 ∧ v < 0, 1/ε, 0)
        "transcendental": ufl.conditional(ufl.lt(eta, 0.1), ufl.exp(-eta) * ufl.sin(3 * x) + ufl.sqrt(abs(v)), 0),
        "elastic (no conditional)": elastic.penalty(eta, v, params),
    }


def _patterns(rng, x):
    yield "none", np.abs(rng.standard_normal(x.size)) + 1.0
    yield "all", -np.abs(rng.standard_normal(x.size)) - 1.0
    yield "interval", np.where((x > 0.3) & (x < 0.6), -1.0, 1.0) * rng.random(x.size)
    yield "scattered", np.where(rng.random(x.size) < 0.05, -1.0, 1.0) * rng.random(x.size)
    yield "ends", np.where((x < 0.05) | (x > 0.95), -1.0, 1.0) * rng.random(x.size)


def _bits(a):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), (N + 1,))).view(np.uint64)


def test_candidate_subset_is_the_full_evaluation_bit_for_bit(space):
    eta, eta_old, v, params, x = space
    rng = np.random.default_rng(28)
    for name, expr in _laws(eta, v, params).items():
        law = nodal.NodalExpression(expr)
        for pattern, e in _patterns(rng, x):
            e_old = e + 1e-3 * rng.standard_normal(x.size)
            env = nodal.environment({eta: e, eta_old: e_old}, x)
            with np.errstate(all="ignore"):
                full = np.where(True, law._f(env), 0.0)  # the whole graph on every node
                got = law.evaluate_env(env)
            assert np.array_equal(_bits(got), _bits(full)), f"{name}, {pattern}"  # -0.0 and NaN bits too


def test_the_penalties_take_the_candidate_path(space):
    eta, eta_old, v, params, x = space
    laws = _laws(eta, v, params)
    for name in ("penalty", "penalty_damping", "transcendental"):
        assert nodal.NodalExpression(laws[name])._candidates is not None, name
    assert nodal.NodalExpression(laws["elastic (no conditional)"])._candidates is None


@pytest.mark.parametrize("true_at", [[], [0], [N], [0, N], [7], [3, 4, 5, 90], list(range(N + 1))])
def test_the_candidate_span_is_from_the_first_true_node_to_the_last(true_at):
    c1 = np.zeros(N + 1, dtype=bool)
    c1[true_at] = True
    for c in (c1, c1[::2], c1[::-1]):  # contiguous, and views with other strides
        nodes = np.flatnonzero(c)
        assert nodal._span(c) == ((nodes[0], nodes[-1] + 1) if nodes.size else (-1, 0))


def test_a_constant_condition_broadcast_to_every_node_spans_them_all():
    assert nodal._span(np.broadcast_to(np.True_, (N + 1,))) == (0, N + 1)
    assert nodal._span(np.broadcast_to(np.False_, (N + 1,))) == (-1, 0)
