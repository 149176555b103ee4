# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # A moving obstacle: a piston throws the string
#
# The obstacle may move: the scene's `obstacle` is an expression in $x$ and $t$, $\psi(x, t)$. The
# built-in scene `piston` holds a string at rest at height 0 (ends held there) on the top of a piston
# under its middle third, $|x - \tfrac12| < 0.2$, which rises at speed 2 and stops at height 0.3 at
# $t = 0.15$:
#
# $$\psi(x, t) = 0.3\,\min(t/0.15,\ 1)\ \text{ on } |x - \tfrac12| < 0.2, \qquad -1 \text{ elsewhere}.$$
#
# Scheme `projection` puts $\psi(\cdot, t^{n+1})$ into each step's constraint
# $\eta^{n+1} \ge \psi^{n+1}$: while the piston rises the string lies on it and moves with it; when the
# piston stops, the string keeps going up (it is thrown), flies, is pulled back by its tension and
# lands on the piston, inelastically.

# +
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import stringcontact as sc

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_piston"))
OUT.mkdir(parents=True, exist_ok=True)

scene = sc.load_scene("piston")
if FAST:  # half the grid, the same Δt/Δx
    scene = scene.replace(nx=100, nt=125)
print(scene.obstacle)
res = sc.simulate(scene)
# -

# ## The string on the piston, then in the air
#
# The middle node's height against the piston's top: equal (to round-off) while the piston rises, then
# the string flies above it and comes back.

# +
mid = int(np.argmin(np.abs(res.x - 0.5)))
psi = np.array([scene.obstacle_values(res.x, t) for t in res.t])
rising = res.t < 0.15
print(f"while rising: max |eta - psi| at the middle {np.max(np.abs(res.eta[rising, mid] - psi[rising, mid])):.1e}, "
      f"its speed {res.velocity[rising, mid][-1]:.3f}")
print(f"highest flight: eta = {res.eta[:, mid].max():.3f} at t = {res.t[np.argmax(res.eta[:, mid])]:.3f}")
fig, ax = plt.subplots(figsize=(6.5, 3.6), constrained_layout=True)
ax.plot(res.t, res.eta[:, mid], label="string at x = 1/2")
ax.plot(res.t, psi[:, mid], "--", label="piston top ψ(1/2, t)")
ax.set_xlabel("t")
ax.set_ylabel("height")
ax.legend()
picture = OUT / "piston.png"
fig.savefig(picture, dpi=120)
plt.close(fig)
print(f"wrote {picture}")
# -

# ## The piston's work in the energy ledger
#
# The contact force's work on the string, $\tfrac12 F\cdot(\eta^{n+1} - \eta^{n-1})$ per step, splits
# into the obstacle's work $\tfrac12 F\cdot(\psi^{n+1} - \psi^{n-1})$, booked as **external work**, and
# the work on the gap, booked as contact dissipation, which is $\ge 0$ because the constraint holds:
# the piston gives the string energy, the landing takes it. The ledger
# $E(0) + W_\mathrm{ext} = E(t) + D_\mathrm{visc} + D_\mathrm{con} + D_\mathrm{num}$ closes.

b = res.checks["energy_balance"]
print(f"piston's work {b['external_work']:.4f} = E(T) {b['final']:.4f} + viscous {b['viscous_dissipation']:.4f} "
      f"+ contact {b['contact_dissipation']:.4f} + numerical {b['numerical_dissipation']:.2g}; "
      f"relative residual {b['relative_residual']:.1e}, closes: {b['closes']}")
