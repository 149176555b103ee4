"""The paper's model (Definition 2.1) in UFL: the viscoelastic string's weak momentum equation and the inelastic
velocity penalty on the obstacle y = 0,

    ∫ η_tt w dx + α ∫ η_tx w_x dx + ∫ η_x w_x dx = ∫ F w dx,    F = (1/ε) χ{η<0} (η_t)⁻.

These functions are the defaults of every `Model`; a variant replaces one of them. What each must return is the
model contract's (`model.interface`).
"""

from __future__ import annotations

import ufl


def momentum_form(eta, eta_t, eta_tt, force, w, p):
    """The semi-discrete weak momentum equation of the viscoelastic string, as a residual."""
    dx = ufl.dx
    return (eta_tt * w * dx + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w)) * dx
            + ufl.inner(ufl.grad(eta), ufl.grad(w)) * dx - force * w * dx)


def penetration(eta, p):
    """χ{η<0}: where the penalty acts (strictly below the obstacle, as in the paper)."""
    return ufl.lt(eta, 0)


def penalty(eta, v, p):
    """The velocity penalty (1/ε) χ{η<0} (v)⁻: it only brakes downward motion below the obstacle."""
    return ufl.conditional(penetration(eta, p), ufl.max_value(-v, 0) / p.eps, 0)


penalty.penetration_bound = "velocity"  # the bound this law has (Model.penetration_bound "auto")


def penalty_damping(eta, v, p):
    """The same law as an implicit damping coefficient d with F = -d v^{n+1} (semi-implicit penalty): the same
    active set χ{η<0, v<0}; applied to the new velocity it cannot overshoot."""
    return ufl.conditional(ufl.And(penetration(eta, p), ufl.lt(v, 0)), 1 / p.eps, 0)


def contact_set(eta, p):
    """The contact indicator written to the results: η ≤ 0 (on or below the obstacle)."""
    return ufl.le(eta, 0)


def gap(eta, p):
    """The signed distance to the obstacle y = 0; the admissible set is gap ≥ 0."""
    return eta


def restitution_bound(dt: float, eps: float, penalty: str):
    """The explicit velocity penalty rebounds with restitution r − 1, r = Δt/ε: refuse r ≥ 2 (growth), warn r > 1;
    the semi-implicit penalty cannot overshoot: no bound."""
    r = dt / eps
    if penalty != "explicit" or r <= 1:
        return None
    if r >= 2:
        return "refuse", (f"explicit velocity penalty with r = dt/eps = {r:.4g} >= 2 grows energy at every impact "
                          f"(restitution r-1 = {r - 1:.3g} >= 1); use penalty='semi-implicit' (--penalty "
                          "semi-implicit), scheme 'projection', or dt <= eps")
    return "warn", (f"explicit velocity penalty with r = dt/eps = {r:.4g} > 1 rebounds with restitution {r - 1:.3g}; "
                    "use dt <= eps, penalty='semi-implicit' or scheme 'projection' for inelastic contact")


__all__ = ["contact_set", "gap", "momentum_form", "penalty", "penalty_damping", "penetration", "restitution_bound"]
