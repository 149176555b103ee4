# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # A string landing on a viscous film
#
# The paper's inelastic law (the velocity vanishes on contact) stands for contact inside a viscous fluid.
# The model `film` puts the fluid in: a thin Reynolds film of viscosity $\mu$ fills the gap $\eta$ between
# the string and the obstacle, and its pressure pushes the string,
#
# $$\eta_{tt} - \alpha\eta_{txx} - \eta_{xx} = p - p_a, \qquad
#   \eta_t = \Bigl(\frac{\max(\eta, h_{min})^3}{12\mu}\,p_x\Bigr)_x, \qquad p = p_a \text{ at the ends.}$$
#
# A flat string thrown down onto a film stops before the obstacle: the pressure under it grows like
# $1/\eta^3$. The thinner the fluid, the closer it comes, and the closer its motion is to the inelastic
# landing (docs/explanation/film.md has the study).

# +
import os
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import stringcontact as sc
from stringcontact.fem.compat import trapezoid

OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_film"))  # where the picture goes
OUT.mkdir(parents=True, exist_ok=True)
flat = sc.load_scene("film_landing").replace(name="flat", eta0="0.2", v0="-1", h=0.2, T=0.6, dt=0.001, nx=100,
                                            output_times=[], model=None, parameters=None, scheme=None)


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)


inelastic = run(flat, scheme="projection")
films = {mu: run(flat.replace(model="film", parameters={"mu": mu}, eps=1e-6), scheme="paper", penalty="semi-implicit")
         for mu in (1e-3, 1e-2, 1e-1)}
# -

# The middle of the string, and the film's pressure there, against time: the film brakes the string before
# it lands, and with a thicker fluid it never reaches the obstacle.

# +
mid = len(flat.x()) // 2
fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
ax.plot(inelastic.t, inelastic.eta[:, mid], "k", label="inelastic (projection)")
for mu, r in films.items():
    ax.plot(r.t, r.eta[:, mid], label=f"film, μ = {mu:g}")
    bx.plot(r.t, r.fields["pressure"][:, mid], label=f"μ = {mu:g}")
ax.set(xlabel="t", ylabel="η(l/2, t)")
bx.set(xlabel="t", ylabel="p − p_a at l/2", yscale="symlog")
ax.legend()
bx.legend()
fig.savefig(OUT / "demo_film.png", dpi=90)
# -

# The distance to the inelastic landing in $L^\infty(0,T;L^2)$ falls with $\mu$, and the ledger books the
# film's dissipation $\int \eta^3 p_x^2/(12\mu)$ with the viscous one: it closes.

for mu, r in films.items():
    distance = np.sqrt(trapezoid((r.eta - inelastic.eta) ** 2, r.x, axis=1)).max()
    print(f"mu = {mu:g}: thinnest film {r.eta[:, 1:-1].min():.3g}, distance to the inelastic landing "
          f"{distance:.3g}, energy ledger closes: {r.checks['energy_balance']['closes']}")
    assert r.checks["energy_balance"]["closes"]
distances = [np.sqrt(trapezoid((r.eta - inelastic.eta) ** 2, r.x, axis=1)).max() for r in films.values()]
assert distances[0] < distances[1] < distances[2]
