"""The energy ledger of a run: E(0) + W_ext = E(t) + D_visc + D_int + D_con + D_num summed from the scheme's terms,
and the guard that stops a run whose energy rises."""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

__all__ = ["EnergyLedger", "energy_roundoff"]


class EnergyLedger:
    """E(0) + W_ext = E(t) + D_visc + D_int + D_con + D_num, summed from the scheme's terms; and the energy guard.

    D_int, the model's internal variables' dissipation (`fem.dissipation`, by name in `internal`), is taken from D_num.

    A dissipative law may not raise the energy at all (1e-9 E(0) per step for round-off). A conservative
    law (a contact spring, `Model.contact_energy`) held explicitly makes it wobble by O(Δt/√ε) during an
    impact, which can be most of E(0) at large Δt/ε; an instability grows exponentially, so there the
    energy may not exceed 2 E(0). So for a scheme that declares `energy_may_rise` (a restitution e > 0, whose
    impact gives back in its later steps what its first steps took; a nonlinear force in a leapfrog step).

    The stepper books every step's terms (`add`); `cumulative` and `residual` are the balance now.
    """

    def __init__(self, start, conservative: bool, floor: float = 0.0, slack: float = 0.0):
        kin, el, _, _, _, _, stored = start
        self.kin, self.el, self.stored = kin, el, stored
        self.visc = self.con = self.num = self.ext = 0.0
        self.internal: dict[str, float] = {}
        self.conservative = conservative
        self.E_prev = self.E_ref = kin + el + stored + slack
        self.E_start = kin + el
        self.tol = max((1.0 if conservative else 1e-9) * abs(self.E_prev), floor, 1e-300)

    def add(self, terms, slack: float = 0.0, internal: dict | None = None) -> str | None:
        """Book one step's terms and its internal variables' dissipation (taken from the scheme's numerical term); the
        reason if the energy (with the scheme's `energy_slack`) rose or is not finite, else None."""
        self.kin, self.el, visc, con, num, ext, stored = terms
        self.stored = stored
        for name, value in (internal or {}).items():
            self.internal[name] = self.internal.get(name, 0.0) + value
            num -= value
        self.num += num
        self.visc += visc
        self.con += con
        self.ext += ext
        E = self.kin + self.el - self.ext + slack
        if self.conservative:
            E += stored
        if not math.isfinite(E):
            return "a value is not finite"
        if E > (self.E_ref if self.conservative else self.E_prev) + self.tol:
            return f"the energy rose from {self.E_prev:.6g} to {E:.6g}"
        self.E_prev = E
        return None

    def rebase(self, start, numerical: bool = False) -> float:
        """A scheme started afresh from the state: the state's energies as the new scheme counts them (its `start`
        terms) replace the old, and the difference is booked as external work (a model's constant changed: the work
        done on the string by changing it) or, with `numerical`, as numerical dissipation (a sub-stepped step: the
        schemes at Δt/m and Δt count the kinetic energy of the same state differently); returns it."""
        kin, el, _, _, _, _, stored = start
        spring = (stored - self.stored) if self.conservative else 0.0
        self.con += spring  # a contact spring's energy is D_con's: its jump (k changed while pressed) is held there
        work = kin + el - self.kin - self.el + spring
        if numerical:
            self.num -= work
        else:
            self.ext += work
        self.kin, self.el, self.stored = kin, el, stored  # E − ext (− num) is unchanged: the guard holds
        return work

    @property
    def cumulative(self) -> tuple:
        """(kinetic, elastic, viscous, contact, numerical, external, internal) so far (`io.result.ENERGY_KEYS`)."""
        return self.kin, self.el, self.visc, self.con, self.num, self.ext, sum(self.internal.values())

    @property
    def residual(self) -> float:
        """E(0) + W_ext − (E(t) + D_visc + D_int + D_con + D_num): round-off when the scheme's identity closes."""
        spent = self.visc + sum(self.internal.values()) + self.con + self.num
        return self.E_start + self.ext - (self.kin + self.el + spent)


def energy_roundoff(K, eta: np.ndarray, comm) -> float:
    """The round-off of the energy of a state of height |η|: ½ηᵀKη carries up to u·|η|²·Σ|K_ij| ≤ u·|η|²·N·‖K‖∞
    (8× that here). A small motion on a large height (η = 1e-3 + 1e-8 t) has less energy than this, and its
    energy "rose" by 1e-20 of 5e-17 at step 14 without this floor: noise, not an instability, which grows
    exponentially past any floor. Example 1's floor (4e-7) is below 1e-9 E(0) (1.3e-6). Collective."""
    height = comm.allreduce(float(np.max(np.abs(eta), initial=0.0)), op=MPI.MAX)
    return 8 * np.finfo(float).eps * height**2 * K.getSize()[0] * K.norm(PETSc.NormType.INFINITY)
