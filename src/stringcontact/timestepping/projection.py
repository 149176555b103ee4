"""Inelastic contact with no ε: central differences, implicit viscosity, and the step as a complementarity problem
(docs/explanation/schemes.md, restitution.md). With lumped mass M and A = M/Δt² + C/Δt, at the interior nodes

    M (η^{n+1} − 2η^n + η^{n−1})/Δt² + C (η^{n+1} − η^n)/Δt + K η^n = b + F,   η^{n+1} ≥ ψ,  F ≥ 0,  F·(η^{n+1} − ψ) = 0

(`complementarity.ActiveSet`; ψ from the model's ``gap`` = η − ψ): a landing node stops on ψ, F is a true contact force.
The leapfrog's energy E^{n+1/2} = ½|v^{n+1}|²_M + ½ η^{n+1}·K η^n has no numerical dissipation; E^{n+1/2} + (Δt/4)|v|²_C
never rises (`energy_slack`). The stored velocity is the centred (η^{n+1} − η^{n−1})/(2Δt), so the scheme runs one step
ahead of what it reports. Restitution e constrains the weighted position (η^{n+1} + e η^{n−1})/(1 + e) (Paoli and
Schatzman, `_weighted_step`); `release.py` adds Signorini's release. A nonlinear model takes the Newton path (η
explicit, the other fields and η_t implicit: the VI by SNES). Stability: Δt ≤ μ + √(μ² + 4/λ) (`spectrum.py`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InstabilityError
from ..fem.operators import diagonal_matrix, stacked
from ..scene import SceneWarning
from .base import PETSC_OPTIONS, RESTITUTION, StepEnergy, mass_option, petsc_vector
from .complementarity import ActiveSet
from .linear import dirichlet_rows
from .newton import NewtonStep, _NewtonScheme  # the Newton path
from .paper import PAPER
from .release import ContactAccount, MasslessRelease, start_correction
from .spectrum import dt_of_mode, largest_stable_dt, top_mode_krylov

#: A node within CONTACT_TOL × (the data's height scale) of the obstacle is in contact: the implicit viscous
#: solve spreads round-off-size values (1e-64 ... 1e-14 seen on Example 1) over a region lying on it.
CONTACT_TOL = 1e-9
#: The round-off allowed in a contact force before the active set lets its node go: FORCE_TOL × the height scale ×
#: A's diagonal, so that a node whose force is −1e-17 does not leave and re-enter forever (1e-9 moved Example 1 by
#: 7e-7 against the nodal maximum at α = 0, where the two must agree; 1e-14: 6e-12).
FORCE_TOL = 1e-14

#: The Newton path's difference quotients: the paper's, with η explicit (the other fields implicit, an algebraic one
#: solved).
PROJECTION = PAPER | {"eta": lambda u, e0, em, v0, dt: e0, "fields": lambda u, e0, em, v0, dt: u}


class ProjectionScheme(_NewtonScheme):
    """The ε-free scheme (the module docstring): the linear path (A = M/Δt² + C/Δt factorised once, each step
    `complementarity.ActiveSet`) for a linear model, the Newton path (SNES VI) for a nonlinear one."""

    DESCRIPTION = "explicit central difference, implicit viscosity, contact as a complementarity problem (no eps)"
    OPTIONS = (mass_option("lumped"), RESTITUTION, PETSC_OPTIONS)
    remedy = "use a smaller dt (nt >= T / dt_max) or scheme 'newmark'"
    QUOTIENTS = PROJECTION  # the Newton path's difference quotients

    @staticmethod
    def requires(model) -> str | None:
        if model.gap is None:
            return f"model '{model.name}' declares no gap (its law lets the string through the obstacle)"
        return None

    def __init__(self, problem):
        super().__init__(problem)
        n, comm = problem.n_owned, problem.comm
        nonlinear = problem.ops.nonlinear is not None
        self._check_stability(nonlinear)
        laws = problem.laws
        self.gap = laws.compile(laws.model.gap(laws.eta, laws.params))
        self.psi = self._obstacle()
        # Four rotating time levels [next, ahead, now, before], each η, [K η, (C/Δt) η] and the force density
        # that produced it: `now` is what the scheme reports, `ahead` (one step on) gives its centred velocity.
        self.levels = [_Level(comm, n) for _ in range(4)]
        self.v0 = None  # the given initial velocity, reported at t = 0
        self.e = problem.restitution
        self.psi_levels = [self.psi.copy(), self.psi.copy()]  # ψ^{k−1}, ψ^k (a moving obstacle's; k: `ahead`'s level)
        self.signorini = getattr(laws.model, "release", "inelastic") == "signorini"  # checked: check_declarations
        if self.signorini and (self.e or self.moving or nonlinear):
            raise ValueError(f"release: model '{laws.model.name}' declares release 'signorini', which schemes "
                             "'projection' and 'fitted' take on their linear path with restitution 0 and a fixed "
                             "obstacle only")
        self.account = ContactAccount(n)  # each node's contact dissipation: a rebound spends at most that (`release`)
        if nonlinear:  # its inertia lumped (`fitted`'s blend is its linear path's only)
            lumped = dataclasses.replace(problem, mass="lumped")
            self.newton = NewtonStep(lumped, self.QUOTIENTS, lower=self._lower(self.psi))
            self._check_fields_stiffness()
        else:
            self._linear_operators(problem)
            # a rebound or a release gives back in later steps what a landing took; a moving obstacle gives energy
            self.energy_may_rise = bool(self.e) or self.moving or self.signorini

    def _linear_operators(self, problem) -> None:
        """The linear path's constant operators, its contact step and its scratch vectors."""
        ops, dt, comm, n = problem.ops, problem.dt, problem.comm, problem.n_owned
        A = self._inertia_matrix()
        A.axpy(1.0 / dt, ops.C, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        dirichlet_rows(A, problem.bc)
        self.A_diagonal = A.getDiagonal().array.copy()
        C_over_dt = ops.C.copy()
        C_over_dt.scale(1.0 / dt)
        self.KC = stacked(ops.K, C_over_dt)  # K η and (C/Δt) η of one η in one mat-vec
        self.m_dt2 = ops.m / dt**2
        self.contact_step = ActiveSet(A, comm, problem.petsc_options, problem.bc, problem.g, problem.x.ndim, self.psi,
                                      problem.interior, force_tol=np.zeros(n))
        rhs = np.zeros(n)
        self.rhs = (petsc_vector(rhs, comm), rhs)
        self.R = np.zeros(n)  # A η − b of the latest iterate
        self.work = np.zeros((2, n))  # scratch rows for the energy terms
        self.has_load = bool(np.any(ops.load != 0))
        self.release = MasslessRelease(self, A) if self.signorini else None
        if self.e:  # the weighted position z = (η^{n+1} + e η^{n−1})/(1 + e): its level and right-hand side
            self.z = _Level(comm, n)
            rhs_z = np.zeros(n)
            self.rhs_z = (petsc_vector(rhs_z, comm), rhs_z)

    def _check_stability(self, nonlinear: bool) -> None:
        """Refuse (one line) a Δt above the explicit elastic term's stable `dt_max`."""
        problem = self.problem
        self.dt_max = largest_stable_dt(problem.ops, problem.interior, krylov=problem.x.ndim == 2, dt=problem.dt)
        self._check_dt(f"(its explicit elastic term, linearised at {problem.ops.linearised_at})" if nonlinear else
                       "(its explicit elastic term; dt_max from the operators)")

    def _start_correction(self, eta0: np.ndarray, v0: np.ndarray) -> np.ndarray | None:
        """The second-order term of η^{−1}, (Δt²/2) a0 on the free interior nodes, a0 = m⁻¹(b − Kη0 − Cv0)
        (`release.start_correction`): under Signorini's release; None (first order) otherwise."""
        return start_correction(self.problem, eta0, v0, self.psi, self.tol) if self.signorini else None

    def _inertia_matrix(self) -> PETSc.Mat:
        """The inertia operator over Δt², M/Δt²: the lumped mass's diagonal."""
        return diagonal_matrix(self.problem.ops.M, self.problem.ops.m / self.problem.dt**2)

    def _inertia(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        """(M/Δt²) x into `out` (which may be x itself); returns `out`."""
        return np.multiply(self.m_dt2, x, out=out)

    def _check_dt(self, why: str) -> None:
        """InstabilityError (one line) if Δt is above the stable `dt_max` of the explicit elastic term."""
        problem = self.problem
        if problem.dt > self.dt_max * (1 + 1e-12):
            raise InstabilityError(
                f"scheme 'projection' is unstable with dt = {problem.dt:.6g} > dt_max = {self.dt_max:.6g} {why}; use "
                f"nt >= {math.ceil(problem.dt * problem.nt / self.dt_max)} (dt <= {self.dt_max:.6g}), or scheme "
                "'newmark' or 'paper' for larger steps", step=0, time=0.0)

    def _check_fields_stiffness(self) -> None:
        """Fields that add to η's stiffness (K + βKM⁻¹K through η's second derivative) are explicit too: the stable Δt
        is that of η's stiffness with them eliminated (`NewtonStep.eta_stiffness`), below the tangent's."""
        problem = self.problem
        S = self.newton.eta_stiffness()
        if S is None:
            return
        if problem.x.ndim == 2:  # no Gershgorin bound or SLEPc copy of a shell: its top mode by SLEPc on the shell
            lam, phi = top_mode_krylov(S, problem.ops.m, problem.interior, hermitian=False)
            self.dt_max = min(self.dt_max, dt_of_mode(lam, phi, S, problem.ops.C))
        else:  # a string: power iteration from the alternating mode, as for K
            self.dt_max = min(self.dt_max, largest_stable_dt(dataclasses.replace(problem.ops, K=S), problem.interior))
        self._check_dt(f"(its explicit elastic term with the model's fields {', '.join(problem.laws.model.fields)})")

    def _gap_at(self, eta) -> np.ndarray:
        """gap(η) at the nodes, the environment's other arrays as they are."""
        laws, n = self.problem.laws, self.problem.n_owned
        return np.asarray(self.gap.evaluate_env(laws.env | {id(laws.eta): eta}), dtype=float) * np.ones(n)

    def _obstacle(self) -> np.ndarray:
        """ψ at the nodes, from gap(η) = η − ψ; ValueError unless gap has slope 1 in η and gap ≤ 0 is the contact set."""
        laws, n = self.problem.laws, self.problem.n_owned
        model = laws.model
        g = [self._gap_at(np.full(n, c)) for c in (0.0, 1.0)]
        if not np.allclose(g[1] - g[0], 1.0, rtol=0, atol=1e-12):
            raise ValueError(f"model '{model.name}': scheme 'projection' needs gap = eta - psi (slope 1 in eta)")
        contact = laws.compile(model.contact_set(laws.eta, laws.params))
        psi = -g[0]
        for shift, expected in ((1e-3, False), (-1e-3, True)):
            found = np.asarray(contact.evaluate_env(laws.env | {id(laws.eta): psi + shift}), dtype=bool) * np.ones(n, bool)
            if np.any(found[self.problem.interior] != expected):
                raise ValueError(f"model '{model.name}': its gap and contact_set disagree (gap <= 0 must be the contact "
                                 "set); a variant that moves the obstacle must give both")
        return psi

    def _lower(self, bound: np.ndarray) -> np.ndarray:
        """The Newton path's VI bound: `bound` at the interior nodes, none at the held ends."""
        return np.where(self.problem.interior, bound, PETSc.NINFINITY)

    @property
    def eta(self):
        return self.levels[2].eta

    @property
    def velocity(self):
        if self.v0 is not None:
            return self.v0
        return (self.levels[1].eta - self.levels[3].eta) / (2.0 * self.problem.dt)

    @property
    def contact_force(self):
        return self.levels[2].force

    def _linear_timings(self):
        return {"linear solver": self.contact_step.describe_solver(), "contact step": self.contact_step.describe()}

    def contact(self) -> np.ndarray:
        laws = self.problem.laws
        if self.moving:  # the obstacle where the reported level is, one step behind the computed one
            self.problem.obstacle.set((self.k - 1) * self.problem.dt)
        laws.set(eta=self.eta)
        touching = self._contact_law.evaluate_env(laws.env)
        if self.e:  # the impact holds the weighted position z, not η: the nodes it pushes are in contact too
            return np.asarray(touching, dtype=bool) | (self.contact_force > 0)
        return touching

    def _obstacle_at(self, t: float) -> np.ndarray:
        """A moving obstacle's ψ(·, t) on the owned nodes, from the model's gap: −gap(0) with the fields at t."""
        self.problem.obstacle.set(t)
        return -self._gap_at(np.zeros(self.problem.n_owned))

    def _move(self):
        """ψ^{k+1} into the contact step's bound; returns the obstacle's work ½ F·(ψ^{k+1} − ψ^{k−1}) to book (the
        force's work on the string splits into it and the contact dissipation), as a function of F."""
        self.k += 1
        before, now = self.psi_levels
        new = self._obstacle_at(self.k * self.problem.dt)
        np.copyto(self.psi, new)
        if self.newton is None:
            self.contact_step.moved()
        else:
            self.newton.set_lower(self._lower(self.psi))
        self.psi_levels = [now, new]
        return lambda F: 0.5 * float(np.dot(F, new - before))

    def start(self, eta0, v0):
        problem = self.problem
        laws = problem.laws
        scale = max(float(problem.comm.allreduce(np.max(np.abs(eta0), initial=0.0), op=MPI.MAX)),
                    float(np.max(np.abs(problem.g), initial=0.0)), 1e-300)
        if self.moving:  # the heights the obstacle carries the string to
            carried = self._obstacle_at(problem.dt * problem.nt)[problem.interior]
            scale = max(scale, problem.comm.allreduce(float(np.max(np.abs(carried), initial=0.0)), op=MPI.MAX))
            self.psi_levels = [self._obstacle_at(-problem.dt), self._obstacle_at(0.0)]
            np.copyto(self.psi, self.psi_levels[1])
            if self.newton is not None:
                self.newton.set_lower(self._lower(self.psi))
        self.scale, self.tol = scale, CONTACT_TOL * scale
        tol = fem.Constant(laws.eta.function_space.mesh, PETSc.ScalarType(self.tol))
        self._contact_law = laws.compile(laws.model.contact_set(laws.eta - tol, laws.params))
        ahead, now = self.levels[1], self.levels[2]
        ahead.eta[:] = eta0
        below = problem.interior & (ahead.eta < self.psi)
        if self.anysum(bool(np.any(below))):
            warnings.warn("scheme 'projection': the initial displacement is below the obstacle at some nodes; "
                          "projected onto it at t = 0 (the penalty schemes let it rise through instead)",
                          SceneWarning, stacklevel=4)
            ahead.eta[below] = self.psi[below]
        np.subtract(ahead.eta, problem.dt * v0, out=now.eta)
        correction = self._start_correction(ahead.eta, v0)
        if correction is not None:  # the elastic force acts over the first half-cell only
            now.eta += correction
        if self.moving:  # η^{−1} = η^0 − Δt v0 is no state of the string: its gap counts as ≥ 0 (the first D_con ≥ 0)
            np.minimum(self.psi_levels[0], now.eta, out=self.psi_levels[0])
        if self.newton is None:
            self.contact_step.force_tol = FORCE_TOL * self.scale * self.A_diagonal
            for level in (ahead, now):
                self.KC.mult(level.eta_vec, level.kc_vec)
            d = ahead.eta - now.eta
            kin, el, self.energy_slack = self.allsum(0.5 * float(np.dot(d, self._inertia(d, np.empty_like(d)))),
                                                     0.5 * float(np.dot(ahead.eta, now.kc[0])),
                                                     0.25 * float(np.dot(d, ahead.kc[1] - now.kc[1])))
        else:
            d = (ahead.eta - now.eta) / problem.dt
            self.newton.start_fields(ahead.eta, v0)
            self.stored_ahead = self._stored(ahead.eta)  # the next step's Π(η^n), this rank's share
            kin, el = self.allsum(0.5 * float(np.dot(d, problem.ops.m * d)),
                                  0.5 * (self.stored_ahead + self._stored(now.eta)))
            self.E = kin + el
        self.pending = self._advance()  # η¹: the first row's centred velocity needs it
        self.v0 = np.array(v0, dtype=float)
        return StepEnergy(kin, el, 0.0, 0.0, 0.0, 0.0, 0.0)

    def step(self):
        (reported, self.energy_slack), self.pending = self.pending, self._advance()
        self.v0 = None
        return reported

    def _advance(self):
        """The next level from `ahead` (η^n) and `now` (η^{n−1}): that step's energy terms and the guard's slack."""
        return self._advance_linear() if self.newton is None else self._advance_newton()

    def _residual(self, level, rhs):
        """A η − b at the level's η (0 at the ends), with [K η, (C/Δt) η] left in the level for its energy."""
        def residual(eta):
            self.KC.mult(level.eta_vec, level.kc_vec)
            self._inertia(eta, self.R)
            self.R += level.kc[1]
            self.R -= rhs
            self.R *= self.problem.interior
            return self.R
        return residual

    def _advance_linear(self):
        """The linear path's step: the contact step of A η^{n+1} = b + F (`complementarity.ActiveSet`)."""
        problem = self.problem
        new, e0, em = self.levels[0], self.levels[1], self.levels[2]
        rhs_v, rhs = self.rhs
        # A η^{n+1} = (M/Δt²)(2η^n − η^{n−1}) + (C/Δt) η^n − K η^n + b + F
        np.subtract(e0.eta, em.eta, out=rhs)
        rhs += e0.eta
        self._inertia(rhs, rhs)
        rhs += e0.kc[1]
        rhs -= e0.kc[0]
        if self.has_load:
            rhs += problem.ops.load
        problem.hold_ends(rhs)
        if self.contact_step.iterative:  # CG starts from the leapfrog's guess 2η^n − η^{n−1}
            np.subtract(e0.eta, em.eta, out=new.eta)
            new.eta += e0.eta
        obstacle_work = self._move() if self.moving else None
        if self.release is not None:  # the work booked is the momentum residual of the massless nodes too
            F, booked = self.release.step(new, e0, em, rhs, self._residual(new, rhs))
        elif self.e:
            F = booked = self._weighted_step(new, em, rhs)
        else:
            F, _ = self.contact_step.solve(rhs_v, new.eta_vec, self._residual(new, rhs))
            np.maximum(F, 0.0, out=F)  # within the active set's round-off allowance
            booked = F
        np.multiply(F, self.inv_mF, out=new.force)  # stored with the step's end
        d, w = np.subtract(new.eta, e0.eta, out=self.work[0]), self.work[1]  # scratch rows: no temporaries
        kin = 0.5 * float(np.dot(d, self._inertia(d, w)))
        el = 0.5 * float(np.dot(new.eta, e0.kc[0]))
        visc = 0.5 * float(np.dot(d, np.subtract(new.kc[1], em.kc[1], out=w)))  # (Δt/2) v¹·C(v¹ + v⁰), Δt v = η differences
        slack = 0.25 * float(np.dot(d, np.subtract(new.kc[1], e0.kc[1], out=w)))  # (Δt/4)|v¹|²_C
        d += e0.eta
        d -= em.eta  # now η^{n+1} − η^{n−1}
        con = -0.5 * float(np.dot(booked, d))
        ext = 0.5 * float(np.dot(problem.ops.load, d)) if self.has_load else 0.0
        if obstacle_work is not None:  # the obstacle's share of F's work is external work, not contact dissipation
            work = obstacle_work(F)
            con, ext = con + work, ext + work
        kin, el, visc, con, ext, slack = self.allsum(kin, el, visc, con, ext, slack)
        self.levels = [self.levels[3], new, e0, em]  # before is free; next → ahead → now → before
        return StepEnergy(kin, el, visc, con, 0.0, ext, 0.0), slack

    def _weighted_step(self, new, em, rhs):
        """Paoli and Schatzman's step with restitution e: the contact step for z = (η^{n+1} + e η^{n−1})/(1 + e),

            A z = (b + e A η^{n−1})/(1 + e) + G,   z ≥ ψ,   G ≥ 0,   G·(z − ψ) = 0,

        then η^{n+1} = (1 + e) z − e η^{n−1} and F = (1 + e) G; `new` gets η^{n+1} and its [K η, (C/Δt) η] by linearity.
        A step that would take the contact dissipation as a whole below 0 is solved again with η^{n+1} ≥ min(ψ, η^{n−1})
        (whose work is ≤ 0) at the nodes that give the most energy back (`_givers`)."""
        e, z = self.e, self.z
        rhs_zv, rhs_z = self.rhs_z
        self._inertia(em.eta, rhs_z)  # A η^{n−1} = (M/Δt²) η^{n−1} + (C/Δt) η^{n−1}
        rhs_z += em.kc[1]
        rhs_z *= e
        rhs_z += rhs
        rhs_z /= 1.0 + e
        self.problem.hold_ends(rhs_z)  # z = g at the ends, as η^{n+1} and η^{n−1} are
        if self.contact_step.iterative:  # z of the leapfrog's guess
            np.multiply(e, em.eta, out=z.eta)
            z.eta += new.eta
            z.eta /= 1.0 + e
        guess, bound, settled = z.eta.copy(), None, np.zeros(z.eta.size, dtype=bool)
        while True:
            G, _ = self.contact_step.solve(rhs_zv, z.eta_vec, self._residual(z, rhs_z))
            np.maximum(G, 0.0, out=G)
            np.multiply(1.0 + e, z.eta, out=new.eta)
            new.eta -= e * em.eta
            self.problem.hold_ends(new.eta)  # (1 + e) g − e g is g only to round-off
            step = -0.5 * (1.0 + e) * G * (new.eta - em.eta)
            giving = self._givers(step, settled)
            if giving is None:
                break
            settled |= giving
            bound = np.where(settled, (np.minimum(self.psi, em.eta) + e * em.eta) / (1.0 + e), self.psi)
            self.contact_step.psi = bound
            self.contact_step.moved()
            z.eta[:] = guess
        G *= 1.0 + e
        if bound is not None:
            self.contact_step.psi = self.psi
            self.contact_step.moved()
        self.account.book(step)
        np.multiply(1.0 + e, z.kc, out=new.kc)
        new.kc -= e * em.kc
        return G

    def _givers(self, step: np.ndarray, settled: np.ndarray) -> np.ndarray | None:
        """None if the step's contact dissipation `step` keeps the accounts together ≥ 0 or no node gives; else the
        nodes off `settled` giving the most back (step < 0), the fewest whose gifts exceed the deficit (all ranks)."""
        deficit = self.account.deficit(step, self.allsum)
        if deficit <= 0.0:
            return None
        step = np.where(settled, 0.0, step)
        gifts = -step[step < 0]
        every = np.sort(np.concatenate(self.problem.comm.allgather(gifts)))[::-1] if self.problem.comm.size > 1 \
            else np.sort(gifts)[::-1]
        if every.size:
            k = min(int(np.searchsorted(np.cumsum(every), deficit)), every.size - 1)
            giving = -step >= every[k]
        else:
            giving = np.zeros(step.size, dtype=bool)
        return giving if self.anysum(bool(giving.any())) else None

    def _advance_newton(self):
        """The Newton path's step: the VI G(u) ⊥ u − lower ≥ 0, the force the reaction on the active set."""
        problem, dt, newton = self.problem, self.problem.dt, self.newton
        new, ahead, now = self.levels[0], self.levels[1], self.levels[2]
        e0, em = ahead.eta, now.eta
        obstacle_work = self._move() if self.moving else None
        newton.set_known(e0, em)
        lower = (1 + self.e) * self.psi - self.e * em if self.e else self.psi
        while True:  # with e > 0, a node whose account the step would overdraw takes the bound min(ψ, η^{n−1})
            if self.e:
                newton.set_lower(self._lower(lower))
            u = newton.solve(np.maximum(2 * e0 - em, np.where(problem.interior, lower, -np.inf)))
            r = newton.last_residual(u)  # G(u) without the force: the reaction where u sits on its bound
            active = problem.interior & (u <= lower + self.tol)
            F = np.where(active, np.maximum(r, 0.0), 0.0)
            step = -0.5 * F * (u - em)
            if not self.e:
                break
            floor = np.minimum(self.psi, em)  # the bound whose work is ≤ 0
            giving = self._givers(step, lower == floor)
            if giving is None:
                break
            lower = np.where(giving, floor, lower)
        self.account.book(step)
        delta = 0.5 * (u - em)
        work = obstacle_work(F) if obstacle_work is not None else 0.0  # the obstacle's share of F's work
        visc_vec = newton.viscous_force(u)
        d = (u - e0) / dt
        stored_e0, self.stored_ahead = self.stored_ahead, self._stored(u)  # Π(η^n) assembled last step, as its Π(u)
        kin, el, visc, con, ext = self.allsum(
            0.5 * float(np.dot(d, problem.ops.m * d)), 0.5 * (self.stored_ahead + stored_e0),
            float(np.dot(visc_vec * problem.interior, delta)), -float(np.dot(F, delta)) + work,
            float(np.dot(problem.ops.load, delta)) + work)
        num = self.E - (kin + el) - visc - con + ext
        self.E = kin + el
        new.eta[:] = u
        np.multiply(F, self.inv_mF, out=new.force)
        self.levels = [self.levels[3], new, ahead, now]  # before is free; next → ahead → now → before
        return StepEnergy(kin, el, visc, con, num, ext, 0.0), 0.0


class _Level:
    """One time level of the projection scheme: η, [K η, (C/Δt) η] (as arrays and PETSc vectors over them) and the
    contact force density of the step that reached it."""

    def __init__(self, comm, n: int):
        self.eta, self.kc, self.force = np.zeros(n), np.zeros((2, n)), np.zeros(n)
        self.eta_vec, self.kc_vec = petsc_vector(self.eta, comm), petsc_vector(self.kc, comm)


__all__ = ["CONTACT_TOL", "PROJECTION", "ProjectionScheme"]
