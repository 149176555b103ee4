# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # A stiff string: bending stiffness, inharmonic modes and the bend at contact
#
# A real string (a piano's) resists bending as well as stretching. With a bending stiffness $\beta$ (in string
# units, $\beta = EI/(T l^2)$) the paper's string becomes
#
# $$\eta_{tt} - \alpha\eta_{txx} - \eta_{xx} + \beta\,\eta_{xxxx} = F, \qquad \eta = h,\ \eta_{xx} = 0
#   \text{ at the pinned ends,}$$
#
# the equation of musical acoustics' string–barrier collisions. The model `stiff_string` writes the fourth
# derivative with a second P1 unknown, the curvature $\kappa = -\eta_{xx}$ (a mixed method), tested with $w$ and
# $r$ (both 0 at the ends):
#
# $$\int \eta_{tt} w + \alpha\,\eta_{tx} w_x + \eta_x w_x + \beta\,\kappa_x w_x - F w
#   \;+\; \int \kappa\, r - \eta_x r_x \;=\; 0, \qquad \kappa = 0 \text{ at the ends.}$$
#
# The curvature's row does not involve $\beta$: it is well posed at $\beta = 0$ too, where it gives the
# paper's string back, and $\kappa$ is always the string's curvature. The energy it stores is
# $\int \tfrac12\eta_x^2 + \tfrac\beta2\kappa^2$, which the ledger books. A scene sets $\beta$ in its
# parameters table:
#
# ```toml
# model = "stiff_string"
# [parameters]
# beta = 0.004
# ```

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

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_stiff_string"))
OUT.mkdir(parents=True, exist_ok=True)
BETA = 0.004


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(scene, **kwargs)
# -

# ## Inharmonic modes: the dispersion relation
#
# A mode $\sin(m\pi x)$ of a string without damping and contact oscillates with
#
# $$\omega_m^2 = (m\pi)^2 + \beta\,(m\pi)^4, \qquad \frac{\omega_m}{m\,\omega_1^{(0)}} = \sqrt{1 + \beta (m\pi)^2}:$$
#
# its overtones are sharp, more so the higher they are (a piano's inharmonicity, $B = \beta\pi^2$). We start
# each mode small and high above the obstacle, march it with `newmark` (the midpoint rule: it conserves the
# energy, so the period is not damped away) and read $\omega$ from the zero crossings of the mode's amplitude.

# +
NX = 64 if FAST else 128


def measured_omega(m: int) -> float:
    scene = sc.Scene.from_dict({"name": f"mode{m}", "length": 1.0, "T": 2.5, "dt": 5e-4, "nx": NX, "alpha": 0.0,
                                "eps": 1e-3, "h": 1.0, "eta0": f"1 + 1e-3*sin({m}*pi*x)", "v0": "0",
                                "model": "stiff_string", "parameters": {"beta": BETA}})
    r = run(scene, scheme="newmark", storage=sc.Storage(max_rows=scene.nt + 1))
    a = 2 * trapezoid((r.eta - 1.0) * np.sin(m * np.pi * r.x), r.x, axis=1)  # the mode's amplitude a(t)
    k = np.flatnonzero(np.sign(a[:-1]) * np.sign(a[1:]) < 0)
    crossings = r.t[k] - a[k] * (r.t[k + 1] - r.t[k]) / (a[k + 1] - a[k])
    return np.pi * (len(crossings) - 1) / (crossings[-1] - crossings[0])


modes = np.arange(1, 6)
measured = np.array([measured_omega(m) for m in modes])
exact = np.sqrt((modes * np.pi) ** 2 + BETA * (modes * np.pi) ** 4)
for m, w, e in zip(modes, measured, exact):
    print(f"mode {m}: omega = {w:.5f}, dispersion relation {e:.5f}, string without bending {m * np.pi:.5f}")
print(f"dispersion relation: largest relative error {np.max(np.abs(measured / exact - 1)):.2e} at nx = {NX}")
# -

# The overtones' sharpening, $\omega_m / (m\pi)$, computed and from the relation:

# +
fig, ax = plt.subplots(figsize=(6, 4))
fine = np.linspace(1, modes[-1], 100)
ax.plot(fine, np.sqrt(1 + BETA * (fine * np.pi) ** 2), "k-", label=r"$\sqrt{1 + \beta (m\pi)^2}$")
ax.plot(modes, measured / (modes * np.pi), "o", label=f"stiff_string, nx = {NX}")
ax.set(xlabel="mode m", ylabel=r"$\omega_m / (m\pi)$", title=f"inharmonicity, β = {BETA:g}")
ax.legend()
fig.savefig(OUT / "stiff_string_modes.png", dpi=90)
# -

# ## A landing: the bend at the contact set
#
# Now the string is thrown onto the obstacle $y = 0$ under `projection`, the scheme that enforces
# $\eta \ge 0$ exactly by its contact step. A string without bending stiffness meets the obstacle with a kink at
# the edges of its contact set: its discrete curvature $-\eta_{xx}$ is a spike there, the jump of $\eta_x$ over
# one cell, which grows as $\Delta x$ shrinks. The stiff string cannot kink: it bends over a length of order
# $\sqrt\beta$, its curvature stays bounded (the obstacle's reaction on a bending string concentrates at the
# contact set's edges, where $\kappa$ has a corner), and it lands on a shorter stretch and lifts off sooner.
# `projection`'s elastic term is explicit, and the bending in it too: its stable step shrinks like
# $\Delta x^2/\sqrt\beta$ (`stiff_string.stable_dt`), and the scheme refuses a larger one.

# +
NXL = 100 if FAST else 200
land = sc.Scene.from_dict({"name": "landing", "length": 1.0, "T": 0.3, "dt": 2e-4 if FAST else 5e-5, "nx": NXL,
                           "alpha": 0.01, "eps": 1e-3, "h": 0.1, "eta0": "0.1 + 0.2*sin(pi*x)", "v0": "-4*sin(pi*x)",
                           "model": "stiff_string"})
landings = {beta: run(land.replace(parameters={"beta": beta}), scheme="projection",
                      storage=sc.Storage(max_rows=land.nt + 1)) for beta in (0.0, BETA)}
fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
for beta, r in landings.items():
    n = int(np.argmax(r.contact.sum(axis=1)))  # the stored time of the largest contact set
    kappa = r.fields["curvature"][n]
    edges = np.flatnonzero(np.diff(r.contact[n].astype(int)))
    peak = np.max(np.abs(kappa[max(edges.min() - 5, 0):edges.max() + 6])) if edges.size else 0.0
    ax.plot(r.x, r.eta[n], label=f"β = {beta:g}, t = {r.t[n]:.3f}")
    bx.plot(r.x, kappa, label=f"β = {beta:g}")
    print(f"beta = {beta:g}: largest contact set {r.contact[n].mean():.2f} of the string at t = {r.t[n]:.3f}, "
          f"largest |curvature| at its edges {peak:.3g}; lowest eta {r.eta.min():.2e}; "
          f"energy ledger closes: {r.checks['energy_balance']['closes']}")
ax.axhline(0, color="0.5", lw=3)
ax.set(xlabel="x", ylabel="η at the largest contact set")
bx.set(xlabel="x", ylabel="curvature κ = −η_xx")
ax.legend()
bx.legend()
fig.savefig(OUT / "stiff_string_landing.png", dpi=90)
stiff = landings[BETA]
print(f"the landing stays above the obstacle: {bool(stiff.eta.min() >= -1e-12)}")
print(f"the contact force is >= 0 and 0 off the contact set: "
      f"{bool(stiff.contact_force.min() >= 0 and np.all(stiff.contact_force[~stiff.contact] == 0))}")
# -
