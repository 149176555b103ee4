"""The stability studies on the flat landing: the outcome over r = Δt/ε and Δt per penalty (`stability_map`), over
Δt/Δx without ε (`step_size_map`), and the sweep α → 0 (`alpha_sweep`)."""

from __future__ import annotations

import math

import numpy as np

import stringcontact as sc

from ..verification.exact import flat_landing_time
from ..verification.reference import fd_projection, fd_solve
from .problems import EPS_LIMIT, FLAT_H, FLAT_V, distribute, flat_landing_scene, simulate_self

STABILITY_COLUMNS = ("penalty", "mass", "dt", "eps", "r", "outcome", "restitution", "restitution_theory",
                     "energy_max_ratio", "growth_step", "min_eta")
ALPHA_COLUMNS = ("method", "alpha", "dt", "eps", "r", "restitution", "contact_dissipation", "numerical_dissipation",
                 "viscous_dissipation", "final_energy")
STEP_COLUMNS = ("scheme", "alpha", "dt_over_dx", "dt_max_over_dx", "outcome", "restitution", "energy_max_ratio",
                "min_eta")
STABILITY_R = (0.1, 0.3, 0.5, 0.8, 1.0, 1.2, 1.5, 1.8, 2.0, 2.5, 4.0, 10.0, 30.0, 100.0)
STABILITY_DT = (1 / 100, 1 / 200, 1 / 400)
STEP_RATIOS = (0.5, 0.9, 1.0, 1.05, 1.2, 1.5, 2.0, 4.0, 10.0)
#: Δt²/ε of the explicit spring (the elastic variant) at Δt = Δx = 1/200: r = Δt/ε = 200 q.
SPRING_Q = (0.005, 0.05, 0.5, 2.0, 4.0, 6.0, 8.0, 16.0, 64.0)
#: A post-impact upward velocity above this fraction of the impact speed is a (spurious) rebound.
REBOUND_THRESHOLD = 0.02
#: Energy above E(0)(1 + this) at any step is growth.
GROWTH_TOLERANCE = 1e-9


def restitution(t: np.ndarray, x: np.ndarray, velocity: np.ndarray, *, h: float = FLAT_H, V: float = FLAT_V,
                window: float = 0.1) -> float:
    """The largest upward velocity of the flat landing's middle node in (t*, t* + window] over the impact speed V."""
    mid = int(np.argmin(np.abs(x - 0.5 * (x[0] + x[-1]))))
    t_star = flat_landing_time(h, V)
    sel = (t > t_star) & (t <= t_star + window)
    if not sel.any():
        raise ValueError(f"no stored time in the restitution window ({t_star}, {t_star + window}]")
    v = velocity[sel, mid]
    return max(0.0, float(np.max(v))) / V if np.all(np.isfinite(v)) else math.inf


def restitution_theory(r: float, penalty: str) -> float:
    """Explicit penalty: v ← (1 − r) v per contact step, so no rebound for r ≤ 1 and restitution r − 1 above."""
    return max(0.0, r - 1.0) if penalty == "explicit" else 0.0


def classify(restitution_value: float, energy: np.ndarray) -> tuple[str, int]:
    """("growth" | "rebound" | "inelastic", first step at which the energy rose above E(0), or −1)."""
    E0 = energy[0]
    bad = ~np.isfinite(energy) | (energy > E0 * (1.0 + GROWTH_TOLERANCE))
    if bad.any():
        return "growth", int(np.argmax(bad))
    return ("rebound" if restitution_value > REBOUND_THRESHOLD else "inelastic"), -1


def _finite_difference(solve, scene, window: float = 0.1, **options) -> tuple[float, np.ndarray, dict]:
    """(restitution, energy per row, {energy_max_ratio, min_eta}) of `scene` by a NumPy reference (refusing nothing)."""
    x = scene.x()
    with np.errstate(all="ignore"):
        t, eta, vel = solve(scene.initial_displacement(x), scene.initial_velocity(x), length=1.0, T=scene.T,
                            nt=scene.nt, alpha=scene.alpha, h_left=scene.h_left, h_right=scene.h_right, **options)
        dx = scene.dx  # the lumped scheme's ½|v|²_M + ½ ηᵀKη per row, as the solver's `total_energy`
        energy = 0.5 * dx * np.sum(vel[:, 1:-1] ** 2, axis=1) + 0.5 * np.sum(np.diff(eta, axis=1) ** 2, axis=1) / dx
        e = restitution(t, x, vel, window=window)
    finite = np.all(np.isfinite(energy))
    return e, energy, {"energy_max_ratio": float(np.max(energy) / energy[0]) if finite else math.inf,
                       "min_eta": float(np.nanmin(np.where(np.isfinite(eta), eta, np.nan)))}


def _simulated(scene, window: float = 0.1, **options) -> tuple[dict, object]:
    """(outcome, restitution, growth_step, energy_max_ratio, min_eta; the Result or None) of `scene` by `simulate`."""
    try:
        res = simulate_self(scene, storage=sc.Storage(max_rows=scene.nt), **options)
    except sc.InstabilityError as exc:
        return {"outcome": "refused" if exc.step == 0 else "growth", "restitution": math.nan, "growth_step": exc.step,
                "energy_max_ratio": math.nan, "min_eta": math.nan}, None
    e = restitution(res.t, res.x, res.velocity, window=window)
    outcome, step = classify(e, res.total_energy)
    return {"outcome": outcome, "restitution": e, "growth_step": step, "min_eta": res.min_eta,
            "energy_max_ratio": float(np.max(res.total_energy) / res.total_energy[0])}, res


def stability_case(penalty: str, dt: float, r: float, mass: str = "lumped", T: float = 0.45) -> dict:
    """One cell of the stability map at ε = Δt/r: lumped mass by `fd_solve` (which does not refuse r ≥ 2), else `simulate`."""
    eps = dt / r
    scene = flat_landing_scene(round(1.0 / dt), eps=eps, T=T, nt=round(T / dt))
    row = {"penalty": penalty, "mass": mass, "dt": dt, "eps": eps, "r": r,
           "restitution_theory": restitution_theory(r, penalty) if mass == "lumped" else math.nan}
    if mass != "lumped":
        return row | _simulated(scene, penalty=penalty, mass=mass)[0]
    e, energy, measured = _finite_difference(fd_solve, scene, eps=eps, penalty=penalty)
    outcome, step = classify(e, energy)
    return row | measured | {"outcome": outcome, "restitution": e, "growth_step": step}


def stability_map(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of STABILITY_COLUMNS over penalty × Δt × r (and the explicit penalty with consistent mass)."""
    r_values = (0.5, 1.0, 1.5, 4.0, 100.0) if quick else STABILITY_R
    dts = (1 / 100,) if quick else STABILITY_DT
    cases = [(p, "lumped", dt, r) for p in ("explicit", "semi-implicit") for dt in dts for r in r_values]
    cases += [("explicit", "consistent", dt, r) for dt in dts for r in r_values]
    cases += [("explicit spring", "lumped", 1 / 200, 200 * q) for q in ((0.5, 64.0) if quick else SPRING_Q)]

    def one(c):
        return spring_case(c[3]) if c[0] == "explicit spring" else stability_case(c[0], c[2], c[3], mass=c[1])

    return distribute(one, cases, comm, cost=lambda c: 1 / c[2] ** 2, busy=busy)


def step_size_case(scheme: str, alpha: float, ratio: float, n: int = 200, T: float = 0.45) -> dict:
    """The flat landing at Δt = ratio·Δx (`projection` by `fd_projection`, `newmark` by `simulate` at ε → 0)."""
    from mpi4py import MPI

    from ..model.interface import inelastic
    from ..run.adapter import scene_problem
    from ..timestepping.spectrum import largest_stable_dt

    scene = flat_landing_scene(n, eps=EPS_LIMIT, T=T, nt=max(1, round(T * n / ratio)), alpha=alpha)
    ops = scene_problem(scene, inelastic, MPI.COMM_SELF).operators()
    interior = np.ones(ops.m.size, dtype=bool)
    interior[np.argsort(ops.m)[:2]] = False  # the ends: the two nodes with half a cell of mass
    dt_max = largest_stable_dt(ops, interior)
    row = {"scheme": scheme, "alpha": alpha, "dt_over_dx": scene.dt / scene.dx, "dt_max_over_dx": dt_max / scene.dx}
    window = max(0.1, 2 * scene.dt)
    if scheme != "projection":
        return row | _simulated(scene, window, scheme=scheme)[0]
    # ½|v|² + ½|η|²_K is bounded by the scheme's modified energy when it is stable
    e, energy, measured = _finite_difference(fd_projection, scene, window)
    growth = not np.all(np.isfinite(energy)) or np.max(energy) > 2 * energy[0]
    outcome = "growth" if growth else ("rebound" if e > REBOUND_THRESHOLD else "inelastic")
    if scene.dt > dt_max and not growth:
        outcome = "refused"  # stable here, but simulate refuses it (dt_max is a sufficient bound)
    return row | measured | {"outcome": outcome, "restitution": e}


def step_size_map(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Rows of STEP_COLUMNS: projection and newmark over Δt/Δx, with and without viscosity."""
    ratios = (0.9, 1.0, 1.2, 4.0) if quick else STEP_RATIOS
    n = 100 if quick else 200
    cases = [(scheme, a, c) for scheme in ("projection", "newmark") for a in (0.0, 0.01) for c in ratios]
    return distribute(lambda c: step_size_case(*c, n=n), cases, comm, busy=busy)


def spring_case(r: float, n: int = 200, T: float = 0.45) -> dict:
    """The elastic (spring) law, explicit, at Δt = Δx, ε = Δt/r: growth is its only failure (it bounces by design)."""
    from ..model import variants

    scene = flat_landing_scene(n, eps=1.0 / n / r, T=T)
    measured, res = _simulated(scene, model=variants.elastic)
    row = {"penalty": "explicit spring", "mass": "lumped", "dt": scene.dt, "eps": scene.eps, "r": r,
           "restitution_theory": math.nan}
    return row | measured | ({"outcome": "growth"} if res is None else {"outcome": "stable", "growth_step": -1})


def alpha_sweep(quick: bool = False, comm=None, busy: list | None = None) -> list[dict] | None:
    """Flat landing (Δt = Δx = 1/200, T = 0.6) for α from 0.1 down to 0: restitution and where the energy went."""
    alphas = (0.1, 0.01, 0.0) if quick else (0.1, 0.03, 0.01, 0.003, 0.001, 0.0)
    methods = {"explicit r=1": ("explicit", 1.0), "explicit r=1.5": ("explicit", 1.5),
               "semi-implicit eps->0": ("semi-implicit", None)}
    n = 100 if quick else 200
    cases = [(name, a) for name in methods for a in alphas]

    def one(case):
        name, alpha = case
        penalty, r = methods[name]
        dt = 1.0 / n
        eps = dt / r if r else EPS_LIMIT
        scene = flat_landing_scene(n, eps=eps, alpha=alpha)
        res = simulate_self(scene, penalty=penalty, storage=sc.Storage(max_rows=scene.nt))
        E0 = res.total_energy[0]
        return {"method": name, "alpha": alpha, "dt": dt, "eps": eps, "r": dt / eps, "final_energy":
                res.total_energy[-1] / E0, "restitution": restitution(res.t, res.x, res.velocity),
                **{k: res.energy[k][-1] / E0 for k in ("contact_dissipation", "numerical_dissipation",
                                                        "viscous_dissipation")}}

    return distribute(one, cases, comm, busy=busy)
