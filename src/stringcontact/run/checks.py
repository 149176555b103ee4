"""The energy ledger's verdicts on a run: the one energy balance and the one penetration check.

Every run gets them once (`checks_of`, cached on the `Result`): the driver marks a run whose balance does
not close "unbalanced", the output folder writes them into summary.json, the command line prints them,
and the theorem checks read the energy balance's continuous residual. docs/explanation/reliability.md.
"""

from __future__ import annotations

import math

import numpy as np

from ..fem import compat

#: max |balance residual| / energy scale above which the energy balance is reported as not closing, for a run
#: whose round-off estimate (`roundoff_growth`) is below it; above, the tolerance grows with the estimate.
BALANCE_RTOL = 1e-8
#: The round-off estimate's safety factor: measured residual / (u n η/(|v| Δt)) was 0.013 at 2e4 steps, 0.06 at 1e5
#: and 0.09 at 2e5 (example1, nx = 50; docs/explanation/reliability.md), growing slowly with n.
ROUNDOFF_FACTOR = 10.0
#: |D_num| / the energy (E(0) + the external work put in) above which the run's report says that the scheme's own
#: dissipation is a large share of it (`energy_balance`'s "numerical_share"). D_num is the scheme's time error in
#: energy terms, O(Δt) (`Result`): at 10 % the dissipations the run reports (viscous, contact) are off in their first
#: digit, which a user comparing them with the equation's must be told. The shipped scenes (`stringcontact run`):
#: film_landing 34 % (flagged); film_drum 8.6 %, single_impact 3.7 %, example2 0.9 %, example1 0.3 %, loaded_string
#: 0.1 %, the projection scenes 0.
NUMERICAL_SHARE = 0.10
#: the penetration bound is PENETRATION_FACTOR·(ε + Δt)·max|v| below the lowest initial value (docs/explanation/reliability.md).
PENETRATION_FACTOR = 2.0


def checks_of(result) -> dict:
    """{"energy_balance": ..., "penetration": ...} of `result`, computed once and kept in `result.checks`."""
    if not getattr(result, "checks", None) and len(result.t):
        result.checks = {"energy_balance": energy_balance(result), "penetration": penetration_check(result)}
    return result.checks


def energy_balance(result) -> dict:
    """The discrete energy balance at the last stored time, with a verdict.

    E(0) + W_ext = E(t) + D_visc + D_int + D_con + D_num, where D_num is the scheme's own consistency term
    (see `Result`). The residual is the largest |E(0) + W_ext − [E(t) + D]| over the stored times,
    relative to the largest term; the balance "closes" when it is below BALANCE_RTOL. "numerical_share" is |D_num|
    over the energy E(0) + max(W_ext, 0) ("energy_scale"): a balance that closes may still carry a large D_num,
    which the report flags above NUMERICAL_SHARE. The same scale gives
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
        "internal_dissipation": float(e.get("internal_dissipation", [0.0])[-1]),
    }
    scale = max([abs(v) for v in terms.values()] + [np.finfo(float).tiny])
    worst = float(np.max(np.abs(residual))) if residual.size else 0.0
    relative = worst / scale if math.isfinite(worst) else math.inf
    continuous = residual + np.asarray(e["numerical_dissipation"], dtype=float)
    worst_continuous = float(np.max(np.abs(continuous))) if continuous.size else 0.0
    contact = terms["contact_dissipation"]
    energy = abs(terms["initial"]) + max(terms["external_work"], 0.0)  # what the run had to spend
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
        # the scheme's own dissipation as a share of the energy (the report flags it above NUMERICAL_SHARE)
        "energy_scale": energy,
        "numerical_share": abs(terms["numerical_dissipation"]) / energy if energy > 0 else 0.0,
    }


def roundoff_growth(result) -> float:
    """How far round-off alone can carry the balance beyond BALANCE_RTOL: max(1, estimate / 1e-8), the same on
    every rank (from the scene, the step count and the series every rank holds).

    The scheme's state is η; v = (η^{n+1} − η^n)/Δt inherits η's rounding, a relative error u·|η|/(|v|·Δt) per
    step (u = 2.2e-16), and the identity's work terms carry it into the ledger at every step. So after n steps
    the relative residual may reach ROUNDOFF_FACTOR·u·n·|η|/(|v|·Δt): it grows with n/Δt, about n² at a fixed T
    (example1 at nx = 50: 5.6e-11 at 2e4 steps, 6.4e-9 at 1e5, 4.0e-8 at 2e5). Compensated sums of the ledger
    do not help (math.fsum of every term gave the same 4.04e-8 at 2e5 steps): the error is in the terms.

    The step's solve adds its own: η^{n+1} is rounded relative to the step matrix's condition, which grows with the
    Courant number Δt/h (A = M/Δt² + C/Δt + K), so the estimate is multiplied by max(1, Δt/h) (example1's 1500
    steps: 5.1e-11 at Δt/h = 1, 2.2e-9 at 4, 8.0e-9 at 10 and 8.8e-9 at 20 on dolfinx 0.5; 1.5e-8 at 10 on 0.11:
    `benchmarks/bench_balance_roundoff.py --nx ...`).
    """
    steps = int(np.max(result.steps)) if len(getattr(result, "steps", ())) else 0
    speeds = np.asarray(result.series.get("max_speed", ()) if getattr(result, "series", None) else (), dtype=float)
    if not speeds.size and getattr(result, "has_rows", True) and result.velocity is not None:
        speeds = np.abs(np.asarray(result.velocity, dtype=float))
    speed = float(np.max(speeds, initial=0.0))
    if steps == 0 or not speed > 0.0 or not math.isfinite(speed):
        return 1.0
    estimate = ROUNDOFF_FACTOR * np.finfo(float).eps * steps * _eta_scale(result) / (speed * result.scene.dt)
    return max(1.0, estimate * _courant(result) / 1e-8)


def _courant(result) -> float:
    """max(1, Δt/h) with the scene's mesh size h (1 where it has none: a mesh file)."""
    h = float(result.scene.dx)
    return max(1.0, result.scene.dt / h) if math.isfinite(h) and h > 0 else 1.0


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
    gets the depth alone: "bound" and "within_bound" are None.

    The velocity bound is an impact's: it assumes that nothing keeps pressing the string into the obstacle once it
    has stopped. Under a sustained press λ (a static load, the tension of a string draped over a raised obstacle)
    the penalty lets the node creep in at ε·λ for as long as the press lasts, so the depth grows with time and no
    bound in max|v| holds; the pointwise form of the paper's estimate (its Section 3: (η − ψ)⁻ ≤ ε∫F dt) does.
    A run deeper than the impact bound under such a press (`_press`: a contact force lasting PRESS_SPAN·ε or longer
    in the stored rows) gets bound_kind "pressed", no bound, and what the depth is: "press_force" (the force density
    at the end of the press), "press_time" (how long it lasted) and "creep" (ε times its ∫F dt, from the stored
    rows: the depth the press explains). A press within the impact bound (the string's own tension pressing a node
    for a while after it landed) keeps the bound, which holds there. A run beyond the bound otherwise holds the string down by
    something the penalty cannot stop (a model variant, an r > 1 rebound): see docs/explanation/reliability.md.

    The depth is max(0, −min_gap) (every step: `Result.min_gap`) where the run recorded it, else from the stored
    rows; the initial depth is the first stored row's.
    """
    scene = result.scene
    press = None
    if getattr(result, "has_rows", True):
        velocity = np.asarray(result.velocity, dtype=float)
        # max |v| without the |v| array: Example 1's would be 15 MB of fresh pages, 0.03 s of the run (cProfile)
        v_max = max(float(velocity.max()), -float(velocity.min())) if velocity.size else 0.0
        gaps = np.asarray(result.stored_min_gap, dtype=float)
        start_depth = max(0.0, -float(gaps[0])) if gaps.size else 0.0
        depth = max(0.0, -float(np.min(gaps))) if gaps.size else 0.0
        velocity_law = getattr(result, "penalty", None) != "none" and not getattr(scene, "obstacle_moves", False) \
            and getattr(result, "penetration_bound", "velocity") == "velocity"
        press = _press(result) if velocity_law else None
    else:  # an MPI rank without the rows: the same numbers from the series the ranks summed (Result.series)
        v_max, depth, start_depth = _penetration_from_series(result)
    gap = float(getattr(result, "min_gap", math.nan))
    if math.isfinite(gap):  # min_gap covers every step, not only the stored ones
        depth = max(depth, -gap)
    eps_free = getattr(result, "penalty", None) == "none"  # a contact step (projection): no ε brakes the string
    kind = "contact step" if eps_free else getattr(result, "penetration_bound", "velocity")
    if not eps_free and getattr(scene, "obstacle_moves", False):
        kind = "moving obstacle"  # a penalty brakes the gap rate but never restores the gap: no bound
    elif kind == "velocity" and press is not None and depth > _impact_bound(scene, start_depth, v_max) * (1 + 1e-12):
        kind = "pressed"  # deeper than an impact goes, under a press: the penalty's creep, to which no bound applies
    braking, law = _BRAKING[kind]
    check = {"depth": depth, "initial_depth": start_depth, "max_speed": v_max, "law": law, "eps_free": eps_free,
             "bound_kind": kind}
    if kind == "pressed":
        check |= {"press_force": press[0], "press_time": press[1], "creep": scene.eps * press[2]}
    if braking is None:  # a law with no known bound: the depth alone
        return {**check, "bound": None, "eps_times_speed": None, "within_bound": None}
    braking = braking(scene.eps)
    bound = start_depth + PENETRATION_FACTOR * (braking + scene.dt) * v_max  # `_impact_bound` for the velocity law
    return {**check, "bound": bound, "eps_times_speed": braking * v_max,
            "within_bound": bool(depth <= bound * (1 + 1e-12))}


def _impact_bound(scene, start_depth: float, v_max: float) -> float:
    """The velocity penalty's impact bound: start + PENETRATION_FACTOR·(ε + Δt)·max|v|."""
    return start_depth + PENETRATION_FACTOR * (scene.eps + scene.dt) * v_max


#: A contact force that lasts longer than PRESS_SPAN·ε at a node is a press, not an impact: the velocity penalty
#: F = (1/ε)(v)⁻ stops a landing node within a time of order ε (its speed falls like (1 − r)^k per step, by e each
#: ε), after which F is 0 unless another force keeps pushing the node down (a load, the tension of a string
#: draped over a raised obstacle). Under such a press λ the node creeps in at the speed ε·λ for as long as it
#: lasts, however small its speed when it landed: the impact bound 2(ε + Δt)·max|v| does not hold. 20ε: an
#: impact's force has fallen below e⁻²⁰ ≈ 2e-9 of its peak by then.
PRESS_SPAN = 20.0
#: A stored contact force below this share of the run's largest one is taken as 0 (round-off after a landing).
PRESS_FLOOR = 1e-6


def _press(result) -> tuple[float, float, float] | None:
    """The longest-acting press in the stored rows, or None: (the contact force density at its end, how long it
    lasted, the time integral ∫F dt of the contact force over it, by the trapezoid over the stored rows). A node is
    pressed over a stretch of consecutive stored rows with a contact force above PRESS_FLOOR of the run's largest,
    lasting PRESS_SPAN·ε or longer; the press kept is the one with the largest ∫F dt."""
    force = np.asarray(result.contact_force, dtype=float)
    t = np.asarray(result.t, dtype=float)
    if force.ndim != 2 or len(t) < 2 or not np.isfinite(force).all():
        return None
    on = force > PRESS_FLOOR * float(np.max(force, initial=0.0))
    if not on.any():
        return None
    best = None
    span = PRESS_SPAN * result.scene.eps
    for node in np.flatnonzero(on.sum(axis=0) >= 2):  # nodes pressed in two stored rows at least
        edges = np.flatnonzero(np.diff(np.concatenate([[0], on[:, node].astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):  # stretches of rows a .. b − 1
            lasted = float(t[b - 1] - t[a])
            if lasted >= span:
                impulse = float(compat.trapezoid(force[a:b, node], t[a:b]))
                if best is None or impulse > best[2]:
                    best = (float(force[b - 1, node]), lasted, impulse)
    return best


#: Each contact law's bound (`Model.penetration_bound`): how deep ε lets a node falling at speed 1 go, and its name.
_BRAKING = {
    "contact step": (lambda eps: 0.0, "no penalty (contact step)"),
    "velocity": (lambda eps: eps, "velocity penalty (eps)"),
    "spring": (math.sqrt, "spring (sqrt(eps))"),
    None: (None, "the model's contact law has no known penetration bound"),
    "moving obstacle": (None, "a penalty against a moving obstacle has no known penetration bound"),
    "pressed": (None, "a velocity penalty under a sustained press: it creeps in at eps times the contact force"),
}


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
