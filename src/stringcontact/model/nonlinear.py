"""Nonlinear model variants, registered by name in pyproject.toml: their forms are nonlinear in η, so every scheme
solves each step by Newton; each declares its stored energy (the ledger, ``energy.png``) and keeps the paper's law.

``cubic_foundation``: the string on a Winkler–Duffing foundation, ∫ η_tt w + α ∫ η_tx w_x + ∫ η_x w_x +
∫ (k η + k3 η³) w = ∫ F w, stored energy ∫ ½ η_x² + ½ k η² + ¼ k3 η⁴.

``large_deflection``: the geometrically exact string under unit tension, its restoring force η_x/√(1 + η_x²) (on a
membrane the minimal-surface operator), stored energy ∫ (√(1 + η_x²) − 1); the paper's for small slopes.
"""

from __future__ import annotations

import dataclasses

import ufl

from .inelastic import momentum_form as _paper_momentum_form
from .interface import Parameters, inelastic

#: cubic_foundation's linear and cubic foundation stiffness (per unit length; the paper's tension is 1).
FOUNDATION_K = 1.0
FOUNDATION_K3 = 1.0


def foundation_form(eta, eta_t, eta_tt, force, w, p: Parameters):
    """The paper's momentum form plus the foundation's reaction (k η + k3 η³) w."""
    return _paper_momentum_form(eta, eta_t, eta_tt, force, w, p) + (FOUNDATION_K * eta + FOUNDATION_K3 * eta**3) * w * ufl.dx


def foundation_energy(eta, p: Parameters):
    """½ η_x² + ½ k η² + ¼ k3 η⁴."""
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.5 * FOUNDATION_K * eta**2 + 0.25 * FOUNDATION_K3 * eta**4


def large_deflection_form(eta, eta_t, eta_tt, force, w, p: Parameters):
    """η_tt w + α η_tx·w_x + η_x/√(1 + η_x²)·w_x − F w."""
    slope = ufl.grad(eta)
    return (eta_tt * w + p.alpha * ufl.inner(ufl.grad(eta_t), ufl.grad(w))
            + ufl.inner(slope, ufl.grad(w)) / ufl.sqrt(1 + ufl.inner(slope, slope)) - force * w) * ufl.dx


def large_deflection_energy(eta, p: Parameters):
    """√(1 + η_x²) − 1: the string's stretch under unit tension."""
    return ufl.sqrt(1 + ufl.inner(ufl.grad(eta), ufl.grad(eta))) - 1


cubic_foundation = dataclasses.replace(
    inelastic,
    name="cubic_foundation",
    momentum_form=foundation_form,
    stored_energy=foundation_energy,
    energy_label=r"stored $\int \frac{1}{2}\eta_x^2 + \frac{k}{2}\eta^2 + \frac{k_3}{4}\eta^4\,dx$",
    description=f"the paper's model on a nonlinear foundation k eta + k3 eta^3 (k = {FOUNDATION_K:g}, "
                f"k3 = {FOUNDATION_K3:g}); each step by Newton",
)

large_deflection = dataclasses.replace(
    inelastic,
    name="large_deflection",
    momentum_form=large_deflection_form,
    stored_energy=large_deflection_energy,
    energy_label=r"stored $\int \sqrt{1+\eta_x^2} - 1\,dx$",
    description="the geometrically exact string: tension term eta_x/sqrt(1+eta_x^2), inelastic contact; "
                "each step by Newton",
)

__all__ = ["FOUNDATION_K", "FOUNDATION_K3", "cubic_foundation", "foundation_energy", "foundation_form",
           "large_deflection", "large_deflection_energy", "large_deflection_form"]
