"""GetFEM's impacting rod (``demo_dynamic_contact_1D.py``, Y. Renard, F. Chouly, LGPL 2.1; docs/explanation/getfem.md):
u_tt − u_xx = 0 on (0, 1), u(1, t) = 0, Signorini contact u(0, t) ≥ 0, u_x(0, t) ≤ 0, u u_x = 0 at x = 0, from
u(x, 0) = (1 − x)/2 at rest; its exact solution (`rod_exact`) has period 3 and energy 1/8. Mirrored about the
contact point it is a string on (0, 2) over a point obstacle at x = 1, η(x, t) = u(|x − 1|, t) (`string_exact`,
`rod_scene`, `point_contact`), whose relative errors are the rod's. Shared by `bench_getfem` and the tests (tests/verification/test_getfem.py,
tests/timestepping/test_release.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import ufl

from stringcontact.scene import Scene

PERIOD = 3.0
ROD_ENERGY = 1.0 / 8.0
CONTACT_POINT = 1.0  # of the string on (0, 2)

# u = a + b x + c τ in each (phase, zone) of one period, τ = time since the phase began (GetFEM's table).
# Zones follow the characteristics through (0, 0) and (1, 0): 1 = τ < x, τ ≤ 1 − x; 2 = τ ≥ x, τ ≤ 1 − x;
# 3 = τ < x, τ > 1 − x; 4 = τ ≥ x, τ > 1 − x.
_COEFFICIENTS = np.array([
    [[0.5, -0.5, 0.0], [0.5, 0.0, -0.5], [0.5, -0.5, 0.0], [0.5, 0.0, -0.5]],  # falling to the obstacle
    [[0.0, 0.0, -0.5], [0.0, -0.5, 0.0], [-0.5, 0.5, 0.0], [-0.5, 0.0, 0.5]],  # in contact
    [[0.0, 0.0, 0.5], [0.0, 0.0, 0.5], [0.5, -0.5, 0.0], [0.5, -0.5, 0.0]]])  # lifting off


def rod_exact(x, t: float, derivative: str = "u") -> np.ndarray:
    """The rod's exact u (``"u"``), u_x (``"x"``) or u_t (``"t"``) at the points x ∈ [0, 1] at time t."""
    x = np.asarray(x, dtype=float)
    tp = t % PERIOD
    phase = min(int(np.floor(tp)), 2)
    tau = tp - phase
    zone = np.where(tau < x, np.where(tau <= 1 - x, 0, 2), np.where(tau <= 1 - x, 1, 3))
    a, b, c = np.moveaxis(_COEFFICIENTS[phase][zone], -1, 0)
    return {"u": a + b * x + c * tau, "x": b, "t": c}[derivative]


def string_exact(x, t: float, derivative: str = "u") -> np.ndarray:
    """The mirrored string's exact η (``"u"``) or η_t (``"t"``) at x ∈ [0, 2]: u(|x − 1|, t)."""
    if derivative not in ("u", "t"):
        raise ValueError("string_exact gives 'u' or 't' (η_x changes sign across the contact point)")
    return rod_exact(np.abs(np.asarray(x, dtype=float) - CONTACT_POINT), t, derivative)


def rod_scene(nx_rod: int, dt: float, eps: float, T: float = PERIOD, variant: str = "rod"):
    """The mirrored problem as a `Scene`: 2·nx_rod cells on (0, 2) (the rod's cell size), round(T/Δt) steps of Δt (as
    GetFEM's demo ends); `variant` is one of `VARIANTS`."""
    nt = max(1, round(T / dt))
    data = {"name": f"getfem_{variant}_{nx_rod}", "description": VARIANTS[variant], "length": 2.0, "T": nt * dt,
            "nt": nt, "alpha": 0.0, "scheme": {"eps": eps}, "nx": 2 * nx_rod, "eta0": "0.5 - 0.5*abs(x - 1)",
            "v0": "0", "h": 0.0}
    return Scene.from_dict(data | _VARIANT_DATA[variant])


#: The scenes `rod_scene` makes: GetFEM's rod, and three that test the contact's energy rules on the same string.
VARIANTS = {
    "rod": "GetFEM's impacting rod mirrored into a string on (0, 2) over a point obstacle at x = 1",
    "gap": "the rod lifted 0.1234 above the obstacle's height: it lands at t = 1.2468, between the grid's steps",
    "velocity": "the rod thrown at the obstacle: GetFEM's data with the initial velocity -0.3 (1 - |x - 1|)",
    "pulse": "the string at rest at the obstacle's height, a narrow downward velocity pulse at x = 0.5 that runs into "
             "the point and presses it",
}
_VARIANT_DATA = {"rod": {}, "gap": {"h": 0.1234, "eta0": "0.1234 + 0.5 - 0.5*abs(x - 1)"},
                 "velocity": {"v0": "-0.3*(1 - abs(x - 1))"},
                 "pulse": {"eta0": "0", "v0": "-exp(-((x - 0.5)/0.05)**2)"}}


#: How far below the string the obstacle is away from the point x = 1 (no node gets there).
FAR = 1e6


def point_contact(model, h: float, name: str | None = None):
    """`model` with its contact law acting only at the node x = 1 (cells of size h, |x − 1| < h/2): a damper of
    strength h/ε on a node of mass h, so that r = Δt/ε keeps its meaning."""

    def at_point(p):
        return ufl.lt(abs(p.x[0] - CONTACT_POINT), h / 2)

    def only_at_point(law):
        if law is None:
            return None

        def point_law(*args):
            return ufl.conditional(at_point(args[-1]), law(*args), 0)

        return point_law

    def point_gap(eta, p):
        # away from the point the obstacle is out of reach: ψ = −FAR (slope 1 in η, as `projection` needs)
        return ufl.conditional(at_point(p), model.gap(eta, p), eta + FAR)

    def point_contact_set(eta, p):
        if model.gap is not None:  # {gap ≤ 0}: what `projection` checks the contact set against
            return ufl.le(point_gap(eta, p), 0)
        return ufl.And(at_point(p), model.contact_set(eta, p))

    return dataclasses.replace(
        model, name=name or f"{model.name}_at_x1", penalty=only_at_point(model.penalty),
        penalty_damping=only_at_point(model.penalty_damping), contact_set=point_contact_set,
        gap=None if model.gap is None else point_gap, contact_energy=only_at_point(model.contact_energy),
        description=f"{model.description}; only at the point x = 1")


def p1_l2_norms(values: np.ndarray, h: float) -> np.ndarray:
    """L²-norms of P1 functions with nodal values `values` (rows) on a uniform grid of cell size h, exact."""
    a, b = values[..., :-1], values[..., 1:]
    return np.sqrt(h / 3 * np.sum(a * a + a * b + b * b, axis=-1))


def relative_error(x: np.ndarray, t: np.ndarray, u: np.ndarray, exact=string_exact) -> float:
    """max_t ‖u − I_h u_ex‖_{L²} / max_t ‖I_h u_ex‖_{L²}, GetFEM's demo's relative L∞(0,T;L²) error of u (a row
    per time in `t`, at the uniform nodes `x`; I_h the P1 interpolation)."""
    u_ex = np.array([exact(x, tk) for tk in t])
    h = x[1] - x[0]
    return float(np.max(p1_l2_norms(u - u_ex, h)) / np.max(p1_l2_norms(u_ex, h)))


def relative_velocity_error(x: np.ndarray, t: np.ndarray, v: np.ndarray, exact=string_exact) -> float:
    """(Σ_t ‖v − I_h v_ex‖²_{L²} / Σ_t ‖I_h v_ex‖²_{L²})^½, GetFEM's demo's relative L²(0,T;L²) error of v (a row
    per time in `t`, uniform steps: the demo's factor Δt cancels; `exact` called with ``derivative="t"``)."""
    v_ex = np.array([exact(x, tk, "t") for tk in t])
    h = x[1] - x[0]
    return float(np.sqrt(np.sum(p1_l2_norms(v - v_ex, h) ** 2) / np.sum(p1_l2_norms(v_ex, h) ** 2)))


__all__ = ["CONTACT_POINT", "PERIOD", "ROD_ENERGY", "VARIANTS", "p1_l2_norms", "point_contact", "relative_error",
           "relative_velocity_error", "rod_exact", "rod_scene", "string_exact"]
