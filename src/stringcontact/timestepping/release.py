"""Half-cell impulses for scheme `projection`: the second-order start and the held force carried into a release.

The leapfrog's velocity jump at t_n, v^{n+1/2} − v^{n−1/2} = Δt m⁻¹(−Kη^n + b + F^n), is the impulse of the
forces over the cell [t_n − Δt/2, t_n + Δt/2]. A force that begins or ends at t_n acts over half of that cell:

* **At t = 0** the elastic force begins: the first cell is [0, Δt/2], so v^{1/2} = v0 + (Δt/2) a0 with
  a0 = m⁻¹(b − Kη0 − Cv0), that is η^{−1} = η0 − Δt v0 + (Δt²/2) a0 (`start_correction`), where the
  first-order start η0 − Δt v0 applies a0 over the whole cell. A node that starts on the obstacle keeps the
  first-order start: the contact force at t = 0 is not known.
* **At a release** a node that rested on the obstacle at t_{n−2}, t_{n−1} and t_n was held over
  [t_{n−1}, t_n] by F^{n−1}: the first half [t_n − Δt/2, t_n] of its cell still carries that force, and only
  the second half is decided by the complementarity problem with the gap at t_{n+1}. So the step is
  A η^{n+1} = b + C^n + G, G ≥ 0, G·(η^{n+1} − ψ) = 0 with C^n = ½F^{n−1} on the resting nodes
  (`carried_force`) and F^n = C^n + G. While the node stays on the obstacle F^n is the same as without C^n
  (the constraint fixes the total); when the free step lifts it off, it leaves with the half-cell impulse
  of the force that held it, as a massless contact point of the elastic limit does. A node that landed in
  the last two steps carries nothing: its F^{n−1} holds part of the landing impulse, and landings stay
  exactly inelastic.

This is the release of Signorini contact without the paper's (A4): the model opts in (``release =
"signorini"``, `Model.release`). Under the paper's law (``"inelastic"``, the default) none of this runs.
"""

from __future__ import annotations

import numpy as np

from .base import petsc_vector

#: The model's `release` values: the paper's (A4), and Signorini contact with half-cell impulses.
RELEASES = ("inelastic", "signorini")


def release_of(model) -> str:
    """The model's declared release (`Model.release`, default "inelastic"); ValueError (one line) for another."""
    release = getattr(model, "release", "inelastic")
    if release not in RELEASES:
        raise ValueError(f"release: model '{model.name}' declares release {release!r}; allowed: {', '.join(RELEASES)}")
    return release


def start_correction(problem, eta0: np.ndarray, v0: np.ndarray, psi: np.ndarray, tol: float) -> np.ndarray:
    """(Δt²/2) a0 on the free interior nodes, a0 = m⁻¹(b − Kη0 − Cv0) (0 where η0 is within `tol` of ψ)."""
    ops, n = problem.ops, problem.n_owned
    eta, vel = np.array(eta0, dtype=float), np.array(v0, dtype=float)
    k_eta, c_v = np.zeros(n), np.zeros(n)
    ops.K.mult(petsc_vector(eta, problem.comm), petsc_vector(k_eta, problem.comm))
    ops.C.mult(petsc_vector(vel, problem.comm), petsc_vector(c_v, problem.comm))
    a0 = (ops.load - k_eta - c_v) / ops.m
    free = problem.interior & (eta > psi + tol)
    return np.where(free, 0.5 * problem.dt**2 * a0, 0.0)


def carried_force(eta_n, eta_nm1, eta_nm2, psi, F_last, interior, tol: float) -> np.ndarray:
    """½F^{n−1} (nodal) on the interior nodes that rested on ψ (within `tol`) at the three levels and were pushed
    (F^{n−1} > 0); 0 elsewhere."""
    resting = interior & (F_last > 0.0)
    for eta in (eta_n, eta_nm1, eta_nm2):
        resting &= np.abs(eta - psi) <= tol
    return np.where(resting, 0.5 * F_last, 0.0)


__all__ = ["RELEASES", "carried_force", "release_of", "start_correction"]
