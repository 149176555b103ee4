"""`stringcontact study film`: the film swept over its viscosity μ on two throws, with and without cavitation, against
the inelastic landing and the penalty at ε → 0; `fit_rates` fits power laws in μ; `plot_film_study` draws the
measures against μ (matplotlib)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

import stringcontact as sc

from ..errors import InstabilityError, SolverError
from ..plot.study_charts import study_figure
from .convergence import fitted_order, l2_norm
from .problems import EPS_LIMIT, simulate_self

#: The viscosities swept per problem: from where the backstop still acts to where the film holds the string well up.
MUS = {"example1": (0.1, 1.0, 10.0, 100.0, 1000.0), "flat": (1e-4, 1e-3, 1e-2, 1e-1, 1.0)}
QUICK_MUS = {"example1": (1.0, 100.0), "flat": (1e-3, 1e-1)}
#: `t_up`: the first time after η(x*) is least at which it has risen by this fraction of its initial height.
RISE = 0.05
#: The film runs' backstop, the semi-implicit penalty's ε (at 1e-9 Newton's line search failed on Example 1, μ = 1e-5).
FILM_EPS = 1e-6
#: Cavitation: none, or half-Sommerfeld p >= p_a.
CAVITATION = (None, 0.0)
FILM_COLUMNS = ("problem", "method", "mu", "p_cav", "min_gap", "energy_lost", "rebound", "t_up", "dist_before",
                "dist_after", "t_lift", "E0", "newton_per_step", "status")
RATE_COLUMNS = ("problem", "p_cav", "quantity", "rate", "mus")


def problem_scenes(quick: bool = False) -> dict:
    """The two throws without a film: film_landing's (Example 1's) and the flat landing (η0 = h = 0.2, v0 = −1)."""
    example = sc.load_scene("film_landing").replace(nx=100 if quick else 200, dt=0.00025, T=0.15 if quick else 0.3,
                                                    output_times=[], model=None, parameters=None, scheme=None,
                                                    name="film-example1")
    flat = example.replace(name="film-flat", eta0="0.2", v0="-1", h=0.2, T=0.4 if quick else 0.8, dt=0.0005)
    return {"example1": example, "flat": flat}


def _run(scene, **kwargs):
    """`simulate_self` (on this rank alone: the sweep runs on rank 0) with every step stored and no warnings; a
    failed run's partial result, or None."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return simulate_self(scene, storage=sc.Storage(max_rows=scene.nt), **kwargs)
        except (InstabilityError, SolverError) as exc:
            return getattr(exc, "result", None)


def references(scene) -> dict:
    """The runs without a film: inelastic (projection) and the penalty at ε → 0 (paper, semi-implicit)."""
    return {"inelastic": _run(scene, scheme="projection"),
            "penalty": _run(scene.replace(eps=EPS_LIMIT), scheme="paper", penalty="semi-implicit")}


def film_run(scene, mu: float, p_cav):
    """The film at viscosity `mu` (cavitation at `p_cav`, or none), backed by the penalty at ε = `FILM_EPS`."""
    constants = {"mu": mu} | ({"p_cav": p_cav} if p_cav is not None else {})
    return _run(scene.replace(model="film", parameters=constants, eps=FILM_EPS), scheme="paper",
                penalty="semi-implicit")


def landing_times(reference) -> tuple[float, float, int]:
    """(first contact, first lift-off (T if none), x* the contact node nearest the middle at first contact)."""
    interior = reference.contact[:, 1:-1]
    touching = np.flatnonzero(interior.any(axis=1))
    if touching.size == 0:
        return reference.t[-1], reference.t[-1], len(reference.x) // 2
    first = touching[0]
    free = np.flatnonzero(~interior[first:].any(axis=1))
    lift = first + free[0] if free.size else len(reference.t) - 1
    nodes = np.flatnonzero(interior[first]) + 1
    star = nodes[np.argmin(np.abs(reference.x[nodes] - 0.5 * (reference.x[0] + reference.x[-1])))]
    return float(reference.t[first]), float(reference.t[lift]), int(star)


def measures(r, reference, t_lift: float, star: int) -> dict:
    """The study's numbers for run `r` against the inelastic `reference` (the same grid and stored times)."""
    if r is None or r.status != "complete":
        return {"min_gap": np.nan, "energy_lost": np.nan, "rebound": np.nan, "t_up": np.nan, "dist_before": np.nan,
                "dist_after": np.nan, "status": getattr(r, "status", "failed")}
    E = r.total_energy
    lift = int(np.searchsorted(r.t, t_lift - 1e-12))
    v = r.velocity[: lift + 1, star]
    fastest = int(np.argmin(v))
    rebound = max(float(np.max(v[fastest:])), 0.0) / abs(float(v[fastest])) if v[fastest] < 0 else np.nan
    d = l2_norm(r.x, r.eta - reference.eta)
    return {"min_gap": float(np.min(r.eta[:, 1:-1])), "energy_lost": float(E[0] - E[lift]), "rebound": rebound,
            "t_up": rise_time(r, star), "dist_before": float(np.max(d[: lift + 1])),
            "dist_after": float(np.max(d[lift + 1:])) if lift + 1 < len(d) else np.nan, "status": r.status}


def rise_time(r, star: int) -> float:
    """The first time after η(x*) is least at which it has risen by `RISE` η(x*, 0) (nan if never): the lift-off."""
    eta = r.eta[:, star]
    low = int(np.argmin(eta))
    up = np.flatnonzero(eta[low:] >= eta[low] + RISE * abs(eta[0]))
    return float(r.t[low + up[0]]) if up.size else np.nan


def film_study(quick: bool = False, mus=None) -> list[dict]:
    """The sweep: one row per problem and run (the references, then the film at each μ and cavitation)."""
    rows = []
    for problem, scene in problem_scenes(quick).items():
        refs = references(scene)
        _, t_lift, star = landing_times(refs["inelastic"])
        base = {"problem": problem, "t_lift": t_lift, "E0": float(refs["inelastic"].total_energy[0])}
        for method, r in refs.items():
            rows.append(base | {"method": method, "mu": np.nan, "p_cav": np.nan, "newton_per_step": np.nan}
                        | measures(r, refs["inelastic"], t_lift, star))
        for p_cav in CAVITATION:
            for mu in (mus or (QUICK_MUS if quick else MUS))[problem]:
                r = film_run(scene, mu, p_cav)
                per_step = r.counters.get("newton iterations", np.nan) / scene.nt if r is not None else np.nan
                rows.append(base | {"method": "film", "mu": mu, "p_cav": np.nan if p_cav is None else p_cav,
                                    "newton_per_step": per_step} | measures(r, refs["inelastic"], t_lift, star))
    return rows


def fit_rates(rows: list[dict]) -> list[dict]:
    """Power laws in μ, q ≈ C μ^rate, fitted to the film's rows per problem and cavitation (finite, positive q)."""
    out, films = [], [r for r in rows if r["method"] == "film"]
    for group in dict.fromkeys((r["problem"], repr(r["p_cav"])) for r in films):  # repr: nan equals nan
        sel = [r for r in films if (r["problem"], repr(r["p_cav"])) == group]
        mu = np.array([r["mu"] for r in sel])
        for q in ("min_gap", "dist_before", "dist_after"):
            values = np.array([r[q] for r in sel], dtype=float)
            fitted = np.isfinite(values) & (values > 0)  # the points `fitted_order` fits
            out.append({"problem": group[0], "p_cav": sel[0]["p_cav"], "quantity": q,
                        "rate": fitted_order(mu, values), "mus": " ".join(f"{m:g}" for m in mu[fitted])})
    return out


#: The panels: (column, axis label, log scale).
PANELS = (
    ("min_gap", "thinnest film min η", True),
    ("energy_lost", "energy lost in the first impact / E(0)", False),
    ("t_up", "lift-off time at x* (η(x*) up by 5 %)", False),
    ("dist_before", r"$\|\eta_\mu - \eta_{inelastic}\|_{L^\infty(L^2)}$", True))
CAVITATION_STYLE = {False: {"color": "#1f77b4", "marker": "o", "label": "film"},
                    True: {"color": "#d62728", "marker": "s", "ls": "--", "label": "film, cavitation p ≥ p_a"}}
REFERENCE_STYLE = {"inelastic": {"color": "k", "ls": "-", "label": "inelastic (projection)"},
                   "penalty": {"color": "0.5", "ls": ":", "label": "penalty, ε → 0"}}


def plot_film_study(rows: list[dict], path, h_min: float) -> Path:
    """A row of panels per problem: each measure against μ, the film with and without cavitation, the references
    as horizontal lines; the distance panel shows before (solid) and after (hollow) the first lift-off."""
    probs = list(dict.fromkeys(r["problem"] for r in rows))
    with study_figure(path, len(probs), len(PANELS), figsize=(4.2 * len(PANELS), 3.6 * len(probs)), squeeze=False,
                      layout="constrained") as (_fig, axes):
        for i, p in enumerate(probs):
            mine = [r for r in rows if r["problem"] == p]
            e0 = {r["method"]: r for r in mine if r["method"] != "film"}
            for j, (key, label, log) in enumerate(PANELS):
                ax = axes[i, j]
                scale = next(r["E0"] for r in mine) if key == "energy_lost" else 1.0  # the energy over E(0)
                for cav, style in CAVITATION_STYLE.items():
                    sel = sorted((r for r in mine if r["method"] == "film" and np.isfinite(r["p_cav"]) == cav),
                                 key=lambda r: r["mu"])
                    mu = np.array([r["mu"] for r in sel])
                    y = np.array([r[key] for r in sel], dtype=float) / scale
                    if log and key != "min_gap":
                        y = np.where(y > 0, y, np.nan)
                    ax.plot(mu, y, **style)
                    if key == "dist_before":
                        after = np.array([r["dist_after"] for r in sel], dtype=float)
                        ax.plot(mu, after, mfc="none", **(style | {"label": style["label"] + ", after lift-off"}))
                for name, style in REFERENCE_STYLE.items():
                    value = e0.get(name, {}).get(key, np.nan) / scale
                    if np.isfinite(value) and (value > 0 or not log or key == "min_gap"):
                        ax.axhline(value, **style)
                ax.set_xscale("log")
                if key == "min_gap":  # the backstop's penetration is negative: linear near 0
                    ax.axhline(h_min, color="#2ca02c", ls="-.", label="h_min (mobility floor)")
                    ax.set_yscale("symlog", linthresh=1e-4)
                elif log:
                    ax.set_yscale("log")
                ax.set_xlabel("μ")
                ax.set_title(f"{p}: {label}", fontsize=9)
                ax.grid(True, which="both", alpha=0.3)
            axes[i, 0].legend(fontsize=7)
            axes[i, -1].legend(fontsize=7)
    return Path(path)

