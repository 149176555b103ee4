"""Model variants shipped with stringcontact, registered by name in pyproject.toml (``model = "elastic"``,
``--model elastic``, ``sc.simulate(scene, model=elastic)``); each changes one or two of the paper's functions.

``elastic``
    Elastic (bouncing) contact: the Signorini displacement penalty F = (1/ε) η⁻, a spring of stiffness 1/ε below
    the obstacle, in place of the paper's velocity penalty: an impact gives the energy back (up to O(ε)).
    Explicit only (no damping form).

``loaded_obstacle``
    The paper's model with the scene's ``load`` f(x) and ``obstacle`` ψ(x) (each 0 when not given): ∫ η_tt w +
    α ∫ η_tx w_x + ∫ η_x w_x = ∫ f w + ∫ F w, F = (1/ε) χ{η<ψ} (η_t)⁻, the contact set {η ≤ ψ}. A moving obstacle
    ψ(x, t) brakes the gap rate, (1/ε) χ{η<ψ} (η_t − ψ_t)⁻, with ψ_t from ``p.extra["obstacle_rate"]``.
"""

from __future__ import annotations

import dataclasses

import ufl

from .inelastic import contact_set as _paper_contact_set
from .inelastic import momentum_form as _paper_momentum_form
from .inelastic import penalty as _paper_penalty
from .inelastic import penalty_damping as _paper_penalty_damping
from .interface import Model, Parameters, inelastic

__all__ = ["elastic", "loaded_obstacle"]


def _displacement_penalty(eta, v, p: Parameters):
    """(1/ε) η⁻: a spring pushing back in proportion to the penetration, whatever the velocity."""
    return ufl.max_value(-eta, 0) / p.eps


_displacement_penalty.penetration_bound = "spring"  # a spring of stiffness 1/ε stops V within √ε·V


def spring_bound(dt: float, eps: float, penalty: str):
    """A spring of stiffness 1/ε held explicitly: warn when Δt²/ε > 2 (a lone node is stable up to 4, but its energy
    swings beyond the guard's 2 E(0) from about 3 on: `study stability`); the energy guard decides."""
    q = dt * dt / eps
    if penalty != "explicit" or q <= 2:
        return None
    return "warn", (f"explicit spring with dt^2/eps = {q:.3g} > 2: a distributed contact trips the energy guard "
                    "from about 3 on; use a smaller dt or a larger eps if it does")


def _spring_energy(eta, p: Parameters):
    """Φ = (1/2ε) (η⁻)², the energy stored in the spring (F = −∂Φ/∂η)."""
    return ufl.max_value(-eta, 0) ** 2 / (2 * p.eps)


#: Elastic (bouncing) contact: the Signorini displacement penalty (1/ε) η⁻ in place of the paper's velocity
#: penalty; explicit only. Registered as ``elastic``.
elastic = dataclasses.replace(
    inelastic,
    name="elastic",
    penalty=_displacement_penalty,
    penalty_damping=None,
    gap=None,  # it lets the string through the obstacle: no scheme may project onto it
    stability=spring_bound,
    contact_energy=_spring_energy,
    description="elastic contact: displacement penalty (1/eps) eta^- on the obstacle y = 0 (bounces)",
)


def _obstacle(p: Parameters):
    return p.extra.get("obstacle", 0.0)


def _loaded_momentum_form(eta, eta_t, eta_tt, force, w, p: Parameters):
    """The paper's form minus ∫ f w: a term in no unknown, so the scheme assembles it once as b."""
    R = _paper_momentum_form(eta, eta_t, eta_tt, force, w, p)
    return R - p.extra["load"] * w * ufl.dx if "load" in p.extra else R


def _obstacle_rate(p: Parameters):
    """ψ_t: the moving obstacle's rate (``p.extra["obstacle_rate"]``, set each step), 0 for an obstacle at rest."""
    return p.extra.get("obstacle_rate", 0.0)


def _obstacle_penalty(eta, v, p: Parameters):
    """(1/ε) χ{η<ψ} (v − ψ_t)⁻: the paper's law in the gap η − ψ and its rate v − ψ_t (v for an obstacle at rest)."""
    return _paper_penalty(eta - _obstacle(p), v - _obstacle_rate(p), p)


_obstacle_penalty.penetration_bound = "velocity"


def _obstacle_damping(eta, v, p: Parameters):
    return _paper_penalty_damping(eta - _obstacle(p), v - _obstacle_rate(p), p)


def _obstacle_contact_set(eta, p: Parameters):
    return _paper_contact_set(eta - _obstacle(p), p)


def _obstacle_gap(eta, p: Parameters):
    return eta - _obstacle(p)


#: The paper's model with the scene's ``load`` f(x) and ``obstacle`` ψ(x): the contact set is {η ≤ ψ}.
#: Registered as ``loaded_obstacle``.
loaded_obstacle = Model(
    name="loaded_obstacle",
    momentum_form=_loaded_momentum_form,
    penalty=_obstacle_penalty,
    penalty_damping=_obstacle_damping,
    contact_set=_obstacle_contact_set,
    gap=_obstacle_gap,
    description="the paper's model with a load f(x) (scene key load) over an obstacle psi(x) (scene key obstacle)",
)
