"""Contact that gives energy back only out of what it took (schemes `projection` and `fitted`;
docs/explanation/schemes.md): each node's contact account (`ContactAccount`: a landing fills it, a rebound or a release
may spend it, never below 0, so D_con ≥ 0 at every step); Signorini's release at a massless contact point
(``Model.release = "signorini"``, `MasslessRelease`: a node at rest on ψ whose neighbours are not takes the elastic
equilibrium as its row, and stays massless in flight while its account pays its momentum residual); and the
second-order start (`start_correction`).
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
from petsc4py import PETSc

from .base import Ranks, petsc_vector
from .complementarity import ActiveSet
from .implicit import acceleration, net_force

#: Round-off an account may be overdrawn by, relative to the sizes booked: a release that gives back exactly what the
#: landing took (the rod at Courant number 1) does so to round-off.
ACCOUNT_ROUNDOFF = 1e-12

#: What of an account's turnover counts as spent: a massless node in flight has its mass back then.
SPENT = 1e-9

#: Contact steps kept, one per massless set (a point contact alternates between two or three).
KEPT_STEPS = 4


def start_correction(problem, eta0: np.ndarray, v0: np.ndarray, psi: np.ndarray, tol: float,
                     solve=None) -> np.ndarray:
    """(Δt²/2) a0 on the free interior nodes (0 where η0 is within `tol` of ψ): a0 = m⁻¹(b − Kη0 − Cv0)
    (`implicit.acceleration`), or `solve`(b − Kη0 − Cv0) for another mass."""
    a0 = acceleration(problem, eta0, v0) if solve is None else solve(net_force(problem, eta0, v0))
    free = problem.interior & (np.asarray(eta0, dtype=float) > psi + tol)
    return np.where(free, 0.5 * problem.dt**2 * a0, 0.0)


class ContactAccount:
    """Each node's contact dissipation so far (this rank's nodes): `overdrawn(step)` says where a step's
    −½ F_i (η_i^{n+1} − η_i^{n−1}) would take it below 0 (beyond round-off), `book(step)` adds it."""

    def __init__(self, n: int):
        self.balance, self.turnover = np.zeros(n), np.zeros(n)

    def overdrawn(self, step: np.ndarray) -> np.ndarray:
        """Where adding `step` would take the account below 0 by more than round-off (`ACCOUNT_ROUNDOFF`)."""
        return self.balance + step < -ACCOUNT_ROUNDOFF * (self.turnover + np.abs(step))

    def deficit(self, step: np.ndarray, allsum) -> float:
        """How far `step` would take the accounts together below 0 beyond round-off (≤ 0: covered; `allsum`: ranks)."""
        total, turnover, change = allsum(float(self.balance.sum()), float(self.turnover.sum()), float(step.sum()))
        return -(total + change) - ACCOUNT_ROUNDOFF * (turnover + abs(change))

    def spent(self) -> np.ndarray:
        """Where the account holds no more than `SPENT` of what went through it (a release that gives back exactly
        what the landing took leaves round-off of its size)."""
        return self.balance <= SPENT * self.turnover

    def book(self, step: np.ndarray) -> None:
        """Add a step's contact dissipation, node by node."""
        self.balance += step
        self.turnover += np.abs(step)


class MasslessRelease:
    """The linear path's contact step with the massless rows of Signorini's release (the module docstring), for the
    `projection.ProjectionScheme` `scheme` (its step matrix A, ψ, tolerances). Each massless set's contact step is an
    `ActiveSet` on A with those rows replaced by K + C/Δt (factorised once, the last `KEPT_STEPS` kept)."""

    def __init__(self, scheme, A: PETSc.Mat):
        problem = scheme.problem
        self.scheme, self.problem, self.A = scheme, problem, A
        self.B = problem.ops.K.copy()  # the massless row: K + C/Δt
        self.B.axpy(1.0 / problem.dt, problem.ops.C, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.massless = np.zeros(problem.n_owned, dtype=bool)
        self.neighbours, self.border = _neighbours(problem.ops.K, problem.n_owned)
        self.account = ContactAccount(problem.n_owned)
        self.steps: OrderedDict = OrderedDict()
        self.ranks = Ranks(problem.comm)
        self.rhs = np.zeros(problem.n_owned)
        self.rhs_vec = petsc_vector(self.rhs, problem.comm)

    def _contact_step(self, S: np.ndarray) -> ActiveSet:
        """The `ActiveSet` of A with S's rows replaced by K + C/Δt (made once per set); the scheme's own for S empty."""
        if not self.ranks.any(bool(S.any())):
            return self.scheme.contact_step
        key = S.tobytes() if self.problem.comm.size == 1 else tuple(self.problem.comm.allgather(S.tobytes()))
        if key not in self.steps:
            problem, scheme = self.problem, self.scheme
            ia, ja, a = self.A.getValuesCSR()
            ib, jb, b = self.B.getValuesCSR()
            values = a.copy()
            for i in np.flatnonzero(S):
                if not np.array_equal(ja[ia[i]:ia[i + 1]], jb[ib[i]:ib[i + 1]]):
                    raise ValueError("release: the step and stiffness matrices differ in their sparsity")
                values[ia[i]:ia[i + 1]] = b[ib[i]:ib[i + 1]]
            A_S = self.A.duplicate(copy=True)
            A_S.setValuesCSR(ia, ja, values)
            A_S.assemble()
            step = ActiveSet(A_S, problem.comm, problem.petsc_options, problem.bc, problem.g, problem.x.ndim,
                             scheme.psi, problem.interior, force_tol=np.zeros(problem.n_owned))
            diagonal = self.A.getDiagonal().array  # the force's round-off scales with the row's diagonal
            step.force_tol = scheme.contact_step.force_tol * A_S.getDiagonal().array / np.maximum(diagonal, 1e-300)
            self.steps[key] = step
            while len(self.steps) > KEPT_STEPS:
                self.steps.popitem(last=False)
        self.steps.move_to_end(key)
        return self.steps[key]

    def step(self, new, e0, em, rhs: np.ndarray, residual) -> tuple[np.ndarray, np.ndarray]:
        """η^{n+1} into ``new.eta`` from the levels `e0` (η^n) and `em` (η^{n−1}) and the step's right-hand side `rhs`;
        `residual` is the scheme's momentum residual A η − b. Returns (the stored force, the force booked)."""
        problem, scheme = self.problem, self.scheme
        tol, psi = scheme.tol, scheme.psi
        resting = problem.interior & (np.abs(e0.eta - psi) <= tol) & (np.abs(em.eta - psi) <= tol)
        S = self._isolated((self.massless & ~self.account.spent()) | resting)
        guess = new.eta.copy()
        while True:
            self.rhs[:] = rhs
            self.rhs[S] = e0.kc[1][S] + problem.ops.load[S]  # the massless rows: (C/Δt) η^n + b
            new.eta[:] = guess
            F, _ = self._contact_step(S).solve(self.rhs_vec, new.eta_vec, self._massless_residual(new, S, residual))
            np.maximum(F, 0.0, out=F)
            R = residual(new.eta).copy()  # the momentum equations' residual: what the contact and the lost mass did
            held = F > 0
            work = np.where(S | held, R, 0.0)
            step = -0.5 * work * (new.eta - em.eta)
            over = S & self.account.overdrawn(step)
            if not self.ranks.any(bool(over.any())):
                break
            S = S & ~over  # those nodes take their mass back for this step
        self.account.book(step)
        self.massless = S
        return F, work

    def _isolated(self, S: np.ndarray) -> np.ndarray:
        """The nodes of S none of whose neighbours is in S (nor on another rank): a contact point, not a region."""
        rows, neighbour = self.neighbours
        crowded = np.zeros(S.size, dtype=bool)
        crowded[rows[np.append(S, False)[neighbour]]] = True
        return S & ~crowded & ~self.border

    def _massless_residual(self, level, S: np.ndarray, residual):
        """The contact step's residual: the momentum equations' (`residual`), the massless rows' on S."""
        def massless(eta):
            R = residual(eta)  # leaves [K η, (C/Δt) η] in the level
            R[S] = level.kc[0][S] + level.kc[1][S] - self.rhs[S]
            return R
        return massless


def _neighbours(K: PETSc.Mat, n: int) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """The owned nodes' neighbour pairs (row, neighbour) from K's off-diagonal entries, the neighbour as an owned index
    (n for another rank's), and whether a node has a neighbour on another rank."""
    ia, ja, _ = K.getValuesCSR()
    rows = np.repeat(np.arange(ia.size - 1), np.diff(ia))
    local = ja - K.getOwnershipRange()[0]
    off = local != rows
    rows, local = rows[off], local[off]
    local = np.where((local >= 0) & (local < n), local, n)
    border = np.zeros(n, dtype=bool)
    border[rows[local == n]] = True
    return (rows, local), border


__all__ = ["ACCOUNT_ROUNDOFF", "SPENT", "ContactAccount", "MasslessRelease", "start_correction"]
