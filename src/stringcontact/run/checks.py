"""The energy ledger's verdicts on a run: the one energy balance and the one penetration check.

Every run gets them once (`checks_of`, cached on the `Result`): the driver marks a run whose balance does
not close "unbalanced", the output folder writes them into summary.json, the command line prints them,
and the theorem checks read the energy balance's continuous residual. docs/explanation/reliability.md.
"""

from __future__ import annotations

import math

import numpy as np

#: max |balance residual| / energy scale above which the energy balance is reported as not closing, for a run
#: whose round-off estimate (`roundoff_growth`) is below it; above, the tolerance grows with the estimate.
BALANCE_RTOL = 1e-8
#: The round-off estimate's safety factor: measured residual / (u n η/(|v| Δt)) was 0.013 at 2e4 steps, 0.06 at 1e5
#: and 0.09 at 2e5 (example1, nx = 50; docs/explanation/reliability.md), growing slowly with n.
ROUNDOFF_FACTOR = 10.0
#: the penetration bound is PENETRATION_FACTOR·(ε + Δt)·max|v| below the lowest initial value (docs/explanation/reliability.md).
PENETRATION_FACTOR = 2.0


def checks_of(result) -> dict:
    """{"energy_balance": ..., "penetration": ...} of `result`, computed once and kept in `result.checks`."""
    if not getattr(result, "checks", None) and len(result.t):
        result.checks = {"energy_balance": energy_balance(result), "penetration": penetration_check(result)}
    return result.checks


def energy_balance(result) -> dict:
    """The discrete energy balance at the last stored time, with a verdict.

    E(0) + W_ext = E(t) + D_visc + D_con + D_num, where D_num is the scheme's own consistency term
    (see `Result`). The residual is the largest |E(0) + W_ext − [E(t) + D]| over the stored times,
    relative to the largest term; the balance "closes" when it is below BALANCE_RTOL. The same scale gives
    `continuous_residual`, the identity (1.4) without D_num (the theorem checks: it falls with Δt).
    """
    e = result.energy
    total = result.total_energy
    residual = np.asarray(result.balance_residual, dtype=float)
    terms = {
        "initial": float(total[0]),
        "final": float(total[-1]),
        "viscous_dissipation": float(e["viscous_dissipation"][-1]),
        "contact_dissipation": float(e["contact_dissipation"][-1]),
        "numerical_dissipation": float(e["numerical_dissipation"][-1]),
        "external_work": float(e["external_work"][-1]),
    }
    scale = max([abs(v) for v in terms.values()] + [np.finfo(float).tiny])
    worst = float(np.max(np.abs(residual))) if residual.size else 0.0
    relative = worst / scale if math.isfinite(worst) else math.inf
    continuous = residual + np.asarray(e["numerical_dissipation"], dtype=float)
    worst_continuous = float(np.max(np.abs(continuous))) if continuous.size else 0.0
    contact = terms["contact_dissipation"]
    tolerance = BALANCE_RTOL * roundoff_growth(result)
    return {
        **terms,
        "residual": float(residual[-1]),
        "max_abs_residual": worst,
        "relative_residual": relative,
        "tolerance": tolerance,
        "closes": bool(relative <= tolerance),
        # (1.4) without the scheme's D_num (analysis.theorems.check_energy): -> 0 as dt -> 0
        "continuous_residual": worst_continuous / scale if math.isfinite(worst_continuous) else math.inf,
        "numerical_over_contact": terms["numerical_dissipation"] / contact if contact > 0 else math.nan,
    }


def roundoff_growth(result) -> float:
    """How far round-off alone can carry the balance beyond BALANCE_RTOL: max(1, estimate / 1e-8), the same on
    every rank (from the scene, the step count and the series every rank holds).

    The scheme's state is η; v = (η^{n+1} − η^n)/Δt inherits η's rounding, a relative error u·|η|/(|v|·Δt) per
    step (u = 2.2e-16), and the identity's work terms carry it into the ledger at every step. So after n steps
    the relative residual may reach ROUNDOFF_FACTOR·u·n·|η|/(|v|·Δt): it grows with n/Δt, about n² at a fixed T
    (example1 at nx = 50: 5.6e-11 at 2e4 steps, 6.4e-9 at 1e5, 4.0e-8 at 2e5). Compensated sums of the ledger
    do not help (math.fsum of every term gave the same 4.04e-8 at 2e5 steps): the error is in the terms.
    """
    steps = int(np.max(result.steps)) if len(getattr(result, "steps", ())) else 0
    speeds = np.asarray(result.series.get("max_speed", ()) if getattr(result, "series", None) else (), dtype=float)
    if not speeds.size and getattr(result, "has_rows", True) and result.velocity is not None:
        speeds = np.abs(np.asarray(result.velocity, dtype=float))
    speed = float(np.max(speeds, initial=0.0))
    if steps == 0 or not speed > 0.0 or not math.isfinite(speed):
        return 1.0
    estimate = ROUNDOFF_FACTOR * np.finfo(float).eps * steps * _eta_scale(result) / (speed * result.scene.dt)
    return max(1.0, estimate / 1e-8)


def _eta_scale(result) -> float:
    """max |η| the scene sets (η0 on its grid or probe points, the end heights) and the run reached (min η)."""
    scene = result.scene
    points = scene.x() if scene.dim == 1 else scene.probe_points()
    values = [abs(float(result.min_eta))] if math.isfinite(float(result.min_eta)) else []
    if len(points):
        values.append(float(np.max(np.abs(scene.initial_displacement(points)))))
    values += [abs(float(h)) for h in (scene.h_left, scene.h_right) if h is not None]
    return max(values, default=1.0) or 1.0


def penetration_check(result) -> dict:
    """How far the string went below the obstacle, against the bound of its contact law, if it has one.

    The bound belongs to the law (`Result.penetration_bound`, from `Model.penetration_bound`). The velocity
    penalty F = (1/ε)(v)⁻ ("velocity") brakes a node falling at speed V within a depth ε·V (exactly, for the
    explicit scheme: Σ Δt·V·(1 − r)^k = ε·V), plus at most one step Δt·V travelled before the force switches
    on. The bound allows twice that, for the elastic and viscous forces acting meanwhile, below the deepest
    initial value:

        depth ≤ max(0, max(ψ − η0)) + PENETRATION_FACTOR·(ε + Δt)·V,   V = max |v| over the stored rows,

    with ψ the scene's obstacle (0 unless it gives one). For a spring of stiffness 1/ε ("spring", the
    `elastic` variant) ε·V becomes √ε·V; a contact step (scheme projection) has no ε. A law with no known
    bound (None: a user's penalty; any penalty against a moving obstacle, which brakes the gap rate v − ψ_t but
    never restores the gap, so an accelerating obstacle drives the string ever deeper, docs/howto/nonlinear_models.md)
    gets the depth alone: "bound" and "within_bound" are None. A run beyond the
    bound holds the string down by something the penalty cannot stop (a static load, a model variant, an
    r > 1 rebound): see docs/explanation/reliability.md.
    """
    scene = result.scene
    if getattr(result, "has_rows", True):
        eta = np.asarray(result.eta, dtype=float)
        velocity = np.asarray(result.velocity, dtype=float)
        # max |v| without the |v| array: Example 1's would be 15 MB of fresh pages, 0.03 s of the run (cProfile)
        v_max = max(float(velocity.max()), -float(velocity.min())) if velocity.size else 0.0
        if scene.obstacle is None:  # min_eta covers every step, not only the stored ones
            depth = max(0.0, -float(result.min_eta))
            start_depth = max(0.0, -float(np.min(eta[0]))) if eta.size else 0.0
        else:
            below = _below_obstacle(scene, np.asarray(result.x, dtype=float), np.asarray(result.t, dtype=float), eta)
            depth = max(0.0, float(np.max(below))) if eta.size else 0.0
            start_depth = max(0.0, float(below[0])) if eta.size else 0.0
    else:  # an MPI rank without the rows: the same numbers from the series the ranks summed (Result.series)
        v_max, depth, start_depth = _penetration_from_series(result)
    eps_free = getattr(result, "penalty", None) == "none"  # a contact step (projection): no ε brakes the string
    kind = "contact step" if eps_free else getattr(result, "penetration_bound", "velocity")
    if not eps_free and getattr(scene, "obstacle_moves", False):
        kind = "moving obstacle"  # a penalty brakes the gap rate but never restores the gap: no bound
    braking, law = _BRAKING[kind]
    check = {"depth": depth, "initial_depth": start_depth, "max_speed": v_max, "law": law, "eps_free": eps_free,
             "bound_kind": kind}
    if braking is None:  # a law with no known bound: the depth alone
        return {**check, "bound": None, "eps_times_speed": None, "within_bound": None}
    braking = braking(scene.eps)
    bound = start_depth + PENETRATION_FACTOR * (braking + scene.dt) * v_max
    return {**check, "bound": bound, "eps_times_speed": braking * v_max,
            "within_bound": bool(depth <= bound * (1 + 1e-12))}


#: Each contact law's bound (`Model.penetration_bound`): how deep ε lets a node falling at speed 1 go, and its name.
_BRAKING = {
    "contact step": (lambda eps: 0.0, "no penalty (contact step)"),
    "velocity": (lambda eps: eps, "velocity penalty (eps)"),
    "spring": (math.sqrt, "spring (sqrt(eps))"),
    None: (None, "the model's contact law has no known penetration bound"),
    "moving obstacle": (None, "a penalty against a moving obstacle has no known penetration bound"),
}


def _below_obstacle(scene, x: np.ndarray, t: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """max (ψ − η) of each stored row; a moving obstacle ψ(x, t) at each row's time."""
    if not getattr(scene, "obstacle_moves", False):
        return np.max(scene.obstacle_values(x) - eta, axis=1, initial=-np.inf)
    return np.array([np.max(scene.obstacle_values(x, ti) - row, initial=-np.inf) for ti, row in zip(t, eta)])


def _penetration_from_series(result) -> tuple[float, float, float]:
    """max |v|, the depth and the initial depth from Result.series ("max_speed", "depth" = max(ψ − η))."""
    speed, below = result.series["max_speed"], result.series["depth"]
    if not len(below):
        return 0.0, max(0.0, -float(result.min_eta)), 0.0
    depth = -float(result.min_eta) if result.scene.obstacle is None else float(np.max(below))
    return float(np.max(speed)), max(0.0, depth), max(0.0, float(below[0]))


def unbalanced_message(result) -> str | None:
    """Why a run whose energy balance does not close cannot be called complete; None if it closes."""
    if not len(result.t):
        return None
    b = checks_of(result)["energy_balance"]
    if b["closes"]:
        return None
    return (
        f"the energy balance does not close (relative residual {b['relative_residual']:.2g} > {b['tolerance']:.0e}): "
        "the numbers are not trustworthy; see docs/explanation/reliability.md"
    )
