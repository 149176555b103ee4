"""The linear path of a residual affine in its unknowns: its constant matrices assembled once, a step by mat-vecs
and one back-substitution (`NewtonStep` takes it when `affine_in` holds and the model does not ask for Newton). A
linear two-field model's step then costs about 2.3 times the paper's linear step at nx = 5000, against 12-20 times
through SNES (`benchmarks/bench_stiff_string.py`, docs/explanation/performance.md).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
from ufl.algorithms.apply_derivatives import apply_derivatives
from ufl.algorithms.map_integrands import map_integrand_dags
from ufl.classes import FixedIndex, ListTensor
from ufl.corealg.multifunction import MultiFunction

from ..fem import compat
from ..fem.operators import stacked
from .linear import Linear, dirichlet_rows


class _LiteralComponents(MultiFunction):
    expr = MultiFunction.reuse_if_untouched

    def indexed(self, o, A, ii):
        if isinstance(A, ListTensor) and len(ii) == 1 and isinstance(ii[0], FixedIndex):
            return A.ufl_operands[int(ii[0])]
        return self.reuse_if_untouched(o, A, ii)


def literal_components(form):
    """`form` with each fixed component of a literal vector, ``as_vector([0, u[1]])[0]``, replaced by that component,
    so that a term it zeroes is dropped (UFL keeps the indexing: a kernel of zeros and a C compiler's warning)."""
    return map_integrand_dags(_LiteralComponents(), form)


def _derivative(form, f, direction=None):
    """∂form/∂f along `direction` (a trial function of f's space by default), derivatives applied."""
    direction = ufl.TrialFunction(f.function_space) if direction is None else direction
    return apply_derivatives(ufl.derivative(apply_algebra_lowering(form), f, direction))


def _functions(form) -> set:
    return {c for c in ufl.algorithms.extract_coefficients(form) if isinstance(c, fem.Function)}


def assemble_into(vec: PETSc.Vec, assemble) -> None:
    """`assemble(vec)` into `vec` zeroed, the ghosts' contributions added to their owners."""
    with vec.localForm() as local:
        local.set(0.0)
    assemble(vec)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)


def affine_in(form, unknowns) -> bool:
    """Whether `form` is affine in the Functions `unknowns` with constant coefficients: its derivative along each
    reads no Function (neither an unknown nor a scene field that may move with time)."""
    return all(_derivative(form, f).empty() or not _functions(_derivative(form, f)) for f in unknowns)


def _assembled(a) -> PETSc.Mat | None:
    """The bilinear form `a` assembled, or None if it is empty or assembles to 0."""
    if a.empty():
        return None
    A = fem.petsc.assemble_matrix(fem.form(a))
    A.assemble()
    return compact(A) if A.norm(PETSc.NormType.INFINITY) > 0 else None


def compact(A: PETSc.Mat, keep: np.ndarray | None = None) -> PETSc.Mat:
    """A without its stored zeros (or with the entries `keep` of its CSR values only), as a plain AIJ matrix: a mixed
    space's matrix stores every block of a node pair, and its mat-vec then reads only its nonzeros (a two-field
    ∂R/∂U_t with η's block alone, nx = 5000: 13.5 µs against 87, timeit)."""
    ia, ja, a = A.getValuesCSR()  # this rank's rows, global columns
    keep = a != 0 if keep is None else keep
    rows = np.repeat(np.arange(ia.size - 1), np.diff(ia))
    starts = np.concatenate([[0], np.cumsum(np.bincount(rows[keep], minlength=ia.size - 1))]).astype(ia.dtype)
    B = PETSc.Mat().createAIJ(size=A.getSizes(), csr=(starts, ja[keep], a[keep]), comm=A.getComm())
    B.assemble()
    return B


def _as_slice(idx):
    """An index array that is an arithmetic progression (η's dofs in a blocked space: every k-th) as the strided
    slice that reads the same entries as a view, without a gather."""
    if isinstance(idx, slice) or idx.size < 2 or idx[1] <= idx[0]:
        return idx
    step = int(idx[1] - idx[0])
    if np.array_equal(idx, np.arange(idx[0], idx[0] + step * idx.size, step)):
        return slice(int(idx[0]), int(idx[0]) + step * idx.size, step)
    return idx


class AffineResidual:
    """A residual affine in its unknowns, R(U, U_t, U_tt, 0; W) = A U + B U_t + M U_tt + r₀, by its constant
    matrices (``matrices``: "eta", "eta_t", "eta_tt", assembled once) and r₀ = R(0, 0, 0, 0). With `lumped` η's own
    U_tt column is left out (the schemes lump η's inertia); r₀ is assembled again when it reads a scene field."""

    def __init__(self, form, lumped: bool):
        zero = ufl.zero()
        R = ufl.replace(form.residual, {form.force: zero})
        U_tt = form.eta_tt
        if lumped and form.eta_dofs is not None:  # η's U_tt column off: as the scheme's mapping writes it
            U_tt = ufl.as_vector([0.0, *(form.eta_tt[i] for i in range(1, form.eta_tt.ufl_shape[0]))])
        R_tt = literal_components(ufl.replace(R, {form.eta_tt: U_tt}))
        parts = {"eta": _derivative(R, form.eta), "eta_t": _derivative(R, form.eta_t)}
        if not (lumped and form.eta_dofs is None):
            parts["eta_tt"] = _derivative(R_tt, form.eta_tt)
        self.matrices = {name: A for name, a in parts.items() if (A := _assembled(a)) is not None}
        shape = form.eta.ufl_shape
        r0 = ufl.algorithms.expand_derivatives(
            ufl.replace(R, {f: ufl.zero(*shape) for f in (form.eta, form.eta_t, form.eta_tt)}))
        self.r0_form = None if r0.empty() else fem.form(r0)
        self.r0 = np.zeros(form.space.dofmap.index_map.size_local * form.space.dofmap.index_map_bs)
        self.moving = not r0.empty() and bool(_functions(r0))
        if self.r0_form is not None:
            self.r0_vec = compat.create_vector(self.r0_form)
            self._assemble_r0()

    def _assemble_r0(self) -> None:
        assemble_into(self.r0_vec, lambda vec: fem.petsc.assemble_vector(vec, self.r0_form))
        self.r0[:] = self.r0_vec.array

    def constant(self) -> np.ndarray:
        """r₀ (assembled again when it reads a scene field)."""
        if self.moving:
            self._assemble_r0()
        return self.r0


def _component_columns(A: PETSc.Mat, component: int, k: int) -> PETSc.Mat | None:
    """A's columns of component `component` of a blocked space (column j is component j mod k), as an AIJ matrix of
    A's shape; None if it has none."""
    if k == 1:
        return A
    keep = A.getValuesCSR()[1] % k == component
    if not A.getComm().tompi4py().allreduce(bool(keep.any()), op=MPI.LOR):
        return None
    return compact(A, keep)


#: The unit values of (u, η^n, η^{n−1}, v^n) at which a scheme's (linear) quotient gives its coefficient of each.
UNITS = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))


class LevelTerms:
    """An affine residual at one scheme's quotients, by products with the unknowns' levels: without its nodal terms
    G(u) = Σ_j M_j (a_u u + a_0 e0 + a_m em + a_v v0) + r₀, each matrix split by the component of its columns (a
    scheme's quotient may differ between η and the fields), the coefficients read off the quotients at `UNITS`.

    The matrices a later step applies again (a_0 or a_m ≠ 0) or the ledger's viscous work reads are stacked with the
    energy's H in one matrix S: its product with each new solution (`products`, kept by `NewtonStep._products_of`)
    serves that step's ledger and the next two steps' known part, one mat-vec a step besides the solve. The methods
    take each level's values with its products, or None for products to be computed here.
    """

    def __init__(self, residual: AffineResidual, quotients: dict, dt: float, k: int, dissipative: tuple,
                 energy: QuadraticEnergy | None):
        self.residual, self.energy = residual, energy
        self.terms, self.others = [], []  # (M, a, viscous): stacked, and applied only for a residual's value
        for name, A in residual.matrices.items():
            for c in range(k):
                rule = quotients["fields"] if name == "eta" and c > 0 and "fields" in quotients else quotients[name]
                a = tuple(float(rule(*unit, dt)) for unit in UNITS)
                if not any(a) or (M := _component_columns(A, c, k)) is None:
                    continue
                viscous = name == "eta_t" or (name == "eta" and c in dissipative)
                (self.terms if a[1] or a[2] or viscous else self.others).append((M, a, viscous))
        stack = [M for M, _, _ in self.terms] + ([energy.H] if energy is not None else [])
        self.S = stacked(*stack) if stack else None
        if self.S is not None:
            self.X, self.Y = self.S.createVecs()
        self.N = residual.r0.size
        self.vecs = {id(M): M.createVecs() for M, _, _ in self.terms + self.others}

    def products(self, values: np.ndarray) -> np.ndarray | None:
        """S·values: the stacked terms' products, then H's."""
        if self.S is None:
            return None
        self.X.array[:] = values
        self.S.mult(self.X, self.Y)
        return self.Y.array.copy()

    def _mult(self, M, values: np.ndarray) -> np.ndarray:
        x, y = self.vecs[id(M)]
        x.array[:] = values
        M.mult(x, y)
        return y.array

    def _sum(self, out: np.ndarray, levels: list, products: list, terms: list, which, own: bool,
             rows=slice(None)) -> np.ndarray:
        """Σ over `terms` of a_i × M_j level_i for i in `which` (0: u, 1: e0, 2: em, 3: v0) into `out` (its `rows`
        only). `own`: the stacked terms, their products of u, e0, em from `products` (computed when None)."""
        N = self.N
        for j, (M, a, _) in enumerate(terms):
            for i in which:
                if not a[i]:
                    continue
                if own and i < 3:
                    if products[i] is None:
                        products[i] = self.products(levels[i])
                    out += a[i] * products[i][j * N:(j + 1) * N][rows]
                else:
                    out += a[i] * self._mult(M, levels[i])[rows]
        return out

    def known(self, levels: list, products: list, out: np.ndarray) -> np.ndarray:
        """G(0) without its nodal terms, at `levels` (u, e0, em, v0; u unused): the known part, r₀ included."""
        out[:] = self.residual.constant()
        return self._sum(out, levels, products, self.terms, (1, 2, 3), own=True)

    def value(self, levels: list, products: list, out: np.ndarray) -> np.ndarray:
        """G(u) without its nodal terms."""
        self.known(levels, products, out)
        self._sum(out, levels, products, self.terms, (0,), own=True)
        return self._sum(out, levels, products, self.others, (0,), own=False)

    def viscous(self, levels: list, products: list, rows) -> np.ndarray:
        """The viscous terms at u on `rows`: ∂R/∂U_t U_t and ∂R/∂U on the dissipative fields' columns."""
        terms = [t if t[2] else (t[0], (0.0,) * 4, False) for t in self.terms]  # the stacked positions kept
        return self._sum(np.zeros(len(range(self.N)[rows])), levels, products, terms, (0, 1, 2, 3), own=True, rows=rows)

    def stored(self, values: np.ndarray, products: np.ndarray | None) -> float:
        """The quadratic stored energy at `values` (this rank's share), by its product with H."""
        e = self.energy
        Hx = (self.products(values) if products is None else products)[len(self.terms) * self.N:]
        if e.g is None:
            return e.base + 0.5 * float(np.dot(values, Hx))
        return e.base + float(np.dot(values, 0.5 * Hx + e.g))


class QuadraticEnergy:
    """A stored energy ∫Π(f) quadratic in its Function f, Π₀ + g·f + ½ f·H f with H and g assembled once: the ledger's
    energy by a mat-vec (`LevelTerms.stored`) instead of an assembly."""

    def __init__(self, H: PETSc.Mat, g: np.ndarray, base: float):
        self.H, self.base = H, base
        self.g = g if H.getComm().tompi4py().allreduce(bool(np.any(g)), op=MPI.LOR) else None  # None: no linear term

    @classmethod
    def of(cls, energy, f) -> QuadraticEnergy | None:
        """The energy functional `energy` of the Function `f` as a `QuadraticEnergy`, or None if it is not quadratic
        in f with constant coefficients (its second derivative reads a Function) or reads another Function."""
        if _functions(energy) - {f}:
            return None
        first = _derivative(energy, f, ufl.TestFunction(f.function_space))
        second = _derivative(first, f)
        if first.empty() or second.empty() or _functions(second):
            return None
        zero = ufl.zero(*f.ufl_shape)
        H = fem.petsc.assemble_matrix(fem.form(second))
        H.assemble()
        H = compact(H)
        g = np.zeros(H.getLocalSize()[0])
        slope = ufl.algorithms.expand_derivatives(ufl.replace(first, {f: zero}))
        if not slope.empty():
            vec = fem.petsc.assemble_vector(fem.form(slope))
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            g[:] = vec.array
        base = ufl.algorithms.expand_derivatives(ufl.replace(energy, {f: zero}))
        return cls(H, g, 0.0 if base.empty() else float(fem.assemble_scalar(fem.form(base))))


class LinearPath:
    """`NewtonStep`'s linear path for a residual affine in its unknowns (`affine_in`, `_linear_path`), the other
    fields started from η0 (`start_fields`), η's stiffness with the fields eliminated (`eta_stiffness`)."""

    def _linear_path(self) -> None:
        """G(u) = J u + G(0) with a constant J: the step is one linear solve (`_solve_linear`), J factorised once (again
        when the damping on its diagonal changes), G(0), the viscous work and a quadratic stored energy by mat-vecs.
        A VI tries this step first and keeps SNES for the steps that touch a bound."""
        problem, form = self.problem, self.problem.ops.nonlinear
        self.linear = AffineResidual(form, self.lumped)
        J = fem.petsc.assemble_matrix(self.J_form)
        J.assemble()
        self.diag.set(0.0)
        self.diag.array[self.idx] = self.m_tt
        J.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        dirichlet_rows(J, self.bc)
        if J.getBlockSize() > 1 and problem.comm.size == 1 and self.ksp_options.get("pc_type") == "lu":
            # the blocked matrix's LU: back-substitution by 2 × 2 blocks (10⁴ unknowns: 53 µs against 142 as AIJ)
            J = J.convert("baij")
        self.step_solver = Linear(J, problem.comm, self.ksp_options, self.bc, self.g, problem.x.ndim)
        self.rhs, self.work = J.createVecLeft(), np.zeros(self.N)
        self.extra, self.d_lin = np.zeros(self.N), np.zeros(self.n)  # the damping on J's diagonal: all rows, η's
        self.quadratic = QuadraticEnergy.of(form.stored_energy, self.energy_eta)
        names = getattr(problem.laws.model, "dissipative_fields", ())
        fields = getattr(problem.laws.model, "fields", ())
        k = form.eta.ufl_shape[0] if form.eta_dofs is not None else 1
        self.terms = LevelTerms(self.linear, self.q, problem.dt, k,
                                tuple(i + 1 for i, f in enumerate(fields) if f in names), self.quadratic)
        self.linear_solves, self.stale = 0, False  # stale: G_vec does not hold the last solve's residual
        self.solutions, self.returned = [], None  # the last three solutions (values, S's products); η's last one
        self.level_products = [None, None]  # e0's and em's products, when they are one of `solutions`
        self.held = None  # A = ∂R/∂U with η's rows held: the fields given η (`start_fields`, `eta_stiffness`)

    @property
    def guessless(self) -> bool:
        """Whether `solve` reads no guess: the linear path's direct solve, with no VI to fall back to."""
        return self.linear is not None and self.free is None and not self.step_solver.iterative

    def _level(self, i: int) -> np.ndarray:
        """Known level i (1: e0, 2: em, 3: v0) as `set_known` last gave it, with the other fields' values."""
        return self._full(self.arrays[i - 1], self.levels[i - 1])

    def _at(self, u: np.ndarray) -> tuple[list, list]:
        """The levels at u (η's owned values) and their known products: u's own if the last solve returned u."""
        if u is self.returned:
            values, products = self.solutions[0]
        else:
            values, products = self._full(u, self.levels[3]), None
        return _Levels(self, values), [products, *self.level_products]

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
        """The step's root into `x` by one solve: J u = −(G(0) without its nodal terms) + their known part."""
        rhs = self.rhs.array
        np.negative(self.terms.known(_Levels(self, None), [None, *self.level_products], self.work), out=rhs)
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
            self.held = Linear(A, self.problem.comm, {"ksp_type": "preonly", "pc_type": "lu"}, rows,
                               np.zeros(rows.size), self.problem.x.ndim)
            self.held_rows, self.held_b = rows, A.createVecLeft()
        return self.held

    def start_fields(self, eta0: np.ndarray, v0: np.ndarray) -> None:
        """A model's other fields at t = 0: a field given a start (`DiscreteProblem.fields0`) starts at it, at rest;
        on the linear path the others are the root of their rows with η = η0, η_t = v0 and their own rates 0, as every
        level the scheme starts from (E(0) and the first row hold them). The Newton path starts them at 0."""
        if self.linear is not None and self._held_rows() is not None:
            b = self.held_b.array
            b[:] = self.linear.constant()
            if "eta_t" in self.linear.matrices:  # + ∂R/∂U_t (v0 on η's dofs, 0 on the fields')
                A = self.linear.matrices["eta_t"]
                rate, y = A.createVecs()
                rate.set(0.0)
                rate.array[self.at] = v0
                A.mult(rate, y)
                b += y.array
            np.negative(b, out=b)
            b[self.held_rows] = 0.0
            b[self.at] = eta0
            self.held.solve(self.held_b, self.x)
            for level in self.levels:
                level[:] = self.x.array
        form, given = self.problem.ops.nonlinear, self.problem.fields0
        for i, name in enumerate(self.problem.laws.model.fields if given else ()):
            if name in given:
                dofs = compat.sub_dofs(form.V, form.space, i + 1)[: self.n]
                for level, value in zip(self.levels, (given[name], given[name], 0.0, given[name])):
                    level[dofs] = value

    def eta_stiffness(self) -> PETSc.Mat | None:
        """η's stiffness with the other fields eliminated, the Schur complement S = A_ηη − A_ηf A_ff⁻¹ A_fη of A = ∂R/∂U
        (K + βKM⁻¹K for a field of η's second derivative), a shell on η's dofs; None off the linear path or alone."""
        if self.linear is None or self._held_rows() is None:
            return None
        n = self.n
        S = PETSc.Mat().createPython(((n, PETSc.DECIDE), (n, PETSc.DECIDE)), _SchurComplement(self),
                                     comm=self.problem.comm)
        S.setUp()
        return S


class _Levels:
    """The levels u, e0, em, v0 as the forms read them (the unknowns' owned values), each built when first read."""

    def __init__(self, step: LinearPath, u):
        self.step, self.values = step, [u, None, None, None]

    def __getitem__(self, i: int) -> np.ndarray:
        if self.values[i] is None:
            self.values[i] = self.step._level(i)
        return self.values[i]


class _SchurComplement:
    """The shell `NewtonStep.eta_stiffness`: y = S x = (A Z)_η with Z = (x, the other fields solved for x)."""

    def __init__(self, step: LinearPath):
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
