"""The explicit step's stability: the top mode of M⁻¹K (power iteration on a string, SLEPc on a membrane or a
shell operator) and the largest stable Δt it gives, for `projection`'s linear and Newton paths alike."""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .base import petsc_vector

__all__ = ["dt_of_mode", "gershgorin_bound", "largest_stable_dt", "top_mode", "top_mode_krylov"]


def top_mode(K, m: np.ndarray, interior: np.ndarray, iterations: int = 200, rtol: float = 1e-6):
    """(λ_max, φ) of M⁻¹K on the interior nodes by power iteration, M = diag(m), φ normalised: from the alternating
    vector (the top mode on a uniform 1D mesh, close to it on others) until λ changes by less than `rtol`."""
    comm = K.getComm().tompi4py()
    phi = np.where(np.arange(m.size) % 2 == 0, 1.0, -1.0) * interior
    y = np.zeros_like(phi)
    vx, vy = petsc_vector(phi, K.getComm()), petsc_vector(y, K.getComm())
    lam = 0.0
    for _ in range(iterations):
        K.mult(vx, vy)
        y /= np.where(m > 0, m, 1.0)
        y *= interior
        norm = math.sqrt(comm.allreduce(float(np.dot(y, y))))
        if norm == 0.0:
            return 0.0, phi
        new = comm.allreduce(float(np.dot(phi, y))) / comm.allreduce(float(np.dot(phi, phi)))
        phi[:] = y / norm
        if abs(new - lam) <= rtol * abs(new):
            return new, phi
        lam = new
    return lam, phi


def top_mode_krylov(K: PETSc.Mat, m: np.ndarray, interior: np.ndarray, hermitian: bool = True,
                    rtol: float = 1e-10) -> tuple[float, np.ndarray]:
    """(λ_max, φ) of M⁻¹K on the interior nodes by SLEPc's Krylov-Schur on the shell D K D, D = M^(-1/2) (0 on the
    boundary), φ normalised: a 2D spectrum's top is crowded, and power iteration stalls below λ_max (overestimating
    dt_max). K may be a shell itself; not `hermitian` for η's stiffness with fields eliminated."""
    from slepc4py import SLEPc

    d = _scaling(m, interior)
    A = PETSc.Mat().createPython(K.getSizes(), _Scaled(K, d), comm=K.getComm())
    A.setUp()
    eps = SLEPc.EPS().create(A.getComm())
    eps.setOperators(A)
    eps.setProblemType(SLEPc.EPS.ProblemType.HEP if hermitian else SLEPc.EPS.ProblemType.NHEP)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_REAL)
    eps.setDimensions(1)
    eps.setTolerances(rtol, 10000)
    eps.solve()
    if eps.getConverged() < 1:
        raise RuntimeError("scheme 'projection': the top eigenvalue of M^-1 K did not converge (SLEPc)")
    y = A.createVecRight()
    lam = eps.getEigenpair(0, y).real
    phi = d * y.array
    return lam, phi / math.sqrt(A.getComm().tompi4py().allreduce(float(np.dot(phi, phi))))


def _scaling(m: np.ndarray, interior: np.ndarray) -> np.ndarray:
    """D = M^(-1/2) on the interior nodes, 0 on the boundary."""
    return np.where(interior, 1.0 / np.sqrt(np.where(m > 0, m, 1.0)), 0.0)


class _Scaled:
    """The shell D S D of `top_mode_krylov`."""

    def __init__(self, S: PETSc.Mat, d: np.ndarray):
        self.S, self.d = S, d
        self.x, self.y = S.createVecs()

    def mult(self, mat, x, y) -> None:
        self.x.array[:] = self.d * x.array_r
        self.S.mult(self.x, self.y)
        y.array[:] = self.d * self.y.array


def gershgorin_bound(K, m: np.ndarray, interior: np.ndarray) -> float:
    """Gershgorin's upper bound of λ_max(M⁻¹K) on the interior, max_i Σ_j |K_ij| / √(m_i m_j): one mat-vec with |K|."""
    ia, ja, a = K.getValuesCSR()  # this rank's rows, global columns
    absK = PETSc.Mat().createAIJ(size=K.getSizes(), csr=(ia, ja, np.abs(a)), comm=K.getComm())
    absK.assemble()
    d = _scaling(m, interior)
    out = absK.createVecLeft()
    absK.mult(petsc_vector(d, K.getComm()), out)
    return K.getComm().tompi4py().allreduce(float(np.max(d * out.array, initial=0.0)), op=MPI.MAX)


def largest_stable_dt(ops, interior: np.ndarray, krylov: bool = False, dt: float | None = None) -> float:
    """The explicit step's largest stable Δt from the top mode of M⁻¹K (`dt_of_mode`); `krylov` (2D): by SLEPc, which
    takes minutes on 1e5 nodes, so a `dt` below 2/√(Gershgorin's bound) (stable for any C ≥ 0) returns that bound."""
    if krylov and dt is not None:
        safe = 2.0 / math.sqrt(max(gershgorin_bound(ops.K, ops.m, interior), 1e-300))
        if dt <= safe:
            return safe
    lam, phi = (top_mode_krylov if krylov else top_mode)(ops.K, ops.m, interior)
    return dt_of_mode(lam, phi, ops.K, ops.C)


def dt_of_mode(lam: float, phi: np.ndarray, K: PETSc.Mat, C: PETSc.Mat) -> float:
    """The explicit step's largest stable Δt μ + √(μ² + 4/λ), (λ, φ) M⁻¹K's top mode, μ = φ·Cφ/φ·Kφ; inf if λ ≤ 0."""
    if lam <= 0:
        return math.inf
    comm = K.getComm()
    v, Kv, Cv = petsc_vector(phi, comm), K.createVecLeft(), C.createVecLeft()
    K.mult(v, Kv)
    C.mult(v, Cv)
    mpi = comm.tompi4py()
    damping = max(mpi.allreduce(float(np.dot(phi, Cv.array))) / mpi.allreduce(float(np.dot(phi, Kv.array))), 0.0)
    return damping + math.sqrt(damping * damping + 4.0 / lam)
