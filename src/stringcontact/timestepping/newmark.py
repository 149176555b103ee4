"""Newmark's average-acceleration (trapezoidal) rule: energy-conserving and unconditionally stable.

With a nodal velocity v and η^{n+1} − η^n = (Δt/2)(v^{n+1} + v^n),

    M (v^{n+1} − v^n)/Δt + C (v^{n+1} + v^n)/2 + K (η^{n+1} + η^n)/2 = −D v^{n+1} + b,

where D = m_F∘d is the model's `penalty_damping` d on the active set χ{η^n < 0, v^n < 0} (lumped): the
semi-implicit penalty, applied to the *new* velocity so that it brakes and never reflects (with ε → 0,
v^{n+1} → 0 on landing). Eliminating v^{n+1},

    (4M/Δt² + 2C/Δt + K + 4D/Δt) η^{n+1} = 4M(η^n/Δt² + v^n/Δt) + (2C/Δt − K) η^n + 4D η^n/Δt + 2D v^n + 2b.

Only the diagonal changes with the active set; the matrix is refactorised then. Multiplying by
η^{n+1} − η^n gives the energy identity exactly: ½|v|²_M + ½|η|²_K changes by −(Δt/4)|v^{n+1} + v^n|²_C
(viscous), −(Δt/2) v^{n+1}·D(v^{n+1} + v^n) (contact) and the load's work. There is no numerical
dissipation: with no contact and α = 0 the energy is conserved to round-off. Any Δt, either mass matrix.

A moving obstacle ψ(x, t) (`base.MovingObstacle`): the damping brakes the gap rate, −D(v^{n+1} − ψ_t^{n+1}), on
the active set χ{η^n < ψ^n, v^n < ψ_t^n}, with ψ_t^k the centred quotient (ψ^{k+1} − ψ^{k−1})/(2Δt) (exact on a
uniformly accelerating obstacle, which the nodal velocity then follows at the force m a) in
``p.extra["obstacle_rate"]``; the right-hand side gains 2Dψ_t^{n+1}. The force f = −D(v^{n+1} − ψ_t^{n+1})
does the work f·(η^{n+1} − η^n) on the string: its share f·(ψ^{n+1} − ψ^n) is the obstacle's work, booked as
external work, and the rest, −f·(gap^{n+1} − gap^n), the contact dissipation. The identity stays exact.

A nonlinear model takes the Newton path: the same step with the quotients `NEWMARK` in the model's residual, the
semi-implicit penalty −D v^{n+1} on the diagonal, the same release of nodes it would hold down. Energy: kinetic
½|v^{n+1}|²_M, the model's stored energy, δ = η^{n+1} − η^n, contact −(Δt/2) f·(v^n + v^{n+1}), and as numerical
dissipation the rest of the identity (the midpoint rule of a nonlinear force does not conserve its energy).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..fem.operators import diagonal_matrix, stacked
from .base import EPS, PETSC_OPTIONS, Ranks, StepEnergy, check_law_stability, mass_option, penalty_option, petsc_vector
from .implicit import kinetic_energy
from .linear import DampedLU, dirichlet_rows
from .newton import NewtonStep, _NewtonScheme

#: The scheme's difference quotients on its Newton path (a nonlinear model): v^{n+1} = 2(η^{n+1} − η^n)/Δt − v^n,
#: η_tt → (v^{n+1} − v^n)/Δt, η_t → (v^{n+1} + v^n)/2, η → (η^{n+1} + η^n)/2 (the midpoint: the trapezoidal rule
#: of a linear model).
NEWMARK = {
    "eta": lambda u, e0, em, v0, dt: (u + e0) / 2,
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: 2 * (u - e0) / dt**2 - 2 * v0 / dt,
}


class NewmarkScheme(_NewtonScheme):
    """The trapezoidal rule: the linear path (the module docstring's matrix, refactorised when the active set
    changes) for a linear model, the Newton path for a nonlinear one, with one damping law, one release of held
    nodes and one bookkeeping of a moving obstacle's work for both."""

    DESCRIPTION = "trapezoidal rule (energy-conserving), semi-implicit penalty on the active set"
    OPTIONS = (penalty_option("semi-implicit"), mass_option("lumped", "consistent"), EPS, PETSC_OPTIONS)
    remedy = "use a smaller dt"

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
        self.allsum, self.anysum = Ranks(problem.comm).sum, Ranks(problem.comm).any
        self.eta_, self.v_ = np.zeros(n), np.zeros(n)
        self.force_density = np.zeros(n)
        self.moving = problem.obstacle is not None  # ψ(x, t): the damping brakes v − ψ_t (module docstring)
        self.k = 0  # the step index: η^k is the current state
        if problem.ops.nonlinear is not None:
            self.newton = NewtonStep(problem, NEWMARK)
            self.v_old = np.zeros(n)  # v^{n−1}: the guess extrapolates v
        else:
            self.newton = None
            self._linear_operators(problem)
            self.energy_may_rise = self.moving  # a moving obstacle gives the string energy

    def _linear_operators(self, problem) -> None:
        """The linear path's matrix, its factorisation, the stacked [K; C] and the scratch vectors."""
        ops, dt, comm, n = problem.ops, problem.dt, problem.comm, problem.n_owned
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        self.Ms = diagonal_matrix(ops.M, ops.m) if problem.mass == "lumped" else ops.M
        self.A = ops.K.copy()
        self.A.axpy(2.0 / dt, ops.C, structure=same)
        self.A.axpy(4.0 / dt**2, self.Ms, structure=same)
        dirichlet_rows(self.A, problem.bc)
        # 4D/Δt goes on its diagonal
        self.lu = DampedLU(self.A, comm, problem.petsc_options, problem.bc, problem.g, problem.x.ndim)
        self.KC = stacked(ops.K, ops.C)  # K η and C η of one η in one mat-vec
        self.KC_now, self.KC_new = ((petsc_vector(a, comm), a) for a in np.zeros((2, 2, n)))  # [K η; C η], η^n and η^{n+1}
        self.rhs, self.new, self.Mu = np.zeros(n), np.zeros(n), np.zeros(n)
        self.v_new = np.zeros(n)
        self.work = np.zeros((2, n))  # scratch for the right-hand side: no temporaries per step (measured: bench_step)
        self.vec = {k: petsc_vector(a, comm) for k, a in (("rhs", self.rhs), ("new", self.new), ("Mu", self.Mu),
                                                  ("v_new", self.v_new), ("work", self.work[0]))}  # wrapped once
        self.D = np.zeros(n)  # m_F d on the active interior nodes
        self.rate_new = np.zeros(n)  # ψ_t^{k+1}, the rate the step's damping brakes towards

    @property
    def eta(self):
        return self.eta_

    @property
    def velocity(self):
        return self.v_

    @property
    def contact_force(self):
        return self.force_density

    @property
    def timings(self):
        if self.newton is not None:
            return self.newton.describe()
        return {"refactorisations": self.lu.refactorisations, "linear solver": self.lu.linear.describe()}

    def _mass(self, u: np.ndarray, name: str | None = None) -> np.ndarray:
        """M u (the scheme's mass matrix) into self.Mu; `name`: u's vector in `self.vec` (wrapped once)."""
        if self.problem.mass == "lumped":
            return np.multiply(self.problem.ops.m, u, out=self.Mu)
        self.Ms.mult(self.vec[name] if name else petsc_vector(u, self.problem.comm), self.vec["Mu"])
        return self.Mu

    def start(self, eta0, v0):
        if self.moving:
            self.problem.obstacle.set_centred(0.0)
        self.eta_[:], self.v_[:] = eta0, v0
        if self.newton is not None:
            self.v_old[:] = v0
            self.newton.start_fields(eta0, v0)
            kin, el = self.allsum(kinetic_energy(self.problem, self.v_), self._stored(self.eta_))
            self.E = kin + el
            return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.KC.mult(petsc_vector(self.eta_, self.problem.comm), self.KC_now[0])
        kin = 0.5 * float(np.dot(self.v_, self._mass(self.v_)))
        el = 0.5 * float(np.dot(self.eta_, self.KC_now[1][0]))
        self.kin, self.el = self.allsum(kin, el)
        return StepEnergy(self.kin, self.el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def _active_damping(self) -> None:
        """D = m_F d at η^n, v^n."""
        problem = self.problem
        problem.laws.set(eta=self.eta_, v=self.v_)
        d = np.asarray(self.damping.evaluate_env(problem.laws.env), dtype=float)
        np.multiply(d, problem.interior, out=self.work[0])  # (d·1 is d: the old `* np.ones` only broadcast a constant)
        np.multiply(problem.ops.m_force, self.work[0], out=self.D)

    def _solve(self) -> np.ndarray:
        """η^{n+1} into self.new for the current D; returns v^{n+1}."""
        problem, dt = self.problem, self.problem.dt
        eta, v, D = self.eta_, self.v_, self.D
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
        """A moving obstacle's work f·(ψ^{n+1} − ψ^n) on the string (this rank's; the module docstring), which moves
        from the contact term to the external work; 0 for an obstacle at rest."""
        if not self.moving:
            return 0.0
        o, t = self.problem.obstacle, (self.k + 1) * self.problem.dt
        return float(np.dot(f, o.at(t)[: o.n] - o.at(t - o.dt)[: o.n]))

    def step(self):
        if self.newton is not None:
            return self._newton_step()
        problem, dt = self.problem, self.problem.dt
        eta, v, D = self.eta_, self.v_, self.D
        KC_now, KC_new = self.KC_now[1], self.KC_new[1]
        self._active_damping()
        if self.moving:
            self.rate_new[:] = self.problem.obstacle.centred_rate((self.k + 1) * dt)[: self.problem.n_owned]
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
        if self.moving:  # −(Δt/2) f·(v^{n+1} + v^n), f = −D(v^{n+1} − ψ_t^{n+1})
            con = 0.5 * dt * float(np.dot(mean, np.multiply(D, v_new - self.rate_new, out=b)))
            f = np.subtract(self.v_new, self.rate_new, out=self.work[1])  # f = −D(v^{n+1} − ψ_t^{n+1})
            f *= self.D
            np.negative(f, out=f)
            work = self._obstacle_work(f)
            con += work
        else:
            con, work = 0.5 * dt * float(np.dot(mean, np.multiply(D, v_new, out=b))), 0.0
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
        self.k += 1
        if self.moving:  # the law's fields at t^{k}: the stored row's contact set, the next step's active set
            self.problem.obstacle.set_centred(self.k * dt)
        return StepEnergy(kin, el, visc, con, 0.0, ext, 0.0)

    def _newton_step(self):
        """The Newton path's step: the quotients `NEWMARK` in the model's residual, the damping on the diagonal."""
        problem, dt, newton = self.problem, self.problem.dt, self.newton
        e0, v = self.eta_, self.v_
        newton.set_known(e0, None, v)
        problem.laws.set(eta=e0, v=v)
        D = (np.asarray(self.damping.evaluate_env(problem.laws.env), dtype=float) * problem.interior
             * problem.ops.m_force)
        # ψ_t^{n+1}: D brakes v − ψ_t
        rate = problem.obstacle.centred_rate((self.k + 1) * dt)[: problem.n_owned] if self.moving else 0.0
        while True:  # −D (v^{n+1} − ψ_t^{n+1}) = −(2D/Δt)(u − η^n − (Δt/2)(v^n + ψ_t^{n+1}))
            newton.d[:], newton.c[:] = 2.0 * D / dt, e0 + 0.5 * dt * (v + rate)
            u = newton.solve(None if newton.guessless else e0 + dt * v + 0.5 * dt * (v - self.v_old))  # v^{n+1} extrapolated
            v1 = 2.0 * (u - e0) / dt - v
            v1[problem.bc] = 0.0
            sticky = (D > 0) & (v1 > rate)  # a damping that would hold a node down: released (as on the linear path)
            if not self.anysum(bool(np.any(sticky))):
                break
            D[sticky] = 0.0
        f = -D * (v1 - rate)
        delta = u - e0
        visc_vec = newton.viscous_force(u)
        kin, el, visc, con, ext, work = self.allsum(
            kinetic_energy(problem, v1), self._stored(u), float(np.dot(visc_vec * problem.interior, delta)),
            -0.5 * dt * float(np.dot(f, v + v1)), float(np.dot(problem.ops.load, delta)), self._obstacle_work(f))
        num = self.E - (kin + el) - visc - con + ext
        con, ext = con + work, ext + work  # the obstacle's share of the force's work: external, not dissipated
        self.E = kin + el
        np.divide(f, problem.ops.m_force, out=self.force_density, where=problem.ops.m_force > 0)
        self.force_density[problem.ops.m_force <= 0] = 0.0
        self.v_old[:], self.eta_[:], self.v_[:] = v, u, v1
        self.k += 1
        if self.moving:  # the law's fields at t^k: the stored row's contact set, the next step's active set
            self.problem.obstacle.set_centred(self.k * dt)
        return StepEnergy(kin, el, visc, con, num, ext, 0.0)


__all__ = ["NEWMARK", "NewmarkScheme"]
