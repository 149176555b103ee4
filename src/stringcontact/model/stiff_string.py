"""The stiff string: a string with bending stiffness β (musical acoustics' string–barrier collisions).

In string units (density, tension and length scales 1),

    η_tt − α η_txx − η_xx + β η_xxxx = F          on (0, l),   η = h and η_xx = 0 at the ends (pinned),

with F the contact law's force (the paper's velocity penalty, or `projection`'s contact step). The fourth
derivative is written with a second unknown, the curvature κ = −η_xx, so that both unknowns are P1 (the
Ciarlet–Raviart mixed method): with w and r the test functions of η's and κ's rows (both 0 at the ends),

    ∫ η_tt w + α η_tx w_x + η_x w_x + β κ_x w_x − F w  +  ∫ κ r − η_x r_x  = 0,      κ = 0 at the ends.

κ's row is the discrete curvature, M₀κ = K η (M₀ the mass and K the stiffness on the interior nodes), and η's
row carries the bending force β K κ = β K M₀⁻¹ K η. Why this form and not a symmetric one:

- It is well posed for every β ≥ 0, β = 0 too: κ's row does not depend on β, so κ is the string's curvature
  (an honest output) and at β = 0 the first row is the paper's string. The symmetric saddle point (κ's row
  multiplied by −β) is singular at β = 0, and the symmetric one in σ = √β κ has σ ≡ 0 there and no curvature to
  write.
- Its energy ledger closes exactly: testing η's row with η^{n+1} − η^n, the bending work β κ·K(η^{n+1} − η^n)
  is β κ·M₀(κ^{n+1} − κ^n) by κ's row, the increment of ½β∫κ² (for the midpoint κ of `newmark`, exactly;
  ½β(|κ^{n+1}|² − |κ^n|²) + ½β|κ^{n+1} − κ^n|² for the paper's backward Euler, whose extra term is numerical
  dissipation ≥ 0). So the stored energy is

      Π(η, κ) = ½ η_x² + ½ β κ²          (`stored_energy`, in both unknowns),

  and the curvature is conservative: it is not one of the `dissipative_fields`.

The form is linear in (η, κ) and their derivatives: its steps take the Newton module's linear path
(`timestepping.newton`: J factorised once, one solve per step, no Newton iteration), and κ starts from η0's
curvature. κ has no time derivative, so every scheme solves it with the η its row reads: `paper` at the new level,
`newmark` at the midpoint (κ's midpoint is the midpoint η's curvature, so each κ^n is η^n's), `projection` at its
explicit η^n: the bending force is then explicit too, and the stable Δt shrinks like Δx²/√β (`stable_dt`; the
scheme checks its own bound and refuses a larger Δt).

On a membrane the same form (∇ for the x-derivatives) is a simply supported plate, κ = −Δη held at 0 on the
boundary; its nonsymmetric system is factorised by MUMPS (`linear_options`).

Its constant (`CONSTANTS`, the scene's ``[parameters]``): `beta` ≥ 0, default 0 (the paper's string). Its output
field `curvature` is κ, drawn on a diverging, symmetric scale (`CURVATURE`). A single mode sin(mπx/l) oscillates
with ω² = (mπ/l)² + β (mπ/l)⁴ (α = 0, no contact; demos/demo_stiff_string.py, tests/model/test_stiff_string.py).
"""

from __future__ import annotations

import dataclasses
import math

import ufl

from .interface import DIVERGING, ModelConstant, OutputField, Parameters, SolverHints, inelastic

#: The largest bending stiffness a scene may give (in string units, β = EI/(T l²): the length scale's square); a
#: piano string's inharmonicity B = π²β is 1e-4 to 1e-2 (β ≈ 1e-5 to 1e-3).
BETA_MAX = 1e3
#: The stiff string's constants: a scene's ``[parameters]``.
CONSTANTS = (
    ModelConstant("beta", 0.0, 0.0, BETA_MAX, unit="length²",
                  description="the bending stiffness β in η_tt − α η_txx − η_xx + β η_xxxx = F (0: the paper's string)"),
)
#: The stiff string's output field: the curvature κ = −η_xx on a range symmetric about 0: red where the string
#: arches (a crest, κ > 0), blue where it sags (a trough, the edges of a contact set), grey where it is straight.
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
    mass, α = 0: Δt ≤ 2/ω_max with ω_max² = λ + β λ², λ = 12/Δx² (the consistent κ-mass's largest M₀⁻¹K eigenvalue
    on the alternating mode is 12/Δx², the lumped η-mass's 4/Δx²: ω² = λ_K + β λ_K λ_κ). An estimate for a scene's
    Δt; the scheme measures its own bound."""
    lam_eta, lam_kappa = 4.0 / dx**2, 12.0 / dx**2
    return 2.0 / math.sqrt(lam_eta + beta * lam_eta * lam_kappa)


#: The mixed system is not symmetric (κ's row is the curvature, not the bending energy's derivative): a direct
#: solver. On a membrane (a simply supported plate) MUMPS' LU; on a string on several ranks each rank factorises
#: the banded system (PCREDUNDANT), as the film's; in serial the size rule's LU.
PLATE_LU = (("ksp_type", "preonly"), ("pc_type", "lu"), ("pc_factor_mat_solver_type", "mumps"))
STRING_PARALLEL = (("ksp_type", "preonly"), ("pc_type", "redundant"))


def linear_options(dim: int, ranks: int, constants: dict) -> tuple:
    """The linear solver (`SolverHints.linear_options`): a direct one whatever the size (the size rule's CG does not
    fit the nonsymmetric mixed system)."""
    if dim == 2:
        return PLATE_LU
    return STRING_PARALLEL if ranks > 1 else ()


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
    solver=SolverHints(linear_options=linear_options),
    energy_label=r"stored $\int \frac{1}{2}\eta_x^2 + \frac{\beta}{2}\kappa^2\,dx$",
    description="the string with bending stiffness beta (eta_tt - alpha eta_txx - eta_xx + beta eta_xxxx = F), "
                "pinned ends; the paper's contact law",
)

__all__ = ["BETA_MAX", "CONSTANTS", "CURVATURE", "PLATE_LU", "STRING_PARALLEL", "linear_options", "stable_dt",
           "stiff_string", "stiff_string_residual", "stored_energy"]
