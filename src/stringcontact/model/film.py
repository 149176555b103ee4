"""The fluid film: a Reynolds lubrication layer between the string (or membrane) and the obstacle y = 0.

In string units (docs/explanation/film.md) the string is pushed by the film's pressure above ambient, and the film's
thickness is the gap η:

    η_tt − α η_txx − η_xx = p − p_a + F,   η_t = (m(η) p_x)_x,   m(η) = max(η, h_min)³/(12 μ),   p = p_a at the ends,

on a membrane ∇·(m(η)∇p). F is the paper's penalty, a backstop for η ≥ 0. The unknowns are η and the gauge pressure
q = p − p_a (held at 0 on the boundary) on the mixed P1 space, one residual (tests w, r): ∫ η_tt w + α η_tx·w_x +
η_x·w_x − q w − F w + ∫ η_t r + m(η) q_x·r_x. With r = q, the pressure's work is the film's viscous dissipation
−∫ m(η)|q_x|². The pressure has no time derivative: the scheme must be L-stable (the paper's backward Euler).
Newton's line search is ``l2``: with PETSc's ``bt`` 3 of the 20 runs of `stringcontact study film` stalled.
"""

from __future__ import annotations

import dataclasses

import ufl

from ..errors import SceneError
from .interface import DIVERGING, ModelConstant, OutputField, Parameters, SolverHints, direct_options, inelastic

#: The film's default thickness floor in the mobility max(η, h_min)³/(12 μ): it keeps the pressure's equation
#: nonsingular where the string touches (η ≤ 0 under the penalty); docs/explanation/film.md measures its effect.
H_MIN = 1e-3
#: The film's constants: a scene's ``[parameters]`` (all optional but `mu`).
CONSTANTS = (
    ModelConstant("mu", required=True, low=0.0, high=1e6, low_open=True,
                  description="the film's viscosity μ in the Reynolds mobility η³/(12μ)"),
    ModelConstant("p_ambient", 0.0, -1e6, 1e6, unit="pressure", description="the ambient pressure at the film's open ends"),
    ModelConstant("p_cav", None, -1e6, 1e6, unit="pressure",
                  description="cavitation, p ≥ p_cav (at most p_ambient; none: no cavitation)"),
    ModelConstant("h_min", H_MIN, 0.0, 1e3, low_open=True, unit="η",
                  description="the film-thickness floor in the mobility, max(η, h_min)³"),
)
#: The film's output field: the gauge pressure q = p − p_a, symmetric-log, blue below ambient, red above.
PRESSURE = OutputField("pressure", label="film pressure p − p_a", unit="pressure", colours=DIVERGING, scale="symlog",
                       linear_share=1e-3, surface=True)


def check_cavitation(values: dict) -> None:
    """The film's rule between its constants: the cavitation pressure p_cav at most the ambient p_ambient."""
    p_cav, p_a = values.get("p_cav"), values.get("p_ambient", 0.0)
    if p_cav is not None and p_cav > p_a:
        raise SceneError(f"p_cav: {p_cav:g} is above the ambient pressure p_ambient = {p_a:g}; "
                         f"allowed: a number in [-1e+06, {p_a:g}]")


def mobility(eta, p: Parameters):
    """m(η) = max(η, h_min)³/(12 μ): the film's flow per unit pressure gradient."""
    return ufl.max_value(eta, p.constants["h_min"]) ** 3 / (12 * p.constants["mu"])


def film_residual(U, U_t, U_tt, force, W, p: Parameters):
    """The string pushed by the gauge pressure q, and the film's mass balance η_t = ∇·(m(η)∇q)."""
    (eta, q), (eta_t, _), (eta_tt, _) = U, U_t, U_tt
    w, r = W
    string = (eta_tt * w + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w))
              + ufl.inner(ufl.grad(eta), ufl.grad(w)) - q * w - force * w)
    film = eta_t * r + mobility(eta, p) * ufl.inner(ufl.grad(q), ufl.grad(r))
    return (string + film) * ufl.dx


def string_energy(U, p: Parameters):
    """The energy the film's string stores, ½|∇η|²: the pressure stores none (its work is the film's dissipation)."""
    return 0.5 * ufl.inner(ufl.grad(U[0]), ufl.grad(U[0]))


def pressure_lower(p: Parameters) -> dict:
    """Cavitation: q = p − p_a ≥ p_cav − p_a where the scene gives p_cav; no bound otherwise."""
    return _lower({name: float(c.value) for name, c in p.constants.items()})


def _lower(values: dict) -> dict:
    return {} if values.get("p_cav") is None else {"pressure": values["p_cav"] - values.get("p_ambient", 0.0)}


#: A membrane that does not cavitate: GMRES with a Schur fieldsplit on the pressure ("selfp", BoomerAMG on both):
#: 3.7 s per step at 1e5 nodes against MUMPS' 8.5 s; AMG on the whole system stalls once the membrane lands.
MEMBRANE_FIELDSPLIT = (
    ("ksp_type", "gmres"), ("pc_side", "right"), ("ksp_norm_type", "unpreconditioned"), ("ksp_rtol", 1e-10),
    ("ksp_atol", 0.0), ("ksp_initial_guess_nonzero", False), ("ksp_gmres_restart", 100), ("ksp_max_it", 500),
    ("pc_type", "fieldsplit"), ("pc_fieldsplit_type", "schur"), ("pc_fieldsplit_schur_fact_type", "lower"),
    ("pc_fieldsplit_schur_precondition", "selfp"),
    ("fieldsplit_0_ksp_type", "preonly"), ("fieldsplit_0_pc_type", "hypre"),
    ("fieldsplit_1_ksp_type", "preonly"), ("fieldsplit_1_pc_type", "hypre"))
def linear_options(dim: int, ranks: int, constants: dict) -> tuple:
    """The film's linear solver: on a membrane the Schur fieldsplit, or MUMPS' LU when it cavitates (its VI's
    reduced systems have no block size to split); on a string the `direct_options`."""
    return MEMBRANE_FIELDSPLIT if dim == 2 and not _lower(constants) else direct_options(dim, ranks)


film = dataclasses.replace(
    inelastic,
    name="film",
    fields=("pressure",),
    residual=film_residual,
    stored_energy=string_energy,
    held_fields=("pressure",),
    field_lower=pressure_lower,
    dissipative_fields=("pressure",),
    schemes=("paper",),
    constants=CONSTANTS,
    check_constants=check_cavitation,
    outputs=(PRESSURE,),
    # cells = [1000, 1000] peaked at 5.5 GB: 5.5 KB per node, 1.8 times one unknown's (η and the pressure, their LU)
    solver=SolverHints(newton_options=(("snes_linesearch_type", "l2"),), linear_options=linear_options,
                       setup_bytes_per_node=5500),
    scheme_note="its pressure has no time derivative, so it needs an L-stable step (the paper's backward Euler); "
                "newmark's midpoint rule is not L-stable and projection's elastic term is explicit",
    description="a Reynolds lubrication film (viscosity mu) between the string and the obstacle; the paper's "
                "penalty as a backstop; each step by Newton",
)

__all__ = ["CONSTANTS", "H_MIN", "MEMBRANE_FIELDSPLIT", "PRESSURE", "check_cavitation", "film", "film_residual",
           "linear_options", "mobility", "pressure_lower", "string_energy"]
