"""The chart of `stringcontact study film` (matplotlib): the film's measures against its viscosity μ
(`analysis.film`'s rows)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plot.study_charts import study_figure

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

