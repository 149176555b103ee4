"""The paper's Figure 1 on a computed solution (matplotlib): the numbers come from the theorem checks
(`stringcontact.analysis.theorems.draw_figure1` measures them and calls :func:`draw`); this module only draws."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .charts import figure, literal, savefig
from .style import SCREEN


def draw(result, path, front_force_rate, stress_jump_rate, all_force_rate, delta: float = 0.02,
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
