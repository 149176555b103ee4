"""Newmark's average-acceleration (trapezoidal) rule: energy-conserving and unconditionally stable
(docs/explanation/schemes.md). With a nodal velocity, η^{n+1} − η^n = (Δt/2)(v^{n+1} + v^n) and

    (4M/Δt² + 2C/Δt + K + 4D/Δt) η^{n+1} = 4M(η^n/Δt² + v^n/Δt) + (2C/Δt − K) η^n + 4D η^n/Δt + 2D v^n + 2b,

D = m_F∘d the model's `penalty_damping` on the active set: the semi-implicit penalty on the new velocity, which brakes
and never reflects; the matrix is refactorised when the active set changes. Its energy identity is exact: viscous
−(Δt/4)|v^{n+1} + v^n|²_C, contact −(Δt/2) v^{n+1}·D(v^{n+1} + v^n), no numerical dissipation. A moving obstacle: D
brakes v − ψ_t (ψ_t centred), and the force's work on ψ's motion, f·(ψ^{n+1} − ψ^n), is external work. A nonlinear
model takes the Newton path (`NEWMARK`).
"""

from __future__ import annotations

import numpy as np

from ..fem.operators import stacked, step_matrices
from .base import EPS, PETSC_OPTIONS, StepEnergy, check_law_stability, mass_option, penalty_option, petsc_vector
from .linear import Linear, dirichlet_rows
from .newton import NewtonStep, _NewtonScheme

#: The Newton path's difference quotients: v^{n+1} = 2(η^{n+1} − η^n)/Δt − v^n, η_tt → (v^{n+1} − v^n)/Δt,
#: η_t → (v^{n+1} + v^n)/2, η → (η^{n+1} + η^n)/2 (the trapezoidal rule of a linear model).
NEWMARK = {
    "eta": lambda u, e0, em, v0, dt: (u + e0) / 2,
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: 2 * (u - e0) / dt**2 - 2 * v0 / dt,
}


class NewmarkScheme(_NewtonScheme):
    """The trapezoidal rule: the linear path (the module docstring's matrix) for a linear model, the Newton path for
    a nonlinear one, with one damping law, release of held nodes and bookkeeping of a moving obstacle for both."""

    DESCRIPTION = "trapezoidal rule (energy-conserving), semi-implicit penalty on the active set"
    OPTIONS = (penalty_option("semi-implicit"), mass_option("lumped", "consistent"), EPS, PETSC_OPTIONS)

    @staticmethod
    def requires(model) -> str | None:
        if model.penalty_damping is None:
            return f"model '{model.name}' has no penalty_damping (its law is not a velocity damping)"
        return None

    def __init__(self, problem):
        super().__init__(problem)
        n, laws = problem.n_owned, problem.laws
        check_law_stability(laws.model, problem.dt, problem.eps, problem.penalty)
        self.damping = laws.compile(laws.model.penalty_damping(laws.eta, laws.v, laws.params))
        self.eta_, self.v = np.zeros(n), np.zeros(n)
        if problem.ops.nonlinear is not None:
            self.newton = NewtonStep(problem, NEWMARK)
            self.v_old = np.zeros(n)  # v^{n−1}: the guess extrapolates v
        else:
            self._linear_operators(problem)
            self.energy_may_rise = self.moving  # a moving obstacle gives the string energy

    def _linear_operators(self, problem) -> None:
        """The linear path's matrix, its factorisation (4D/Δt on its diagonal), the stacked [K; C], scratch vectors."""
        ops, dt, comm, n = problem.ops, problem.dt, problem.comm, problem.n_owned
        self.A, self.Ms, _ = step_matrices(ops, dt / 2, problem.mass)  # the paper's A at Δt/2, bit for bit
        dirichlet_rows(self.A, problem.bc)
        self.lu = Linear(self.A, comm, problem.petsc_options, problem.bc, problem.g, problem.x.ndim)
        self.KC = stacked(ops.K, ops.C)  # K η and C η of one η in one mat-vec
        self.KC_now, self.KC_new = ((petsc_vector(a, comm), a) for a in np.zeros((2, 2, n)))  # η^n's, η^{n+1}'s
        self.rhs, self.new, self.Mu, self.v_new = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        self.work = np.zeros((2, n))  # scratch for the right-hand side: no temporaries per step (measured: bench_step)
        self.vec = {k: petsc_vector(a, comm) for k, a in (("rhs", self.rhs), ("new", self.new), ("Mu", self.Mu),
                                                          ("v_new", self.v_new), ("work", self.work[0]))}
        self.D = np.zeros(n)  # m_F d on the active interior nodes
        self.rate_new = np.zeros(n)  # ψ_t^{k+1}, the rate the step's damping brakes towards

    def _mass(self, u: np.ndarray, name: str | None = None) -> np.ndarray:
        """M u (the scheme's mass matrix) into self.Mu; `name`: u's vector in `self.vec` (wrapped once)."""
        if self.problem.mass == "lumped":
            return np.multiply(self.problem.ops.m, u, out=self.Mu)
        self.Ms.mult(self.vec[name] if name else petsc_vector(u, self.problem.comm), self.vec["Mu"])
        return self.Mu

    def start(self, eta0, v0):
        if self.moving:
            self.problem.obstacle.set_centred(0.0)
        self.eta_[:], self.v[:] = eta0, v0
        if self.newton is not None:
            self.v_old[:] = v0
            self.newton.start_fields(eta0, v0)
            return self._start_energy(self.eta_, self.v)
        self.KC.mult(petsc_vector(self.eta_, self.problem.comm), self.KC_now[0])
        kin = 0.5 * float(np.dot(self.v, self._mass(self.v)))
        el = 0.5 * float(np.dot(self.eta_, self.KC_now[1][0]))
        kin, el = self.allsum(kin, el)
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def _active_damping(self) -> np.ndarray:
        """The model's damping d at η^n, v^n."""
        problem = self.problem
        problem.laws.set(eta=self.eta_, v=self.v)
        return np.asarray(self.damping.evaluate_env(problem.laws.env), dtype=float)

    def _solve(self) -> np.ndarray:
        """η^{n+1} into self.new for the current D; returns v^{n+1}."""
        problem, dt = self.problem, self.problem.dt
        eta, v, D = self.eta_, self.v, self.D
        a, b = self.work  # the same operations as written out with temporaries, into two buffers (bit for bit)
        np.multiply(4.0 / dt, D, out=a)
        self.lu.update(a)
        rhs = self.rhs
        np.divide(eta, dt**2, out=a)
        np.divide(v, dt, out=b)
        a += b
        rhs[:] = self._mass(a, "work")
        rhs *= 4.0
        np.multiply(2.0 / dt, self.KC_now[1][1], out=a)
        a -= self.KC_now[1][0]
        rhs += a
        np.multiply(4.0 / dt, eta, out=a)
        np.multiply(2.0, v, out=b)
        a += b
        a *= D
        rhs += a
        np.multiply(2.0, problem.ops.load, out=b)
        rhs += b
        if self.moving:  # the damping's target, −D(v^{n+1} − ψ_t^{n+1}): 2Dψ_t^{n+1} on the right
            np.multiply(2.0, D, out=b)
            b *= self.rate_new
            rhs += b
        problem.hold_ends(rhs)
        if self.lu.iterative:  # CG starts from the guess η^n + Δt v^n
            np.add(eta, dt * v, out=self.new)
        self.lu.solve(self.vec["rhs"], self.vec["new"])
        v_new = np.subtract(self.new, eta, out=self.v_new)  # 2/Δt (η^{n+1} − η^n) − v^n
        np.multiply(2.0 / dt, v_new, out=v_new)
        v_new -= v
        v_new[problem.bc] = 0.0
        return v_new

    def _obstacle_work(self, f: np.ndarray) -> float:
        """A moving obstacle's work f·(ψ^{n+1} − ψ^n) on the string (this rank's), which moves from the contact term
        to the external work; 0 for an obstacle at rest."""
        if not self.moving:
            return 0.0
        o, t = self.problem.obstacle, (self.k + 1) * self.problem.dt
        return float(np.dot(f, o.at(t)[: o.n] - o.at(t - o.dt)[: o.n]))

    def _rate(self):
        """ψ_t^{n+1}, the rate the step's damping brakes towards (0 for an obstacle at rest)."""
        problem = self.problem
        return problem.obstacle.centred_rate((self.k + 1) * problem.dt)[: problem.n_owned] if self.moving else 0.0

    def _advanced(self) -> None:
        """The step index on; a moving obstacle's fields at t^k (the stored row's contact set, the next active set)."""
        self.k += 1
        if self.moving:
            self.problem.obstacle.set_centred(self.k * self.problem.dt)

    def step(self):
        if self.newton is not None:
            return self._newton_step()
        problem, dt = self.problem, self.problem.dt
        eta, v, D = self.eta_, self.v, self.D
        KC_now, KC_new = self.KC_now[1], self.KC_new[1]
        np.multiply(self._active_damping(), problem.interior, out=self.work[0])
        np.multiply(problem.ops.m_force, self.work[0], out=D)
        if self.moving:
            self.rate_new[:] = self._rate()
        v_new = self._solve()
        # A damping that holds a node down (F = −D v^{n+1} < 0, it wants to lift) would do work against the
        # mean velocity and raise the energy: release such nodes and solve again (a few times at most).
        while self.anysum(bool(np.any(sticky := (D > 0) & (v_new > self.rate_new)))):
            D[sticky] = 0.0
            v_new = self._solve()
        self.KC.mult(self.vec["new"], self.KC_new[0])
        mean, b = np.add(v_new, v, out=self.work[0]), self.work[1]
        np.subtract(KC_new[1], KC_now[1], out=b)
        visc = 0.5 * float(np.dot(mean, b))  # (Δt/4)|v¹+v⁰|²_C, with C(η¹ − η⁰) = (Δt/2) C(v¹+v⁰)
        np.multiply(D, v_new - self.rate_new if self.moving else v_new, out=b)  # −f, f = −D(v^{n+1} − ψ_t^{n+1})
        work = self._obstacle_work(-b) if self.moving else 0.0  # the obstacle's share of f's work: external work
        con = 0.5 * dt * float(np.dot(mean, b)) + work  # −(Δt/2) f·(v^{n+1} + v^n)
        ext = 0.5 * dt * float(np.dot(problem.ops.load, mean)) + work
        kin = 0.5 * float(np.dot(v_new, self._mass(v_new, "v_new")))
        el = 0.5 * float(np.dot(self.new, KC_new[0]))
        kin, el, visc, con, ext = self.allsum(kin, el, visc, con, ext)
        b[:] = 0.0  # −(D/m_F)·v^{n+1}, 0 where no force acts (m_F = 0)
        np.divide(D, problem.ops.m_force, out=b, where=problem.ops.m_force > 0)
        np.negative(b, out=b)
        np.multiply(b, v_new - self.rate_new if self.moving else v_new, out=self.force_density)
        eta[:], v[:] = self.new, v_new
        self.KC_now, self.KC_new = self.KC_new, self.KC_now
        self._advanced()
        return StepEnergy(kin, el, visc, con, 0.0, ext, 0.0)

    def _newton_step(self):
        """The Newton path's step: the quotients `NEWMARK` in the model's residual, the damping on the diagonal."""
        problem, dt, newton = self.problem, self.problem.dt, self.newton
        e0, v = self.eta_, self.v
        newton.set_known(e0, None, v)
        D = self._active_damping() * problem.interior * problem.ops.m_force
        rate = self._rate()
        while True:  # −D (v^{n+1} − ψ_t^{n+1}) = −(2D/Δt)(u − η^n − (Δt/2)(v^n + ψ_t^{n+1}))
            newton.d[:], newton.c[:] = 2.0 * D / dt, e0 + 0.5 * dt * (v + rate)
            u = newton.solve(None if newton.guessless else e0 + dt * v + 0.5 * dt * (v - self.v_old))  # v extrapolated
            v1 = 2.0 * (u - e0) / dt - v
            v1[problem.bc] = 0.0
            sticky = (D > 0) & (v1 > rate)  # a damping that would hold a node down: released (as on the linear path)
            if not self.anysum(bool(np.any(sticky))):
                break
            D[sticky] = 0.0
        f = -D * (v1 - rate)
        terms = self._step_energy(u, e0, v, v1, f, self._obstacle_work)
        np.divide(f, problem.ops.m_force, out=self.force_density, where=problem.ops.m_force > 0)
        self.force_density[problem.ops.m_force <= 0] = 0.0
        self.v_old[:], self.eta_[:], self.v[:] = v, u, v1
        self._advanced()
        return terms


__all__ = ["NEWMARK", "NewmarkScheme"]
