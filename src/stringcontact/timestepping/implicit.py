"""A time scheme given by its difference quotients: each step by Newton (`newton.NewtonStep`), the contact force
from the previous step (the paper's explicit penalty) or a damping on the new velocity (semi-implicit).

A scheme writes the momentum form's placeholders η, η_t, η_tt as functions of the unknown u = η^{n+1}, the known
levels η^n, η^{n−1}, the nodal velocity v^n and Δt (``QUOTIENTS``; ``"fields"`` for a model's other unknowns, u by
default). The step solves, with the ends held,

    R(q_η(u), q_t(u), q_tt(u), 0; w) = m_F∘F(η^n, v^n) + b          (explicit penalty)

or puts the damping m_F d on the diagonal, F = −d (v^{n+1} − Δψ/Δt) (semi-implicit). A linear model's step is one
back-substitution (`affine.LinearPath`); a scheme with a faster path of its own (``LINEAR_PATH = True``: `paper`) is
given the constant operators only. Energy: `newton`'s, over δ = η^{n+1} − η^n. A moving obstacle's share
½ f·(ψ^{n+1} − ψ^{n−1}) of the force's work is external work; a damping that would hold a node down is released.

A scheme of one's own: a module with ``class Scheme(ImplicitScheme)`` that sets ``DESCRIPTION`` and ``QUOTIENTS``,
registered under the entry-point group ``stringcontact.schemes`` (or handed to `simulate` as a class).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ..errors import SolverError
from .base import EPS, PETSC_OPTIONS, check_law_stability, mass_option, penalty_option, petsc_vector
from .newton import NewtonStep, _NewtonScheme, kinetic_energy


def acceleration(problem, eta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """M_L⁻¹(b − Kη − Cv) on this rank's nodes, 0 at the held ones: a linear model's acceleration at (η, v) without
    contact, from ``problem.ops`` (`fem.operators.Operators`: K, C on the owned dofs, the lumped mass m, the load b)."""
    return net_force(problem, eta, v) / problem.ops.m * problem.interior


def net_force(problem, eta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """b − Kη − Cv on this rank's nodes: a linear model's force at (η, v) without contact."""
    ops = problem.ops
    force = np.array(ops.load, dtype=float)
    for A, x in ((ops.K, eta), (ops.C, v)):
        out = A.createVecLeft()
        A.mult(petsc_vector(np.array(x, dtype=float), problem.comm), out)
        force -= out.array
    return force


class ImplicitScheme(_NewtonScheme):
    """A scheme given by its difference quotients (``QUOTIENTS``), stepped by Newton for every model; the penalty
    explicit (the law at (η^n, η^{n−1})) or semi-implicit (a damping d v^{n+1} on the diagonal), the mass lumped or
    consistent. Energy and moving obstacles: the module docstring."""

    DESCRIPTION = "a scheme given by its difference quotients, each step by Newton"
    OPTIONS = (penalty_option("explicit", "semi-implicit"), mass_option("lumped", "consistent"), EPS, PETSC_OPTIONS)
    LINEAR_PATH = False  # every model by Newton: a linear one's step is one back-substitution (`affine.LinearPath`)
    #: The difference quotients: placeholder name -> f(u, η^n, η^{n−1}, v^n, Δt) (UFL in u, arrays otherwise).
    QUOTIENTS: ClassVar[dict] = {}
    remedy = "use penalty='semi-implicit', scheme 'projection' or a smaller dt"

    def __init__(self, problem):
        super().__init__(problem)
        self.force_law = self._penalty_law(problem)
        self.newton = NewtonStep(problem, self.QUOTIENTS)
        n = problem.n_owned
        self.eta_, self.old, self.v = np.zeros(n), np.zeros(n), np.zeros(n)
        self.older = None

    def _penalty_law(self, problem):
        """The model's contact law for the penalty, compiled; refused if missing, checked by its bound on Δt/ε."""
        laws = problem.laws
        if problem.penalty == "semi-implicit" and laws.model.penalty_damping is None:
            raise ValueError(f"model '{laws.model.name}' has no penalty_damping, so it has no semi-implicit penalty")
        check_law_stability(laws.model, problem.dt, problem.eps, problem.penalty)
        law = laws.model.penalty if problem.penalty == "explicit" else laws.model.penalty_damping
        return laws.compile(law(laws.eta, laws.quotient, laws.params))

    @property
    def situation(self) -> str:
        """r = Δt/ε and the penalty, for an instability message."""
        return f"r = dt/eps = {self.problem.dt / self.problem.eps:.4g}, penalty {self.problem.penalty}"

    def start(self, eta0, v0):
        """The initial state (η^0, v^0) and the level before it (`level_before`); the initial energy."""
        problem = self.problem
        if self.moving:  # ψ^{−1}, ψ^0; the law's fields at t = 0
            self.psi_levels = [problem.obstacle.owned(-problem.dt).copy(), problem.obstacle.set(0.0).copy()]
        self.eta_[:], self.v[:] = eta0, v0
        self.old[:] = self.level_before(eta0, self.v)
        self.newton.start_fields(eta0, v0)
        terms = self._start_energy(self.eta_, self.v)
        self._force()
        return terms

    def level_before(self, eta0: np.ndarray, v0: np.ndarray) -> np.ndarray:
        """η^{−1}, the level the first step's quotients read: η^0 − Δt v^0, first order; a scheme of second order
        returns η^0 − Δt v^0 + ½Δt² a^0 (`acceleration`)."""
        return eta0 - self.problem.dt * v0

    def known_rate(self) -> np.ndarray | None:
        """What the quotients receive as their fourth argument, a nodal array known before the step (a multistep
        scheme's past velocities), or None: unused (0)."""
        return None

    def _force(self) -> None:
        """The law at (η^n, η^{n−1}): the explicit force density (0 where no force acts), or the damping weights."""
        laws = self.problem.laws
        laws.set(eta=self.eta_, eta_old=self.old)
        law = np.asarray(self.force_law.evaluate_env(laws.env), dtype=float) * np.ones(self.problem.n_owned)
        self.law = law * self.problem.interior
        if self.problem.penalty == "explicit":
            np.multiply(self.law, self.inv_mF > 0, out=self.force_density)

    def _solve(self, e0, em):
        """η^{n+1} by Newton from η extrapolated quadratically (a kept Jacobian then serves more steps); past a sudden
        stop that guess overshoots and Newton may diverge from it: then from the linear one."""
        newton = self.newton
        if newton.guessless:  # the linear path's one direct solve
            return newton.solve(None)
        linear = 2 * e0 - em
        if self.older is None:
            return newton.solve(linear)
        try:
            return newton.solve(3 * e0 - 3 * em + self.older)
        except SolverError:
            return newton.solve(linear)

    def step(self):
        """One step n → n+1 by Newton; its terms of the energy identity (`StepEnergy`)."""
        problem, dt, newton = self.problem, self.problem.dt, self.newton
        e0, em = self.eta_, self.old
        newton.set_known(e0, em, self.known_rate())
        # a moving obstacle: the semi-implicit damping brakes the step's gap rate, v^{n+1} − (ψ^{n+1} − ψ^n)/Δt
        dpsi = problem.obstacle.owned((self.k + 1) * dt) - self.psi_levels[1] if self.moving else 0.0
        explicit = problem.penalty == "explicit"
        if explicit:
            newton.f[:] = problem.ops.m_force * self.law
        else:  # F = −d (v^{n+1} − Δψ/Δt): (m_F d/Δt)(u − η^n − Δψ) on the diagonal
            newton.d[:] = problem.ops.m_force * self.law / dt
            newton.c[:] = e0 + dpsi
        u = self._solve(e0, em)
        if self.moving and not explicit:
            u = self._release(u)
        self.older = em.copy()
        v1 = (u - e0) / dt
        f = newton.f if explicit else newton.d * (newton.c - u)
        terms = self._step_energy(u, e0, self.v, v1, f, self._obstacle_work)  # (and the law's fields to t^{n+1})
        if not explicit:
            self.force_density[:] = f * self.inv_mF
        self.old[:], self.eta_[:], self.v[:] = e0, u, v1
        self._force()
        return terms

    def _release(self, u: np.ndarray) -> np.ndarray:
        """A moving obstacle under the semi-implicit penalty: a damping that would hold a node down (u above the
        centre η^n + Δψ: an obstacle that stops under a string it lifted) is released and the step solved again from
        u (a kept Jacobian takes the change of d on its diagonal)."""
        newton = self.newton
        while self.anysum(bool(np.any(sticky := (newton.d > 0) & (u > newton.c)))):
            newton.d[sticky] = 0.0
            u = newton.solve(u)
        return u

    def _obstacle_work(self, f: np.ndarray) -> float:
        """A moving obstacle's share ½ f·(ψ^{n+1} − ψ^{n−1}) of the force's work (this rank's), with the law's
        fields moved to t^{n+1} (the next step's law, the stored row's force); 0 for an obstacle at rest."""
        if not self.moving:
            return 0.0
        self.k += 1
        psi_new = self.problem.obstacle.set(self.k * self.problem.dt).copy()
        work = 0.5 * float(np.dot(f, psi_new - self.psi_levels[0]))
        self.psi_levels = [self.psi_levels[1], psi_new]
        return work


__all__ = ["ImplicitScheme", "acceleration", "kinetic_energy", "net_force"]
