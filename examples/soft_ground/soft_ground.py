"""A soft, damped ground (a Kelvin–Voigt bed) in place of the paper's rigid, inelastic obstacle.

Below y = 0 the ground pushes back with F = (k η⁻ − c η_t)⁺: a spring k and a dashpot c per unit length,
pushing only. A point hitting it at speed V bounces off with restitution e = exp(−ζπ/√(1−ζ²)),
ζ = c/(2√k). demos/demo_model_variant.py explains the numbers and runs it next to the paper's model.

k and c are the model's constants: a scene sets them in its [parameters] table (``k = 1e5``), Python through
``scene.replace(parameters={"k": 1e5})``; the UFL reads them as ``p.constants["k"]``. The model writes one field
of its own besides η, v, the contact set and force: ``spring_force``, the spring's part k η⁻ of the ground's push.
"""

import dataclasses
import math

import ufl

import stringcontact as sc

# The defaults: a bed that a point hitting it at 50 indents by 0.1 (an undamped spring stops it after V/√k),
# with the dashpot for a restitution of one half.
speed, depth, restitution = 50.0, 0.1, 0.5
k = (speed / depth) ** 2
zeta = -math.log(restitution) / math.sqrt(math.pi**2 + math.log(restitution) ** 2)
c = 2 * zeta * math.sqrt(k)

CONSTANTS = (
    sc.ModelConstant("k", default=k, low=0.0, high=1e12, low_open=True, unit="tension/length²",
                     description="the ground's spring stiffness per unit length (depth V/√k at speed V)"),
    sc.ModelConstant("c", default=c, low=0.0, high=1e12, unit="tension·time/length²",
                     description="the ground's dashpot per unit length (restitution from ζ = c/(2√k))"),
)


def ground_force(eta, v, p):
    """Kelvin–Voigt ground below y = 0: spring k η⁻ plus dashpot −c v, pushing only."""
    k, c = p.constants["k"], p.constants["c"]
    return ufl.conditional(ufl.lt(eta, 0), ufl.max_value(k * (-eta) - c * v, 0), 0)


def ground_energy(eta, p):
    """The spring's stored energy k (η⁻)² / 2."""
    return p.constants["k"] / 2 * ufl.max_value(-eta, 0) ** 2


def spring_force(U, p):
    """The spring's part of the ground's push, k η⁻ (the output field; U = (η,), the unknowns)."""
    return p.constants["k"] * ufl.max_value(-U[0], 0)


SPRING_FORCE = sc.OutputField("spring_force", expression=spring_force, label="ground spring force k η⁻",
                              unit="tension/length")

soft_ground = dataclasses.replace(
    sc.inelastic,
    name="soft_ground",
    penalty=ground_force,
    penalty_damping=None,  # no semi-implicit form for a spring
    contact_energy=ground_energy,
    constants=CONSTANTS,
    outputs=(SPRING_FORCE,),
    description=f"soft damped ground below y = 0: F = (k eta^- - c eta_t)^+ (defaults k = {k:g}, c = {c:.4g}: "
                "restitution 0.5)",
)
