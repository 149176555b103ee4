"""What a simulation returns: arrays at the stored times, ordered by x, on every rank."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import compat

ENERGY_KEYS = (
    "kinetic",
    "elastic",
    "viscous_dissipation",
    "contact_dissipation",
    "numerical_dissipation",
    "external_work",
)


@dataclass
class Result:
    """Stored rows of one run.

    `contact` is η ≤ 0 (on or below the obstacle); the penalty acts where η < 0.
    `contact_force` at t_n is the force density applied in the step that ends at t_n.
    `energy` holds (k,) arrays; the dissipations and the external work are cumulative from t=0.
    `numerical_dissipation` is the scheme's own consistency term: ½|v^{n+1}−v^n|²_M + ½|η^{n+1}−η^n|²_K
    per step, so that the discrete balance below closes to round-off.
    """

    scene: object
    x: np.ndarray
    t: np.ndarray
    steps: np.ndarray
    eta: np.ndarray
    velocity: np.ndarray
    contact: np.ndarray
    contact_force: np.ndarray
    energy: dict
    min_eta: float
    penalty: str
    mass: str
    model: str
    status: str = "complete"
    timings: dict = field(default_factory=dict)
    message: str = ""
    scheme: str = "paper"

    @property
    def total_energy(self) -> np.ndarray:
        return self.energy["kinetic"] + self.energy["elastic"]

    @property
    def balance_residual(self) -> np.ndarray:
        """E(0) + W_ext − [E(t) + D_visc + D_con + D_num] at each stored time; round-off for this scheme."""
        e = self.energy
        spent = e["viscous_dissipation"] + e["contact_dissipation"] + e["numerical_dissipation"]
        return self.total_energy[0] + e["external_work"] - (self.total_energy + spent)

    @property
    def contact_length(self) -> np.ndarray:
        """Measure of the contact set {η ≤ 0} at each stored time (trapezoidal in x)."""
        c = self.contact.astype(float)
        return compat.trapezoid(c, self.x, axis=1) if c.shape[1] > 1 else c[:, 0]
