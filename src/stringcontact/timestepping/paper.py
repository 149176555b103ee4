"""The paper's Section 6 scheme: implicit elastic and viscous terms, the contact force from the previous step
(docs/explanation/schemes.md). A η^{n+1} = (M/Δt²)(2η^n − η^{n−1}) + (C/Δt) η^n + m_F∘F(η^n, v^n) + b with
A = M/Δt² + C/Δt + K factorised once; ``penalty="semi-implicit"`` puts the law as a damping d on A's diagonal,
F = −d v^{n+1} (−d (v^{n+1} − Δψ/Δt) with a moving obstacle). The numerical dissipation is ½|v^{n+1} − v^n|²_M +
½|η^{n+1} − η^n|²_K + (Δt/2) f·(v^n − v^{n+1}). A step is one mat-vec with the stacked [K; C/Δt], one back-substitution
and a few ufuncs into arrays allocated once, whose rows swap roles each step (K η, C η and M v are reused).
"""

from __future__ import annotations

import numpy as np

from ..fem.operators import stacked, step_matrices
from .base import StepEnergy, petsc_vector
from .implicit import ImplicitScheme
from .linear import Linear, dirichlet_rows
from .newton import _NewtonScheme

#: The scheme's difference quotients (its Newton path: `implicit.ImplicitScheme`): implicit Euler in η.
PAPER = {
    "eta": lambda u, e0, em, v0, dt: u,
    "eta_t": lambda u, e0, em, v0, dt: (u - e0) / dt,
    "eta_tt": lambda u, e0, em, v0, dt: (u - 2 * e0 + em) / dt**2,
}


class PaperScheme(ImplicitScheme):
    """The paper's scheme: the Newton path for a nonlinear model (`ImplicitScheme` with the quotients `PAPER`), the
    same step with the constant operators for a linear one (the module docstring)."""

    DESCRIPTION = "the paper's Section 6: implicit elastic and viscous terms, penalty from the previous step"
    QUOTIENTS = PAPER
    LINEAR_PATH = True

    def __init__(self, problem):
        if problem.ops.nonlinear is not None:  # the Newton path
            super().__init__(problem)
            return
        _NewtonScheme.__init__(self, problem)
        ops, dt, comm, n = problem.ops, problem.dt, problem.comm, problem.n_owned
        laws = problem.laws
        self.force_law = self._penalty_law(problem)
        self.A, self.Ms, C_over_dt = step_matrices(ops, dt, problem.mass)
        self.KC = stacked(ops.K, C_over_dt)  # K η and (C/Δt) η of one η in one mat-vec
        dirichlet_rows(self.A, problem.bc)
        self.energy_law = None
        if laws.model.contact_energy is not None:
            self.energy_law = laws.compile(laws.model.contact_energy(laws.eta, laws.params))
        # the semi-implicit penalty's damping goes on its diagonal
        self.lu = Linear(self.A, comm, problem.petsc_options, problem.bc, problem.g, problem.x.ndim)
        # Dotted with v^{n+1}: C v^{n+1}, the applied force m_F∘F, M v^{n+1} and M v^n (rows 2, 3 alternate).
        self.by_v = np.zeros((4, n))
        self.KC_etas = np.zeros((2, 2, n))  # [K η, (C/Δt) η] of η^{n+1} and of η^n
        # η^{n+1}, η^n, η^{n−1} and v^{n+1}, v^n in rows of one array each, whose roles rotate
        self.eta_new, self.eta_now, self.eta_old = ((petsc_vector(r, comm), r) for r in np.zeros((3, n)))
        self.v_new, self.v_now = ((petsc_vector(r, comm), r) for r in np.zeros((2, n)))
        self.M_v_new, self.M_v = ((petsc_vector(r, comm), r) for r in self.by_v[2:])
        self.KC_new, self.KC_old = ((petsc_vector(p, comm), p) for p in self.KC_etas)
        # b; with the consistent mass 2η^n − η^{n−1}
        self.rhs, self.two_steps = ((petsc_vector(r, comm), r) for r in np.zeros((2, n)))
        self.dots_v, self.dots_K = np.zeros(4), np.zeros(2)
        self.diag_w = np.zeros(n)  # semi-implicit: the damping weights m_F d / Δt on the active set
        self.m_dt2 = ops.m / dt**2
        self.has_load = bool(np.any(ops.load != 0))
        self.step_index = 0
        self.law_ahead = (-1, None)  # (step index, F) of the law evaluated by `contact_force`
        # Read every step: set once (see `step`).
        self.dt, self.explicit, self.lumped = dt, problem.penalty == "explicit", problem.mass == "lumped"
        self.m, self.m_force, self.load, self.hold_ends = ops.m, ops.m_force, ops.load, problem.hold_ends
        self.iterative = self.lu.iterative
        self.env, self.key_eta, self.key_eta_old = laws.env, laws.key("eta"), laws.key("eta_old")
        self.K_etas = self.KC_etas[:, 0]  # K η of η^{n+1} and of η^n: a view, taken once
        self.energy_may_rise = self.moving  # a moving obstacle gives the string energy

    @property
    def eta(self):
        return self.eta_now[1] if self.newton is None else self.eta_

    @property
    def velocity(self):
        return self.v_now[1] if self.newton is None else self.v

    @property
    def contact_force(self):
        """The force density at the current state: with the explicit penalty the paper's F(η^n, v^n), the force
        the next step applies (so it lives on the contact set at t_n); semi-implicit, the one the last step
        applied, −d v^n on its active set (which it brakes, so those nodes are still below the obstacle)."""
        if self.newton is not None:
            return self.force_density
        if self.explicit:
            self.problem.laws.set(eta=self.eta_now[1], eta_old=self.eta_old[1])
            law = self.force_law.evaluate_env(self.problem.laws.env)
            self.law_ahead = (self.step_index, law)  # the next step applies this F(η^n, v^n): kept, not recomputed
            np.multiply(law, self.inv_mF > 0, out=self.force_density)  # 0 where no force acts (the ends)
        else:
            np.multiply(self.by_v[1], self.inv_mF, out=self.force_density)
        return self.force_density

    def stored_energy(self, eta) -> float:
        """Σ m_F Φ(η) on owned dofs: the energy held by a conservative (spring) law."""
        if self.energy_law is None:
            return 0.0
        self.problem.laws.set(eta=eta)
        return float(np.dot(self.m_force, self.energy_law.evaluate_env(self.problem.laws.env)))

    def _apply_mass(self, u, out) -> None:
        if self.lumped:
            np.multiply(self.m, u[1], out=out[1])
        else:
            self.Ms.mult(u[0], out[0])

    def start(self, eta0, v0):
        if self.newton is not None:
            return super().start(eta0, v0)
        if self.moving:  # ψ^{−1}, ψ^0; the law's fields at t = 0
            self.psi_levels = [self.problem.obstacle.owned(-self.dt).copy(), self.problem.obstacle.set(0.0).copy()]
        self.eta_now[1][:] = eta0
        self.v_now[1][:] = v0
        self.eta_old[1][:] = eta0 - self.dt * self.v_now[1]
        self.KC.mult(self.eta_now[0], self.KC_old[0])
        self._apply_mass(self.v_now, self.M_v)
        kin, el, stored = self.allsum(
            0.5 * float(np.dot(self.v_now[1], self.M_v[1])),
            0.5 * float(np.dot(self.eta_now[1], self.KC_old[1][0])),
            self.stored_energy(self.eta_now[1]),
        )
        self.kin, self.el = kin, el
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, stored)

    def _law(self):
        """F(η^n, v^n) at the state the environment points at; `contact_force` may have evaluated it already."""
        kept_at, law = self.law_ahead
        if kept_at != self.step_index:  # `contact_force` evaluated it at this state for a stored row (1 in 4 here)
            law = self.force_law.evaluate_env(self.env)
        return law

    def _damping(self, e0) -> None:
        """Semi-implicit: the damping weights m_F d/Δt on the active set onto A's diagonal (refactorised when they
        change), and the damping's known part (d/Δt) η^n into by_v[1], where the explicit penalty has m_F∘F^n."""
        law, f_applied, diag_w = self._law(), self.by_v[1], self.diag_w
        active = law > 0
        active &= self.problem.interior
        np.multiply(self.m_force, law, out=diag_w)
        diag_w *= 1.0 / self.dt
        np.multiply(diag_w, active, out=diag_w)
        self.lu.update(diag_w)
        if self.moving:  # the gap rate's: (d/Δt)(η^n + ψ^{n+1} − ψ^n)
            self.dpsi = self.problem.obstacle.owned((self.step_index + 1) * self.dt) - self.psi_levels[1]
            np.multiply(diag_w, e0 + self.dpsi, out=f_applied)
            return
        np.multiply(diag_w, e0, out=f_applied)

    def step(self):
        if self.newton is not None:
            return super().step()
        # The NumPy operations in the order that fixes every bit of η and of the energy terms; what a step reads is
        # set once in __init__: 1-3.5 % of the step (three passes of benchmarks/bench_step.py --loop,
        # docs/explanation/performance.md). Three of its four parts as methods cost 1 %: kept, to read on one screen.
        e0, em = self.eta_now[1], self.eta_old[1]
        self._right_hand_side(e0, em)
        if self.iterative:  # CG starts from the guess 2η^n − η^{n−1}
            np.subtract(e0, em, out=self.eta_new[1])
            np.add(self.eta_new[1], e0, out=self.eta_new[1])
        self.lu.solve(self.rhs[0], self.eta_new[0])
        if self.moving and not self.explicit:
            self._release_linear(e0)
        terms = self._energy_terms(e0)
        if self.moving:  # the obstacle's share of the force's work: external work, not contact dissipation
            (work,) = self.allsum(self._obstacle_work(self.by_v[1]))
            terms = terms._replace(contact=terms.contact + work, external=terms.external + work)
        self._rotate()
        return terms

    def _release_linear(self, e0) -> None:
        """A moving obstacle under the semi-implicit penalty: a damping that would hold a node down (the step's gap
        rate > 0: an obstacle that stops under a string it lifted) is released and the step solved again."""
        diag_w, f_applied, b, shift = self.diag_w, self.by_v[1], self.rhs[1], e0 + self.dpsi
        while self.anysum(bool(np.any(sticky := (diag_w > 0) & (self.eta_new[1] > shift)))):
            diag_w[sticky] = 0.0
            self.lu.update(diag_w)
            b -= f_applied
            np.multiply(diag_w, shift, out=f_applied)
            b += f_applied
            self.lu.solve(self.rhs[0], self.eta_new[0])

    def _right_hand_side(self, e0, em) -> None:
        """b = (M/Δt²)(2η^n − η^{n−1}) + (C/Δt) η^n + m_F∘F^n (+ the load), the ends held; F^n is the law at
        (η^n, η^{n−1}), or with the semi-implicit penalty its known part."""
        env, b_a = self.env, self.rhs[1]
        env[self.key_eta], env[self.key_eta_old] = e0, em  # the law's η and η_old (`NodalLaws.set`)
        f_applied = self.by_v[1]
        if self.explicit:
            np.multiply(self.m_force, self._law(), out=f_applied)
        else:
            self._damping(e0)
        if self.lumped:
            np.subtract(e0, em, out=b_a)
            b_a += e0
            b_a *= self.m_dt2
        else:
            two, two_a = self.two_steps
            np.subtract(e0, em, out=two_a)
            two_a += e0
            self.Ms.mult(two, self.rhs[0])
            b_a *= 1.0 / self.dt**2
        b_a += self.KC_old[1][1]  # (C/Δt) η^n
        b_a += f_applied
        if self.has_load:
            b_a += self.load
        self.hold_ends(b_a)

    def _energy_terms(self, e0):
        """The step n → n+1's terms of the discrete energy identity (module docstring), from η^{n+1} just solved."""
        dt, e1, v1, f_applied = self.dt, self.eta_new[1], self.v_new[1], self.by_v[1]
        np.subtract(e1, e0, out=v1)
        v1 *= 1.0 / dt
        if not self.explicit:  # the force actually applied: −m_F d v^{n+1} (d times the gap rate with ψ moving)
            if self.moving:  # (d/Δt)(η^n + Δψ − η^{n+1}): ≥ 0 exactly on the nodes `_release_linear` kept
                np.subtract(e0 + self.dpsi, e1, out=f_applied)
                f_applied *= self.diag_w
            else:
                np.multiply(self.diag_w, v1, out=f_applied)
                f_applied *= -dt
        self.KC.mult(self.eta_new[0], self.KC_new[0])  # K η^{n+1} and (C/Δt) η^{n+1}
        np.subtract(self.KC_new[1][1], self.KC_old[1][1], out=self.by_v[0])  # = C v^{n+1}
        self._apply_mass(self.v_new, self.M_v_new)
        dots_v, dots_K = self.dots_v, self.dots_K
        np.einsum("ij,j->i", self.by_v, v1, out=dots_v)  # v¹·Cv¹, v¹·f, v¹·Mv¹ and v¹·Mv⁰ (rows 2, 3 alternate)
        np.einsum("ij,j->i", self.K_etas, e1, out=dots_K)  # η¹·Kη¹ and η¹·Kη⁰ (rows alternate)
        n = self.step_index
        iM = 2 + (n & 1)  # the row of M v^{n+1}: rows 2 and 3 swap roles every step, as do the K rows
        iK = n & 1
        # With M, K symmetric, ½|v¹−v⁰|²_M = ½v¹·Mv¹ + ½v⁰·Mv⁰ − v¹·Mv⁰ (and likewise for K): no difference vectors.
        kin_new, el_new, visc, work, cross, ext, stored, split = self.allsum(
            0.5 * dots_v[iM],
            0.5 * dots_K[iK],
            dt * dots_v[0],
            -dt * dots_v[1],
            dots_v[5 - iM] + dots_K[1 - iK],
            dt * float(np.dot(v1, self.load)) if self.has_load else 0.0,
            self.stored_energy(e1),
            -dt * float(np.dot(f_applied, self.v_now[1])),
        )
        # D_con is the force's work with the step's mean velocity, −(Δt/2) f·(v^n + v^{n+1}); the rest of the
        # identity's work term, (Δt/2) f·(v^{n+1} − v^n), is numerical.
        split = 0.5 * (work + split)
        num = kin_new + self.kin + el_new + self.el - cross - (split - work)
        self.kin, self.el = kin_new, el_new
        return StepEnergy(kin_new, el_new, visc, split, num, ext, stored)

    def _rotate(self) -> None:
        """η^{n−1} ← η^n ← η^{n+1}; the new step's v, K η, (C/Δt) η and M v become the old ones."""
        self.eta_old, self.eta_now, self.eta_new = self.eta_now, self.eta_new, self.eta_old
        self.v_now, self.v_new = self.v_new, self.v_now
        self.KC_old, self.KC_new = self.KC_new, self.KC_old
        self.M_v, self.M_v_new = self.M_v_new, self.M_v
        self.step_index += 1


__all__ = ["PAPER", "PaperScheme"]
