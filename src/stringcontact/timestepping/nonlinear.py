"""A nonlinear model's step, solved by Newton's method with line search (PETSc SNES), for every scheme.

The model writes its residual R(η, η_t, η_tt, F; w) once (`model.paper`); a nonlinear one reaches the schemes
as `Operators.nonlinear` (`fem.operators.NonlinearForm`). Each scheme writes the placeholders as its difference
quotients in the unknown u = η^{n+1} and the known levels η^n, η^{n−1} (and a nodal velocity v^n), and the
step is the root of

    G(u) = R(q_η(u), q_t(u), q_tt(u), 0; w) − f + d∘(u − c),      u = g at the fixed ends,

with f the scheme's nodal contact force (the penalty law, lumped as on the linear path) and d∘(u − c) an
implicit damping on the diagonal (the semi-implicit penalty). With lumped mass the η_tt term is m∘q_tt(u),
the row-sum mass, as on the linear path; R is affine in η_tt and in the force (`semi_discrete_operators`
checks), so only η and η_t may enter nonlinearly. The Jacobian is ``ufl.derivative`` of the compiled
residual (plus the lumped mass and the damping on its diagonal); both forms are compiled once, integer
powers as products (`powers_as_products`), the residual and the stored energy with their coefficients packed once
(`fem.packed.PackedForm`). A step may keep an earlier step's Jacobian and its LU factor for a few chord
iterations (`NewtonStep._keeps_jacobian`); once it takes a fresh one, its later iterations do too.

`projection`'s contact step is the variational inequality G(u) ⊥ u − ψ ≥ 0 (SNES ``vinewtonrsls``, bounds
u ≥ ψ at the interior nodes), tried as a plain Newton step first while the last solution touched no bound;
its contact force is the reaction G₀(u) of the unconstrained residual on the active set: ≥ 0, and 0 off the
contact set.

The linear path. A model with several fields reaches this module even when its residual is linear (a
fourth-order term written with a second unknown, η's second derivative). A residual affine in its unknowns with
constant coefficients (`affine_in`: its derivatives read no Function), of a model that does not ask for Newton
(`Model.newton`), takes no Newton iteration and no SNES: G(u) = J u + G(0) with a constant J, assembled and
factorised once (again only when a damping on its diagonal changes), and the step is one back-substitution (`NewtonStep._linear_path`). G(0), the
ledger's viscous work and a quadratic stored energy (`QuadraticEnergy`) come from the residual's constant matrices
(`affine.AffineResidual`) by products with the solutions, one stacked mat-vec per step (`affine.LevelTerms`). A VI tries that
solve first and keeps SNES for the steps that touch a bound. On this path the other fields start from η0 (their
rows solved with η = η0, `NewtonStep.start_fields`; the Newton path starts them at 0), and `projection` checks
its Δt against η's stiffness with the fields eliminated (`NewtonStep.eta_stiffness`). Measured on a linear
two-field string model at nx = 5000, such a step costs 2.3× the paper's linear step, by SNES 12-20×.

Energy (every scheme): the ledger gets the kinetic energy of its velocity, the stored energy ∫Π(η) of the model
(`Model.stored_energy`, default ½|∇η|²) assembled at the new level, the viscous dissipation as the work of
R's η_t-dependent part over the step, [R(q_η, q_t) − R(q_η, 0)]·δ, the external work b·δ (δ the scheme's test
increment), the contact dissipation as on the linear path, and as numerical dissipation what is left of the
identity: E^n − E^{n+1} − D_visc − D_con + W_ext. So the ledger closes by construction, and the numerical
dissipation says how far the scheme is from conserving the model's energy (for the paper's implicit step
and a convex Π it is ≥ 0; the leapfrog and the midpoint rule of a nonlinear force make it change sign, so
these steps declare ``energy_may_rise`` and the driver's guard allows what it allows a contact spring).
"""

from __future__ import annotations

import dataclasses
import math

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms.map_integrands import map_integrand_dags
from ufl.constantvalue import IntValue
from ufl.corealg.multifunction import MultiFunction

from ..errors import InstabilityError, SolverError
from ..fem import compat
from ..fem.packed import PackedForm
from .affine import (
    UNITS,
    AffineResidual,
    LevelTerms,
    QuadraticEnergy,
    _as_slice,
    affine_in,
    compact,
    literal_components,
)
from .base import Scheme as Base
from .base import StepEnergy, any_rank, check_law_stability, summer, wrap
from .linear import PREFIX, DampedLU, Linear, dirichlet_rows, options_held, set_from_options, solver_options
from .spectrum import dt_of_mode, top_mode_of_shell

#: Newton's defaults (a scene's or the command line's `petsc_options` go on top): the relative residual and the
#: relative step (quadratic convergence makes the error after a step of 1e-9 |u| about 1e-18 |u|).
#: The absolute residual Newton stops at, relative to the inertia term's norm: a few hundred round-offs of it.
ROUNDOFF = 1e-13
SNES_DEFAULTS = {"snes_linesearch_type": "bt", "snes_rtol": 1e-10, "snes_stol": 1e-9, "snes_max_it": 50}


#: The most iterations a kept Jacobian serves in one step, and the surplus iterations (beyond one a step) it may
#: cost before a fresh one is assembled: a chord iteration (a residual and a triangular solve) costs about 0.2 ms
#: at nx = 5000, a fresh J with its LU factor about ten of them. See `_keeps_jacobian`.
CHORD_ITERATIONS = 3
CHORD_BUDGET = 10

#: The largest integer power that `powers_as_products` writes out as a product.
MAX_PRODUCT_POWER = 8


class _PowersAsProducts(MultiFunction):
    expr = MultiFunction.reuse_if_untouched

    def power(self, o, base, exponent):
        if not isinstance(exponent, IntValue) or not 2 <= int(exponent) <= MAX_PRODUCT_POWER:
            return self.reuse_if_untouched(o, base, exponent)
        product = base
        for _ in range(int(exponent) - 1):
            product = product * base
        return product


def powers_as_products(form):
    """`form` with every integer power f**n (2 ≤ n ≤ MAX_PRODUCT_POWER) written as the product f*f*…*f.

    FFCx compiles f**n to libm's ``pow``, which the C compiler keeps as a call without -ffast-math (only
    ``pow(f, 2)`` becomes a product). Measured at nx = 5000 (timeit, same process): the cubic foundation's
    residual assembly 0.52 -> 0.35 ms, its stored energy (η⁴) 0.39 -> 0.12 ms. So a model writes ``eta**3``
    and the Newton step compiles η·η·η (the same value to round-off; its derivative is then products too).
    """
    return map_integrand_dags(_PowersAsProducts(), form)


class NewtonStep:
    """G(u) = 0 (or the VI with lower bounds) for one scheme's quotients; see the module docstring.

    `quotients` maps "eta", "eta_t", "eta_tt" to functions (u, e0, em, v0, dt) -> the quotient, written so
    that they work on UFL functions and on NumPy arrays alike (e0, em: η^n, η^{n−1}; v0: a nodal velocity);
    "fields" (optional, default "eta"'s): the value of the other fields of a model with several.
    ``lower``: the nodal lower bound of the VI (−inf where free), or None for a plain Newton step.
    `reuse_jacobian` (default True): a step's iterations may keep the Jacobian and its LU factor from an
    earlier step (chord iterations, `_keeps_jacobian`); False gives Newton's fresh Jacobian at every iteration.
    """

    reuse_jacobian = True

    def __init__(self, s, quotients: dict, lower: np.ndarray | None = None):
        nl = s.ops.nonlinear
        Z, n = nl.space, s.n_owned
        self.s, self.n, self.q = s, n, quotients
        self.allsum, self.anyrank = summer(s.comm), any_rank(s.comm)
        self.u, self.e0, self.em, self.v0 = (fem.Function(Z) for _ in range(4))
        self.lumped = s.mass == "lumped"
        args = (self.u, self.e0, self.em, self.v0, s.dt)
        q_eta, q_t, q_tt = (quotients[k](*args) for k in ("eta", "eta_t", "eta_tt"))
        zero = ufl.zero()  # UFL's zero, not a Constant 0: the terms it multiplies leave the compiled kernel
        k = nl.eta.ufl_shape[0] if nl.eta_dofs is not None else 0  # the number of fields, η's among them
        if k:  # several fields: η's inertia is lumped on the nodes, the other fields keep their own η_tt
            zeros = ufl.as_vector([0.0] * k)
            q_fields = quotients.get("fields", quotients["eta"])(*args)  # the other fields' values
            q_eta = ufl.as_vector([q_eta[0], *(q_fields[i] for i in range(1, k))])
            q_tt = ufl.as_vector([0.0, *(q_tt[i] for i in range(1, k))]) if self.lumped else q_tt
        else:
            zeros = zero
            q_tt = zero if self.lumped else q_tt
        mapping = {nl.eta: q_eta, nl.eta_t: q_t, nl.eta_tt: q_tt, nl.force: zero}
        G = powers_as_products(ufl.replace(nl.residual, mapping))
        G_static = powers_as_products(
            ufl.replace(nl.residual, mapping | {nl.eta_t: zeros} | _without_dissipative(s, q_eta, k)))
        self.G = PackedForm(G)  # assembled at least twice a step: its coefficients gathered, not packed again
        self.known = [f for f in self.G.functions if f is not self.u]  # what `_residual` does not refresh
        self.J_form = fem.form(ufl.derivative(G, self.u, ufl.TrialFunction(Z)))
        self.G_static_form = fem.form(G_static)
        self.energy_eta = nl.energy_eta
        self.energy = PackedForm(powers_as_products(nl.stored_energy))
        self.a_tt = float(quotients["eta_tt"](1.0, 0.0, 0.0, 0.0, s.dt))  # ∂q_tt/∂u
        self.G_vec = compat.create_vector(self.G.form)
        self.work_vec = compat.create_vector(self.G.form)
        self.J = fem.petsc.create_matrix(self.J_form)
        self.x = self.G_vec.duplicate()
        # η's entries in the unknowns' (owned) arrays: all of them for one field, a fancy index for several
        self.idx = slice(0, n) if nl.eta_dofs is None else np.asarray(nl.eta_dofs[:n])
        self.bc = s.bc if nl.eta_dofs is None else self.idx[s.bc]
        self.at = _as_slice(self.idx)  # the same entries, as a strided slice where they are one (a blocked space's)
        self.N = self.x.getLocalSize()
        self.diag = self.J.createVecLeft()  # the lumped mass and the damping, added to J's diagonal
        self.m_tt = self.a_tt * s.ops.m if self.lumped else np.zeros(n)
        self.inertia = self.a_tt * s.ops.m
        self.f = np.zeros(n)  # the applied nodal force
        self.viscous_vecs = None  # C's (right, left) vectors for `viscous_force`
        self.d, self.c = np.zeros(n), np.zeros(n)  # an implicit damping d∘(u − c) on the diagonal
        self.nodal_slope, self.nodal_known = np.zeros(n), np.zeros(n)  # G's nodal terms, set by `solve`
        self.arrays = [np.zeros(n) for _ in range(3)]  # η^n, η^{n−1}, v^n (owned)
        self.unsynced = set()  # the known levels not yet in their Functions (`_sync`)
        self.levels = [np.zeros(self.N) for _ in range(4)]  # all fields: η^n, η^{n−1}, v^n, the last solution
        self.iterations, self.solves, self.history = 0, 0, []
        self.jacobians, self.kept, self.fresh_only = 0, False, False  # kept: this solve started from an old J
        self.chord, self.norms = False, []  # chord: the J in use is a kept one; norms: this solve's residual norms
        self.surplus = 0  # the kept J's iterations beyond the first of each step, since it was assembled
        self.age, self.kept_age, self.drift = 0, 0, 0.0  # J's age in steps; r₁/(r₀ × age) when a kept J was last tried
        self.d_in_J = np.zeros(n)  # the damping on J's diagonal when it was assembled
        if lower is not None and nl.eta_dofs is not None:
            full = np.full(self.N, PETSc.NINFINITY)
            full[self.idx] = lower
            lower = full
        self.g = s.g
        lower = self._held_and_bounded(lower)
        self.snes = self._snes(lower)
        self.free = self._snes(None) if lower is not None else None  # a VI's plain Newton step, tried first
        self.try_free, self.free_solves = True, 0
        self.linear = self.quadratic = None  # the linear path (`_linear_path`), the energy as a quadratic form
        if not getattr(s.laws.model, "newton", False) and affine_in(
                ufl.replace(nl.residual, {nl.force: zero}), (nl.eta, nl.eta_t, nl.eta_tt)):
            self._linear_path()

    def _linear_path(self) -> None:
        """A residual affine in the unknowns: G(u) = J u + G(0) with a constant J, so the step is one linear solve
        (`_solve_linear`): J assembled and factorised once (again only when the damping on its diagonal changes),
        G(0) from the residual's constant matrices (`AffineResidual`) by mat-vecs, no assembly and no SNES; the
        ledger's viscous work and a quadratic stored energy (`QuadraticEnergy`) by mat-vecs too. A VI tries this
        step first, as its plain Newton step, and keeps SNES for the steps that touch a bound."""
        s, nl = self.s, self.s.ops.nonlinear
        self.linear = AffineResidual(nl, self.lumped)
        J = fem.petsc.assemble_matrix(self.J_form)
        J.assemble()
        self.diag.set(0.0)
        self.diag.array[self.idx] = self.m_tt
        J.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        dirichlet_rows(J, self.bc)
        if J.getBlockSize() > 1 and s.comm.size == 1 and self.ksp_options.get("pc_type") == "lu":
            # PETSc's own LU of the blocked matrix: its back-substitution by 2 × 2 blocks (two fields, 10⁴
            # unknowns: 53 µs against 142 as AIJ, timeit)
            J = J.convert("baij")
        self.step_solver = DampedLU(J, s.comm, self.ksp_options, self.bc, self.g, s.x.ndim)
        self.rhs, self.work = J.createVecLeft(), np.zeros(self.N)
        self.extra, self.d_lin = np.zeros(self.N), np.zeros(self.n)  # the damping on J's diagonal: all rows, η's
        self.quadratic = QuadraticEnergy.of(nl.stored_energy, self.energy_eta)
        names = getattr(s.laws.model, "dissipative_fields", ())
        fields = getattr(s.laws.model, "fields", ())
        k = nl.eta.ufl_shape[0] if nl.eta_dofs is not None else 1
        self.terms = LevelTerms(self.linear, self.q, s.dt, k, tuple(i + 1 for i, f in enumerate(fields) if f in names),
                                self.quadratic)
        self.linear_solves, self.stale = 0, False  # stale: G_vec does not hold the last solve's residual
        self.solutions, self.returned = [], None  # the last three solutions (values, S's products); η's last one
        self.level_products = [None, None]  # e0's and em's products, when they are one of `solutions`
        self.held = None  # A = ∂R/∂U with η's rows held: the fields given η (`start_fields`, `eta_stiffness`)

    @property
    def guessless(self) -> bool:
        """Whether `solve` reads no guess: the linear path's direct solve, with no VI to fall back to."""
        return self.linear is not None and self.free is None and not self.step_solver.iterative

    def _levels(self, u=None) -> _Levels:
        """The levels u (or None), e0, em, v0 as the forms read them (the unknowns' owned values), each built when
        first read."""
        return _Levels(self, u)

    def _level(self, i: int) -> np.ndarray:
        """Known level i (1: e0, 2: em, 3: v0) as `set_known` last gave it, with the other fields' values."""
        return self._full(self.arrays[i - 1], self.levels[i - 1])

    def _at(self, u: np.ndarray) -> tuple[list, list]:
        """The levels at u (η's owned values) and the products known for them: u's own when u is the solution the
        last solve returned."""
        if u is self.returned:
            values, products = self.solutions[0]
        else:
            values, products = self._full(u, self.levels[3]), None
        return self._levels(values), [products, *self.level_products]

    def _products_of(self, eta: np.ndarray | None, back: int) -> np.ndarray | None:
        """S's products of a known level whose η (owned) is one of the last solutions' (`back` steps back, likely),
        else None: its other fields are that solution's by `set_known`."""
        if eta is None:
            return None
        order = sorted(range(len(self.solutions)), key=lambda i: i != back)
        for i in order:
            values, products = self.solutions[i]
            if np.array_equal(eta, values[self.at]):
                return products
        return None

    def _solve_linear(self, guess: np.ndarray) -> None:
        """The step's root into `x` by one solve: J u = −(G(0) without its nodal terms) + their known part, the ends
        at their heights."""
        rhs = self.rhs.array
        np.negative(self.terms.known(self._levels(), [None, *self.level_products], self.work), out=rhs)
        rhs[self.at] += self.nodal_known
        rhs[self.bc] = self.g
        if self.anyrank(not np.array_equal(self.d, self.d_lin)):  # J's diagonal changes with the damping
            self.extra[self.at] = self.d
            self.extra[self.bc] = 0.0
            self.step_solver.update(self.extra)
            self.d_lin[:] = self.d
        if self.step_solver.iterative:  # its first guess
            x = self.x.array
            x[:] = self._full(guess, self.levels[3])
            x[self.bc] = self.g
        self.step_solver.solve(self.rhs, self.x)
        self.linear_solves += 1
        self.stale = True

    def _linear_residual(self) -> None:
        """G at the last linear solve's x into G_vec, as `_residual` would assemble it (the ends' rows 0)."""
        u = self.x.array
        levels, products = self._at(self.returned)
        G = self.terms.value(levels, products, self.G_vec.array)
        self.nodal_slope[:] = self.d + self.m_tt
        G[self.at] += self.nodal_slope * u[self.at] - self.nodal_known
        G[self.bc] = u[self.bc] - self.g
        self.stale = False

    def _held_rows(self):
        """A = ∂R/∂U with η's rows (and the held fields') identity, factorised (LU): A Z = (η, 0 held, r) gives the
        other fields of η (`start_fields`, `eta_stiffness`). None without the matrix or for a single field."""
        if self.held is None and "eta" in self.linear.matrices and not isinstance(self.idx, slice):
            A = self.linear.matrices["eta"].copy()
            rows = np.union1d(self.idx, self.bc)
            dirichlet_rows(A, rows)
            self.held = Linear(A, self.s.comm, {"ksp_type": "preonly", "pc_type": "lu"}, rows, np.zeros(rows.size),
                               self.s.x.ndim)
            self.held_rows, self.held_b = rows, A.createVecLeft()
        return self.held

    def start_fields(self, eta0: np.ndarray, v0: np.ndarray) -> None:
        """A model's other fields at t = 0, on the linear path: the root of their rows with η = η0, η_t = v0 and their
        own rates 0, as every level the scheme starts from, so that E(0) and the first stored row hold them and
        `newmark`'s midpoint starts from them. The Newton path starts them at 0 (their first values are then
        Newton's first guess, and the first stored row's)."""
        if self.linear is None or self._held_rows() is None:
            return
        rate = np.zeros(self.N)
        rate[self.at] = v0
        b = self.held_b.array
        np.negative(self.linear.apply({"eta_t": rate}, self.work), out=b)
        b[self.held_rows] = 0.0
        b[self.at] = eta0
        self.held.solve(self.held_b, self.x)
        for level in self.levels:
            level[:] = self.x.array

    def eta_stiffness(self) -> PETSc.Mat | None:
        """η's stiffness with the other fields eliminated, the Schur complement S = A_ηη − A_ηf A_ff⁻¹ A_fη of
        A = ∂R/∂U (K + βKM⁻¹K for a field κ with Mκ = Kη and a term βKκ in η's row), as a shell matrix on η's P1 dofs: what an explicit elastic step
        sees. None off the linear path or for a single field (η's own K)."""
        if self.linear is None or self._held_rows() is None:
            return None
        n = self.n
        S = PETSc.Mat().createPython(((n, PETSc.DECIDE), (n, PETSc.DECIDE)), _SchurComplement(self), comm=self.s.comm)
        S.setUp()
        return S

    def _held_and_bounded(self, lower):
        """A model's other fields held at 0 on the boundary (`Model.held_fields`: their rows join η's ends in
        `bc`, their values in `g`) and bounded below (`Model.field_lower`: the step becomes the VI)."""
        s, nl = self.s, self.s.ops.nonlinear
        model = s.laws.model
        if nl.eta_dofs is None:
            return lower
        dofs = {name: compat.sub_dofs(nl.V, nl.space, i + 1)[: self.n] for i, name in enumerate(model.fields)}
        for name in getattr(model, "held_fields", ()):
            self.bc = np.concatenate([self.bc, dofs[name][s.bc]])
            self.g = np.concatenate([self.g, np.zeros(len(s.bc))])
        bounds = model.field_lower(nl.params) if getattr(model, "field_lower", None) is not None else {}
        if bounds and lower is None:
            lower = np.full(self.N, PETSc.NINFINITY)
        for name, value in bounds.items():
            lower[dofs[name]] = value
        return lower

    def _snes(self, lower):
        s = self.s
        snes = PETSc.SNES().create(s.comm)
        snes.setFunction(self._residual, self.G_vec)
        snes.setJacobian(self._jacobian, self.J)
        options = solver_options(self.J.getSize()[0], s.comm.size, s.petsc_options, dim=s.x.ndim)
        # s.petsc_options hold the model's defaults (`Model.solver`) below the user's, merged once by the run
        options = {"snes_type": "vinewtonrsls" if lower is not None else "newtonls"} | SNES_DEFAULTS | options
        set_from_options(snes, PREFIX, options)
        # the linear solver's options held again while SNES solves: its KSP reads some at set-up (`options_held`)
        self.ksp_options = {k: v for k, v in options.items() if not k.startswith("snes_")}
        if lower is not None:
            lo, hi = self.x.duplicate(), self.x.duplicate()
            lo.array[:] = lower
            hi.set(PETSc.INFINITY)
            snes.setVariableBounds(lo, hi)
            self.bounds = (lo, hi)
        snes.setConvergenceHistory(reset=True)
        return snes

    def set_lower(self, lower: np.ndarray) -> None:
        """η's lower bound of the VI, for the next solve (a restitution moves it every step)."""
        self.bounds[0].array[self.idx] = lower

    # -- the state the forms read

    def _set(self, f: fem.Function, a: np.ndarray) -> None:
        f.x.array[: a.size] = a
        f.x.scatter_forward()

    def _full(self, eta: np.ndarray, rest: np.ndarray) -> np.ndarray:
        """η's values in the unknowns' array, the other fields' from `rest` (η itself for one field)."""
        if isinstance(self.idx, slice):
            return eta
        full = rest.copy()
        full[self.at] = eta
        return full

    def set_known(self, e0, em=None, v0=None) -> None:
        """The known levels η^n, η^{n−1} and the velocity v^n (owned arrays) into the forms; once per step. Several
        fields: theirs are the last two solutions (and their difference quotient)."""
        levels = self.levels
        if not isinstance(self.idx, slice):  # (by reference: `_accept` puts each solution in an array of its own)
            levels[1], levels[0] = levels[0], levels[3]
            if v0 is not None:
                levels[2] = (levels[0] - levels[1]) / self.s.dt
        for i, (a, keep) in enumerate(zip((e0, em, v0), self.arrays)):
            if a is not None:
                keep[:] = a
                self.unsynced.add(i)
        if self.linear is None:
            self._sync()
        else:  # the forms read them only if SNES solves a step (`_sync`)
            self.level_products = [self._products_of(e0, 0), self._products_of(em, 1)]

    def _sync(self) -> None:
        """The known levels `set_known` was given into the forms' Functions (all the unknowns' values)."""
        functions = (self.e0, self.em, self.v0)
        for i in self.unsynced:
            values = functions[i].x.array
            if not isinstance(self.idx, slice):
                values[: self.N] = self.levels[i]
            values[self.at] = self.arrays[i]
            functions[i].x.scatter_forward()
        self.unsynced.clear()

    def residual_at(self, u: np.ndarray, form=None) -> np.ndarray:
        """The assembled residual (`form`: the compiled G by default) at u, η's owned dofs, no force, no ends."""
        self._sync()
        self._set(self.u, self._full(u, self.levels[3]))
        vec = self.work_vec
        with vec.localForm() as local:
            local.set(0.0)
        if form is None:
            self.G.refresh(self.u)
            self.G.assemble_vector(vec)
        else:
            fem.petsc.assemble_vector(vec, form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        r = vec.array[self.idx].copy()
        if self.lumped:
            r += self.s.ops.m * self.q["eta_tt"](u, *self.arrays, self.s.dt)
        return r

    def last_residual(self, u: np.ndarray) -> np.ndarray:
        """`residual_at(u)` for the u that `solve` just returned, without assembling: SNES's last residual (the linear
        path's, by mat-vecs) with the force and the damping taken out again (the ends' rows hold u − g there, 0)."""
        if self.stale:
            self._linear_residual()
        r = self.G_vec.array[self.at].copy()
        r += self.f
        r -= self.d * (u - self.c)
        return r

    def viscous_force(self, u: np.ndarray) -> np.ndarray:
        """The η_t-dependent part of the residual at u, R(q_η, q_t) − R(q_η, 0): C q_t(u) by one mat-vec when
        ∂R/∂η_t is constant, else two assemblies."""
        if self.s.ops.nonlinear.viscous_linear:
            if self.viscous_vecs is None:
                self.viscous_vecs = self.s.ops.C.createVecs()
            q_t, out = self.viscous_vecs
            q_t.array[:] = self.q["eta_t"](u, *self.arrays, self.s.dt)
            self.s.ops.C.mult(q_t, out)
            return out.array.copy()
        if self.linear is not None:  # ∂R/∂U_t q_t, and ∂R/∂U on the dissipative fields' values: kept products
            return self.terms.viscous(*self._at(u), self.at)
        return self.residual_at(u) - self.residual_at(u, self.G_static_form)

    def stored_energy(self, eta: np.ndarray) -> float:
        """∫Π(η) on this rank's cells (the caller sums over the ranks); several fields: ∫Π(η, *fields), the fields
        of the last solve."""
        if self.quadratic is not None:
            levels, products = self._at(eta)
            return self.terms.stored(levels[0], products[0])
        self._set(self.energy_eta, self._full(eta, self.levels[3]))
        self.energy.refresh()
        return self.energy.assemble_scalar()

    # -- SNES callbacks

    # SNES hands the callbacks x locked for reading (PETSc 3.22, trixie): read it through array_r, never array.
    def _residual(self, snes, x, G) -> None:
        u = x.array_r
        self._set(self.u, u)
        self.G.refresh(self.u)
        with G.localForm() as local:
            local.set(0.0)
        self.G.assemble_vector(G)
        G.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        g = G.array
        nodal = self.nodal_slope * u[self.idx]
        nodal -= self.nodal_known
        g[self.idx] += nodal
        g[self.bc] = u[self.bc] - self.g

    def _jacobian(self, snes, x, J, P) -> None:
        if self._keeps_jacobian(snes):
            self._update_damping(J)
            return
        self._set(self.u, x.array_r)
        J.zeroEntries()
        fem.petsc.assemble_matrix(J, self.J_form)
        J.assemble()
        diag = self.diag.array
        diag[self.idx] = self.d + self.m_tt
        J.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        dirichlet_rows(J, self.bc)  # identity rows; the guess holds the ends, so their columns need no lift
        self.d_in_J[:] = self.d
        self.jacobians += 1
        self.age = self.surplus = 0

    def _keeps_jacobian(self, snes) -> bool:
        """Whether the last J (and its LU factor), from an earlier step, serves this iteration; the caller then
        leaves J untouched, so PETSc keeps its factor. A kept J contracts the residual by a rate ρ per iteration
        (a chord iteration) where a fresh one converges quadratically, but its iteration costs a residual and a
        triangular solve, about a tenth of assembling and factorising J at nx = 5000 (CHORD_BUDGET). So it is kept while
        it is predicted to reach what Newton stops at within CHORD_ITERATIONS iterations: at the first
        iteration with ρ = drift × age (drift: r₁/(r₀ × age) when a kept J was last tried, halved at each step
        that did not try one, so that one bad step, an active set that changes, does not stop the reuse for
        good), at later ones with the rate just seen; and while the iterations it cost beyond one a step stay
        below CHORD_BUDGET, the cost of a fresh J (the rent-or-buy rule: at most twice the better of the two).
        Once J is fresh, it stays fresh (Newton's own iterations)."""
        it = snes.getIterationNumber()
        if it == 0:
            self.chord, self.norms = False, []
        self.norms.append(snes.getFunctionNorm())
        if (not self.reuse_jacobian or self.fresh_only or self.jacobians == 0 or (it and not self.chord)
                or self.surplus >= CHORD_BUDGET):
            return False
        r = self.norms
        rtol, atol = snes.getTolerances()[:2]
        stop = max(atol, rtol * r[0])
        if it == 0:
            self.kept_age = max(self.age, 1)  # 0: assembled in this step, by a VI's plain Newton step
            self.kept = self.chord = (self.drift * self.kept_age) ** CHORD_ITERATIONS * r[0] < stop
            if not self.kept:
                self.drift *= 0.5
            return self.chord
        rate = r[it] / r[it - 1] if r[it - 1] > 0 else 0.0
        self.chord = it < CHORD_ITERATIONS and rate ** (CHORD_ITERATIONS - it) * r[it] < stop
        self.surplus += self.chord
        return self.chord

    def _update_damping(self, J) -> None:
        """A kept J with the step's damping d on its diagonal: the change since J was assembled, added (a new
        factor then, but no assembly); nothing when d has not changed on any rank."""
        change = self.d - self.d_in_J
        if not self.anyrank(bool(np.any(change))):
            return
        self.diag.set(0.0)
        self.diag.array[self.idx] = change
        self.diag.array[self.bc] = 0.0
        J.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        J.assemble()
        self.d_in_J[:] = self.d

    def solve(self, guess: np.ndarray) -> np.ndarray:
        """The root from `guess` (η; the ends set to their heights, the other fields from their last solution);
        η's owned values. SolverError if SNES fails.

        A VI first tries the plain Newton step when the last step's solution touched no bound: if that root
        respects the bounds it is the VI's solution. (SNES VI builds and factorises its inactive rows' matrix
        again at every iteration, ordering included: 2.2 of a 3.5 ms step at nx = 5000.)

        On the linear path (an affine residual, `_linear_path`) that step is one linear solve, without SNES."""
        self.age += 1
        # the nodal terms of G, affine in u: d∘(u − c) − f (+ m∘q_tt(u), lumped) = slope∘u − known (the slope is
        # on the linear path's J already)
        if self.linear is None:
            self.nodal_slope[:] = self.d + self.m_tt
        self.nodal_known[:] = self.d * self.c + self.f
        if self.lumped:
            self.nodal_known -= self.s.ops.m * self.q["eta_tt"](0.0, *self.arrays, self.s.dt)
        x = self.x.array
        if self.linear is not None and (self.free is None or self.try_free):
            self._solve_linear(guess)
            if self.free is None or not self.anyrank(bool(np.any(x < self.bounds[0].array))):
                self.free_solves += self.free is not None
                return self._accept()
        # The residual's round-off floor: ROUNDOFF × the inertia term's norm (its largest term). An rtol below it
        # (a good predictor) would stall at the floor (2.6e-9 against 2.4e-9 asked at nx = 5000).
        if "snes_atol" not in (self.s.petsc_options or {}):  # the user's wins
            inertia = self.inertia * guess
            floor = max(ROUNDOFF * math.sqrt(self.allsum(float(np.dot(inertia, inertia)))[0]), 1e-50)
            for snes in (self.snes, self.free) if self.free is not None else (self.snes,):
                snes.setTolerances(atol=floor)
        self._sync()
        if self.linear is not None:
            self.nodal_slope[:] = self.d + self.m_tt
        if self.known:  # the known levels and any field that moved with the step (an obstacle ψ(x, t))
            self.G.refresh(*self.known)
        self.stale = False  # SNES's residual in G_vec
        if self.free is not None and self.try_free and self.linear is None:
            reason = self._run(self.free, guess)
            if reason >= 0 and not self.anyrank(bool(np.any(x < self.bounds[0].array))):
                self.free_solves += 1
                return self._accept()
        reason = self._run(self.snes, guess)
        if reason < 0:
            raise SolverError(f"Newton did not converge (SNES reason {reason}) after {self.snes.getIterationNumber()} "
                              "iterations; use a smaller dt or petsc_options snes_max_it / snes_linesearch_type")
        if self.free is not None:
            self.try_free = not self.anyrank(bool(np.any(x <= self.bounds[0].array)))
        return self._accept()

    def _run(self, snes, guess: np.ndarray) -> int:
        """One SNES solve from `guess`, again with a fresh J at every iteration if a kept J led it astray; its
        converged reason."""
        x = self.x.array
        for fresh in (False, True):
            x[:] = self._full(guess, self.levels[3])
            x[self.bc] = self.g
            self.kept, self.fresh_only = False, fresh
            try:
                with options_held(PREFIX, self.ksp_options):
                    snes.solve(None, self.x)
            finally:
                self.fresh_only = False
            reason = snes.getConvergedReason()
            self.iterations += snes.getIterationNumber()
            self.history = list(snes.getConvergenceHistory()[0])
            if self.kept and len(self.history) > 1 and self.history[0] > 0:
                self.drift = self.history[1] / (self.history[0] * self.kept_age)
            if reason >= 0 or not self.kept:
                return reason
        return reason

    def _accept(self) -> np.ndarray:
        self.solves += 1
        self.levels[3] = self.x.array.copy()  # a new array: `set_known` passes it on by reference
        eta = self.x.array[self.at].copy()
        if self.linear is not None:  # S's products of the solution: its ledger's, the next two steps' known part
            self.solutions = [(self.levels[3], self.terms.products(self.levels[3]))] + self.solutions[:2]
            self.returned = eta
        return eta

    def field(self, i: int) -> np.ndarray:
        """Field `i` (0 is η) of the last solution, at the nodes of η's owned dofs."""
        nl = self.s.ops.nonlinear
        if nl.eta_dofs is None:
            return self.levels[3].copy()
        return self.levels[3][compat.sub_dofs(nl.V, nl.space, i)[: self.n]]

    def describe(self) -> dict:
        """Newton's counters for the summary."""
        if self.linear is not None:
            refactored = self.step_solver.refactorisations
            how = (f"none: the residual is affine, {self.linear_solves} linear solves for {self.solves} steps with J "
                   f"factorised once" + (f" and again {refactored} times for the damping" if refactored else ""))
            if self.free is not None:
                how += (f"; {self.solves - self.free_solves} contact steps by SNES {self.snes.getType()}, "
                        f"{self.iterations} Newton iterations")
            return {"newton iterations": self.iterations, "jacobian assemblies": self.jacobians,
                    "linear solves": self.linear_solves, "nonlinear solver": how}
        per_step = self.iterations / self.solves if self.solves else 0.0
        free = f", {self.free_solves} of {self.solves} steps solved without the VI" if self.free is not None else ""
        return {"newton iterations": self.iterations, "jacobian assemblies": self.jacobians,
                "nonlinear solver": f"SNES {self.snes.getType()}, {per_step:.3g} Newton iterations per step{free}"}


class _Levels:
    """The levels u, e0, em, v0 of `NewtonStep._levels`, each built when first read (`NewtonStep._level`)."""

    def __init__(self, step: NewtonStep, u):
        self.step, self.values = step, [u, None, None, None]

    def __getitem__(self, i: int) -> np.ndarray:
        if self.values[i] is None:
            self.values[i] = self.step._level(i)
        return self.values[i]


class _SchurComplement:
    """The shell `NewtonStep.eta_stiffness`: y = S x = (A Z)_η with Z = (x, the other fields solved for x)."""

    def __init__(self, step: NewtonStep):
        self.step = step
        self.A = step.linear.matrices["eta"]
        self.X, self.Z = step.held_b.duplicate(), step.held_b.duplicate()
        self.AZ = self.A.createVecLeft()

    def mult(self, mat, x, y) -> None:
        step = self.step
        X = self.X.array
        X[:] = 0.0
        X[step.idx] = x.array_r
        step.held.solve(self.X, self.Z)
        self.A.mult(self.Z, self.AZ)
        y.array[:] = self.AZ.array[step.idx]


def _without_dissipative(s, q_eta, k: int) -> dict:
    """The model's dissipative fields (`Model.dissipative_fields`) at 0 in η's value: their work on η is then
    in the viscous work, as the η_t-dependent terms' (a lubricating fluid's)."""
    model = s.laws.model
    names = getattr(model, "dissipative_fields", ())
    if not k or not names:
        return {}
    kept = [q_eta[i] if i == 0 or model.fields[i - 1] not in names else 0.0 for i in range(k)]
    return {s.ops.nonlinear.eta: ufl.as_vector(kept)}


class _NewtonScheme(Base):
    """What the three schemes' Newton steps share: the stored energy summed over the ranks, the counters."""

    energy_may_rise = True

    @property
    def fields(self) -> dict:
        """A model's other fields (`Model.fields`) by name, at η's owned nodes, from the last solve ({} for one
        field). `paper` and `newmark` report them with the η they solved for; `projection` reports its η one step
        behind its solve, so its fields would be a step ahead of its η (a model may refuse it: `Model.schemes`)."""
        return {name: self.newton.field(i + 1) for i, name in enumerate(self.s.laws.model.fields)}

    def _stored(self, eta) -> float:
        return self.newton.stored_energy(eta)

    @property
    def timings(self):
        return self.newton.describe()


# --- paper: implicit Euler in η, the force from the previous step -----------------------------------------


PAPER = {
    "eta": lambda u, e0, em, v0, dt: u,
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: (u - 2 * e0 + em) / dt**2,
}


class PaperStep(_NewtonScheme):
    """The paper's Section 6 scheme for a nonlinear model: η and η_t implicit, the penalty explicit (or
    semi-implicit: d v^{n+1} on the diagonal), the mass lumped or consistent. Energy: the module docstring,
    with the kinetic energy ½|v^{n+1}|²_M, δ = η^{n+1} − η^n and the contact work −(Δt/2) f·(v^n + v^{n+1}).
    A moving obstacle ψ(x, t), as on the linear path (paper.py): the law's fields at t^n; the semi-implicit
    damping brakes the step's gap rate, centre c = η^n + ψ^{n+1} − ψ^n, and a node it would hold down is released
    (`_release`); the obstacle's share ½ f·(ψ^{n+1} − ψ^{n−1}) of the force's work is external work."""

    def __init__(self, s):
        super().__init__(s)
        laws = s.laws
        if s.penalty == "semi-implicit" and laws.model.penalty_damping is None:
            raise ValueError(f"model '{laws.model.name}' has no penalty_damping, so it has no semi-implicit penalty")
        check_law_stability(laws.model, s.dt, s.eps, s.penalty)
        law = laws.model.penalty if s.penalty == "explicit" else laws.model.penalty_damping
        self.force_law = laws.compile(law(laws.eta, laws.quotient, laws.params))
        self.newton = NewtonStep(s, PAPER)
        self.allsum, self.anysum = summer(s.comm), any_rank(s.comm)
        n = s.n_owned
        self.eta_, self.old, self.v = np.zeros(n), np.zeros(n), np.zeros(n)
        self.older = None
        self.moving, self.k = s.obstacle is not None, 0  # a moving obstacle ψ(x, t); the step index
        self.inv_mF = np.divide(1.0, s.ops.m_force, out=np.zeros(n), where=s.ops.m_force > 0)
        self.force_density = np.zeros(n)

    @property
    def eta(self):
        return self.eta_

    @property
    def velocity(self):
        return self.v

    @property
    def contact_force(self):
        return self.force_density

    def _kinetic(self, v) -> float:
        if self.s.mass == "lumped":
            return 0.5 * float(np.dot(v, self.s.ops.m * v))
        out = self.s.ops.M.createVecLeft()
        self.s.ops.M.mult(wrap(v, self.s.comm), out)
        return 0.5 * float(np.dot(v, out.array))

    def start(self, eta0, v0):
        s = self.s
        if self.moving:  # ψ^{−1}, ψ^0; the law's fields at t = 0
            self.psi_levels = [s.obstacle.owned(-s.dt).copy(), s.obstacle.set(0.0).copy()]
        self.eta_[:], self.v[:] = eta0, v0
        self.old[:] = eta0 - s.dt * self.v
        self.newton.start_fields(eta0, v0)
        kin, el = self.allsum(self._kinetic(self.v), self._stored(self.eta_))
        self.E = kin + el
        self._force()
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def _force(self) -> None:
        """The law at (η^n, η^{n−1}): the explicit force density (0 where no force acts), or the damping weights."""
        laws = self.s.laws
        laws.set(eta=self.eta_, eta_old=self.old)
        law = np.asarray(self.force_law.evaluate_env(laws.env), dtype=float) * np.ones(self.s.n_owned)
        self.law = law * self.s.interior
        if self.s.penalty == "explicit":
            np.multiply(self.law, self.inv_mF > 0, out=self.force_density)

    def step(self):
        s, dt, nw = self.s, self.s.dt, self.newton
        e0, em = self.eta_, self.old
        nw.set_known(e0, em)
        # a moving obstacle: the semi-implicit damping brakes the step's gap rate, v^{n+1} − (ψ^{n+1} − ψ^n)/Δt
        dpsi = s.obstacle.owned((self.k + 1) * dt) - self.psi_levels[1] if self.moving else 0.0
        if s.penalty == "explicit":
            nw.f[:] = s.ops.m_force * self.law
        else:  # F = −d (v^{n+1} − Δψ/Δt): (m_F d/Δt)(u − η^n − Δψ) on the diagonal
            nw.d[:] = s.ops.m_force * self.law / dt
            nw.c[:] = e0 + dpsi
        # η extrapolated quadratically: a smaller first residual, so that a kept Jacobian serves more steps; past a
        # sudden stop (a landing through a lubricating layer at nx = 200 lands in one step) that guess overshoots and Newton diverges from it:
        # then from the linear one
        if nw.guessless:  # the linear path's one direct solve
            u = nw.solve(None)
        else:
            linear = 2 * e0 - em
            try:
                u = nw.solve(3 * e0 - 3 * em + self.older if self.older is not None else linear)
            except SolverError:
                if self.older is None:
                    raise
                u = nw.solve(linear)
        if self.moving and s.penalty != "explicit":
            u = self._release(u)
        self.older = em.copy()
        v1 = (u - e0) / dt
        f = nw.f if s.penalty == "explicit" else nw.d * (nw.c - u)
        delta = u - e0
        visc_vec = nw.viscous_force(u)
        work = self._obstacle_work(f)  # (and the law's fields to t^{n+1})
        kin, el, visc, con, ext, work = self.allsum(
            self._kinetic(v1), self._stored(u), float(np.dot(visc_vec * s.interior, delta)),
            -0.5 * dt * float(np.dot(f, self.v + v1)), float(np.dot(s.ops.load, delta)), work)
        num = self.E - (kin + el) - visc - con + ext
        con, ext = con + work, ext + work  # the obstacle's share of the force's work: external, not dissipated
        self.E = kin + el
        if s.penalty != "explicit":
            self.force_density[:] = f * self.inv_mF
        self.old[:], self.eta_[:], self.v[:] = e0, u, v1
        self._force()
        return StepEnergy(kin, el, visc, con, num, ext, 0.0)

    def _release(self, u: np.ndarray) -> np.ndarray:
        """A moving obstacle under the semi-implicit penalty: a damping that would hold a node down (u above the
        centre η^n + Δψ, F < 0: an obstacle that stops under a string it lifted) is released and the step solved
        again from u, as on the linear path. The kept Jacobian takes the change of d on its diagonal
        (`NewtonStep._update_damping`); the centre c enters only the residual."""
        nw = self.newton
        while self.anysum(bool(np.any(sticky := (nw.d > 0) & (u > nw.c)))):
            nw.d[sticky] = 0.0
            u = nw.solve(u)
        return u

    def _obstacle_work(self, f: np.ndarray) -> float:
        """A moving obstacle's share ½ f·(ψ^{n+1} − ψ^{n−1}) of the force's work (this rank's), with the law's
        fields moved to t^{n+1} (the next step's law, the stored row's force); 0 for an obstacle at rest."""
        if not self.moving:
            return 0.0
        self.k += 1
        psi_new = self.s.obstacle.set(self.k * self.s.dt).copy()
        work = 0.5 * float(np.dot(f, psi_new - self.psi_levels[0]))
        self.psi_levels = [self.psi_levels[1], psi_new]
        return work


# --- projection: central differences, η explicit, the contact step a variational inequality ---------------


PROJECTION = {
    "eta": lambda u, e0, em, v0, dt: e0,
    "fields": lambda u, e0, em, v0, dt: u,  # the other fields implicit: an algebraic one is solved, not lagged
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: (u - 2 * e0 + em) / dt**2,
}


class ProjectionStep(_NewtonScheme):
    """`projection` for a nonlinear model: the elastic term explicit (η → η^n), η_t implicit, lumped mass, and
    the step the VI G(u) ⊥ u − ψ ≥ 0 by SNES ``vinewtonrsls``. The contact force is the reaction G(u) on the
    active set (≥ 0, 0 elsewhere). With a restitution e > 0 (Paoli-Schatzman, as on the linear path) the bound is
    on the weighted position, (u + e η^{n−1})/(1 + e) ≥ ψ, that is u ≥ (1 + e)ψ − e η^{n−1}. Energy at the half step: kinetic ½|(η^{n+1} − η^n)/Δt|²_m, stored
    ½(Π(η^{n+1}) + Π(η^n)), δ = (η^{n+1} − η^{n−1})/2, contact −½ F·(η^{n+1} − η^{n−1}) as on the linear path.
    The stored velocity is centred, so the scheme reports one step behind the one it computes, as `projection`.
    The stable Δt is the linear path's bound for the tangent at η = 0. `projection` hands over its
    `largest_stable_dt`, its obstacle from the model's gap and its contact tolerance (no import circle)."""

    def __init__(self, s, largest_stable_dt, obstacle, contact_tol: float):
        super().__init__(s)
        self.contact_tol = contact_tol
        self.dt_max = largest_stable_dt(s.ops, s.interior, krylov=s.x.ndim == 2, dt=s.dt)
        if s.dt > self.dt_max * (1 + 1e-12):
            raise InstabilityError(
                f"scheme 'projection' is unstable with dt = {s.dt:.6g} > dt_max = {self.dt_max:.6g} (its explicit "
                f"elastic term, linearised at eta = 0); use nt >= {math.ceil(s.dt * s.nt / self.dt_max)} or scheme "
                "'paper' or 'newmark'", step=0, time=0.0)
        laws = s.laws
        self.gap = laws.compile(laws.model.gap(laws.eta, laws.params))
        self.psi = obstacle(self)
        lower = np.where(s.interior, self.psi, PETSc.NINFINITY)
        self.newton = NewtonStep(s, PROJECTION, lower=lower)
        self._check_fields_stiffness(largest_stable_dt)
        self.allsum, self.anysum = summer(s.comm), any_rank(s.comm)
        n = s.n_owned
        self.etas = [np.zeros(n) for _ in range(4)]  # [next, ahead, now, before]
        self.forces = [np.zeros(n) for _ in range(4)]
        self.inv_mF = np.divide(1.0, s.ops.m_force, out=np.zeros(n), where=s.ops.m_force > 0)
        self.v0 = None
        self.e = s.restitution
        self.moving, self.k = s.obstacle is not None, 0  # a moving obstacle: ψ^{k+1} in each step's bounds

    def _check_fields_stiffness(self, largest_stable_dt) -> None:
        """A model whose other fields add to η's stiffness (a fourth-order term through η's second derivative:
        K + βKM⁻¹K) has them explicit here too (their rows read η^n): its stable Δt is that of η's stiffness with the
        fields eliminated (`NewtonStep.eta_stiffness`, on the linear path), a smaller one than the fields-at-0
        tangent's checked above."""
        s = self.s
        S = self.newton.eta_stiffness()
        if S is None:
            return
        if s.x.ndim == 2:  # no Gershgorin bound or SLEPc copy of a shell: its top mode by SLEPc on the shell
            lam, phi = top_mode_of_shell(S, s.ops.m, s.interior)
            self.dt_max = min(self.dt_max, dt_of_mode(lam, phi, S, s.ops.C))
        else:  # a string: power iteration from the alternating mode, as for K
            self.dt_max = min(self.dt_max, largest_stable_dt(dataclasses.replace(s.ops, K=S), s.interior))
        if s.dt > self.dt_max * (1 + 1e-12):
            raise InstabilityError(
                f"scheme 'projection' is unstable with dt = {s.dt:.6g} > dt_max = {self.dt_max:.6g} (its explicit "
                f"elastic term with the model's fields {', '.join(s.laws.model.fields)}); use nt >= "
                f"{math.ceil(s.dt * s.nt / self.dt_max)} or scheme 'paper' or 'newmark'", step=0, time=0.0)

    def _move_to(self, k: int) -> np.ndarray:
        """A moving obstacle's ψ^k = −gap(0) with the fields at t = kΔt into the VI's lower bound; returns it."""
        s, laws = self.s, self.s.laws
        s.obstacle.set(k * s.dt)
        psi = -np.asarray(self.gap.evaluate_env(laws.env | {id(laws.eta): np.zeros(s.n_owned)}), dtype=float)
        self.psi[:] = psi
        self.newton.set_lower(np.where(s.interior, self.psi, PETSc.NINFINITY))
        return self.psi.copy()

    @property
    def eta(self):
        return self.etas[2]

    @property
    def velocity(self):
        if self.v0 is not None:
            return self.v0
        return (self.etas[1] - self.etas[3]) / (2.0 * self.s.dt)

    @property
    def contact_force(self):
        return self.forces[2]

    def contact(self) -> np.ndarray:
        laws = self.s.laws
        if self.moving:  # the obstacle where the reported level is, one step behind the computed one
            self.s.obstacle.set((self.k - 1) * self.s.dt)
        laws.set(eta=self.eta)
        return self._contact_law.evaluate_env(laws.env)

    def start(self, eta0, v0):
        s, laws = self.s, self.s.laws
        scale = max(float(s.comm.allreduce(np.max(np.abs(eta0), initial=0.0), op=MPI.MAX)),
                    float(np.max(np.abs(s.g), initial=0.0)), 1e-300)
        if self.moving:  # ψ^{−1}, ψ^0; the heights the obstacle carries the string to count in the contact tolerance
            scale = max(scale, s.comm.allreduce(float(np.max(np.abs(self._move_to(s.nt)[s.interior]), initial=0.0)),
                                                op=MPI.MAX))
            self.psi_levels = [self._move_to(-1), self._move_to(0)]
        self.tol = self.contact_tol * scale
        tol = fem.Constant(laws.eta.function_space.mesh, PETSc.ScalarType(self.tol))
        self._contact_law = laws.compile(laws.model.contact_set(laws.eta - tol, laws.params))
        ahead, now = self.etas[1], self.etas[2]
        ahead[:] = eta0
        below = s.interior & (ahead < self.psi)
        ahead[below] = self.psi[below]
        now[:] = ahead - s.dt * v0
        if self.moving:  # η^{−1} = η^0 − Δt v0 is no state of the string: its gap counts as ≥ 0 (the first D_con ≥ 0)
            np.minimum(self.psi_levels[0], now, out=self.psi_levels[0])
        d = (ahead - now) / s.dt
        self.newton.start_fields(ahead, v0)
        self.stored_ahead = self._stored(ahead)  # the next step's Π(η^n), this rank's share
        kin, el = self.allsum(0.5 * float(np.dot(d, s.ops.m * d)), 0.5 * (self.stored_ahead + self._stored(now)))
        self.E = kin + el
        self.pending = self._advance()
        self.v0 = np.array(v0, dtype=float)
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def step(self):
        reported, self.pending = self.pending, self._advance()
        self.v0 = None
        return reported

    def _advance(self):
        s, dt, nw = self.s, self.s.dt, self.newton
        e0, em = self.etas[1], self.etas[2]
        if self.moving:  # ψ^{k+1}; the obstacle's work ½ F·(ψ^{k+1} − ψ^{k−1}) is booked as external work
            self.k += 1
            psi_before, psi_new = self.psi_levels[0], self._move_to(self.k)
            self.psi_levels = [self.psi_levels[1], psi_new]
        nw.set_known(e0, em)
        lower = (1 + self.e) * self.psi - self.e * em if self.e else self.psi
        if self.e:
            nw.set_lower(np.where(s.interior, lower, PETSc.NINFINITY))
        u = nw.solve(np.maximum(2 * e0 - em, np.where(s.interior, lower, -np.inf)))
        r = nw.last_residual(u)  # G(u) without the force: the reaction where u sits on its bound
        active = s.interior & (u <= lower + self.tol)
        F = np.where(active, np.maximum(r, 0.0), 0.0)
        delta = 0.5 * (u - em)
        work = 0.5 * float(np.dot(F, psi_new - psi_before)) if self.moving else 0.0  # the obstacle's share of F's work
        visc_vec = nw.viscous_force(u)
        d = (u - e0) / dt
        stored_e0, self.stored_ahead = self.stored_ahead, self._stored(u)  # Π(η^n) assembled last step, as its Π(u)
        kin, el, visc, con, ext = self.allsum(
            0.5 * float(np.dot(d, s.ops.m * d)), 0.5 * (self.stored_ahead + stored_e0),
            float(np.dot(visc_vec * s.interior, delta)), -float(np.dot(F, delta)) + work, float(np.dot(s.ops.load, delta)) + work)
        num = self.E - (kin + el) - visc - con + ext
        self.E = kin + el
        new = self.etas[0]
        new[:] = u
        self.forces[0][:] = F * self.inv_mF
        self.etas = [self.etas[3], new, e0, em]
        self.forces = [self.forces[3], self.forces[0], self.forces[1], self.forces[2]]
        return StepEnergy(kin, el, visc, con, num, ext, 0.0)


# --- newmark: the trapezoidal rule, the midpoint in η -----------------------------------------------------


NEWMARK = {
    "eta": lambda u, e0, em, v0, dt: (u + e0) / 2,
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: 2 * (u - e0) / dt**2 - 2 * v0 / dt,
}


class NewmarkStep(_NewtonScheme):
    """`newmark` for a nonlinear model: v^{n+1} = 2(η^{n+1} − η^n)/Δt − v^n, η_tt → (v^{n+1} − v^n)/Δt,
    η_t → (v^{n+1} + v^n)/2, η → (η^{n+1} + η^n)/2 (the midpoint: the trapezoidal rule of a linear model), the
    semi-implicit penalty −D v^{n+1} on the diagonal, with the same release of nodes it would hold down.
    Energy: kinetic ½|v^{n+1}|²_M, δ = η^{n+1} − η^n, contact −(Δt/2) f·(v^n + v^{n+1}). A moving obstacle
    ψ(x, t), as on the linear path (newmark.py): the law reads the centred ψ_t^n, the damping brakes
    v^{n+1} − ψ_t^{n+1}, and the obstacle's work f·(ψ^{n+1} − ψ^n) is external work."""

    def __init__(self, s):
        super().__init__(s)
        laws = s.laws
        check_law_stability(laws.model, s.dt, s.eps, s.penalty)
        self.damping = laws.compile(laws.model.penalty_damping(laws.eta, laws.v, laws.params))
        self.newton = NewtonStep(s, NEWMARK)
        self.allsum, self.anysum = summer(s.comm), any_rank(s.comm)
        n = s.n_owned
        self.eta_, self.v, self.v_old = np.zeros(n), np.zeros(n), np.zeros(n)
        self.force_density = np.zeros(n)
        self.moving, self.k = s.obstacle is not None, 0  # a moving obstacle ψ(x, t); the step index

    eta = property(lambda self: self.eta_)
    velocity = property(lambda self: self.v)
    contact_force = property(lambda self: self.force_density)
    _kinetic = PaperStep._kinetic

    def start(self, eta0, v0):
        if self.moving:
            self.s.obstacle.set_centred(0.0)
        self.eta_[:], self.v[:], self.v_old[:] = eta0, v0, v0
        self.newton.start_fields(eta0, v0)
        kin, el = self.allsum(self._kinetic(self.v), self._stored(self.eta_))
        self.E = kin + el
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def step(self):
        s, dt, nw = self.s, self.s.dt, self.newton
        e0, v = self.eta_, self.v
        nw.set_known(e0, None, v)
        s.laws.set(eta=e0, v=v)
        D = np.asarray(self.damping.evaluate_env(s.laws.env), dtype=float) * s.interior * s.ops.m_force
        rate = s.obstacle.centred_rate((self.k + 1) * dt)[: s.n_owned] if self.moving else 0.0  # ψ_t^{n+1}: D brakes v − ψ_t
        while True:  # −D (v^{n+1} − ψ_t^{n+1}) = −(2D/Δt)(u − η^n − (Δt/2)(v^n + ψ_t^{n+1}))
            nw.d[:], nw.c[:] = 2.0 * D / dt, e0 + 0.5 * dt * (v + rate)
            u = nw.solve(None if nw.guessless else e0 + dt * v + 0.5 * dt * (v - self.v_old))  # v^{n+1} extrapolated
            v1 = 2.0 * (u - e0) / dt - v
            v1[s.bc] = 0.0
            sticky = (D > 0) & (v1 > rate)  # a damping that would hold a node down: released (as on the linear path)
            if not self.anysum(bool(np.any(sticky))):
                break
            D[sticky] = 0.0
        f = -D * (v1 - rate)
        delta = u - e0
        visc_vec = nw.viscous_force(u)
        kin, el, visc, con, ext, work = self.allsum(
            self._kinetic(v1), self._stored(u), float(np.dot(visc_vec * s.interior, delta)),
            -0.5 * dt * float(np.dot(f, v + v1)), float(np.dot(s.ops.load, delta)), self._obstacle_work(f))
        num = self.E - (kin + el) - visc - con + ext
        con, ext = con + work, ext + work  # the obstacle's share of the force's work: external, not dissipated
        self.E = kin + el
        np.divide(f, s.ops.m_force, out=self.force_density, where=s.ops.m_force > 0)
        self.force_density[s.ops.m_force <= 0] = 0.0
        self.v_old[:], self.eta_[:], self.v[:] = v, u, v1
        self.k += 1
        if self.moving:  # the law's fields at t^k: the stored row's contact set, the next step's active set
            self.s.obstacle.set_centred(self.k * dt)
        return StepEnergy(kin, el, visc, con, num, ext, 0.0)

    def _obstacle_work(self, f: np.ndarray) -> float:
        """A moving obstacle's work f·(ψ^{n+1} − ψ^n) on the string (this rank's); 0 for an obstacle at rest."""
        if not self.moving:
            return 0.0
        o, t = self.s.obstacle, (self.k + 1) * self.s.dt
        return float(np.dot(f, o.at(t)[: o.n] - o.at(t - o.dt)[: o.n]))


__all__ = [
    "CHORD_BUDGET",
    "CHORD_ITERATIONS",
    "MAX_PRODUCT_POWER",
    "NEWMARK",
    "PAPER",
    "PROJECTION",
    "SNES_DEFAULTS",
    "UNITS",
    "AffineResidual",
    "LevelTerms",
    "NewmarkStep",
    "NewtonStep",
    "PaperStep",
    "ProjectionStep",
    "QuadraticEnergy",
    "affine_in",
    "compact",
    "literal_components",
    "powers_as_products",
]
