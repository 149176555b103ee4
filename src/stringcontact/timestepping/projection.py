"""Inelastic contact with no ε: central differences, implicit viscosity, and a nodal projection onto gap ≥ 0.

With lumped mass M and v^n = (η^n − η^{n−1})/Δt, the free step is

    M (η̃ − 2η^n + η^{n−1})/Δt² + C (η̃ − η^n)/Δt + K η^n = b,

(the elastic term explicit, the viscous one implicit: A = M/Δt² + C/Δt is factorised once), and then
η^{n+1} = η̃ + max(−gap(η̃), 0) at the interior nodes: every node that would pass the obstacle is put on
it. A node that lands keeps η^{n+1} = ψ, so its velocity becomes 0: restitution 0, the paper's (A4).
This is Paoli and Schatzman's scheme with e = 0. The model must declare ``gap`` (η − ψ).

Energy: with R = A(η^{n+1} − η̃), the reaction the projection applies, η^{n+1} solves the same step with
b + R on the right. Tested with (η^{n+1} − η^{n−1})/2 that gives exactly E^{n+1/2} − E^{n−1/2}
= −(Δt/2) v^{n+1}·C(v^{n+1} + v^n) + ½(b + R)·(η^{n+1} − η^{n−1}), with the leapfrog's energy
E^{n+1/2} = ½|v^{n+1}|²_M + ½ η^{n+1}·K η^n. So the numerical dissipation is 0, the viscous one is the first
term, and −½ R·(η^{n+1} − η^{n−1}) is the contact dissipation. R is the system's residual at η^{n+1}, so
a step costs one back-substitution and one mat-vec, as the paper's scheme does.

Stability: the energy is positive, so the scheme stable, while M − (Δt²/4) K + (Δt/2) C > 0. Along the top
eigenvector φ of M⁻¹K (eigenvalue λ, found by power iteration in 1D, by SLEPc on a 2D mesh) with
μ = φ·Cφ/φ·Kφ, that is Δt < μ + √(μ² + 4/λ): Δx on a uniform mesh with α = 0, more with viscosity (exact
when C = αK). On a 2D mesh a Δt below 2/√(Gershgorin's bound of λ) is stable without the eigenvalue.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InstabilityError
from ..scene.data import SceneWarning
from ..fem.operators import diagonal_matrix, stacked
from .base import Scheme as Base
from .base import Linear, any_rank, dirichlet_rows, summer, wrap


def top_mode(K, m: np.ndarray, interior: np.ndarray, iterations: int = 200, rtol: float = 1e-6):
    """(λ_max, φ) of M⁻¹K on the interior nodes by power iteration, M = diag(m) (ends held at 0).

    Starts from a node-alternating vector, which is the top mode on a uniform 1-D mesh and close to it
    on others; stops when λ changes by less than `rtol`. Returns (λ, φ) with φ normalised.
    """
    comm = K.getComm().tompi4py()
    phi = np.where(np.arange(m.size) % 2 == 0, 1.0, -1.0) * interior
    y = np.zeros_like(phi)
    vx, vy = wrap(phi, K.getComm()), wrap(y, K.getComm())
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


def top_mode_krylov(K, m: np.ndarray, interior: np.ndarray, rtol: float = 1e-10):
    """(λ_max, φ) of M⁻¹K on the interior nodes by SLEPc's Krylov-Schur, M = diag(m).

    For 2D meshes: the top of a 2D spectrum is crowded and on an unstructured mesh the top mode has no
    simple shape, so power iteration from any fixed start stalls below λ_max (and would overestimate
    dt_max). Solves the symmetric D K D y = λ y with D = M^(-1/2) on the interior (0 on the boundary).
    """
    from slepc4py import SLEPc

    d = np.where(interior, 1.0 / np.sqrt(np.where(m > 0, m, 1.0)), 0.0)
    A = K.copy()
    D = A.createVecLeft()
    D.array[:] = d
    A.diagonalScale(D, D)
    eps = SLEPc.EPS().create(K.getComm())
    eps.setOperators(A)
    eps.setProblemType(SLEPc.EPS.ProblemType.HEP)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_REAL)
    eps.setDimensions(1)
    eps.setTolerances(rtol, 10000)
    eps.solve()
    if eps.getConverged() < 1:
        raise RuntimeError("scheme 'projection': the top eigenvalue of M^-1 K did not converge (SLEPc)")
    y = A.createVecRight()
    lam = eps.getEigenpair(0, y).real
    phi = d * y.array
    comm = K.getComm().tompi4py()
    return lam, phi / math.sqrt(comm.allreduce(float(np.dot(phi, phi))))


def gershgorin_bound(K, m: np.ndarray, interior: np.ndarray) -> float:
    """An upper bound of λ_max(M⁻¹K) on the interior: max_i Σ_j |K_ij| / √(m_i m_j) (Gershgorin's discs of
    M^(-1/2) K M^(-1/2)); one mat-vec with |K|. Exact on a uniform right-diagonal mesh, above λ_max elsewhere."""
    ia, ja, a = K.getValuesCSR()  # this rank's rows, global columns
    absK = PETSc.Mat().createAIJ(size=K.getSizes(), csr=(ia, ja, np.abs(a)), comm=K.getComm())
    absK.assemble()
    d = np.where(interior, 1.0 / np.sqrt(np.where(m > 0, m, 1.0)), 0.0)
    out = absK.createVecLeft()
    absK.mult(wrap(d, K.getComm()), out)
    return K.getComm().tompi4py().allreduce(float(np.max(d * out.array, initial=0.0)), op=MPI.MAX)


def largest_stable_dt(ops, interior: np.ndarray, krylov: bool = False, dt: float | None = None) -> float:
    """μ + √(μ² + 4/λ), with λ and φ the top mode of M⁻¹K and μ = φ·Cφ/φ·Kφ (the viscous relief).

    `krylov` (2D meshes): λ from SLEPc instead of power iteration (the 1D interval, whose top mode is the
    alternating start vector). A 2D top mode costs seconds to minutes on 1e5 nodes (its spectrum is crowded),
    so when `dt` is below 2/√λ_G, with λ_G the Gershgorin bound (M − Δt²K/4 > 0 then, stable whatever C ≥ 0),
    that lower bound of Δt_max is returned and no eigenvalue is computed.
    """
    if krylov and dt is not None:
        safe = 2.0 / math.sqrt(max(gershgorin_bound(ops.K, ops.m, interior), 1e-300))
        if dt <= safe:
            return safe
    lam, phi = (top_mode_krylov if krylov else top_mode)(ops.K, ops.m, interior)
    if lam <= 0:
        return math.inf
    comm = ops.K.getComm()
    v, Kv, Cv = wrap(phi, comm), ops.K.createVecLeft(), ops.C.createVecLeft()
    ops.K.mult(v, Kv)
    ops.C.mult(v, Cv)
    mpi = comm.tompi4py()
    mu = mpi.allreduce(float(np.dot(phi, Cv.array))) / mpi.allreduce(float(np.dot(phi, Kv.array)))
    mu = max(mu, 0.0)
    return mu + math.sqrt(mu * mu + 4.0 / lam)


#: A node within CONTACT_TOL × (the data's height scale) of the obstacle is in contact: the implicit viscous
#: solve spreads round-off-size values (1e-64 ... 1e-14 seen on Example 1) over a region lying on it.
CONTACT_TOL = 1e-9


class Scheme(Base):
    PENALTIES = ()
    MASSES = ("lumped",)
    # With viscosity the nodal projection also moves the neighbours' viscous force (A = M/Δt² + C/Δt is not
    # diagonal), which can feed a little energy on coarse grids: Example 1 at nx = 125, none from 250 on.
    remedy = "refine the grid (nx and nt) or use scheme 'newmark'"

    @staticmethod
    def requires(model) -> str | None:
        if model.gap is None:
            return f"model '{model.name}' declares no gap (its law lets the string through the obstacle)"
        return None

    def __init__(self, s):
        super().__init__(s)
        ops, dt, comm, n = s.ops, s.dt, s.comm, s.n_owned
        self.dt_max = largest_stable_dt(ops, s.interior, krylov=s.x.ndim == 2, dt=dt)
        if dt > self.dt_max * (1 + 1e-12):
            T = dt * s.nt
            raise InstabilityError(
                f"scheme 'projection' is unstable with dt = {dt:.6g} > dt_max = {self.dt_max:.6g} (its explicit "
                f"elastic term; dt_max from the operators); use nt >= {math.ceil(T / self.dt_max)} "
                f"(dt <= {self.dt_max:.6g}), or scheme 'newmark' for larger steps",
                step=0, time=0.0,
            )
        self.A = diagonal_matrix(ops.M, ops.m / dt**2)
        self.A.axpy(1.0 / dt, ops.C, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        dirichlet_rows(self.A, s.bc)
        C_over_dt = ops.C.copy()
        C_over_dt.scale(1.0 / dt)
        self.KC = stacked(ops.K, C_over_dt)  # K η and (C/Δt) η of one η in one mat-vec
        self.linear = Linear(self.A, comm, s.petsc_options, s.bc, s.g, s.x.ndim)
        self.solve = self.linear.solve
        laws = s.laws
        self.gap = laws.compile(laws.model.gap(laws.eta, laws.params))
        self._check_gap()
        self.allsum = summer(comm)
        self.anysum = any_rank(comm)
        # Rotating rows, allocated once: η^{n+1}, η^n, η^{n−1}, and [K η, (C/Δt) η] of η^{n+1}, η^n, η^{n−1}.
        self.etas = [(wrap(a, comm), a) for a in np.zeros((3, n))]
        self.KCs = [(wrap(a, comm), a) for a in np.zeros((3, 2, n))]
        rhs = np.zeros(n)
        self.rhs = (wrap(rhs, comm), rhs)
        self.buf = np.zeros((3, n))  # scratch: the push, η^{n+1} − η^n, the reaction R
        self.m_dt2 = ops.m / dt**2
        self.inv_mF = np.divide(1.0, ops.m_force, out=np.zeros(n), where=ops.m_force > 0)
        self.force_density = np.zeros(n)
        self.has_load = bool(np.any(ops.load != 0))

    def _check_gap(self) -> None:
        """The projection adds −gap to η, the distance to ψ only if gap = η − ψ; and gap ≤ 0 must be the contact set."""
        laws, n = self.s.laws, self.s.n_owned
        model = laws.model
        g = [np.asarray(self.gap.evaluate_env(laws.env | {id(laws.eta): np.full(n, c)}), dtype=float) * np.ones(n)
             for c in (0.0, 1.0)]
        if not np.allclose(g[1] - g[0], 1.0, rtol=0, atol=1e-12):
            raise ValueError(f"model '{model.name}': scheme 'projection' needs gap = eta - psi (slope 1 in eta)")
        contact = laws.compile(model.contact_set(laws.eta, laws.params))
        psi = -g[0]
        for shift, expected in ((1e-3, False), (-1e-3, True)):
            found = np.asarray(contact.evaluate_env(laws.env | {id(laws.eta): psi + shift}), dtype=bool) * np.ones(n, bool)
            if np.any(found[self.s.interior] != expected):
                raise ValueError(f"model '{model.name}': its gap and contact_set disagree (gap <= 0 must be the contact "
                                 "set); a variant that moves the obstacle must give both")

    @property
    def eta(self):
        return self.etas[1][1]

    @property
    def velocity(self):
        return (self.etas[1][1] - self.etas[2][1]) / self.s.dt

    @property
    def contact_force(self):
        return self.force_density

    @property
    def timings(self):
        return {"linear solver": self.linear.describe()}

    def _project(self, eta: np.ndarray, push: np.ndarray) -> np.ndarray:
        """η + max(−gap(η), 0) at the interior nodes, in place; the correction into `push`."""
        self.s.laws.set(eta=eta)
        np.negative(self.gap.evaluate_env(self.s.laws.env), out=push)
        np.maximum(push, 0.0, out=push)
        push *= self.s.interior
        eta += push
        return push

    def contact(self) -> np.ndarray:
        laws = self.s.laws
        laws.set(eta=self.eta)
        return self._contact_law.evaluate_env(laws.env)

    def start(self, eta0, v0):
        s = self.s
        laws = s.laws
        scale = max(float(s.comm.allreduce(np.max(np.abs(eta0), initial=0.0), op=MPI.MAX)),
                    float(np.max(np.abs(s.g), initial=0.0)), 1e-300)
        tol = fem.Constant(laws.eta.function_space.mesh, PETSc.ScalarType(CONTACT_TOL * scale))
        self._contact_law = laws.compile(laws.model.contact_set(laws.eta - tol, laws.params))
        (_, e0), (_, em) = self.etas[1], self.etas[2]
        e0[:] = eta0
        if self.anysum(bool(np.any(self._project(e0, self.buf[0]) > 0))):
            warnings.warn("scheme 'projection': the initial displacement is below the obstacle at some nodes; "
                          "projected onto it at t = 0 (the penalty schemes let it rise through instead)",
                          SceneWarning, stacklevel=4)
        np.subtract(e0, s.dt * v0, out=em)
        for i in (1, 2):
            self.KC.mult(self.etas[i][0], self.KCs[i][0])
        d = e0 - em
        self.kin, self.el = self.allsum(0.5 * float(np.dot(d, self.m_dt2 * d)), 0.5 * float(np.dot(e0, self.KCs[2][1][0])))
        return self.kin, self.el, 0.0, 0.0, 0.0, 0.0, 0.0

    def step(self):
        s = self.s
        (v1, e1), (_, e0), (_, em) = self.etas
        (kc1v, kc1), (_, kc0), (_, kcm) = self.KCs
        (rhs_v, rhs), (push, d, R) = self.rhs, self.buf
        # free step: A η̃ = (M/Δt²)(2η^n − η^{n−1}) + (C/Δt) η^n − K η^n + b
        np.subtract(e0, em, out=rhs)
        rhs += e0
        rhs *= self.m_dt2
        rhs += kc0[1]
        rhs -= kc0[0]
        if self.has_load:
            rhs += s.ops.load
        for i, g in zip(s.bc, s.g):
            rhs[i] = g
        if self.linear.iterative:  # CG starts from the leapfrog's guess 2η^n − η^{n−1}
            np.subtract(e0, em, out=e1)
            e1 += e0
        self.solve(rhs_v, v1)
        self._project(e1, push)
        self.KC.mult(v1, kc1v)
        # R = A η^{n+1} − rhs, the reaction (0 at the ends, whose rows are the identity)
        np.multiply(self.m_dt2, e1, out=R)
        R += kc1[1]
        R -= rhs
        R *= s.interior
        np.subtract(e1, e0, out=d)
        kin = 0.5 * float(np.dot(d, self.m_dt2 * d))
        el = 0.5 * float(np.dot(e1, kc0[0]))
        visc = 0.5 * float(np.dot(d, kc1[1] - kcm[1]))  # (Δt/2) v¹·C(v¹ + v⁰), with Δt v = η differences
        d += e0
        d -= em  # now η^{n+1} − η^{n−1}
        con = -0.5 * float(np.dot(R, d))
        ext = 0.5 * float(np.dot(s.ops.load, d)) if self.has_load else 0.0
        kin, el, visc, con, ext = self.allsum(kin, el, visc, con, ext)
        np.multiply(R, self.inv_mF, out=self.force_density)
        self.etas = [self.etas[2], self.etas[0], self.etas[1]]  # η^{n−1} ← η^n ← η^{n+1}
        self.KCs = [self.KCs[2], self.KCs[0], self.KCs[1]]
        return kin, el, visc, con, 0.0, ext, 0.0


__all__ = ["Scheme", "gershgorin_bound", "largest_stable_dt", "top_mode", "top_mode_krylov"]
