"""The model: the paper's weak momentum equation and contact law, in UFL.

This is the one place to edit for a model variant. The time loop (`solver`) never looks inside
these functions; it only asks them for UFL.

The semi-discrete momentum equation is written once, in the unknowns' time derivatives, as in
Irksome: `eta`, `eta_t` and `eta_tt` are placeholders that the time scheme (`scheme.py`)
replaces by its difference quotients. It must be *linear* in them; the nonlinear contact law
enters only through `force`, a pointwise density that the scheme takes from the previous step
(the paper's Section 6) and lumps onto the nodes.

    ∫ η_tt w dx + α ∫ η_tx w_x dx + ∫ η_x w_x dx = ∫ F w dx,    F = (1/ε) χ{η<0} (η_t)⁻.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import ufl


@dataclass(frozen=True)
class Parameters:
    """What a model may use, as UFL objects: α and ε are `fem.Constant`s, `x` the coordinate."""

    alpha: object
    eps: object
    x: object
    length: float
    extra: dict = field(default_factory=dict)


def momentum_form(eta, eta_t, eta_tt, force, w, p: Parameters):
    """The semi-discrete weak momentum equation of the viscoelastic string, as a residual."""
    dx = ufl.dx
    return (
        eta_tt * w * dx
        + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w)) * dx
        + ufl.inner(ufl.grad(eta), ufl.grad(w)) * dx
        - force * w * dx
    )


def penetration(eta, p: Parameters):
    """χ{η<0}: where the penalty acts (strictly below the obstacle, as in the paper)."""
    return ufl.lt(eta, 0)


def penalty(eta, v, p: Parameters):
    """The velocity penalty (1/ε) χ{η<0} (v)⁻: it only brakes downward motion below the obstacle."""
    return ufl.conditional(penetration(eta, p), ufl.max_value(-v, 0) / p.eps, 0)


def penalty_damping(eta, v, p: Parameters):
    """The same law as an implicit damping coefficient d with F = -d v^{n+1} (semi-implicit penalty).

    Same active set as the explicit law, χ{η<0, v<0}; applied to the new velocity it cannot overshoot.
    """
    return ufl.conditional(ufl.And(penetration(eta, p), ufl.lt(v, 0)), 1 / p.eps, 0)


def contact_set(eta, p: Parameters):
    """The contact indicator written to the results: η ≤ 0 (on or below the obstacle)."""
    return ufl.le(eta, 0)


@dataclass(frozen=True)
class Model:
    """A model is four UFL functions; replace one to make a variant (see `demos/demo_model_variant.py`)."""

    name: str = "inelastic"
    momentum_form: Callable = momentum_form
    penalty: Callable = penalty
    penalty_damping: Callable | None = penalty_damping
    contact_set: Callable = contact_set


inelastic = Model()
