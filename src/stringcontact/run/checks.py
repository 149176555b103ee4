"""A run's energy balance and penetration check, computed once (`checks_of`): they mark a run "unbalanced", go
into summary.json and the report (docs/explanation/reliability.md, "The two checks at the end of every run")."""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from ..fem import compat
from ..timestepping.affine import affine_in
from ..timestepping.implicit import acceleration

#: The relative residual above which the balance does not close (raised by `roundoff_growth`'s estimate).
BALANCE_RTOL = 1e-8
#: The round-off estimate's safety factor: measured residual / (u n η/(|v| Δt)) was 0.013 at 2e4 steps, 0.06 at 1e5
#: and 0.09 at 2e5 (example1, nx = 50; docs/explanation/reliability.md), growing slowly with n.
ROUNDOFF_FACTOR = 10.0
#: |D_num| / the energy above which the report flags the scheme's own dissipation: at 10 % the reported dissipations
#: are off in their first digit (the shipped scenes: film_landing 34 %, the others at most 8.6 %).
NUMERICAL_SHARE = 0.10
#: the penetration bound is PENETRATION_FACTOR·(ε + Δt)·max|v| below the lowest initial value.
PENETRATION_FACTOR = 2.0


def checks_of(result) -> dict:
    """{"energy_balance": ..., "penetration": ...} of `result`, computed once and kept in `result.checks`."""
    if not getattr(result, "checks", None) and len(result.t):
        result.checks = {"energy_balance": energy_balance(result), "penetration": penetration_check(result)}
    return result.checks


def energy_balance(result) -> dict:
    """E(0) + W_ext = E(t) + D_visc + D_int + D_con + D_num at the stored times: the largest residual relative to the
    largest term ("closes" below the tolerance), "numerical_share" |D_num| / (E(0) + max(W_ext, 0)), and
    "continuous_residual", the identity (1.4) without D_num (the theorem checks: it falls with Δt)."""
    e, total = result.energy, result.total_energy
    residual = np.asarray(result.balance_residual, dtype=float)
    terms = {"initial": float(total[0]), "final": float(total[-1])} | {key: float(e[key][-1]) for key in (
        "viscous_dissipation", "contact_dissipation", "numerical_dissipation", "external_work")}
    terms["internal_dissipation"] = float(e.get("internal_dissipation", [0.0])[-1])
    scale = max([abs(v) for v in terms.values()] + [np.finfo(float).tiny])
    worst = float(np.max(np.abs(residual))) if residual.size else 0.0
    relative = worst / scale if math.isfinite(worst) else math.inf
    continuous = residual + np.asarray(e["numerical_dissipation"], dtype=float)
    worst_continuous = float(np.max(np.abs(continuous))) if continuous.size else 0.0
    contact, numerical = terms["contact_dissipation"], terms["numerical_dissipation"]
    energy = abs(terms["initial"]) + max(terms["external_work"], 0.0)  # what the run had to spend
    tolerance = BALANCE_RTOL * roundoff_growth(result)
    return terms | {
        "residual": float(residual[-1]), "max_abs_residual": worst, "relative_residual": relative,
        "tolerance": tolerance, "closes": bool(relative <= tolerance),
        "continuous_residual": worst_continuous / scale if math.isfinite(worst_continuous) else math.inf,
        "numerical_over_contact": numerical / contact if contact > 0 else math.nan,
        "energy_scale": energy, "numerical_share": abs(numerical) / energy if energy > 0 else 0.0}


def roundoff_growth(result) -> float:
    """How far round-off alone carries the balance beyond BALANCE_RTOL, the same on every rank: max(1, estimate /
    1e-8), the estimate ROUNDOFF_FACTOR·u·n·|η|/(|v|·Δt)·max(1, Δt/h) after n steps, as v = (η^{n+1} − η^n)/Δt
    inherits η's rounding and the solve's grows with the Courant number (measured: `bench_balance_roundoff.py`;
    math.fsum of the ledger gave the same residual: the error is in the terms)."""
    steps = int(np.max(result.steps)) if len(getattr(result, "steps", ())) else 0
    speeds = np.asarray(result.series.get("max_speed", ()) if getattr(result, "series", None) else (), dtype=float)
    if not speeds.size and getattr(result, "has_rows", True) and result.velocity is not None:
        speeds = np.abs(np.asarray(result.velocity, dtype=float))
    speed = float(np.max(speeds, initial=0.0))
    if steps == 0 or not speed > 0.0 or not math.isfinite(speed):
        return 1.0
    estimate = ROUNDOFF_FACTOR * np.finfo(float).eps * steps * _eta_scale(result) / (speed * result.scene.dt)
    h = float(result.scene.dx)  # the scene's mesh size (a mesh file gives none)
    courant = max(1.0, result.scene.dt / h) if math.isfinite(h) and h > 0 else 1.0
    return max(1.0, estimate * courant / 1e-8)


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
    """How far the string went below the obstacle (max(0, −min_gap)) against its contact law's bound
    (docs/explanation/reliability.md, "Penetration against ε·|v|"): the velocity penalty's
    depth ≤ max(0, max(ψ − η0)) + PENETRATION_FACTOR·(ε + Δt)·max|v| (√ε for a spring, no ε for a contact step);
    no bound ("bound", "within_bound" None) for a law without one or a moving obstacle, or, deeper than the impact
    bound under a sustained press (`_press`), bound_kind "pressed" with "press_force", "press_time" and "creep"
    (ε∫F dt over the press, the depth it explains)."""
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
    elif kind == "velocity" and press is not None:  # deeper than an impact goes under a press: the penalty's creep
        impact = start_depth + PENETRATION_FACTOR * (scene.eps + scene.dt) * v_max
        kind = "pressed" if depth > impact * (1 + 1e-12) else kind
    braking, law = _BRAKING[kind]
    check = {"depth": depth, "initial_depth": start_depth, "max_speed": v_max, "law": law, "eps_free": eps_free,
             "bound_kind": kind}
    if kind == "pressed":
        check |= {"press_force": press[0], "press_time": press[1], "creep": scene.eps * press[2]}
    if braking is None:  # a law with no known bound: the depth alone
        return {**check, "bound": None, "eps_times_speed": None, "within_bound": None}
    braking = braking(scene.eps)
    bound = start_depth + PENETRATION_FACTOR * (braking + scene.dt) * v_max
    return {**check, "bound": bound, "eps_times_speed": braking * v_max,
            "within_bound": bool(depth <= bound * (1 + 1e-12))}


#: A contact force lasting PRESS_SPAN·ε or longer at a node is a press, not an impact: the velocity penalty stops a
#: landing node within a time of order ε, so an impact's force has fallen below e⁻²⁰ ≈ 2e-9 of its peak by then.
PRESS_SPAN = 20.0
#: A stored contact force below this share of the run's largest one is taken as 0 (round-off after a landing).
PRESS_FLOOR = 1e-6


def _press(result) -> tuple[float, float, float] | None:
    """The press with the largest ∫F dt in the stored rows (a node's consecutive rows with a force above PRESS_FLOOR of
    the largest, lasting PRESS_SPAN·ε or longer), or None: (the force at its end, its duration, ∫F dt)."""
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


#: A free node whose one step Δt|v0| + ½Δt²|a0| exceeds this share of max|η0| is not at rest: a force that is only the
#: rounding of an equilibrium moves a node by about 1e-16 (Δt/h)² |η| a step, far below it.
REST_SHARE = 1e-10


def restless(stepper, eta0: np.ndarray, v0: np.ndarray) -> bool:
    """Whether the initial state (η0, v0) on this rank is not at rest, from the model and not the scheme: one step's
    Δt|v0| + ½Δt²|a0| beyond REST_SHARE·max|η0| at a free node off the obstacle (outside the model's contact set at
    η0); a0 = M_L⁻¹(b − Kη0 − Cv0) for a form affine in η and η_t with one field, else 0 (v0 alone)."""
    d, nl = stepper.discrete, stepper.discrete.ops.nonlinear
    linear = nl is None or (nl.eta_dofs is None and affine_in(nl.residual, (nl.eta, nl.eta_t)))
    a0 = acceleration(d, eta0, v0) if linear else 0.0
    laws, env = d.laws, dict(d.laws.env)  # a copy: a scheme's placeholders keep pointing at its own arrays
    env[laws.key("eta")] = eta0
    on = laws.compile(stepper.model.contact_set(laws.eta, laws.params)).evaluate_env(env)
    moves = d.dt * np.abs(v0) + 0.5 * d.dt**2 * np.abs(a0) > REST_SHARE * np.max(np.abs(eta0), initial=0.0)
    return bool(np.any(moves & d.interior & ~np.broadcast_to(np.asarray(on, dtype=bool), eta0.shape)))


def still_message(st, eta0: np.ndarray, moving: bool) -> str | None:
    """Why a run whose η never left η0 (bit for bit at T and in every stored row) cannot be complete though its initial
    state was not at rest (`moving`, from `restless`) or it stored a velocity: its scheme did not step, whatever
    energies it reported; None otherwise. Collective."""
    rows, n = st.rows, st.rows.n
    still = bool(np.array_equal(st.scheme.eta, eta0))
    if rows.gather.holds and n:
        still = still and bool((rows.fields["eta"][:n] == rows.fields["eta"][0]).all())
    moving = moving or float(np.max(rows.series["max_speed"][:n], initial=0.0)) > 0.0
    if st.comm.size > 1:
        still, moving = st.comm.allreduce(still, op=MPI.LAND), st.comm.allreduce(moving, op=MPI.LOR)
    if not (still and moving):
        return None
    return (f"eta never moved: it equals eta(0) bit for bit at every stored time, though the initial state is not at "
            f"rest (v0, the net force b - K eta0 - C v0 or a stored velocity off the obstacle): scheme '{st.name}' did "
            "not step; the numbers are not trustworthy; see docs/explanation/reliability.md")
