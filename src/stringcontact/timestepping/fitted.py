"""The ε-free scheme fitted to the Courant number (docs/explanation/schemes.md): `projection` with its lumped mass
replaced by M_eff = M_θ + β Δt² K, β = ¼ (the elastic term at Newmark's average, implicit), the same contact step,
restitution and release.

M_θ = M_L − Σ_edges θ_ij m_ij (e_i − e_j)(e_i − e_j)ᵀ keeps the row sums; on a uniform string the phase error is
(kh)² (θ − ½ − ν²)/12 + O((kh)⁴) at Courant number ν, so θ = ½ + ν², taken edge by edge from the edge's own ν (up to
`THETA_BOUND`, `blended_mass`), makes it fourth order. The energy ½|v^{n+1}|²_{M_θ} + ½|η^{n+½}|²_K is positive for
every Δt: no Δt_max. The start is of second order (M_eff a0 = b − K η^0 − C v0). The Newton path (`FITTED`) lumps
the mass.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import projection
from .base import PETSC_OPTIONS, RESTITUTION, mass_option, petsc_vector
from .linear import Linear, dirichlet_rows
from .release import start_correction

#: Newmark's β of the elastic term: ¼, the least that makes the energy positive whatever Δt.
BETA = 0.25
#: The blend θ at which an element's M_θ stops being positive definite, by the cell's dimension (an interval's element
#: matrix (h/6)[[3 − θ, θ], [θ, 3 − θ]] has the eigenvalue (h/6)(3 − 2θ); a triangle's (A/12)(4 − 3θ) at the worst).
THETA_BOUND = {1: 1.5, 2: 4.0 / 3.0}

#: The Newton path's difference quotients: projection's, with the elastic term at the β-average.
FITTED = projection.PROJECTION | {"eta": lambda u, e0, em, v0, dt: BETA * u + (1 - 2 * BETA) * e0 + BETA * em}


def blended_mass(M: PETSc.Mat, K: PETSc.Mat, m: np.ndarray, dt: float, dim: int) -> tuple[PETSc.Mat, np.ndarray]:
    """M_θ: the consistent mass `M` with each off-diagonal entry m_ij scaled by θ_ij = ½ + min(ν_ij², c²/ν_ij²), ν_ij² =
    Δt² max(−k_ij, 0)/(6 m_ij) the edge's Courant number squared and c = `THETA_BOUND` − ½ (so θ reaches the bound only
    at ν_ij² = c), and the diagonal m_i − Σ_j θ_ij m_ij, so that the row sums stay the lumped mass `m`. Returns M_θ and
    the θ of this rank's off-diagonal entries."""
    ia, ja, mv = M.getValuesCSR()
    ib, jb, kv = K.getValuesCSR()
    if not (np.array_equal(ia, ib) and np.array_equal(ja, jb)):
        raise ValueError("scheme 'fitted' needs the mass and stiffness matrices on one sparsity pattern")
    rows = np.repeat(np.arange(ia.size - 1), np.diff(ia)) + M.getOwnershipRange()[0]
    off = ja != rows
    courant2 = np.divide(dt**2 * np.maximum(-kv, 0.0), 6.0 * mv, out=np.zeros_like(mv), where=mv > 0)
    reach = THETA_BOUND.get(dim, 1.0) - 0.5  # θ = ½ + min(ν², c²/ν²): ½ + ν² up to the bound, then back down
    fitted = 0.5 + np.minimum(courant2, np.divide(reach**2, courant2, out=np.full_like(mv, np.inf), where=courant2 > 0))
    theta = np.where(off & (mv > 0), fitted, 0.0)
    values = theta * mv
    diagonal = m - np.add.reduceat(values, ia[:-1]) if values.size else m
    values[~off] = diagonal[rows[~off] - M.getOwnershipRange()[0]]
    M_theta = M.duplicate(copy=True)
    M_theta.setValuesCSR(ia, ja, values)
    M_theta.assemble()
    return M_theta, theta[off]


class FittedScheme(projection.ProjectionScheme):
    """`projection` with the effective mass M_θ + ¼Δt²K (the module docstring): no Δt_max, a second-order start."""

    DESCRIPTION = ("blended mass fitted to the Courant number, implicit elastic term (the trapezoidal average), "
                   "contact as a complementarity problem (no eps)")
    OPTIONS = (mass_option("blended"), RESTITUTION, PETSC_OPTIONS)
    QUOTIENTS = FITTED

    def _check_stability(self, nonlinear: bool) -> None:
        self.dt_max = math.inf  # the energy is positive for every Δt (the module docstring)

    def _check_fields_stiffness(self) -> None:
        return None

    def _inertia_matrix(self) -> PETSc.Mat:
        """(M_θ + ¼Δt²K)/Δt², kept for the products (`_inertia`); the theta range for `timings`."""
        problem = self.problem
        ops, dt = problem.ops, problem.dt
        M_theta, theta = blended_mass(ops.M, ops.K, ops.m, dt, problem.x.ndim)
        M_theta.axpy(BETA * dt**2, ops.K, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        M_theta.scale(1.0 / dt**2)
        self.inertia_matrix = M_theta
        lo, hi = (float(f(theta, initial=v)) for f, v in ((np.min, np.inf), (np.max, -np.inf)))
        lo, hi = problem.comm.allreduce(lo, op=MPI.MIN), problem.comm.allreduce(hi, op=MPI.MAX)
        self.theta_range = (lo, hi) if math.isfinite(lo) else (0.0, 0.0)
        n = problem.n_owned
        self._x, self._y = np.zeros(n), np.zeros(n)
        self._xv, self._yv = petsc_vector(self._x, problem.comm), petsc_vector(self._y, problem.comm)
        return M_theta.copy()

    def _inertia(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        self._x[:] = x
        self.inertia_matrix.mult(self._xv, self._yv)
        out[:] = self._y
        return out

    def _linear_timings(self):
        """projection's counters, and the range of the blend θ."""
        return super()._linear_timings() | {"blend": "theta in [{:.3g}, {:.3g}]".format(*self.theta_range)}

    def _start_correction(self, eta0: np.ndarray, v0: np.ndarray) -> np.ndarray:
        """(Δt²/2) a0 with M_eff a0 = b − Kη0 − Cv0 at the interior nodes, 0 where η0 is on the obstacle."""
        if self.newton is not None:
            return start_correction(self.problem, eta0, v0, self.psi, self.tol)
        problem, comm = self.problem, self.problem.comm

        def solve(force):
            M_eff = self.inertia_matrix.copy()
            M_eff.scale(problem.dt**2)
            dirichlet_rows(M_eff, problem.bc)
            a0 = np.zeros(problem.n_owned)
            Linear(M_eff, comm, problem.petsc_options, problem.bc, np.zeros(problem.bc.size), problem.x.ndim).solve(
                petsc_vector(np.where(problem.interior, force, 0.0), comm), petsc_vector(a0, comm))
            return a0

        return start_correction(problem, eta0, v0, self.psi, self.tol, solve)


__all__ = ["BETA", "FITTED", "THETA_BOUND", "FittedScheme", "blended_mass"]
