"""The linear path of a residual affine in its unknowns: its constant matrices assembled once, a step by mat-vecs
and one back-substitution (`NewtonStep` takes it when `affine_in` holds and the model does not ask for Newton).

A linear model with several fields (η's second derivative beside η, a reaction) then costs about 2.3 times the
paper's linear step at nx = 5000, against 12-20 times through SNES (`benchmarks/bench_stiff_string.py`,
docs/explanation/performance.md).
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


class _LiteralComponents(MultiFunction):
    expr = MultiFunction.reuse_if_untouched

    def indexed(self, o, A, ii):
        if isinstance(A, ListTensor) and len(ii) == 1 and isinstance(ii[0], FixedIndex):
            return A.ufl_operands[int(ii[0])]
        return self.reuse_if_untouched(o, A, ii)


def literal_components(form):
    """`form` with each fixed component of a literal vector, ``as_vector([0, u[1]])[0]``, replaced by that component:
    UFL keeps the indexing, so a term it zeroes would still reach the compiler (a kernel of zeros, and a C
    compiler's warning about its unused quadrature weights); replaced, it is dropped."""
    return map_integrand_dags(_LiteralComponents(), form)


def _derivative(form, f, direction=None):
    """∂form/∂f along `direction` (a trial function of f's space by default), derivatives applied."""
    direction = ufl.TrialFunction(f.function_space) if direction is None else direction
    return apply_derivatives(ufl.derivative(apply_algebra_lowering(form), f, direction))


def _functions(form) -> set:
    return {c for c in ufl.algorithms.extract_coefficients(form) if isinstance(c, fem.Function)}


def affine_in(form, unknowns) -> bool:
    """Whether `form` is affine in the Functions `unknowns` with constant coefficients: its derivative along each of
    them reads no Function at all (an unknown left in a derivative, by a power, a product of two unknowns or a
    conditional, makes it nonlinear; a scene field in it, a coefficient that may move with time)."""
    return all(_derivative(form, f).empty() or not _functions(_derivative(form, f)) for f in unknowns)


def _assembled(a) -> PETSc.Mat | None:
    """The bilinear form `a` assembled, or None if it is empty or assembles to 0 (UFL does not simplify a component
    of a literal vector, ``as_vector([0, u[1]])[0]``, so a term that vanishes may still reach the compiler)."""
    if a.empty():
        return None
    A = fem.petsc.assemble_matrix(fem.form(a))
    A.assemble()
    return compact(A) if A.norm(PETSc.NormType.INFINITY) > 0 else None


def compact(A: PETSc.Mat) -> PETSc.Mat:
    """A without its stored zeros, as a plain AIJ matrix: a mixed space's matrix stores every block of a node pair
    (2 × 2 for two fields), and a term in one field's row and column leaves the other three zero. Its mat-vec
    then reads only its nonzeros (a two-field ∂R/∂U_t with η's block alone, nx = 5000: 13.5 µs against 87, timeit)."""
    ia, ja, a = A.getValuesCSR()  # this rank's rows, global columns
    keep = a != 0
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
    matrices (``∂R/∂U``, ``∂R/∂U_t``, ``∂R/∂U_tt``, assembled once) and its constant part r₀ = R(0, 0, 0, 0).

    `apply(values, out)` evaluates it at the arrays `values` (``"eta"``, ``"eta_t"``, ``"eta_tt"``: U, U_t, U_tt on
    the unknowns' owned dofs) by mat-vecs, without assembling. With `lumped` η's own U_tt column is left out (the
    schemes lump η's inertia on the nodes); r₀ is assembled again at each `apply` only when it reads a scene field
    (a load, an obstacle that moves), which `affine_in` allows there and nowhere else.
    """

    def __init__(self, nl, lumped: bool):
        zero = ufl.zero()
        R = ufl.replace(nl.residual, {nl.force: zero})
        U_tt = nl.eta_tt
        if lumped and nl.eta_dofs is not None:  # η's U_tt column off: as the scheme's mapping writes it
            U_tt = ufl.as_vector([0.0, *(nl.eta_tt[i] for i in range(1, nl.eta_tt.ufl_shape[0]))])
        R_tt = literal_components(ufl.replace(R, {nl.eta_tt: U_tt}))
        parts = {"eta": _derivative(R, nl.eta), "eta_t": _derivative(R, nl.eta_t)}
        if not (lumped and nl.eta_dofs is None):
            parts["eta_tt"] = _derivative(R_tt, nl.eta_tt)
        self.matrices = {name: A for name, a in parts.items() if (A := _assembled(a)) is not None}
        self.vecs = {name: A.createVecs() for name, A in self.matrices.items()}
        shape = nl.eta.ufl_shape
        r0 = ufl.algorithms.expand_derivatives(
            ufl.replace(R, {f: ufl.zero(*shape) for f in (nl.eta, nl.eta_t, nl.eta_tt)}))
        self.r0_form = None if r0.empty() else fem.form(r0)
        self.r0 = np.zeros(nl.space.dofmap.index_map.size_local * nl.space.dofmap.index_map_bs)
        self.moving = not r0.empty() and bool(_functions(r0))
        if self.r0_form is not None:
            self.r0_vec = compat.create_vector(self.r0_form)
            self._assemble_r0()

    def _assemble_r0(self) -> None:
        vec = self.r0_vec
        with vec.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector(vec, self.r0_form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.r0[:] = vec.array

    def constant(self) -> np.ndarray:
        """r₀ (assembled again when it reads a scene field)."""
        if self.moving:
            self._assemble_r0()
        return self.r0

    def apply(self, values: dict, out: np.ndarray, constant: bool = True) -> np.ndarray:
        """R at `values` (owned arrays by placeholder name; a missing one counts as 0) into `out`; without r₀ if not
        `constant` (the part linear in the unknowns)."""
        if constant and self.moving:
            self._assemble_r0()
        out[:] = self.r0 if constant else 0.0
        for name, A in self.matrices.items():
            if name in values:
                x, y = self.vecs[name]
                x.array[:] = values[name]  # (a number broadcast)
                A.mult(x, y)
                out += y.array
        return out


def _stack(mats: list) -> PETSc.Mat:
    """[A₁; A₂; …]: each rank's rows of A₁, then its rows of A₂, …: one mat-vec gives every product (as
    `fem.operators.stacked` for two)."""
    ia, ja, a = zip(*(A.getValuesCSR() for A in mats))
    offsets = np.cumsum([0] + [i[-1] for i in ia[:-1]])
    starts = np.concatenate([ia[0][:1]] + [i[1:] + o for i, o in zip(ia, offsets)])
    rows, cols = sum(A.getLocalSize()[0] for A in mats), mats[0].getLocalSize()[1]
    S = PETSc.Mat().createAIJ(size=((rows, PETSc.DECIDE), (cols, PETSc.DECIDE)),
                              csr=(starts, np.concatenate(ja), np.concatenate(a)), comm=mats[0].getComm())
    S.assemble()
    return S


def _component_columns(A: PETSc.Mat, component: int, k: int) -> PETSc.Mat | None:
    """A's columns of one component of a blocked space of block size k (global column j is component j mod k), as
    an AIJ matrix of A's shape; None if it has none."""
    if k == 1:
        return A
    ia, ja, a = A.getValuesCSR()
    keep = ja % k == component
    if not A.getComm().tompi4py().allreduce(bool(keep.any()), op=MPI.LOR):
        return None
    rows = np.repeat(np.arange(ia.size - 1), np.diff(ia))
    starts = np.concatenate([[0], np.cumsum(np.bincount(rows[keep], minlength=ia.size - 1))]).astype(ia.dtype)
    B = PETSc.Mat().createAIJ(size=A.getSizes(), csr=(starts, ja[keep], a[keep]), comm=A.getComm())
    B.assemble()
    return B


#: The unit values of (u, η^n, η^{n−1}, v^n) at which a scheme's (linear) quotient gives its coefficient of each.
UNITS = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))


class LevelTerms:
    """An affine residual at one scheme's quotients, by products with the unknowns' levels: without its nodal
    terms G(u) = Σ_j M_j (a_u u + a_0 e0 + a_m em + a_v v0) + r₀, each matrix of `AffineResidual` split by the
    component of its columns (η, each field: a scheme's quotient may differ between them, `projection`'s), with
    the scheme's coefficients (its quotients are linear: read off at unit values, `UNITS`).

    A step needs the matrices' products with its earlier solutions (e0, em) and the stored energy's with the new
    one. So the matrices that a later step applies again (a_0 or a_m ≠ 0) or that the ledger's viscous work reads
    (∂R/∂U_t, and ∂R/∂U on the dissipative fields' columns) are stacked with the energy's H in one matrix S: its
    product with each new solution (`products`) serves that step's ledger and the next two steps' known part (the
    caller keeps them, `NewtonStep._products_of`), so a step costs one mat-vec besides its solve. The methods take
    each level's values with its products, or None for products to be computed here.
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
        self.S = _stack(stack) if stack else None
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
        only). `own`: the terms are the stacked ones, whose products of u, e0, em come from `products` (computed
        when None)."""
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
    """A stored energy ∫Π(f) quadratic in its Function f: Π₀ + g·f + ½ f·H f, H and g assembled once, so that the
    ledger's energy costs a mat-vec (`LevelTerms.stored`) instead of an assembly. `of(f)` returns None when the
    energy is not quadratic with constant coefficients (then it is assembled as before)."""

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
