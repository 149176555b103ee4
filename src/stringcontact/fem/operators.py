"""From the model's semi-discrete UFL form to constant operators, each assembled once.

The model writes M η_tt + C η_t + K η = B F + b in UFL (`model.interface`); `ufl.derivative` along each placeholder
takes it apart: M = ∂R/∂η_tt, C = ∂R/∂η_t, K = ∂R/∂η, B = −∂R/∂F, b = −R(0, 0, 0, 0). A form nonlinear in η or η_t
(or with several fields) keeps the same operators, linearised at 0 (the stability estimates and round-off floors
read them), and hands its residual to the schemes (`NonlinearForm`), which solve each step by Newton
(`timestepping.newton`). A form not finite at 0 (k/η, √η) is linearised at the run's initial state instead, and its
load is what its declared stored energy leaves of its static force there, b = δΠ(η⁰) − R(η⁰, 0, 0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
from ufl.algorithms.apply_derivatives import apply_derivatives

from ..errors import ModelError
from ..model.forms import FormError, check_form, mass_density
from . import compat


@dataclass
class Operators:
    """The assembled constant operators of one model on one mesh (PETSc objects, no BCs applied): ``M``, ``C``, ``K``
    (∂R/∂η_tt, ∂R/∂η_t, ∂R/∂η); ``m``, the row sums of M on the owned dofs (the lumped mass); ``m_force``, the row
    sums of B (the lumped force weights); ``load``, b on the owned dofs; ``V``, the space (kept alive with its
    matrices: dolfinx 0.9 crashes otherwise); ``nonlinear``, a nonlinear model's residual (`NonlinearForm`; M, C, K
    are then its tangent) or None; ``linearised_at``, ``"eta = 0"`` or ``"the state"`` (a form not finite at 0).
    """

    M: PETSc.Mat
    C: PETSc.Mat
    K: PETSc.Mat
    m: np.ndarray
    m_force: np.ndarray
    load: np.ndarray
    V: object = None
    nonlinear: NonlinearForm | None = None
    linearised_at: str = "eta = 0"


@dataclass
class NonlinearForm:
    """A model whose momentum form is nonlinear in η or η_t, for a scheme that solves each step by Newton
    (`timestepping.newton`). R is affine in η_tt and the force with constant coefficients (the `Operators`' M and
    m_force), so a scheme keeps its mass lumping and its nodal force.

    Its fields: ``residual``, the UFL form R(eta, eta_t, eta_tt, force; w); ``eta``, ``eta_t``, ``eta_tt``, the
    placeholders (Functions on ``space``), ``force`` a Function on ``V``, η's P1 space; ``params``, the model's
    constants; ``stored_energy``, the UFL form ∫Π(energy_eta) dx of the ledger, ``energy_eta`` the Function it reads,
    ``energy_derived`` True when it is the form's potential (`potential_energy`), not declared; ``viscous_linear``,
    ∂R/∂η_t constant (the viscous force is C η_t, a mat-vec); ``space``, V or the mixed space of ``(η, *fields)``,
    ``eta_dofs`` the mixed space's local dof of each local dof of V (None when the space is V).
    """

    residual: object
    eta: object
    eta_t: object
    eta_tt: object
    force: object
    V: object
    params: object
    stored_energy: object
    energy_eta: object
    viscous_linear: bool = False
    space: object = None
    eta_dofs: object = None
    energy_derived: bool = False


def _assemble_matrix(a, pattern: PETSc.Mat | None = None) -> PETSc.Mat:
    """Assemble `a`; with `pattern`, into a copy of its sparsity (P1 forms on one mesh share it)."""
    if pattern is None:
        A = fem.petsc.assemble_matrix(fem.form(a))
    else:
        A = pattern.duplicate(copy=False)  # MatDuplicate without copying values zeroes them
        fem.petsc.assemble_matrix(A, fem.form(a))
    A.assemble()
    return A


def assemble_vector(L) -> np.ndarray:
    """The linear form `L` assembled on the owned dofs (ghost contributions added to their owners)."""
    vec = fem.petsc.assemble_vector(fem.form(L))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return vec.array.copy()


def _assemble_row_sums(a, V) -> np.ndarray:
    """Row sums of the bilinear form `a` on owned dofs, as the vector a(1, w): no matrix is built."""
    one = fem.Constant(V.mesh, PETSc.ScalarType(1.0))
    return assemble_vector(ufl.replace(a, {ufl.algorithms.extract_arguments(a)[1]: one}))


def _row_sums(A: PETSc.Mat) -> np.ndarray:
    ones, rs = A.createVecRight(), A.createVecLeft()
    ones.set(1.0)
    A.mult(ones, rs)
    return rs.array.copy()


#: Gauss–Legendre on [0, 1], 3 points: the potential's s-integral exact for a static force of degree ≤ 5 in η
#: (the paper's and a cubic foundation's), a few digits for a smooth one (a model with a closed form declares it).
_GAUSS_S = ((0.5 - 0.5 * math.sqrt(0.6), 5 / 18), (0.5, 8 / 18), (0.5 + 0.5 * math.sqrt(0.6), 5 / 18))


def potential_energy(R, placeholders, w, V):
    """The stored energy of a momentum form R(η, η_t, η_tt, F; w) that declares none: the potential Π(η) = ∫₀¹ G(sη; η)
    ds of its static force G(η; w) = R(η, 0, 0, 0; w) − R(0, 0, 0, 0; w) (the load is external work), by
    Gauss–Legendre in s: for a conservative form its energy, zero at η = 0 (½∫η_x² for the paper's form). Returns the
    UFL functional and the Function on V it reads."""
    eta, eta_t, eta_tt, force = placeholders
    e = fem.Function(V)
    zero = fem.Constant(V.mesh, PETSc.ScalarType(0.0))
    rest = {eta_t: zero, eta_tt: zero, force: zero, w: e}
    energy = -ufl.replace(R, rest | {eta: zero})
    for s, weight in _GAUSS_S:
        energy = energy + weight * ufl.replace(R, rest | {eta: s * e})
    return energy, e


def semi_discrete_operators(model, V, params, residual: bool = False, state=None) -> Operators:
    """Assemble M, C, K, the lumped force weights and the load of `model.momentum_form` on V.

    A form nonlinear in η or η_t (or a model with ``newton=True``, or any model when `residual` is set) gives the
    same operators linearised at 0 plus `Operators.nonlinear`; ModelError if it is nonlinear in η_tt or the force.
    `state` (a callable giving η and η_t on V's owned dofs, the run's initial state) is where a form singular at
    η = 0 is linearised and its load taken; ModelError naming the cause if that cannot be done.
    """
    eta, eta_t, eta_tt, force = (fem.Function(V) for _ in range(4))
    w = ufl.TestFunction(V)
    u = ufl.TrialFunction(V)
    mixed = _mixed_residual(model, V, params, force) if getattr(model, "fields", ()) else None
    if mixed is None:
        R = model.momentum_form(eta, eta_t, eta_tt, force, w, params)
        check_form(model.name, "momentum_form", R, w)  # before anything is compiled: a bilinear form aborted
    else:  # η's equation with the other fields at 0: the operators below are its tangent at 0
        k = len(model.fields)
        Z_fns, R_Z, W = mixed
        as_eta = [ufl.as_vector([f, *[0.0] * k]) for f in (eta, eta_t, eta_tt, w)]
        R = ufl.replace(R_Z, dict(zip((*Z_fns, W), as_eta)))
    placeholders = (eta, eta_t, eta_tt, force)
    what = "residual" if mixed is not None else "momentum_form"
    density = mass_density(model.name, what, R, eta_tt, w, (*placeholders, *(mixed[0] if mixed else ())))
    mass_known = _check_mass(model.name, what, density, V, params)
    zero = fem.Constant(V.mesh, PETSc.ScalarType(0.0))
    at_zero = dict.fromkeys(placeholders, zero)

    R_lowered = apply_algebra_lowering(R)  # once, not per derivative
    tangents = {}  # the tangents that read the placeholders, before they are taken at 0

    def part(f, at=at_zero):
        a = apply_derivatives(ufl.derivative(R_lowered, f, u))
        used = set(ufl.algorithms.extract_coefficients(a)) & set(placeholders)
        if used and f in (eta_tt, force):
            raise ModelError(f"model '{model.name}': momentum_form must be affine in eta_tt and in force with "
                             "constant coefficients (a constant mass and nodal force weights); it may be nonlinear in "
                             "eta and eta_t")
        if used:  # the tangent at 0 stands for the operator (stability estimates, round-off floors)
            tangents[f] = a
            a = apply_derivatives(ufl.algorithms.expand_derivatives(ufl.replace(a, at)))
        # no such term (e.g. α = 0 written out): a zero matrix, same pattern
        return zero * u * w * ufl.dx if a.empty() else a

    K = _assemble_matrix(part(eta))
    M, C = (_assemble_matrix(part(f), pattern=K) for f in (eta_tt, eta_t))
    nonlinear_in = set(tangents)
    linearised_at = "eta = 0"
    if nonlinear_in and not (_finite(K) and _finite(C)):  # singular at η = 0: the tangent at the run's state
        at = _state(model.name, V, state, placeholders, zero, "its tangent (C, K) is not finite at eta = 0")
        K_at, C_at = (_assemble_matrix(part(f, at), pattern=M) for f in (eta, eta_t))
        if _finite(K_at) and _finite(C_at):  # else not finite at the state either: the first step names the form
            K, C, linearised_at = K_at, C_at, "the state"
    m_force = -_assemble_row_sums(part(force), V)  # B = −∂R/∂F is only needed lumped
    b_form = ufl.algorithms.expand_derivatives(-ufl.replace(R, at_zero))
    m = _row_sums(M)
    if not mass_known:  # a mass density the nodes cannot give (a field's gradient in it): its lumped rows
        _refuse_mass(model.name, what, m, node_coordinates(V)[: m.size], V.mesh.comm, "lumped mass")
    load = np.zeros_like(m) if b_form.empty() else assemble_vector(b_form)
    declared = getattr(model, "stored_energy", None)
    if nonlinear_in and mixed is None and not _all_ranks(V, np.isfinite(load).all()):  # R(0) singular
        load = _load_at_state(model.name, what, R, placeholders, w, V, params, state, zero, declared, load)
    ops = Operators(M=M, C=C, K=K, m=m, m_force=m_force, load=load, V=V, linearised_at=linearised_at)
    if mixed is not None:  # several fields: the energy the model declares in all of them
        if declared is None:
            raise ModelError(f"model '{model.name}': a model with fields {model.fields} must declare stored_energy(U, p), "
                             "the energy density its form stores in U = (eta, *fields) (the paper's: "
                             "0.5*inner(grad(U[0]), grad(U[0])); the energy ledger books it)")
        (U, U_t, U_tt), R_Z, _ = mixed
        Z = U.function_space
        state = fem.Function(Z)  # the unknowns whose energy is booked: η and the fields of the same solve
        ops.nonlinear = NonlinearForm(residual=R_Z, eta=U, eta_t=U_t, eta_tt=U_tt, force=force, V=V, params=params,
                                      stored_energy=declared(ufl.split(state), params) * ufl.dx, energy_eta=state,
                                      space=Z, eta_dofs=compat.sub_dofs(V, Z, 0))
    elif nonlinear_in or residual or getattr(model, "newton", False):
        if declared is None:  # the form's own potential, not the paper's ½|∇η|²
            stored, energy_eta = potential_energy(R, placeholders, w, V)
        else:
            stored, energy_eta = declared(eta, params) * ufl.dx, eta
        ops.nonlinear = NonlinearForm(residual=R, eta=eta, eta_t=eta_t, eta_tt=eta_tt, force=force, V=V,
                                      params=params, stored_energy=stored, energy_eta=energy_eta,
                                      viscous_linear=eta_t not in nonlinear_in, space=V, energy_derived=declared is None)
    return ops


def _finite(A: PETSc.Mat) -> bool:
    """Whether every entry of the assembled matrix is finite (its norm is: inf or nan otherwise). Collective."""
    return math.isfinite(A.norm(PETSc.NormType.FROBENIUS))


def _all_ranks(V, flag) -> bool:
    """`flag` on every rank of V's mesh."""
    return all(V.mesh.comm.allgather(bool(flag)))


def _state(name: str, V, state, placeholders, zero, why: str) -> dict:
    """The placeholders at the run's state (`state()`'s η and η_t, η_tt and the force at 0); ModelError naming `why`
    without a state (an operator built without a run)."""
    if state is None:
        raise ModelError(f"model '{name}': momentum_form is evaluated at eta = 0 for its operators, and {why}; "
                         "allowed: a form finite at eta = 0, or a run from an initial state where it is")
    eta, eta_t, eta_tt, force = placeholders
    at = {eta_tt: zero, force: zero}
    n = V.dofmap.index_map.size_local
    for f, values in zip((eta, eta_t), state()):
        g = fem.Function(V)
        g.x.array[:n] = np.asarray(values, dtype=float)[:n]
        g.x.scatter_forward()
        at[f] = g
    return at


def _load_at_state(name: str, what: str, R, placeholders, w, V, params, state, zero, declared, load) -> np.ndarray:
    """The load of a form not finite at η = 0: what the declared stored energy Π leaves of the static force at the
    run's state η⁰, b = δΠ(η⁰) − R(η⁰, 0, 0, 0); ModelError without a declared energy if the form is finite at η⁰;
    `load` (−R(0)) as it is if it is not (the first step names the form)."""
    why = "its load -R(0) is not finite (a term singular at eta = 0)"
    at = _state(name, V, state, placeholders, zero, why)
    at[placeholders[1]] = zero  # the static force: at rest
    static = ufl.algorithms.expand_derivatives(ufl.replace(R, at))
    if not _all_ranks(V, np.isfinite(assemble_vector(static)).all()):
        return load
    if declared is None:
        raise ModelError(f"model '{name}': {what} is evaluated at eta = 0 for its load and the zero of its potential "
                         f"energy, and {why}; allowed: a form finite at eta = 0, or a model that declares "
                         "stored_energy(eta, p), its energy density (the load is then taken at the initial state)")
    state_eta = at[placeholders[0]]
    energy = ufl.derivative(declared(state_eta, params) * ufl.dx, state_eta, w)
    b = assemble_vector(ufl.algorithms.expand_derivatives(energy - ufl.replace(R, at)))
    return b if _all_ranks(V, np.isfinite(b).all()) else load


def _check_mass(name: str, what: str, density, V, params) -> bool:
    """FormError unless the mass density (`model.forms.mass_density`) is positive and finite at every node (a zero or
    negative mass ran to 1e30, marked complete); False if it is no pointwise expression (the caller checks the rows)."""
    from .nodal import evaluate

    x = node_coordinates(V)
    try:
        values = np.broadcast_to(evaluate(density, {f: f.x.array for f in params.extra.values()}, x), x.shape[:1])
    except (ValueError, KeyError, TypeError, AttributeError, NotImplementedError):
        values = None
    if not all(V.mesh.comm.allgather(values is not None)):  # one outcome on every rank: each then checks alike
        return False
    _refuse_mass(name, what, values, x, V.mesh.comm, "mass")
    return True


def _refuse_mass(name: str, what: str, values: np.ndarray, x: np.ndarray, comm, kind: str) -> None:
    """FormError on every rank if `values` (a mass per node) is not positive and finite at some node of some rank."""
    bad = np.flatnonzero(~(np.asarray(values) > 0) | ~np.isfinite(values))
    found = (float(values[bad[0]]), np.atleast_1d(x[bad[0]]).tolist()) if bad.size else None
    found = next((f for f in comm.allgather(found) if f is not None), None)
    if found is not None:
        value, where = found
        at = ", ".join(f"{c:.4g}" for c in where)
        raise FormError(f"model '{name}': {what}'s {kind} (the coefficient of eta_tt) is {value:.4g} at x = ({at}); "
                        "allowed: positive and finite at every node (with a zero or negative mass no time step is "
                        "stable)")


def _mixed_residual(model, V, params, force):
    """A model with `fields`: its residual on the mixed space of (η, *fields), with mixed placeholders."""
    if model.residual is None:
        raise ModelError(f"model '{model.name}': a model with fields {model.fields} must give residual(U, U_t, U_tt, "
                         "force, W, p)")
    Z = compat.mixed_space(V.mesh, 1 + len(model.fields))
    U, U_t, U_tt = (fem.Function(Z) for _ in range(3))
    W = ufl.TestFunction(Z)
    R = model.residual(ufl.split(U), ufl.split(U_t), ufl.split(U_tt), force, ufl.split(W), params)
    check_form(model.name, "residual", R, W)  # before anything is compiled
    return (U, U_t, U_tt), R, W


def diagonal_matrix(template: PETSc.Mat, diag: np.ndarray) -> PETSc.Mat:
    """A matrix with the sparsity of `template` holding `diag` on its diagonal (so sums stay cheap)."""
    D = template.duplicate(copy=False)
    d = template.createVecLeft()
    d.array[:] = diag
    D.setDiagonal(d)
    D.assemble()
    return D


def step_matrices(ops: Operators, dt: float, mass: str):
    """The constant matrices of one time step: (A, M_scheme, C/Δt), A = M/Δt² + C/Δt + K with M_scheme = M
    (consistent) or diag(m) (lumped); the time loop builds the right-hand side."""
    Ms = diagonal_matrix(ops.M, ops.m) if mass == "lumped" else ops.M
    same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN  # M, C, K share one sparsity (see semi_discrete_operators)
    A = ops.K.copy()
    A.axpy(1.0 / dt, ops.C, structure=same)
    A.axpy(1.0 / dt**2, Ms, structure=same)
    C_dt = ops.C.copy()
    C_dt.scale(1.0 / dt)
    return A, Ms, C_dt


def stacked(*mats: PETSc.Mat) -> PETSc.Mat:
    """[A₁; A₂; …], each rank's rows of A₁, then its rows of A₂, …: one mat-vec gives every product (the time loop
    needs K η and (C/Δt) η of the same η every step)."""
    ia, ja, a = zip(*(A.getValuesCSR() for A in mats))  # this rank's rows, global column indices
    offsets = np.cumsum([0] + [i[-1] for i in ia[:-1]])
    # PETSc's own index type (int32 on trixie's PETSc): the offsets' sums are int64
    starts = np.concatenate([ia[0][:1]] + [i[1:] + o for i, o in zip(ia, offsets)]).astype(PETSc.IntType)
    rows, cols = sum(A.getLocalSize()[0] for A in mats), mats[0].getLocalSize()[1]
    S = PETSc.Mat().createAIJ(size=((rows, PETSc.DECIDE), (cols, PETSc.DECIDE)), comm=mats[0].getComm(),
                              csr=(starts, np.concatenate(ja).astype(PETSc.IntType), np.concatenate(a)))
    S.assemble()
    return S


def node_coordinates(V) -> np.ndarray:
    """Coordinates of this rank's dofs (P1: the vertices), the owned ones first, then the ghosts: x, shape
    (N,), on the interval; (x, y), shape (N, 2), on a 2D mesh."""
    if V.mesh.topology.dim == 1:
        return V.tabulate_dof_coordinates()[:, 0].copy()
    # 2D: the mesh's own node coordinates (P1 dofs sit on them), not tabulate_dof_coordinates: that maps the
    # reference vertices through a cell, exact only to an ulp that depends on the cell, hence on the ranks
    x = np.empty((V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, 2))
    x[compat.cell_dofs(V)] = V.mesh.geometry.x[compat.geometry_nodes(V.mesh), :2]
    return x


__all__ = ["ModelError", "NonlinearForm", "Operators", "node_coordinates", "potential_energy",
           "semi_discrete_operators", "stacked", "step_matrices"]
