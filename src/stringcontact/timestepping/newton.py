"""A nonlinear model's step by Newton's method (PETSc SNES): `NewtonStep`, shared by every scheme's Newton path
(`_NewtonScheme`; docs/howto/nonlinear_models.md). A scheme writes the residual's placeholders as difference quotients
in u = η^{n+1} and the known levels; the step is the root of

    G(u) = R(q_η(u), q_t(u), q_tt(u), 0; w) − f + d∘(u − c),      u = g at the fixed ends,

f the nodal contact force, d∘(u − c) an implicit damping (the semi-implicit penalty), the η_tt term m∘q_tt(u) when
lumped. `projection`'s step is the VI G(u) ⊥ u − ψ ≥ 0 (``vinewtonrsls``); a residual affine in its unknowns takes one
linear solve (`affine.LinearPath`). The ledger: kinetic, stored ∫Π(η), the work of R's η_t-dependent part (viscous),
b·δ and the contact work; numerical dissipation is the rest of the identity, which the leapfrog and the midpoint rule
of a nonlinear force make change sign (``energy_may_rise``).
"""

from __future__ import annotations

import math

import dolfinx.fem.petsc  # noqa: F401 - dolfinx 0.9 no longer imports the PETSc layer with dolfinx.fem
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..errors import SolverError
from ..fem import compat
from ..fem.packed import PackedForm
from ..fem.powers import powers_as_products
from .affine import LinearPath, _as_slice, affine_in, assemble_into
from .base import Ranks, StepEnergy, petsc_callback, petsc_vector
from .base import Scheme as Base
from .linear import PREFIX, check_vi_linesearch, dirichlet_rows, options_held, set_from_options, solver_options

#: The absolute residual Newton stops at, relative to the inertia term's norm: a few hundred round-offs of it.
ROUNDOFF = 1e-13
#: Newton's defaults, below a scene's `petsc_options` (a relative step of 1e-9 leaves an error of about 1e-18 |u|).
SNES_DEFAULTS = {"snes_linesearch_type": "bt", "snes_rtol": 1e-10, "snes_stol": 1e-9, "snes_max_it": 50}
#: The VI's defaults on top: a node is on its bound only where it is exactly there. PETSc's 1e-8 froze nodes just above
#: the obstacle and a stiff landing cycled for 50 iterations (benchmarks/bench_vi.py).
VI_DEFAULTS = {"snes_vi_zero_tolerance": 0.0}
#: The line search a failed step is tried again with (a fresh J, the same guess): `l2` diverged on a landing at
#: nt = 600 (benchmarks/bench_vi.py), `bt` stalled on others.
RESCUE_LINE_SEARCH = {"l2": "bt", "bt": "l2", "basic": "bt", "cp": "bt"}
#: The most iterations a kept Jacobian serves in a step, and its surplus iterations before a fresh one: a chord
#: iteration costs about a tenth of a fresh J with its LU factor at nx = 5000 (`_keeps_jacobian`).
CHORD_ITERATIONS = 3
CHORD_BUDGET = 10


class NewtonStep(LinearPath):
    """G(u) = 0 (or the VI with lower bounds) for one scheme's quotients; see the module docstring.

    `quotients` maps "eta", "eta_t", "eta_tt" to functions (u, e0, em, v0, dt) -> the quotient, for UFL and NumPy
    alike (e0, em: η^n, η^{n−1}; v0: a nodal velocity); "fields" (optional): the other fields' values. ``lower``: the
    VI's nodal lower bound (−inf where free), or None. `reuse_jacobian` False takes a fresh Jacobian at every
    iteration (no chord iterations).
    """

    reuse_jacobian = True

    def __init__(self, problem, quotients: dict, lower: np.ndarray | None = None):
        form = problem.ops.nonlinear
        Z, n = form.space, problem.n_owned
        self.problem, self.n, self.q = problem, n, quotients
        self.allsum, self.anyrank = Ranks(problem.comm).sum, Ranks(problem.comm).any
        self.u, self.e0, self.em, self.v0 = (fem.Function(Z) for _ in range(4))
        self.lumped = problem.mass == "lumped"
        # Δt as a Constant: a run of another Δt (a retry's sub-steps) reuses the compiled forms (1 s each, cold)
        dt = fem.Constant(Z.mesh, PETSc.ScalarType(problem.dt))
        args = (self.u, self.e0, self.em, self.v0, dt)
        q_eta, q_t, q_tt = (quotients[k](*args) for k in ("eta", "eta_t", "eta_tt"))
        zero = ufl.zero()  # UFL's zero, not a Constant 0: the terms it multiplies leave the compiled kernel
        k = form.eta.ufl_shape[0] if form.eta_dofs is not None else 0  # the number of fields, η's among them
        if k:  # several fields: η's inertia is lumped on the nodes, the other fields keep their own η_tt
            zeros = ufl.as_vector([0.0] * k)
            q_fields = quotients.get("fields", quotients["eta"])(*args)
            q_eta = ufl.as_vector([q_eta[0], *(q_fields[i] for i in range(1, k))])
            q_tt = ufl.as_vector([0.0, *(q_tt[i] for i in range(1, k))]) if self.lumped else q_tt
        else:
            zeros = zero
            q_tt = zero if self.lumped else q_tt
        mapping = {form.eta: q_eta, form.eta_t: q_t, form.eta_tt: q_tt, form.force: zero}
        G = powers_as_products(ufl.replace(form.residual, mapping))
        G_static = powers_as_products(
            ufl.replace(form.residual, mapping | {form.eta_t: zeros} | _without_dissipative(problem, q_eta, k)))
        self.G = PackedForm(G)  # assembled at least twice a step: its coefficients gathered, not packed again
        self.known = [f for f in self.G.functions if f is not self.u]  # what `_residual` does not refresh
        self.J_form = fem.form(ufl.derivative(G, self.u, ufl.TrialFunction(Z)))
        self.G_static_form = fem.form(G_static)
        self.energy_eta = form.energy_eta
        self.energy = PackedForm(powers_as_products(form.stored_energy))
        self.a_tt = float(quotients["eta_tt"](1.0, 0.0, 0.0, 0.0, problem.dt))  # ∂q_tt/∂u
        self.G_vec = compat.create_vector(self.G.form)
        self.work_vec = compat.create_vector(self.G.form)
        self.J = fem.petsc.create_matrix(self.J_form)
        self.x = self.G_vec.duplicate()
        # η's entries in the unknowns' (owned) arrays: all of them for one field, a fancy index for several, and as a
        # strided slice where they are one (a blocked space's)
        self.idx = slice(0, n) if form.eta_dofs is None else np.asarray(form.eta_dofs[:n])
        self.bc = problem.bc if form.eta_dofs is None else self.idx[problem.bc]
        self.at = _as_slice(self.idx)
        self.N = self.x.getLocalSize()
        self.diag = self.J.createVecLeft()  # the lumped mass and the damping, added to J's diagonal
        self.m_tt = self.a_tt * problem.ops.m if self.lumped else np.zeros(n)
        self.inertia = self.a_tt * problem.ops.m
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
        self.g = problem.g
        lower = self._held_and_bounded(lower)
        self.bounds = None
        self.snes = self._snes(lower)
        self.free = self._snes(None) if lower is not None else None  # a VI's plain Newton step, tried first
        self.rescue, self.rescues = None, 0  # the other line search's SNES (made at the first failure), its solves
        self.try_free, self.free_solves = True, 0
        self.linear = self.quadratic = None
        if not getattr(problem.laws.model, "newton", False) and affine_in(
                ufl.replace(form.residual, {form.force: zero}), (form.eta, form.eta_t, form.eta_tt)):
            self._linear_path()

    def _held_and_bounded(self, lower):
        """The unknowns' lower bound (None: none) from η's `lower`, a model's other fields held at 0 on the boundary
        (`Model.held_fields`: their rows join η's ends in `bc`) and bounded below (`Model.field_lower`)."""
        problem, form = self.problem, self.problem.ops.nonlinear
        model = problem.laws.model
        if form.eta_dofs is None:
            return lower
        dofs = {name: compat.sub_dofs(form.V, form.space, i + 1)[: self.n] for i, name in enumerate(model.fields)}
        for name in getattr(model, "held_fields", ()):
            self.bc = np.concatenate([self.bc, dofs[name][problem.bc]])
            self.g = np.concatenate([self.g, np.zeros(len(problem.bc))])
        bounds = model.field_lower(form.params) if getattr(model, "field_lower", None) is not None else {}
        if lower is None and not bounds:
            return None
        full = np.full(self.N, PETSc.NINFINITY)
        if lower is not None:
            full[self.idx] = lower
        for name, value in bounds.items():
            full[dofs[name]] = value
        return full

    def _snes(self, lower, line_search: str | None = None):
        """A SNES for G; a VI's (``vinewtonrsls``, `VI_DEFAULTS`) with `lower` (None: plain Newton, or the bounds
        already made, `bounds`, for a VI's rescue). `line_search` replaces the options' (a rescue's)."""
        problem = self.problem
        snes = PETSc.SNES().create(problem.comm)
        snes.setFunction(petsc_callback(self._residual), self.G_vec)
        snes.setJacobian(petsc_callback(self._jacobian), self.J)
        self.notes = []
        options = solver_options(self.J.getSize()[0], problem.comm.size, problem.petsc_options, dim=problem.x.ndim,
                                 notes=self.notes)
        vi = lower is not None or (line_search is not None and self.bounds is not None)
        # problem.petsc_options hold the model's defaults (`Model.solver`) below the user's
        options = (
            {"snes_type": "vinewtonrsls" if vi else "newtonls"} | SNES_DEFAULTS | (VI_DEFAULTS if vi else {}) | options
        )
        if vi:
            check_vi_linesearch(options)
        self.line_search = options["snes_linesearch_type"]
        if line_search is not None:
            options["snes_linesearch_type"] = line_search
        set_from_options(snes, PREFIX, options)
        # the linear solver's options held again while SNES solves: its KSP reads some at set-up (`options_held`)
        self.ksp_options = {k: v for k, v in options.items() if not k.startswith("snes_")}
        if lower is not None:
            lo, hi = self.x.duplicate(), self.x.duplicate()
            lo.array[:] = lower
            hi.set(PETSc.INFINITY)
            self.bounds = (lo, hi)
        if vi:
            snes.setVariableBounds(*self.bounds)
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
                levels[2] = (levels[0] - levels[1]) / self.problem.dt
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
        if form is None:
            self.G.refresh(self.u)
            assemble_into(self.work_vec, self.G.assemble_vector)
        else:
            assemble_into(self.work_vec, lambda vec: fem.petsc.assemble_vector(vec, form))
        r = self.work_vec.array[self.idx].copy()
        if self.lumped:
            r += self.problem.ops.m * self.q["eta_tt"](u, *self.arrays, self.problem.dt)
        return r

    def last_residual(self, u: np.ndarray) -> np.ndarray:
        """`residual_at(u)` for the u that `solve` just returned, without assembling: SNES's last residual (the linear
        path's, by mat-vecs) with the force and the damping taken out again."""
        if self.stale:
            self._linear_residual()
        r = self.G_vec.array[self.at].copy()
        r += self.f
        r -= self.d * (u - self.c)
        return r

    def viscous_force(self, u: np.ndarray) -> np.ndarray:
        """The η_t-dependent part of the residual at u, R(q_η, q_t) − R(q_η, 0): C q_t(u) if ∂R/∂η_t is constant."""
        if self.problem.ops.nonlinear.viscous_linear:
            if self.viscous_vecs is None:
                self.viscous_vecs = self.problem.ops.C.createVecs()
            q_t, out = self.viscous_vecs
            q_t.array[:] = self.q["eta_t"](u, *self.arrays, self.problem.dt)
            self.problem.ops.C.mult(q_t, out)
            return out.array.copy()
        if self.linear is not None:  # ∂R/∂U_t q_t, and ∂R/∂U on the dissipative fields' values: kept products
            return self.terms.viscous(*self._at(u), self.at)
        return self.residual_at(u) - self.residual_at(u, self.G_static_form)

    def stored_energy(self, eta: np.ndarray) -> float:
        """∫Π(η) on this rank's cells (the caller sums over the ranks); ∫Π(η, *fields) with the last solve's fields."""
        if self.quadratic is not None:
            levels, products = self._at(eta)
            return self.terms.stored(levels[0], products[0])
        self._set(self.energy_eta, self._full(eta, self.levels[3]))
        self.energy.refresh()
        return self.energy.assemble_scalar()

    # -- SNES callbacks: SNES hands them x locked for reading (PETSc 3.22): read it through array_r, never array

    def _residual(self, snes, x, G) -> None:
        u = x.array_r
        self._set(self.u, u)
        self.G.refresh(self.u)
        assemble_into(G, self.G.assemble_vector)
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
        """Whether the last J and its LU factor, from an earlier step, serve this iteration (PETSc keeps the factor of
        an untouched J): while it is predicted to reach Newton's tolerance within CHORD_ITERATIONS iterations (at
        the first with ρ = drift × age, drift halved at each step that did not try one; later with the rate just
        seen) and its surplus iterations stay below CHORD_BUDGET, rent or buy (docs/howto/nonlinear_models.md).
        Once J is fresh, it stays fresh for the step."""
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
        """A kept J with the step's damping d on its diagonal: the change since its assembly added (no assembly)."""
        change = self.d - self.d_in_J
        if not self.anyrank(bool(np.any(change))):
            return
        self.diag.set(0.0)
        self.diag.array[self.idx] = change
        self.diag.array[self.bc] = 0.0
        J.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        J.assemble()
        self.d_in_J[:] = self.d

    def _above_bounds(self, x: np.ndarray) -> bool:
        """Whether `x` is nowhere below the VI's lower bound (on every rank)."""
        return not self.anyrank(bool(np.any(x < self.bounds[0].array)))

    def solve(self, guess: np.ndarray) -> np.ndarray:
        """The root from `guess` (η; the ends at their heights, the other fields from their last solution): η's owned
        values; SolverError if SNES fails. A VI first tries the plain Newton step (the linear path's solve) when the
        last solution touched no bound (SNES VI refactorises at every iteration: 2.2 of a 3.5 ms step at nx = 5000)."""
        self.age += 1
        # G's nodal terms, affine in u: d∘(u − c) − f (+ m∘q_tt(u), lumped) = slope∘u − known (the linear path's
        # slope is on its J; SNES's is set below)
        self.nodal_known[:] = self.d * self.c + self.f
        if self.lumped:
            self.nodal_known -= self.problem.ops.m * self.q["eta_tt"](0.0, *self.arrays, self.problem.dt)
        x = self.x.array
        if self.linear is not None and (self.free is None or self.try_free):
            self._solve_linear(guess)
            if self.free is None or self._above_bounds(x):
                self.free_solves += self.free is not None
                return self._accept()
        # the round-off floor, ROUNDOFF × the inertia term's norm: an rtol below it (a good predictor) would stall
        if "snes_atol" not in (self.problem.petsc_options or {}):  # the user's wins
            inertia = self.inertia * guess
            floor = max(ROUNDOFF * math.sqrt(self.allsum(float(np.dot(inertia, inertia)))[0]), 1e-50)
            for snes in (self.snes, self.free) if self.free is not None else (self.snes,):
                snes.setTolerances(atol=floor)
        self._sync()
        self.nodal_slope[:] = self.d + self.m_tt
        if self.known:  # the known levels and any field that moved with the step (an obstacle ψ(x, t))
            self.G.refresh(*self.known)
        self.stale = False  # SNES's residual in G_vec
        if (self.free is not None and self.try_free and self.linear is None and self._run(self.free, guess) >= 0
                and self._above_bounds(x)):
            self.free_solves += 1
            return self._accept()
        reason = self._run(self.snes, guess)
        if reason == compat.snes_diverged_nan() and self.snes.getIterationNumber() == 0:
            raise self._not_finite(guess)
        if reason < 0 and RESCUE_LINE_SEARCH.get(self.line_search):  # the other line search: same guess, fresh J
            if self.rescue is None:
                self.other = RESCUE_LINE_SEARCH[self.line_search]
                self.rescue = self._snes(None, line_search=self.other)
            self.rescues += 1
            reason = self._run(self.rescue, guess, fresh_only=True)
        if reason < 0:
            raise SolverError(f"Newton did not converge (SNES reason {reason}) after {self.snes.getIterationNumber()} "
                              "iterations; use a smaller dt or petsc_options snes_max_it / snes_linesearch_type")
        if self.free is not None:
            self.try_free = not self.anyrank(bool(np.any(x <= self.bounds[0].array)))
        return self._accept()

    def _not_finite(self, guess: np.ndarray) -> SolverError:
        """The model's form is not finite at the step's first guess: no smaller dt or sub-step changes that, so the
        error says so (``not_finite``: the run does not sub-step it)."""
        model = self.problem.laws.model
        residual = self.G_vec.array
        bad = residual[~np.isfinite(residual)]
        value = f"{bad[0]:g}" if bad.size else "not finite"
        lo, hi = (float(np.min(guess)), float(np.max(guess))) if guess.size else (math.nan, math.nan)
        what = "residual" if getattr(model, "fields", ()) else "momentum_form"
        exc = SolverError(f"model '{model.name}': its {what} is {value} (not finite) at the step's first guess "
                          f"(eta in [{lo:.4g}, {hi:.4g}] on this rank): a square root or logarithm of a negative "
                          "number, a division by zero or an exponential that overflows in the form; a smaller dt "
                          "does not change it")
        exc.not_finite = True
        return exc

    def _run(self, snes, guess: np.ndarray, fresh_only: bool = False) -> int:
        """SNES's converged reason from `guess`, solved again with fresh Js if a kept J led it astray (`fresh_only`:
        only so)."""
        x = self.x.array
        for fresh in (True,) if fresh_only else (False, True):
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
        form = self.problem.ops.nonlinear
        if form.eta_dofs is None:
            return self.levels[3].copy()
        return self.levels[3][compat.sub_dofs(form.V, form.space, i)[: self.n]]

    def describe(self) -> dict:
        """Newton's counters for the summary."""
        counts = {"newton iterations": self.iterations, "jacobian assemblies": self.jacobians}
        if self.linear is not None:
            refactored = self.step_solver.refactorisations
            counts["linear solves"] = self.linear_solves
            how = (f"none: the residual is affine, {self.linear_solves} linear solves for {self.solves} steps with J "
                   f"factorised once" + (f" and again {refactored} times for the damping" if refactored else ""))
            if self.free is not None:
                how += (f"; {self.solves - self.free_solves} contact steps by SNES {self.snes.getType()}, "
                        f"{self.iterations} Newton iterations")
        else:
            per_step = self.iterations / self.solves if self.solves else 0.0
            free = f", {self.free_solves} of {self.solves} steps solved without the VI" if self.free is not None else ""
            rescued = f", {self.rescues} steps tried again with line search {self.other}" if self.rescues else ""
            how = f"SNES {self.snes.getType()}, {per_step:.3g} Newton iterations per step{free}{rescued}"
        if self.rescues:
            counts["line search rescues"] = self.rescues
        fallback = {"preconditioner": "; ".join(self.notes)} if getattr(self, "notes", None) else {}
        return counts | {"nonlinear solver": how} | fallback


def _without_dissipative(problem, q_eta, k: int) -> dict:
    """The model's dissipative fields (`Model.dissipative_fields`) at 0 in η's value: their work on η is then
    in the viscous work, as the η_t-dependent terms' (a lubricating fluid's)."""
    model = problem.laws.model
    names = getattr(model, "dissipative_fields", ())
    if not k or not names:
        return {}
    kept = [q_eta[i] if i == 0 or model.fields[i - 1] not in names else 0.0 for i in range(k)]
    return {problem.ops.nonlinear.eta: ufl.as_vector(kept)}


class _NewtonScheme(Base):
    """What the schemes share around their Newton step: the reductions over the ranks, the force's nodal weights, the
    moving obstacle's step index, the Newton path's energy terms and counters."""

    energy_may_rise = True
    newton = None

    def __init__(self, problem):
        super().__init__(problem)
        n, m_force = problem.n_owned, problem.ops.m_force
        self.allsum, self.anysum = Ranks(problem.comm).sum, Ranks(problem.comm).any
        self.inv_mF = np.divide(1.0, m_force, out=np.zeros(n), where=m_force > 0)  # 0 where no force acts (the ends)
        self.force_density = np.zeros(n)
        self.moving, self.k = problem.obstacle is not None, 0  # a moving obstacle ψ(x, t); the step index

    @property
    def eta(self):
        """η^n at this rank's nodes."""
        return self.eta_

    @property
    def velocity(self):
        """The scheme's velocity v^n at this rank's nodes (the backward quotient (η^n − η^{n−1})/Δt, or Newmark's)."""
        return self.v

    @property
    def contact_force(self):
        """The contact force density at this rank's nodes: the one the next step applies (explicit penalty), the
        one the last step applied (semi-implicit)."""
        return self.force_density

    @property
    def fields(self) -> dict:
        """A model's other fields (`Model.fields`) by name at η's owned nodes, from the last solve ({} for one field
        and on a scheme's own linear path): a step ahead in `projection` (a model may refuse it: `Model.schemes`)."""
        if self.newton is None:
            return {}
        return {name: self.newton.field(i + 1) for i, name in enumerate(self.problem.laws.model.fields)}

    def _stored(self, eta) -> float:
        return self.newton.stored_energy(eta)

    def _start_energy(self, eta: np.ndarray, v: np.ndarray) -> StepEnergy:
        """The Newton path's initial energy: ½|v|²_M and the stored energy at η."""
        kin, el = self.allsum(kinetic_energy(self.problem, v), self._stored(eta))
        self.E = kin + el
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def _step_energy(self, u, e0, v0, v1, f, work) -> StepEnergy:
        """The Newton path's terms of a step η^n = `e0` → `u`, velocities `v0` → `v1`, force `f` (module docstring);
        `work(f)`: the moving obstacle's share of the force's work, booked as external work (after the viscous
        force: it may move the obstacle's fields)."""
        problem, dt = self.problem, self.problem.dt
        delta = u - e0
        visc_vec = self.newton.viscous_force(u)
        work = work(f)
        kin, el, visc, con, ext, work = self.allsum(
            kinetic_energy(problem, v1), self._stored(u), float(np.dot(visc_vec * problem.interior, delta)),
            -0.5 * dt * float(np.dot(f, v0 + v1)), float(np.dot(problem.ops.load, delta)), work)
        num = self.E - (kin + el) - visc - con + ext
        self.E = kin + el
        return StepEnergy(kin, el, visc, con + work, num, ext + work, 0.0)

    @property
    def timings(self):
        return self.newton.describe() if self.newton is not None else self._linear_timings()

    def _linear_timings(self) -> dict:
        """A linear path's counters: its solver `lu`, refactorised when the semi-implicit penalty's damping changes."""
        counts = {"refactorisations": self.lu.refactorisations} if self.problem.penalty == "semi-implicit" else {}
        return counts | {"linear solver": self.lu.describe()}


def kinetic_energy(problem, v: np.ndarray) -> float:
    """½ v·M v on this rank's nodes, with the problem's mass (lumped: the row sums m; consistent: M)."""
    if problem.mass == "lumped":
        return 0.5 * float(np.dot(v, problem.ops.m * v))
    out = problem.ops.M.createVecLeft()
    problem.ops.M.mult(petsc_vector(v, problem.comm), out)
    return 0.5 * float(np.dot(v, out.array))
