"""The studies' charts (matplotlib) from `stringcontact.analysis`'s rows: work-precision, convergence, the stability
and step-size maps; and the paper's Figure 1 on a computed solution, its numbers measured by the theorem checks
(`stringcontact.analysis.theorems.draw_figure1`); what else they need (legend labels, the impact speed) is passed in."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from ..io.publish import atomic_path
from .charts import figure, literal, savefig
from .style import SCREEN


@contextlib.contextmanager
def study_figure(path, *args, figsize, layout=None, **kwargs):
    """``with study_figure(path, rows, cols, figsize=...) as (fig, axes):``, written to `path` whole when it ends."""
    fig = figure(figsize, layout=layout)
    yield fig, fig.subplots(*args, **kwargs)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")


STYLE = {
    "paper": {"color": "#d62728", "marker": "s"},
    "explicit-r1": {"color": "#ff7f0e", "marker": "^"},
    "semi-implicit": {"color": "#1f77b4", "marker": "o"},
    "consistent": {"color": "#2ca02c", "marker": "D"},
    "projection": {"color": "#9467bd", "marker": "P"},
    "newmark": {"color": "#8c564b", "marker": "X"},
}
ERROR_LABELS = {
    "err_eta": r"error of $\eta$ in $L^\infty(0,T;L^2)$",
    "err_vel": r"error of $\eta_t(T)$ in $L^2$",
    "err_contact": "contact-set error (space-time measure)",
}


def plot_work_precision(rows: list[dict], path, labels: dict) -> Path:
    """Error against wall-clock time, log-log: a row per problem, a panel per error, a line per method in `labels`."""
    probs = list(dict.fromkeys(r["problem"] for r in rows))
    with study_figure(path, len(probs), 3, figsize=(15, 4.6 * len(probs)), squeeze=False, layout="constrained") as (fig, axes):
        for i, p in enumerate(probs):
            for j, key in enumerate(ERROR_LABELS):
                ax = axes[i, j]
                for m, label in labels.items():
                    sel = sorted((r for r in rows if r["problem"] == p and r["method"] == m and r["status"] == "complete"
                                  and np.isfinite(r[key]) and r[key] > 0), key=lambda r: r["nx"])
                    style = STYLE[m]
                    if sel:
                        ax.loglog([r["wall_s"] for r in sel], [r[key] for r in sel], "-", color=style["color"], label=label)
                    for r in sel:  # hollow markers: 1 < r < 2, a (spurious) rebound
                        hollow = r["r"] > 1 + 1e-9 and r["penalty"] == "explicit"
                        ax.loglog(r["wall_s"], r[key], style["marker"], color=style["color"],
                                  mfc="white" if hollow else style["color"])
                        ax.annotate(f"{int(r['nx'])}", (r["wall_s"], r[key]), fontsize=6, alpha=0.6,
                                    xytext=(3, 3), textcoords="offset points")
                ax.set(xlabel="wall-clock time of one run [s]", ylabel=ERROR_LABELS[key])
                ax.grid(True, which="both", alpha=0.3)
                title = "flat landing (exact, α = 0)" if p == "flat-landing" else "Example 1 (vs fine reference)"
                ax.set_title(title, fontsize=10)
            axes[i, 0].legend(fontsize=7, loc="lower left")
        fig.suptitle("Work-precision: lower left is better; numbers are nx (Δt = Δx = 1/nx); "
                     "hollow = 1 < Δt/ε < 2 (rebounds); missing = refused (Δt/ε ≥ 2)", fontsize=10)
    return Path(path)


def plot_convergence(result: dict, path, labels: dict, impact_speed: float) -> Path:
    """Errors against Δt = Δx with reference slopes; penetration (against ε·`impact_speed`) and error against ε."""
    rows = result["runs"]
    with study_figure(path, 1, 3, figsize=(15, 4.4)) as (_fig, axes):
        ax = axes[0]
        for m in ("explicit-r1", "semi-implicit", "consistent"):
            sel = sorted((r for r in rows if r["sweep"] == "dt" and r["method"] == m and r["status"] == "complete"),
                         key=lambda r: r["dt"])
            style = STYLE[m]
            ax.loglog([r["dt"] for r in sel], [r["err_eta"] for r in sel], "-" + style["marker"], color=style["color"],
                      label=f"{labels[m]}: η")
            ax.loglog([r["dt"] for r in sel], [r["err_vel"] for r in sel], ":" + style["marker"], color=style["color"],
                      mfc="white", label=f"{m}: velocity at T")
        dt_rows = [r for r in rows if r["sweep"] == "dt" and r["status"] == "complete"]
        if dt_rows:  # reference slopes through the finest η error, drawn a little below it
            dts = np.array(sorted({r["dt"] for r in dt_rows}))
            e0 = 0.6 * min(r["err_eta"] for r in dt_rows)
            for p, ls in ((0.5, "--"), (1.0, "-.")):
                ax.loglog(dts, e0 * (dts / dts[0]) ** p, "k" + ls, lw=0.8, label=f"slope {p}")
        ax.set(xlabel="Δt = Δx", ylabel="error (flat landing, exact)")
        ax.legend(fontsize=6)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_title("refinement in Δt = Δx", fontsize=10)
        eps_rows = [r for r in rows if r["sweep"] == "eps" and r["status"] == "complete"]
        for ax, key, label in ((axes[1], "penetration", "penetration −min η"), (axes[2], "err_eta", ERROR_LABELS["err_eta"])):
            for p, color in (("explicit", STYLE["paper"]["color"]), ("semi-implicit", STYLE["semi-implicit"]["color"])):
                sel = sorted((r for r in eps_rows if r["penalty"] == p), key=lambda r: r["eps"])
                vals = [(-r["min_eta"] if key == "penetration" else r[key]) for r in sel]
                ax.loglog([r["eps"] for r in sel], vals, "-o", color=color, label=f"{p} penalty")
            if eps_rows:
                dt = eps_rows[0]["dt"]
                ax.axvline(dt, color="gray", ls=":", lw=1)
                ax.text(dt, ax.get_ylim()[0], " ε = Δt", fontsize=7, color="gray", va="bottom")
                if key == "penetration":
                    e = np.array(sorted({r["eps"] for r in eps_rows}))
                    ax.loglog(e, impact_speed * e, "k--", lw=0.8, label="ε·V")
            ax.set(xlabel="ε", ylabel=label)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
            ax.set_title(f"ε → 0 at Δt = Δx = {eps_rows[0]['dt']:.3g}" if eps_rows else "ε → 0", fontsize=10)
    return Path(path)


OUTCOME_COLOURS = {"inelastic": "#4daf4a", "rebound": "#ffb000", "growth": "#e41a1c", "refused": "#999999",
                   "stable": "#377eb8"}


def _outcome_map(ax, lines: dict, x: str, fontsize: int, below: float) -> None:
    """{(y, label): rows}: each line's rows as squares over their `x` (log scale) coloured by outcome, and the
    outcomes' colours as a legend under `ax` (`below`: its top, in axes coordinates)."""
    for (y, _), sel in lines.items():
        ax.scatter([r[x] for r in sel], [y] * len(sel), s=70, marker="s", edgecolors="k", linewidths=0.3,
                   c=[OUTCOME_COLOURS[r["outcome"]] for r in sel])
    ax.set_xscale("log")
    ax.set_yticks([y for y, _ in lines], [label for _, label in lines], fontsize=fontsize)
    for outcome, colour in OUTCOME_COLOURS.items():
        ax.scatter([], [], marker="s", color=colour, label=outcome, edgecolors="k", linewidths=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, below), ncol=4)


def plot_stability(rows: list[dict], alpha_rows: list[dict] | None, path) -> Path:
    """The map (outcome over r and Δt per treatment), restitution against r with the theory, the α sweep."""
    treatments = list(dict.fromkeys((r["penalty"], r["mass"]) for r in rows))
    ncols = 2 + (1 if alpha_rows else 0)
    with study_figure(path, 1, ncols, figsize=(5.2 * ncols, 4.6)) as (_fig, axes):
        ax = axes[0]
        lines, y = {}, -1
        for pen, mass in treatments:
            y += 1  # a gap between the treatments
            for dt in sorted({r["dt"] for r in rows}, reverse=True):
                sel = [r for r in rows if (r["penalty"], r["mass"], r["dt"]) == (pen, mass, dt)]
                if sel:  # the spring is swept at one Δt only
                    y += 1
                    lines[(y, f"{pen}, {mass}, Δt={dt:.3g}")] = sel
        _outcome_map(ax, lines, "r", 7, -0.13)
        for x0 in (1.0, 2.0):
            ax.axvline(x0, color="k", ls=":", lw=0.8)
        ax.set_xlabel("r = Δt/ε   (dotted: r = 1, r = 2)")
        ax.set_title("outcome of a flat landing (α = 0)", fontsize=10)

        ax = axes[1]
        rr = np.logspace(-1, np.log10(4), 200)
        ax.plot(rr, np.maximum(rr - 1, 0), "k-", lw=1, label="theory (explicit): max(r − 1, 0)")
        for (pen, mass), marker in zip(treatments, ("o", "x", "D")):
            sel = [r for r in rows if (r["penalty"], r["mass"]) == (pen, mass) and np.isfinite(r["restitution"])
                   and r["restitution"] <= 3]
            ax.plot([r["r"] for r in sel], [r["restitution"] for r in sel], marker, ls="none", mfc="none",
                    label=f"measured: {pen}, {mass}")
        ax.set(xscale="log", xlabel="r = Δt/ε", ylabel="restitution (upward / downward velocity)", ylim=(-0.05, 3.05))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title("restitution at the middle node", fontsize=10)

        if alpha_rows:
            ax = axes[2]
            names = list(dict.fromkeys(r["method"] for r in alpha_rows))
            for name, colour in zip(names, ("#ff7f0e", "#d62728", "#1f77b4")):
                sel = sorted((r for r in alpha_rows if r["method"] == name), key=lambda r: r["alpha"])
                a = [max(r["alpha"], 1e-4) for r in sel]
                ax.semilogx(a, [r["numerical_dissipation"] for r in sel], "-o", color=colour, label=f"{name}: numerical")
                ax.semilogx(a, [r["contact_dissipation"] for r in sel], "--s", color=colour, mfc="white",
                            label=f"{name}: contact")
                ax.semilogx(a, [r["restitution"] for r in sel], ":^", color=colour, label=f"{name}: restitution")
            ax.set(xlabel="α (α = 0 drawn at 1e-4)", ylabel="fraction of E(0) dissipated by T / restitution")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=6)
            ax.set_title("α → 0: what is left is the scheme's own dissipation", fontsize=10)
    return Path(path)


def plot_step_size(rows: list[dict], path) -> Path:
    """Outcome over Δt/Δx for the schemes without ε, with each one's Δt_max from the operators."""
    keys = list(dict.fromkeys((r["scheme"], r["alpha"]) for r in rows))
    with study_figure(path, 1, 1, figsize=(7.5, 3.2)) as (_fig, ax):
        lines = {(y, f"{scheme}, α = {alpha:g}"): [r for r in rows if (r["scheme"], r["alpha"]) == (scheme, alpha)]
                 for y, (scheme, alpha) in enumerate(keys)}
        _outcome_map(ax, lines, "dt_over_dx", 8, -0.22)
        for (y, _), sel in lines.items():
            if sel[0]["scheme"] == "projection":
                ax.plot([sel[0]["dt_max_over_dx"]] * 2, [y - 0.4, y + 0.4], "k-", lw=1.5)
        ax.set_ylim(-0.7, len(keys) - 0.3)
        ax.set_xlabel("Δt/Δx   (bar: projection's Δt_max from the operators)")
        ax.set_title("flat landing: where the ε-free schemes fail", fontsize=10)
    return Path(path)


def plot_figure1(result, path, front_force_rate, stress_jump_rate, all_force_rate, delta: float = 0.02,
         title: str | None = None, look=None):
    """Left: the contact set over (x, t), its free boundary and the force density F (log colour). Right: the force on
    the fronts per unit time against the stress jump −[η_x + α η_tx] in a band ±`delta` (Theorem 2.3(1)), and all
    the force; written in each format of `look` (default: PNG on a screen)."""
    look = look or SCREEN
    with look.drawn():
        from matplotlib.colors import ListedColormap, LogNorm

        x, t = result.x, result.t
        F = np.ma.masked_less_equal(result.contact_force, 0.0)
        fig = figure((look.width, 0.42 * look.width))
        ax, bx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.2, 1]})
        extent = (x[0], x[-1], t[0], t[-1])
        ax.imshow(result.contact, origin="lower", aspect="auto", extent=extent,
                  cmap=ListedColormap(["white", "0.85"]), interpolation="nearest")
        if F.count():
            im = ax.imshow(F, origin="lower", aspect="auto", extent=extent, cmap="inferno_r",
                           norm=LogNorm(vmin=max(F.max() * 1e-4, F.min()), vmax=F.max()), interpolation="nearest")
            fig.colorbar(im, ax=ax, label="contact force density F")
        if result.contact.any() and not result.contact.all():
            ax.contour(x, t, result.contact.astype(float), levels=[0.5], colors="tab:blue", linewidths=0.8)
        ax.plot([], [], color="tab:blue", label=r"free boundary $\partial\{\eta=0\}$")
        ax.fill_between([], [], color="0.85", label=r"contact set $\{\eta\leq 0\}$")
        ax.set(xlabel="x", ylabel="t")
        ax.legend(loc="upper right", fontsize="small")
        ax.set_title(title or f"{literal(result.scene.name)}: contact set and force\n"
                     f"model {getattr(result, 'model', None) or 'inelastic'}, scheme {getattr(result, 'scheme', 'paper')}")
        bx.plot(t, front_force_rate, color="tab:red", lw=1, label=r"force on the fronts $\sum m_jF_j$")
        bx.plot(t, stress_jump_rate, color="tab:blue", lw=1, label=r"stress jump $-[\eta_x+\alpha\eta_{tx}]$")
        bx.plot(t, all_force_rate, color="0.5", lw=0.8, ls="--", label=r"all force $\int F\,dx$")
        bx.set_yscale("symlog", linthresh=1.0)
        bx.set(xlabel="t", ylabel="force per unit time", title=f"Theorem 2.3(1): band +-{delta:g} around the fronts")
        bx.legend(fontsize="small")
        savefig(fig, Path(path), look)
    return path
