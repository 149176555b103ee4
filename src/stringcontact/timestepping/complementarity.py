"""The contact step of the ε-free schemes, A η = b + F, η ≥ ψ, F ≥ 0, F·(η − ψ) = 0 at the interior nodes (the minimum
of ½ ηᵀAη − bᵀη over η ≥ ψ), and its solvers.

`ActiveSet` is the primal–dual active-set method (Hintermüller, Ito and Kunisch, SIAM J. Optim. 13, 2003) on the
scheme's own linear solver: fix 𝒜 on ψ, solve, read F = Aη − b, 𝒜 ← {F > 0 on 𝒜} ∪ {η < ψ off 𝒜} until it stays.
Started from the free step's {η̃ < ψ}: 1.11 solves and 0.14 refactorisations a step on Example 1, against 2.66 and
1.66 from the last step's 𝒜 (docs/explanation/study.md). Where it cycles (A not an M-matrix) SNES VI takes over
(`VariationalInequality`); a diagonal A (α = 0) is the nodal maximum max(A⁻¹b, ψ).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .base import Ranks, petsc_callback
from .linear import Linear, _symmetric_rows, dirichlet_rows, set_from_options

#: Active-set iterations before the step falls back to SNES VI. For an M-matrix they are at most the nodes that
#: change; Example 1 at the paper's resolution took 1 to 18 a step, and 130 once (its first landing).
MAX_ITERATIONS = 500

#: Global unknowns up to which the free step η̃ has its own solver, A factorised once (a second factor beside
#: the constrained one: 3.1 GB more at 1e6 nodes, 0.7 GB at 2.5e5). Above, 𝒜 starts from the previous step's.
PREDICT_MAX_NODES = 250_000

#: SNES VI takes its options under this prefix, set just before its setFromOptions and removed just after.
VI_PREFIX = "stringcontact_vi_"


class ActiveSet:
    """The contact step by the primal–dual active-set method on `linear.Linear`.

    ``solve(b, x, residual)`` puts η into the vector `x` and returns (F, iterations), F = A η − b on the active set
    and 0 elsewhere; `residual(x_array)` returns A η − b with 0 at the fixed ends (the scheme's, from the mat-vec
    its energy needs anyway). A node leaves 𝒜 only when its force is below −`force_tol` (per node: round-off in F
    cannot make the set cycle); η < ψ adds a node with no tolerance.
    """

    def __init__(self, A: PETSc.Mat, comm, options: dict | None, bc: np.ndarray, g: np.ndarray, dim: int,
                 psi: np.ndarray, interior: np.ndarray, force_tol: np.ndarray):
        self.A, self.bc, self.g = A, bc, g
        self.psi, self.interior, self.force_tol = psi, interior, force_tol
        self.steps = self.refactorisations = self.solves = self.free_solves = self.fallbacks = 0
        self.anywhere, self.comm = Ranks(comm).any, comm
        self.active, self.nodes = np.zeros(psi.size, dtype=bool), np.zeros(0, dtype=np.int32)
        self.fallback: VariationalInequality | None = None
        self.inverse_diagonal = inverse_diagonal(A, comm)
        if self.inverse_diagonal is not None:  # α = 0: no linear solver at all
            self.linear = self.free = None
            return
        self.work = A.duplicate(copy=True)  # A with 𝒜's rows (and, for CG, columns) fixed
        self.work.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)  # a new 𝒜 refactorises numerically only
        self.linear = Linear(self.work, comm, options, bc, g, dim)
        predict = dim == 1 or A.getSize()[0] <= PREDICT_MAX_NODES
        self.free = Linear(A.duplicate(copy=True), comm, options, bc, g, dim) if predict else None

    @property
    def iterative(self) -> bool:
        return self.linear is not None and self.linear.iterative

    def moved(self) -> None:
        """ψ changed in place (a moving obstacle): CG's lift of the held nodes and the fallback's bounds follow it."""
        if self.iterative and self.nodes.size:
            self._hold(self.active)
        self.fallback = None  # its bounds are the old ψ: made again if needed

    def describe_solver(self) -> str:
        """The linear solver's one line (`Linear.describe`), or why there is none."""
        if self.linear is None:
            return "none: the step matrix is diagonal (lumped mass, no viscosity)"
        return self.linear.describe(*([self.free] if self.free is not None else []))  # both solvers' iterations

    def _hold(self, active: np.ndarray) -> None:
        """Fix the nodes of `active` on ψ (besides the ends): A's rows there become the identity."""
        self.active, self.nodes = active, np.flatnonzero(active).astype(np.int32)
        fixed = np.concatenate([self.bc, self.nodes]).astype(np.int32)
        self.A.copy(self.work, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        if self.linear.iterative:  # CG needs the symmetric form: the fixed columns move to the right-hand side
            self.linear.lift = _symmetric_rows(self.work, fixed, np.concatenate([self.g, self.psi[self.nodes]]))
        else:
            dirichlet_rows(self.work, fixed)
        self.linear.bc = fixed
        self.linear.reset()
        self.refactorisations += 1

    def solve(self, b: PETSc.Vec, x: PETSc.Vec, residual) -> tuple[np.ndarray, int]:
        self.steps += 1
        rhs, eta = b.array, x.array
        active = self.active
        if self.free is not None or self.inverse_diagonal is not None:  # the free step first
            if self.inverse_diagonal is not None:
                np.multiply(rhs, self.inverse_diagonal, out=eta)
            else:
                self.free.solve(b, x)
                self.free_solves += 1
            active = self.interior & (eta < self.psi)
            if not self.anywhere(bool(active.any())):  # no contact: the free step is the answer
                residual(eta)
                return np.zeros_like(eta), 0
            if self.inverse_diagonal is not None:  # A diagonal: η = max(A⁻¹b, ψ) node by node, the active set's answer
                np.copyto(eta, self.psi, where=active)  # (benchmarks/bench_membrane.py --alpha 0: no factorisation)
                self.solves += 1
                return np.where(active, residual(eta), 0.0), 1
            if not self.anywhere(not np.array_equal(active, self.active)):  # every rank: holding is collective
                active = self.active
        seen, key = set(), None  # the active sets of this step (their keys cost an allgather under MPI)
        for k in range(1, MAX_ITERATIONS + 1):
            if active is not self.active:
                self._hold(active)
            saved = rhs[self.nodes]
            rhs[self.nodes] = self.psi[self.nodes]
            self.linear.solve(b, x)
            rhs[self.nodes] = saved
            R = residual(eta)
            new = self.interior & np.where(active, R > -self.force_tol, eta < self.psi)
            changed = self.anywhere(not np.array_equal(new, active))
            self.solves += 1
            if not changed:
                return np.where(active, R, 0.0), k
            seen.add(key if key is not None else self._key(active))
            key = self._key(new)
            if key in seen:  # a cycle (A is not an M-matrix)
                break
            active = new
        return self._fall_back(b, x, residual)

    def _key(self, active: np.ndarray) -> tuple:
        """The active set over all ranks, as a hashable key (one allgather of this rank's packed bits)."""
        mine = np.packbits(active).tobytes()
        return (mine,) if self.comm.size == 1 else tuple(self.comm.allgather(mine))

    def _fall_back(self, b: PETSc.Vec, x: PETSc.Vec, residual) -> tuple[np.ndarray, int]:
        """SNES VI from the last iterate; the active set it ends with is the next step's start."""
        if self.fallback is None:
            self.fallback = VariationalInequality(self.A, self.comm, self.psi, self.interior)
        self.fallbacks += 1
        force, its = self.fallback.solve(b, x, residual)
        self._hold(self.interior & (force > 0))
        return force, MAX_ITERATIONS + its

    def describe(self) -> str:
        """One line for the summary: what the contact steps cost."""
        if self.inverse_diagonal is not None:
            return f"nodal maximum (diagonal step matrix), contact in {self.solves} of {self.steps} steps"
        text = (f"active set, {self.free_solves / max(1, self.steps):.3g} free and {self.solves / max(1, self.steps):.3g}"
                f" constrained solves per step, {self.refactorisations} changes of the active set")
        return text + (f", {self.fallbacks} SNES VI fallbacks" if self.fallbacks else "")


def inverse_diagonal(A: PETSc.Mat, comm) -> np.ndarray | None:
    """1/a_ii of this rank's rows if A is diagonal on every rank (its off-diagonal entries stored zeros, as the
    viscous matrix's are at α = 0), else None."""
    ia, ja, a = A.getValuesCSR()
    rows = np.repeat(np.arange(ia.size - 1), np.diff(ia)) + A.getOwnershipRange()[0]
    d = A.getDiagonal().array
    diagonal = bool(np.all(a[ja != rows] == 0.0)) and bool(np.all(d != 0.0))
    if Ranks(comm).any(not diagonal):
        return None
    return 1.0 / d


class VariationalInequality:
    """The contact step by PETSc's SNES VI (`vinewtonrsls`) with the bounds ψ ≤ η at the interior nodes: about ten
    LU factorisations a step, so `ActiveSet`'s fallback only. `basic` cycled on a non-M-matrix, `bt` stalled on a step
    of Example 1: each is tried in turn from the same first guess."""

    LINE_SEARCHES = ("basic", "bt")

    def __init__(self, A: PETSc.Mat, comm, psi: np.ndarray, interior: np.ndarray, rtol: float = 1e-12):
        self.A, self.interior, self.psi = A, interior, psi
        self.f, self.b, self.guess = A.createVecLeft(), A.createVecLeft(), A.createVecRight()
        lower, upper = A.createVecRight(), A.createVecRight()
        lower.array[:] = np.where(interior, psi, PETSc.NINFINITY)
        upper.set(PETSc.INFINITY)
        self.solvers = [self._snes(comm, lower, upper, search, rtol) for search in self.LINE_SEARCHES]

    def _snes(self, comm, lower, upper, search: str, rtol: float) -> PETSc.SNES:
        snes = PETSc.SNES().create(comm)
        snes.setFunction(petsc_callback(self._residual), self.f)
        snes.setJacobian(self._jacobian, self.A, self.A)  # a static method: it holds nothing
        options = {"snes_type": "vinewtonrsls", "snes_linesearch_type": search, "snes_rtol": rtol,
                   "snes_atol": 1e-300, "snes_stol": 0.0, "snes_max_it": 200, "ksp_type": "preonly",
                   "pc_type": "lu"} | ({"pc_factor_mat_solver_type": "mumps"} if comm.size > 1 else {})
        set_from_options(snes, VI_PREFIX, options)  # petsc4py 3.18 has no getLineSearch: through the options
        snes.setVariableBounds(lower, upper)
        return snes

    def _residual(self, snes, x, f) -> None:
        self.A.mult(x, f)
        f.axpy(-1.0, self.b)

    @staticmethod
    def _jacobian(snes, x, J, P):  # A is constant
        return None

    def solve(self, b: PETSc.Vec, x: PETSc.Vec, residual) -> tuple[np.ndarray, int]:
        """η into `x` (its current values are the first guess), and (F, Newton iterations)."""
        b.copy(self.b)
        x.copy(self.guess)
        tried = []
        for snes in self.solvers:
            self.guess.copy(x)
            snes.setTolerances(atol=1e-14 * b.norm())  # a first guess already at round-off converges too
            snes.solve(None, x)
            tried.append(f"reason {snes.getConvergedReason()} after {snes.getIterationNumber()} iterations")
            if snes.getConvergedReason() > 0:
                R = residual(x.array)
                on = self.interior & (x.array <= self.psi)  # the bounds are met exactly where they are active
                return np.where(on, np.maximum(R, 0.0), 0.0), snes.getIterationNumber()
        raise ValueError("the contact step (SNES VI) did not converge: PETSc " + ", then ".join(tried))


__all__ = ["MAX_ITERATIONS", "ActiveSet", "VariationalInequality"]
