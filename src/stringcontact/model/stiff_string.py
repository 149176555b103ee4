"""The stiff string: a string with bending stiffness β (musical acoustics' string–barrier collisions).

In string units, η_tt − α η_txx − η_xx + β η_xxxx = F on (0, l), η = h and η_xx = 0 at the ends (pinned), F the
contact law's force. The fourth derivative is written with a second P1 unknown, the curvature κ = −η_xx
(Ciarlet–Raviart), with tests w and r (both 0 at the ends):

    ∫ η_tt w + α η_tx w_x + η_x w_x + β κ_x w_x − F w  +  ∫ κ r − η_x r_x  = 0,      κ = 0 at the ends.

κ's row does not depend on β, so the form is well posed for every β ≥ 0 (the symmetric saddle point is singular at
β = 0), and its ledger closes exactly with Π(η, κ) = ½ η_x² + ½ β κ². The form is linear (one factorisation). κ has
no time derivative: `projection`'s stable Δt shrinks like Δx²/√β (`stable_dt`). On a membrane it is a simply
supported plate, κ = −Δη. A mode sin(mπx/l) oscillates with ω² = (mπ/l)² + β (mπ/l)⁴.
"""

from __future__ import annotations

import dataclasses
import math

import ufl

from .interface import DIVERGING, ModelConstant, OutputField, Parameters, SolverHints, direct_options, inelastic

#: The largest bending stiffness a scene may give (in string units, β = EI/(T l²): the length scale's square); a
#: piano string's inharmonicity B = π²β is 1e-4 to 1e-2 (β ≈ 1e-5 to 1e-3).
BETA_MAX = 1e3
#: The stiff string's constants: a scene's ``[parameters]``.
CONSTANTS = (
    ModelConstant("beta", 0.0, 0.0, BETA_MAX, unit="length²",
                  description="the bending stiffness β in η_tt − α η_txx − η_xx + β η_xxxx = F (0: the paper's string)"),
)
#: The stiff string's output field: the curvature κ = −η_xx, symmetric about 0: red on a crest, blue in a trough.
CURVATURE = OutputField("curvature", label="curvature κ = −η_xx", unit="1/length", colours=DIVERGING, symmetric=True)


def stiff_string_residual(U, U_t, U_tt, force, W, p: Parameters):
    """η's row: the viscoelastic string and the bending force β K κ; κ's row: κ = −η_xx weakly (∫κ r = ∫η_x r_x)."""
    (eta, kappa), (eta_t, _), (eta_tt, _) = U, U_t, U_tt
    w, r = W
    beta = p.constants["beta"]
    string = (eta_tt * w + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w)) + ufl.inner(ufl.grad(eta), ufl.grad(w))
              + beta * ufl.inner(ufl.grad(kappa), ufl.grad(w)) - force * w)
    curvature = kappa * r - ufl.inner(ufl.grad(eta), ufl.grad(r))
    return (string + curvature) * ufl.dx


def stored_energy(U, p: Parameters):
    """Π(η, κ) = ½|η_x|² + ½ β κ²: the tension's and the bending's energy density."""
    eta, kappa = U[0], U[1]
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.5 * p.constants["beta"] * kappa * kappa


def stable_dt(dx: float, beta: float, alpha: float = 0.0) -> float:
    """The explicit (`projection`) step's bound for the highest mode of a uniform P1 grid of spacing `dx`, lumped
    mass, α = 0: Δt ≤ 2/ω_max, ω_max² = λ_K + β λ_K λ_κ (the lumped η-mass's 4/Δx², the consistent κ-mass's
    12/Δx² on the alternating mode). An estimate; the scheme measures its own bound."""
    lam_eta, lam_kappa = 4.0 / dx**2, 12.0 / dx**2
    return 2.0 / math.sqrt(lam_eta + beta * lam_eta * lam_kappa)


stiff_string = dataclasses.replace(
    inelastic,
    name="stiff_string",
    fields=("curvature",),
    residual=stiff_string_residual,
    stored_energy=stored_energy,
    held_fields=("curvature",),
    dissipative_fields=(),
    schemes=(),
    constants=CONSTANTS,
    outputs=(CURVATURE,),
    solver=SolverHints(linear_options=direct_options),  # κ's row is not the energy's derivative: nonsymmetric
    energy_label=r"stored $\int \frac{1}{2}\eta_x^2 + \frac{\beta}{2}\kappa^2\,dx$",
    description="the string with bending stiffness beta (eta_tt - alpha eta_txx - eta_xx + beta eta_xxxx = F), "
                "pinned ends; the paper's contact law",
)

__all__ = ["BETA_MAX", "CONSTANTS", "CURVATURE", "stable_dt", "stiff_string", "stiff_string_residual", "stored_energy"]
